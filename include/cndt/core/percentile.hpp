// The p-quantile (0..1) of a sample by the nearest-rank method; 0 for an empty sample.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace cndt::core {

inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::min<double>(
      static_cast<double>(v.size() - 1), std::ceil(p * static_cast<double>(v.size())) - 1));
  return v[i];
}

}  // namespace cndt::core
