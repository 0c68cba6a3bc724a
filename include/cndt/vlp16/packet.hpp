// VLP-16 family data packet: layout constants and validation (VLP-16 manual section 9.3).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "cndt/core/bytes.hpp"
#include "cndt/vlp16/calibration.hpp"

namespace cndt::vlp16 {

inline constexpr std::size_t kDataPacketSize = 1206;
inline constexpr std::size_t kPositionPacketSize = 512;
inline constexpr std::uint16_t kDefaultDataPort = 2368;
inline constexpr std::uint16_t kDefaultPositionPort = 8308;
inline constexpr int kBlocksPerPacket = 12;
inline constexpr std::size_t kBlockSize = 100;  // flag(2) azimuth(2) 32 x (distance(2) refl(1))
inline constexpr int kRecordsPerBlock = 32;
inline constexpr std::size_t kTimestampOffset = 1200;  // uint32 LE, microseconds past the hour
inline constexpr std::size_t kReturnModeOffset = 1204;
inline constexpr std::size_t kProductIdOffset = 1205;
inline constexpr std::uint16_t kBlockFlagUpper = 0xEEFF;  // bytes FF EE read little-endian
inline constexpr std::uint32_t kMicrosPerHour = 3'600'000'000u;

/// Why a data packet was refused. Every refused packet is counted under exactly one reason.
enum class PacketError : std::uint8_t {
  kNone = 0,
  kWrongSize,         ///< payload is not 1206 bytes
  kBadBlockFlag,      ///< a block does not start with FF EE
  kBadAzimuth,        ///< a block azimuth above 36000 (36000 itself is the wrap, read as 0)
  kBadFactoryBytes,   ///< the return-mode byte is not 0x37/0x38/0x39
  kUnsupportedModel,  ///< HDL-64E banks or a product id cndt has no table for
  kBadTimestamp,      ///< microseconds past the hour beyond one hour plus a margin
  kCount,
};

std::string_view packet_error_name(PacketError e) noexcept;

struct PacketHeader {
  std::uint32_t toh_us = 0;  ///< time of the first firing of block 0, microseconds past the hour
  ReturnMode mode = ReturnMode::kStrongest;
  std::uint8_t product_id = 0;
  bool legacy_factory_bytes = false;  ///< firmware older than 3.0.29 leaves both bytes zero
};

/// Checks every field a decoder will read, before any of it is used. Fills `header` when the
/// packet is valid.
PacketError validate_data_packet(core::ByteSpan payload, PacketHeader& header) noexcept;

}  // namespace cndt::vlp16
