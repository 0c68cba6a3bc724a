#include "cndt/ndt/consensus.hpp"

#include <algorithm>
#include <array>
#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <limits>

#include "cndt/ndt/ndt_score.hpp"

namespace cndt::ndt {

double chi2inv(double p, double dof) {
  return boost::math::quantile(boost::math::chi_squared_distribution<double>(dof), p);
}

ChiSquareTable::ChiSquareTable(std::size_t max_dof, double p_low, double p_high)
    : low_(max_dof + 1, 0.0), high_(max_dof + 1, 0.0) {
  for (std::size_t k = 1; k <= max_dof; ++k) {
    low_[k] = chi2inv(p_low, static_cast<double>(k));
    high_[k] = chi2inv(p_high, static_cast<double>(k));
  }
}

double voxel_consensus(double rss, std::uint32_t n, const ChiSquareTable& table,
                       const CvOptions& o) {
  if (n < o.min_points || n <= 4) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t dof = n - 4;
  const double r = rss / static_cast<double>(dof);  // eq 8
  const double lo = table.low(dof), hi = table.high(dof);
  const double z = o.steepness - 2.0 * o.steepness * (r - lo) / (hi - lo);  // eq 9
  return 1.0 / (1.0 + std::exp(-z));
}

void accumulate_residuals(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& x, VoxelResiduals& out) {
  const PoseDerivatives pd(x);
  // Each point is placed and its voxel found kAhead points before its residual is taken, and
  // the voxel fetched into the cache meanwhile (see ndt_score).
  constexpr std::size_t kAhead = 8, kRing = kAhead + 1;
  std::array<Eigen::Vector3d, kRing> placed;
  std::array<std::int32_t, kRing> found{};
  auto look_ahead = [&](std::size_t j) {
    const Eigen::Vector3d v = pd.transform(points[j]);
    placed[j % kRing] = v;
    const auto idx = static_cast<std::int32_t>(grid.index_of(grid.key_of(v)));
    found[j % kRing] = idx;
    if (idx >= 0) grid.prefetch_gaussian(idx);
  };
  for (std::size_t j = 0; j < std::min(kAhead, points.size()); ++j) look_ahead(j);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d v = placed[i % kRing];
    const std::int32_t idx = found[i % kRing];
    if (i + kAhead < points.size()) look_ahead(i + kAhead);
    if (idx < 0) continue;
    const Gaussian& g = grid.gaussians()[static_cast<std::size_t>(idx)];
    if (g.valid == 0) continue;
    Eigen::Vector3d a;
    out.count[static_cast<std::size_t>(idx)] += 1;
    out.rss[static_cast<std::size_t>(idx)] += g.mahalanobis(v, a);
  }
}

void voxel_consensus_all(const VoxelResiduals& res, const ChiSquareTable& table,
                         const CvOptions& options, std::vector<double>& cv) {
  cv.resize(res.count.size());
  for (std::size_t i = 0; i < res.count.size(); ++i) {
    cv[i] = voxel_consensus(res.rss[i], res.count[i], table, options);
  }
}

namespace {
double dop_ratio(const Eigen::Matrix3d& gg, const Eigen::Matrix3d& gwg) {
  // Both matrices are symmetric positive semi-definite; a tiny determinant means the
  // directions (or the weighted ones) do not span 3-D space.
  const double scale = std::max(gg.trace(), 1e-12);
  if (gg.determinant() < 1e-12 * scale * scale * scale) return 0.0;
  if (gwg.determinant() < 1e-12 * scale * scale * scale) return 0.0;
  const double dop = std::sqrt(gg.inverse().trace());     // eq 12
  const double cwdop = std::sqrt(gwg.inverse().trace());  // eq 11
  return std::clamp(dop / cwdop, 0.0, 1.0);               // eq 13
}
}  // namespace

double localization_consensus(std::span<const Eigen::Vector3d> directions,
                              std::span<const double> cv) {
  Eigen::Matrix3d gg = Eigen::Matrix3d::Zero(), gwg = Eigen::Matrix3d::Zero();
  for (std::size_t j = 0; j < directions.size(); ++j) {
    if (std::isnan(cv[j])) continue;
    const Eigen::Vector3d u = directions[j].normalized();
    const Eigen::Matrix3d uu = u * u.transpose();
    gg += uu;                   // G^T G
    gwg += cv[j] * cv[j] * uu;  // G^T Omega G, Omega = diag(Cv^2) (eq 10)
  }
  return dop_ratio(gg, gwg);
}

double localization_consensus(const VoxelGrid& grid, const std::vector<double>& cv,
                              const Eigen::Vector3d& sensor_position) {
  Eigen::Matrix3d gg = Eigen::Matrix3d::Zero(), gwg = Eigen::Matrix3d::Zero();
  const auto& gaussians = grid.gaussians();
  for (std::size_t j = 0; j < gaussians.size() && j < cv.size(); ++j) {
    if (std::isnan(cv[j]) || gaussians[j].valid == 0) continue;
    const Eigen::Vector3d d = gaussians[j].mean_vector() - sensor_position;
    const double n = d.norm();
    if (n < 1e-6) continue;
    const Eigen::Vector3d u = d / n;
    const Eigen::Matrix3d uu = u * u.transpose();
    gg += uu;
    gwg += cv[j] * cv[j] * uu;
  }
  return dop_ratio(gg, gwg);
}

}  // namespace cndt::ndt
