// Where variable-size entries go in a circular buffer that holds them one after the other, in
// the order they came: each right after the one before, or at the start of the buffer when it
// does not fit before the end. The local map's scans and the scans handed to the mapper are kept
// this way.
#pragma once

#include <cstddef>

namespace cndt::core {

/// Elements [offset, offset + count) of the buffer.
struct RingRegion {
  std::size_t offset = 0, count = 0;
  [[nodiscard]] std::size_t end() const noexcept { return offset + count; }
  [[nodiscard]] bool overlaps(const RingRegion& o) const noexcept {
    return offset < o.end() && o.offset < end();
  }
};

/// The region for `n` elements after an entry that ends at `end`, in a buffer of `capacity`
/// (n <= capacity): at `end`, or at 0 when they do not fit before the end of the buffer.
inline RingRegion next_region(std::size_t end, std::size_t n, std::size_t capacity) noexcept {
  return {end + n > capacity ? 0 : end, n};
}

}  // namespace cndt::core
