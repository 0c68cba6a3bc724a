// Counter-based random numbers: the same (seed, stream, index) always gives the same value, so a
// simulated capture does not depend on evaluation order.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

#include "cndt/core/mix64.hpp"

namespace cndt::sim {

using core::mix64;

inline std::uint64_t hash(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) noexcept {
  return mix64(mix64(seed ^ mix64(stream)) ^ index);
}

/// Uniform in [0, 1).
inline double uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) noexcept {
  return core::unit_fraction(hash(seed, stream, index));
}

/// Standard normal (Box-Muller over two counter values).
inline double normal(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) noexcept {
  const double u1 = std::max(uniform(seed, stream, 2 * index), 1e-300);
  const double u2 = uniform(seed, stream, 2 * index + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

/// A sequential generator for building worlds.
class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream) : seed_(seed), stream_(stream) {}
  double uniform() noexcept { return sim::uniform(seed_, stream_, n_++); }
  double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }
  bool chance(double p) noexcept { return uniform() < p; }

 private:
  std::uint64_t seed_, stream_, n_ = 0;
};

}  // namespace cndt::sim
