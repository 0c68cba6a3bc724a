// Explicit little/big-endian loads and stores over byte spans. Packets are read field by field
// with these after their length has been checked; no struct is ever cast over wire bytes.
#pragma once

#include <bit>
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
inline std::uint64_t load_le64(ByteSpan b, std::size_t off) noexcept {
  return static_cast<std::uint64_t>(load_le32(b, off)) |
         (static_cast<std::uint64_t>(load_le32(b, off + 4)) << 32);
}
inline void store_le64(MutableByteSpan b, std::size_t off, std::uint64_t v) noexcept {
  store_le32(b, off, static_cast<std::uint32_t>(v & 0xFFFFFFFFu));
  store_le32(b, off + 4, static_cast<std::uint32_t>(v >> 32));
}
/// IEEE-754 binary64 / binary32, little-endian.
inline double load_le_f64(ByteSpan b, std::size_t off) noexcept {
  return std::bit_cast<double>(load_le64(b, off));
}
inline void store_le_f64(MutableByteSpan b, std::size_t off, double v) noexcept {
  store_le64(b, off, std::bit_cast<std::uint64_t>(v));
}
inline float load_le_f32(ByteSpan b, std::size_t off) noexcept {
  return std::bit_cast<float>(load_le32(b, off));
}
inline void store_le_f32(MutableByteSpan b, std::size_t off, float v) noexcept {
  store_le32(b, off, std::bit_cast<std::uint32_t>(v));
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
