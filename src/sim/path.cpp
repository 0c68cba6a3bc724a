#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "cndt/sim/scene.hpp"

namespace cndt::sim {

Path::Path(const std::vector<Eigen::Vector2d>& points, bool closed, double step)
    : step_(step), closed_(closed) {
  // Resample the polyline at equal arc-length steps.
  std::vector<Eigen::Vector2d> pts = points;
  if (closed) pts.push_back(points.front());
  std::vector<double> cum(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) cum[i] = cum[i - 1] + (pts[i] - pts[i - 1]).norm();
  length_ = cum.back();
  const auto n = static_cast<std::size_t>(std::floor(length_ / step_)) + 1;
  samples_.reserve(n);
  std::size_t seg = 1;
  for (std::size_t k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) * step_;
    while (seg + 1 < pts.size() && cum[seg] < s) ++seg;
    const double f = (s - cum[seg - 1]) / std::max(1e-12, cum[seg] - cum[seg - 1]);
    const Eigen::Vector2d p = pts[seg - 1] + f * (pts[seg] - pts[seg - 1]);
    samples_.emplace_back(p.x(), p.y(), 0.0);
  }
  smooth(closed);
  for (std::size_t k = 0; k < samples_.size(); ++k) {
    const std::size_t a = k == 0 ? (closed ? samples_.size() - 1 : 0) : k - 1;
    const std::size_t b = k + 1 == samples_.size() ? (closed ? 0 : k) : k + 1;
    const Eigen::Vector3d d = samples_[b] - samples_[a];
    samples_[k].z() = std::atan2(d.y(), d.x());
  }
}

void Path::smooth(bool closed) {
  // A polyline turns in steps at its vertices: a vehicle following it would hold its heading and
  // then turn by the whole vertex angle within a few centimetres (on a 20 m corner drawn with 16
  // segments, 5.6 degrees at a time, yaw rate alternating between 0 and about 80 deg/s at 7 m/s).
  // Gaussian smoothing of the positions along the arc length makes heading and yaw rate
  // continuous, as a steered vehicle's are; an arc of radius r moves inwards by about
  // sigma^2 / (2 r) (0.1 m at r = 20 m). Open paths shrink the window near their ends.
  constexpr double kSigma = 2.0;  // m
  const std::size_t n = samples_.size();
  const auto half = static_cast<std::ptrdiff_t>(std::ceil(3.0 * kSigma / step_));
  if (n < 3 || half < 1) return;
  std::vector<double> w(static_cast<std::size_t>(half) + 1);
  for (std::ptrdiff_t d = 0; d <= half; ++d) {
    const double x = static_cast<double>(d) * step_ / kSigma;
    w[static_cast<std::size_t>(d)] = std::exp(-0.5 * x * x);
  }
  const auto count = static_cast<std::ptrdiff_t>(n);
  std::vector<Eigen::Vector2d> out(n);
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    const std::ptrdiff_t reach =
        closed ? std::min(half, (count - 1) / 2) : std::min({half, k, count - 1 - k});
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    double total = 0.0;
    for (std::ptrdiff_t d = -reach; d <= reach; ++d) {
      const std::ptrdiff_t j = ((k + d) % count + count) % count;
      const double wd = w[static_cast<std::size_t>(d < 0 ? -d : d)];
      sum += wd * samples_[static_cast<std::size_t>(j)].head<2>();
      total += wd;
    }
    out[static_cast<std::size_t>(k)] = sum / total;
  }
  for (std::size_t k = 0; k < n; ++k) samples_[k].head<2>() = out[k];
}

Eigen::Vector3d Path::at(double s) const {
  if (closed_) {
    s = std::fmod(s, length_);
    if (s < 0) s += length_;
  }
  const double max_s = static_cast<double>(samples_.size() - 1) * step_;
  if (!closed_ && (s < 0.0 || s > max_s)) {
    const Eigen::Vector3d& e = s < 0.0 ? samples_.front() : samples_.back();
    const double ds = s < 0.0 ? s : s - max_s;
    return {e.x() + ds * std::cos(e.z()), e.y() + ds * std::sin(e.z()), e.z()};
  }
  const double k = s / step_;
  auto i = static_cast<std::size_t>(std::floor(k));
  const double f = k - static_cast<double>(i);
  const std::size_t j = (i + 1 < samples_.size()) ? i + 1 : (closed_ ? 0 : i);
  i = std::min(i, samples_.size() - 1);
  const Eigen::Vector3d& a = samples_[i];
  const Eigen::Vector3d& b = samples_[j];
  double dyaw = b.z() - a.z();
  while (dyaw > std::numbers::pi) dyaw -= 2 * std::numbers::pi;
  while (dyaw < -std::numbers::pi) dyaw += 2 * std::numbers::pi;
  return {a.x() + f * (b.x() - a.x()), a.y() + f * (b.y() - a.y()), a.z() + f * dyaw};
}

double Path::distance_to(const Eigen::Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < samples_.size(); k += 4) {
    best = std::min(best, (samples_[k].head<2>() - p).norm());
  }
  return best;
}

}  // namespace cndt::sim
