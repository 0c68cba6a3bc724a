#include "cndt/vlp16/packet.hpp"

namespace cndt::vlp16 {

std::string_view packet_error_name(PacketError e) noexcept {
  switch (e) {
    case PacketError::kNone:
      return "ok";
    case PacketError::kWrongSize:
      return "wrong_size";
    case PacketError::kBadBlockFlag:
      return "bad_block_flag";
    case PacketError::kBadAzimuth:
      return "bad_azimuth";
    case PacketError::kBadFactoryBytes:
      return "bad_factory_bytes";
    case PacketError::kUnsupportedModel:
      return "unsupported_model";
    case PacketError::kBadTimestamp:
      return "bad_timestamp";
    case PacketError::kCount:
      break;
  }
  return "unknown";
}

PacketError validate_data_packet(core::ByteSpan payload, PacketHeader& header) noexcept {
  if (payload.size() != kDataPacketSize) return PacketError::kWrongSize;
  bool other_bank = false;
  for (int b = 0; b < kBlocksPerPacket; ++b) {
    const std::size_t off = static_cast<std::size_t>(b) * kBlockSize;
    const std::uint16_t flag = core::load_le16(payload, off);
    if (flag != kBlockFlagUpper) {
      // 0xDDFF/0xCCFF/0xBBFF are the lower banks of the HDL-64E and VLS-128.
      if (flag == 0xDDFF || flag == 0xCCFF || flag == 0xBBFF) {
        other_bank = true;
        continue;
      }
      return PacketError::kBadBlockFlag;
    }
    // 36000 itself is sent by real VLP-16 and HDL-32E units at the wrap; it reads as 0.
    if (core::load_le16(payload, off + 2) > 36000) return PacketError::kBadAzimuth;
  }
  if (other_bank) return PacketError::kUnsupportedModel;
  const std::uint8_t mode = payload[kReturnModeOffset];
  const std::uint8_t product = payload[kProductIdOffset];
  header.legacy_factory_bytes = (mode == 0 && product == 0);
  if (header.legacy_factory_bytes) {
    header.mode = ReturnMode::kStrongest;
  } else if (mode >= 0x37 && mode <= 0x39) {
    header.mode = static_cast<ReturnMode>(mode);
  } else {
    return PacketError::kBadFactoryBytes;
  }
  if (!header.legacy_factory_bytes && !model_from_product_id(product).has_value()) {
    return PacketError::kUnsupportedModel;
  }
  header.product_id = product;
  header.toh_us = core::load_le32(payload, kTimestampOffset);
  // A few microseconds past 3600 s are seen near the top of the hour on real units; anything
  // well beyond the hour cannot be a sensor clock.
  if (header.toh_us >= kMicrosPerHour + 10'000'000u) return PacketError::kBadTimestamp;
  return PacketError::kNone;
}

}  // namespace cndt::vlp16
