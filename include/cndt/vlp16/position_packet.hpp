// VLP-16 position (telemetry) packet, 512-byte payload on port 8308 (manual section 9.4).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "cndt/core/bytes.hpp"

namespace cndt::vlp16 {

enum class PpsState : std::uint8_t { kAbsent = 0, kSynchronizing = 1, kLocked = 2, kError = 3 };
std::string_view pps_state_name(PpsState s) noexcept;

struct PositionPacket {
  std::uint32_t toh_us = 0;  ///< sensor clock, microseconds past the hour
  PpsState pps = PpsState::kAbsent;
  bool has_nmea = false;  ///< a '$'-sentence is present at offset 206
  bool nmea_checksum_ok = false;
  bool fix_valid = false;       ///< GPRMC status 'A' or GPGGA quality > 0
  int utc_seconds_of_day = -1;  ///< hhmmss from the sentence, or -1
  std::array<char, 96> nmea{};  ///< the sentence without CR/LF, NUL-terminated
  [[nodiscard]] std::string_view sentence() const noexcept { return {nmea.data()}; }
};

enum class PositionError : std::uint8_t { kNone = 0, kWrongSize, kBadPps };

/// Reads a position packet after checking its size; the NMEA text is optional (no GPS attached).
PositionError parse_position_packet(core::ByteSpan payload, PositionPacket& out) noexcept;

/// Field `index` (0 = sentence id) of a comma-separated NMEA sentence, without the checksum;
/// empty when the sentence has fewer fields.
std::string_view nmea_field(std::string_view sentence, int index) noexcept;

}  // namespace cndt::vlp16
