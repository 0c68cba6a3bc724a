// Cell index of a coordinate on a regular lattice, for the voxel grids and the downsampler.
#pragma once

#include <cstdint>
#include <limits>

namespace cndt::core {

/// Where cell_index() puts values beyond +-1e9 cells, and NaN: no real point lies there, and a
/// neighbour offset of a few cells from it stays inside int32.
inline constexpr std::int32_t kFarCell = std::numeric_limits<std::int32_t>::min() + 16;

/// floor(x) as a 32-bit integer: a truncation and one correction instead of std::floor, which
/// baseline x86-64 (no SSE4.1) expands to a dozen instructions.
inline std::int32_t cell_index(double x) noexcept {
  constexpr double kLimit = 1.0e9;
  if (!(x > -kLimit && x < kLimit)) return kFarCell;
  const auto i = static_cast<std::int32_t>(x);  // towards zero
  return i - static_cast<std::int32_t>(x < static_cast<double>(i));
}

}  // namespace cndt::core
