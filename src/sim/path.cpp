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
  for (std::size_t k = 0; k < samples_.size(); ++k) {
    const std::size_t a = k == 0 ? (closed ? samples_.size() - 1 : 0) : k - 1;
    const std::size_t b = k + 1 == samples_.size() ? (closed ? 0 : k) : k + 1;
    const Eigen::Vector3d d = samples_[b] - samples_[a];
    samples_[k].z() = std::atan2(d.y(), d.x());
  }
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
