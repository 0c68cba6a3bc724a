// sin x and 1 - cos x for the small angles of a scan's undistortion, where the point rotations
// run tens of thousands of times per scan.
#pragma once

#include <cmath>

namespace cndt::core {

/// s = sin x and v = 1 - cos x (the versine, without the cancellation of 1 - cos x near 0). For
/// |x| <= 0.5 rad, a turn of up to 5 rad/s over a 0.1 s scan, from their Taylor series up to
/// x^13 and x^14: the first terms left out are below 2.4e-17 and 7.3e-19 there, under half a unit
/// in the last place of the results. Otherwise from std::sin and std::cos.
inline void sin_versine(double x, double& s, double& v) {
  if (!(std::abs(x) <= 0.5)) {
    s = std::sin(x);
    v = 1.0 - std::cos(x);
    return;
  }
  const double x2 = x * x;
  // Horner in x^2: sin x = x (1 - x^2/3! + x^4/5! - ... - x^12/13!), and
  // 1 - cos x = x^2 (1/2! - x^2/4! + x^4/6! - ... - x^12/14!).
  s = x * (1.0 + x2 * (-1.0 / 6.0 +
                       x2 * (1.0 / 120.0 +
                             x2 * (-1.0 / 5040.0 +
                                   x2 * (1.0 / 362880.0 +
                                         x2 * (-1.0 / 39916800.0 + x2 * (1.0 / 6227020800.0)))))));
  v = x2 * (0.5 + x2 * (-1.0 / 24.0 +
                        x2 * (1.0 / 720.0 +
                              x2 * (-1.0 / 40320.0 +
                                    x2 * (1.0 / 3628800.0 + x2 * (-1.0 / 479001600.0 +
                                                                  x2 * (1.0 / 87178291200.0)))))));
}

}  // namespace cndt::core
