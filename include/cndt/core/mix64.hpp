// A 64-bit mixing function (the finalizer of the splitmix64 generator): consecutive inputs give
// independent-looking outputs, so a counter run through it is a repeatable random sequence.
#pragma once

#include <cstdint>

namespace cndt::core {

inline std::uint64_t mix64(std::uint64_t x) noexcept {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// The top 53 bits of a 64-bit value as a fraction in [0, 1).
inline double unit_fraction(std::uint64_t x) noexcept {
  return static_cast<double>(x >> 11) * 0x1.0p-53;
}

}  // namespace cndt::core
