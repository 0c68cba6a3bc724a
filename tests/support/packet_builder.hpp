// Builds VLP-16 family data packets field by field for tests.
#pragma once

#include <array>
#include <cstdint>

#include "cndt/core/bytes.hpp"
#include "cndt/vlp16/packet.hpp"

namespace cndt::test {

struct PacketBuilder {
  std::array<std::uint8_t, 1206> bytes{};

  PacketBuilder(std::uint8_t mode = 0x37, std::uint8_t product = 0x22) {
    for (int b = 0; b < 12; ++b) core::store_le16(bytes, static_cast<std::size_t>(b) * 100, 0xEEFF);
    bytes[1204] = mode;
    bytes[1205] = product;
  }
  PacketBuilder& azimuth(int block, std::uint16_t cdeg) {
    core::store_le16(bytes, static_cast<std::size_t>(block) * 100 + 2, cdeg);
    return *this;
  }
  /// Azimuths start, start + step, ... (wrapping at 36000).
  PacketBuilder& azimuths(int start, int step) {
    for (int b = 0; b < 12; ++b) azimuth(b, static_cast<std::uint16_t>((start + b * step) % 36000));
    return *this;
  }
  PacketBuilder& record(int block, int rec, std::uint16_t count, std::uint8_t refl) {
    const std::size_t off =
        static_cast<std::size_t>(block) * 100 + 4 + static_cast<std::size_t>(rec) * 3;
    core::store_le16(bytes, off, count);
    bytes[off + 2] = refl;
    return *this;
  }
  PacketBuilder& copy_record(int from_block, int from_rec, int to_block, int to_rec) {
    const auto at = [](int block, int rec) {
      return static_cast<std::size_t>(block) * 100 + 4 + static_cast<std::size_t>(rec) * 3;
    };
    for (std::size_t i = 0; i < 3; ++i)
      bytes[at(to_block, to_rec) + i] = bytes[at(from_block, from_rec) + i];
    return *this;
  }
  PacketBuilder& all_records(std::uint16_t count, std::uint8_t refl) {
    for (int b = 0; b < 12; ++b) {
      for (int r = 0; r < 32; ++r) record(b, r, count, refl);
    }
    return *this;
  }
  PacketBuilder& toh(std::uint32_t us) {
    core::store_le32(bytes, 1200, us);
    return *this;
  }
  [[nodiscard]] core::ByteSpan span() const { return core::ByteSpan(bytes); }
};

}  // namespace cndt::test
