// A reader for the parts of the Vector DBC format that describe frame layouts: messages (BO_),
// signals (SG_: Intel and Motorola byte order, signed and unsigned, factor/offset, range, unit,
// multiplexing), value tables (VAL_) and comments (CM_). Used by `cndt listen --dbc` and by the
// tests that prove config/cndt.dbc alone decodes what cndt sends.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cndt/core/result.hpp"

namespace cndt::output {

struct DbcSignal {
  std::string name;
  unsigned start = 0;         ///< DBC start bit: the LSB for Intel, the MSB (sawtooth) for Motorola
  unsigned length = 0;        ///< bits, 1..64
  bool little_endian = true;  ///< @1 Intel, @0 Motorola
  bool is_signed = false;
  double factor = 1.0, offset = 0.0;
  double minimum = 0.0, maximum = 0.0;
  std::string unit;
  bool is_multiplexer = false;
  int multiplexed_by = -1;  ///< present only when the multiplexer has this value; -1: always
  std::map<std::int64_t, std::string> values;  ///< VAL_ table
  std::string comment;
  int line = 0;  ///< where it was declared

  /// The raw value in a frame's data (sign-extended when signed).
  [[nodiscard]] std::int64_t raw(std::span<const std::uint8_t> data) const noexcept;
  /// raw * factor + offset.
  [[nodiscard]] double physical(std::span<const std::uint8_t> data) const noexcept;
};

struct DbcMessage {
  std::uint32_t id = 0;  ///< without the extended flag
  bool extended = false;
  std::string name;
  unsigned length = 8;  ///< bytes
  std::string transmitter;
  std::vector<DbcSignal> signals;
  std::string comment;
  int line = 0;

  [[nodiscard]] const DbcSignal* signal(std::string_view name) const noexcept;
};

struct DbcDatabase {
  std::vector<DbcMessage> messages;
  [[nodiscard]] const DbcMessage* message(std::uint32_t id, bool extended) const noexcept;
  [[nodiscard]] const DbcMessage* message(std::string_view name) const noexcept;
};

/// Parses DBC text; errors name `source`, the line and what is wrong (exit code 65).
core::Result<DbcDatabase> parse_dbc(std::string_view text, const std::string& source);
/// Reads and parses a DBC file (66 when it cannot be read).
core::Result<DbcDatabase> load_dbc(const std::string& path);

}  // namespace cndt::output
