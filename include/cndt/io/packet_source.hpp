// The seam between live input and replay: a UDP socket and a capture file both deliver sensor
// payloads through this interface (one virtual call per packet, none per point).
#pragma once

#include <chrono>
#include <cstdint>

#include "cndt/core/bytes.hpp"
#include "cndt/io/ip_address.hpp"

namespace cndt::io {

enum class PacketKind : std::uint8_t { kData, kPosition };

struct SourcePacket {
  PacketKind kind = PacketKind::kData;
  std::chrono::nanoseconds time{0};  ///< capture or receive time, Unix epoch
  core::ByteSpan payload;            ///< valid until the next call to next()
  IpAddress source;
  std::uint16_t source_port = 0;
  std::uint16_t dest_port = 0;
  std::uint64_t index = 0;  ///< record number in a capture (1-based), or receive count
};

enum class NextResult : std::uint8_t {
  kPacket,   ///< `packet` holds a payload
  kTimeout,  ///< nothing arrived in the time allowed (live sources only)
  kEnd,      ///< the input is exhausted (capture end, or the source was stopped)
};

class PacketSource {
 public:
  virtual ~PacketSource() = default;
  /// Delivers the next data or position payload. Live sources wait at most `timeout`.
  virtual NextResult next(SourcePacket& packet, std::chrono::milliseconds timeout) = 0;
};

}  // namespace cndt::io
