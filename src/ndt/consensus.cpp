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

namespace {

// Calls take(i, voxel index, residual) for each point in [begin, end) that falls in a voxel
// with a Gaussian at pose x, in point order.
template <class Take>
void residuals_in(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                  const PoseDerivatives& pd, std::size_t begin, std::size_t end, Take take) {
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
  for (std::size_t j = begin; j < std::min(begin + kAhead, end); ++j) look_ahead(j);
  for (std::size_t i = begin; i < end; ++i) {
    const Eigen::Vector3d v = placed[i % kRing];
    const std::int32_t idx = found[i % kRing];
    if (i + kAhead < end) look_ahead(i + kAhead);
    if (idx < 0) continue;
    const Gaussian& g = grid.gaussians()[static_cast<std::size_t>(idx)];
    if (g.valid == 0) continue;
    Eigen::Vector3d a;
    take(i, idx, g.mahalanobis(v, a));
  }
}

struct ResidualJob {
  const VoxelGrid* grid;
  std::span<const Eigen::Vector3d> points;
  const PoseDerivatives* pd;
  std::int32_t* voxel;
  double* residual;
};

// TaskRunner's task: chunk `chunk` of the ResidualJob at `context`.
void residual_chunk(void* context, std::size_t chunk) {
  const ResidualJob& job = *static_cast<ResidualJob*>(context);
  const ChunkRange range = chunk_range(job.points.size(), chunk);
  std::fill(job.voxel + range.begin, job.voxel + range.end, -1);
  residuals_in(*job.grid, job.points, *job.pd, range.begin, range.end,
               [&](std::size_t i, std::int32_t idx, double r) {
                 job.voxel[i] = idx;
                 job.residual[i] = r;
               });
}

}  // namespace

void accumulate_residuals(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& x, VoxelResiduals& out) {
  const PoseDerivatives pd(x);
  residuals_in(grid, points, pd, 0, points.size(), [&](std::size_t, std::int32_t idx, double r) {
    out.count[static_cast<std::size_t>(idx)] += 1;
    out.rss[static_cast<std::size_t>(idx)] += r;
  });
}

ResidualAccumulator::ResidualAccumulator(std::size_t capacity)
    : voxel_(capacity, -1), residual_(capacity, 0.0) {}

void ResidualAccumulator::run(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                              const core::Pose6& x, VoxelResiduals& out, TaskRunner* runner) {
  if (points.size() > voxel_.size()) {
    accumulate_residuals(grid, points, x, out);
    return;
  }
  const PoseDerivatives pd(x);
  ResidualJob job{&grid, points, &pd, voxel_.data(), residual_.data()};
  run_chunks(runner, points.size(), &residual_chunk, &job);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (voxel_[i] < 0) continue;
    const auto idx = static_cast<std::size_t>(voxel_[i]);
    out.count[idx] += 1;
    out.rss[idx] += residual_[i];
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
// Both matrices are symmetric positive semi-definite; a tiny determinant (against the scale of
// G^T G) means the directions, or the weighted ones, do not span 3-D space.
bool spans(const Eigen::Matrix3d& m, const Eigen::Matrix3d& gg) {
  const double scale = std::max(gg.trace(), 1e-12);
  return m.determinant() >= 1e-12 * scale * scale * scale;
}

double dop_ratio(const Eigen::Matrix3d& gg, const Eigen::Matrix3d& gwg) {
  if (!spans(gg, gg) || !spans(gwg, gg)) return 0.0;
  const double dop = std::sqrt(gg.inverse().trace());     // eq 12
  const double cwdop = std::sqrt(gwg.inverse().trace());  // eq 11
  return std::clamp(dop / cwdop, 0.0, 1.0);               // eq 13
}

// G^T G and G^T Omega G (eq 10) over the voxels with a Cv and a Gaussian.
void direction_sums(const VoxelGrid& grid, const std::vector<double>& cv,
                    const Eigen::Vector3d& sensor_position, Eigen::Matrix3d& gg,
                    Eigen::Matrix3d& gwg) {
  gg.setZero();
  gwg.setZero();
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
  return measure_localization_consensus(grid, cv, sensor_position).cm;
}

ConsensusMeasure measure_localization_consensus(const VoxelGrid& grid,
                                                const std::vector<double>& cv,
                                                const Eigen::Vector3d& sensor_position) {
  Eigen::Matrix3d gg, gwg;
  direction_sums(grid, cv, sensor_position, gg, gwg);
  return {dop_ratio(gg, gwg), spans(gg, gg)};
}

}  // namespace cndt::ndt
