#include "cndt/slam/sweep.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "cndt/core/pose.hpp"
#include "cndt/slam/downsample.hpp"

namespace cndt::slam {

std::vector<SweepSample> sweep_cm(const ndt::VoxelGrid& reference,
                                  std::span<const Eigen::Vector3d> test,
                                  const Eigen::Isometry3d& T_ref_test, int axis,
                                  std::span<const double> values, const ndt::ChiSquareTable& chi2) {
  std::vector<SweepSample> out;
  ndt::VoxelResiduals res;
  std::vector<double> cv;
  const core::Pose6 truth = core::to_pose6(T_ref_test);
  for (double v : values) {
    core::Pose6 x = truth;
    x[axis] += v;
    res.reset(reference.size());
    ndt::accumulate_residuals(reference, test, x, res);
    ndt::voxel_consensus_all(res, chi2, {}, cv);
    SweepSample s;
    s.perturbation = v;
    s.cm = ndt::localization_consensus(reference, cv, x.head<3>());
    s.voxels = static_cast<std::size_t>(
        std::count_if(cv.begin(), cv.end(), [](double c) { return !std::isnan(c); }));
    out.push_back(s);
  }
  return out;
}

std::vector<SweepSample> sweep_cm(const ConsensusOdometry& odometry, const OdometryResult& result,
                                  int axis, std::span<const double> values) {
  const OdometryOptions& o = odometry.options();
  // Every count of test points a voxel can hold, as the odometry's own table.
  const ndt::ChiSquareTable chi2(
      max_centroids_per_voxel(o.voxel_size, o.map_cell, o.max_scan_points));
  // The reference lies in the odometry's own (levelled) frame.
  const Eigen::Isometry3d T = Eigen::Isometry3d(odometry.level_rotation()) * result.pose;
  return sweep_cm(odometry.reference_grid(), odometry.scan_points(), T, axis, values, chi2);
}

namespace {
std::vector<double> ranks(std::span<const double> v) {
  std::vector<std::size_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (std::size_t i = 0; i < idx.size();) {
    std::size_t j = i;
    while (j + 1 < idx.size() && v[idx[j + 1]] == v[idx[i]]) ++j;
    const double mean_rank = 0.5 * static_cast<double>(i + j);
    for (std::size_t k = i; k <= j; ++k) r[idx[k]] = mean_rank;
    i = j + 1;
  }
  return r;
}
}  // namespace

double spearman(std::span<const double> a, std::span<const double> b) {
  const std::vector<double> ra = ranks(a), rb = ranks(b);
  const double n = static_cast<double>(ra.size());
  const double ma = std::accumulate(ra.begin(), ra.end(), 0.0) / n;
  const double mb = std::accumulate(rb.begin(), rb.end(), 0.0) / n;
  double sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < ra.size(); ++i) {
    sab += (ra[i] - ma) * (rb[i] - mb);
    saa += (ra[i] - ma) * (ra[i] - ma);
    sbb += (rb[i] - mb) * (rb[i] - mb);
  }
  return (saa > 0 && sbb > 0) ? sab / std::sqrt(saa * sbb) : 0.0;
}

}  // namespace cndt::slam
