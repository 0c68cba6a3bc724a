// Explicit little/big-endian loads and stores over byte spans. Packets are read field by field
// with these after their length has been checked; no struct is ever cast over wire bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace cndt::core {

using ByteSpan = std::span<const std::uint8_t>;
using MutableByteSpan = std::span<std::uint8_t>;

inline std::uint16_t load_le16(ByteSpan b, std::size_t off) noexcept {
  return static_cast<std::uint16_t>(b[off] | (b[off + 1] << 8));
}
inline std::uint32_t load_le32(ByteSpan b, std::size_t off) noexcept {
  return static_cast<std::uint32_t>(b[off]) | (static_cast<std::uint32_t>(b[off + 1]) << 8) |
         (static_cast<std::uint32_t>(b[off + 2]) << 16) |
         (static_cast<std::uint32_t>(b[off + 3]) << 24);
}
inline std::uint16_t load_be16(ByteSpan b, std::size_t off) noexcept {
  return static_cast<std::uint16_t>((b[off] << 8) | b[off + 1]);
}
inline std::uint32_t load_be32(ByteSpan b, std::size_t off) noexcept {
  return (static_cast<std::uint32_t>(b[off]) << 24) |
         (static_cast<std::uint32_t>(b[off + 1]) << 16) |
         (static_cast<std::uint32_t>(b[off + 2]) << 8) | static_cast<std::uint32_t>(b[off + 3]);
}
inline void store_le16(MutableByteSpan b, std::size_t off, std::uint16_t v) noexcept {
  b[off] = static_cast<std::uint8_t>(v & 0xFFu);
  b[off + 1] = static_cast<std::uint8_t>(v >> 8);
}
inline void store_le32(MutableByteSpan b, std::size_t off, std::uint32_t v) noexcept {
  for (std::size_t i = 0; i < 4; ++i)
    b[off + i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFu);
}
inline void store_be16(MutableByteSpan b, std::size_t off, std::uint16_t v) noexcept {
  b[off] = static_cast<std::uint8_t>(v >> 8);
  b[off + 1] = static_cast<std::uint8_t>(v & 0xFFu);
}
inline void store_be32(MutableByteSpan b, std::size_t off, std::uint32_t v) noexcept {
  for (std::size_t i = 0; i < 4; ++i) {
    b[off + i] = static_cast<std::uint8_t>((v >> (8 * (3 - i))) & 0xFFu);
  }
}

}  // namespace cndt::core
