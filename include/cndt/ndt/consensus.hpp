// Consensus metrics (paper section 4): the voxel consensus Cv (eqs 8-9), a chi-square test of
// how well a voxel's test points agree with its reference Gaussian, and the localization
// consensus Cm (eqs 10-13), a consensus-weighted dilution of precision.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "cndt/core/pose.hpp"
#include "cndt/ndt/ndt_score.hpp"
#include "cndt/ndt/voxel_grid.hpp"

namespace cndt::ndt {

/// chi2inv(p, k) for k = 1..max_dof, computed once with Boost.Math.
class ChiSquareTable {
 public:
  ChiSquareTable(std::size_t max_dof, double p_low = 0.001, double p_high = 0.999);
  [[nodiscard]] double low(std::size_t dof) const { return low_[std::min(dof, low_.size() - 1)]; }
  [[nodiscard]] double high(std::size_t dof) const {
    return high_[std::min(dof, high_.size() - 1)];
  }
  [[nodiscard]] std::size_t max_dof() const { return low_.size() - 1; }

 private:
  std::vector<double> low_, high_;  // index = degrees of freedom; [0] unused
};

/// Exact chi-square inverse CDF (Boost.Math), for tests and tables.
double chi2inv(double p, double dof);

struct CvOptions {
  double steepness = 3.0;  ///< s in eq 9
  /// Test points a voxel needs for a Cv. Eq 8 as printed divides the residual sum by N - 4 but
  /// not the thresholds, so a voxel whose points match its Gaussian exactly (expected sum 3 N)
  /// gets Cv 0.005, 0.29, 0.60 and 0.74 at N = 5, 6, 7 and 8, under or at eta = 0.7: with fewer
  /// points the test cannot tell a match from a mismatch. From N = 10 a matching voxel scores
  /// 0.85 or more. Voxels with fewer points have no Cv (NaN): kept by the cut, left out of Cm.
  std::uint32_t min_points = 10;
};

/// Eq 8-9 for one voxel: r = rss / (N - 4), Cv = sigmoid(s - 2 s (r - tau_low) /
/// (tau_high - tau_low)) with tau = chi2inv(0.001 | 0.999, N - 4), as the paper prints it.
double voxel_consensus(double rss, std::uint32_t n, const ChiSquareTable& table,
                       const CvOptions& options = {});

/// Per reference voxel: number of test points and their Mahalanobis residual sum at pose x.
struct VoxelResiduals {
  std::vector<std::uint32_t> count;
  std::vector<double> rss;
  void reset(std::size_t voxels) {
    count.assign(voxels, 0);
    rss.assign(voxels, 0.0);
  }
};

/// Accumulates each test point's q^T Sigma^-1 q into the voxel it falls in at pose x.
void accumulate_residuals(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& x, VoxelResiduals& out);

/// accumulate_residuals on several threads: the points' voxels and residuals are found in
/// kScoreChunks fixed chunks on a TaskRunner, into per-point buffers, and then added to the
/// voxels in point order on the calling thread, so the sums equal accumulate_residuals' to the
/// last bit. The buffers hold `capacity` points, allocated once; a larger set of points is
/// accumulated on the calling thread alone.
class ResidualAccumulator {
 public:
  explicit ResidualAccumulator(std::size_t capacity);
  /// `runner` null: the chunks run on the calling thread.
  void run(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points, const core::Pose6& x,
           VoxelResiduals& out, TaskRunner* runner);

 private:
  std::vector<std::int32_t> voxel_;  // per point: the Gaussian it falls in, -1 none
  std::vector<double> residual_;     // per point: q^T Sigma^-1 q there
};

/// Cv of every reference voxel (NaN where it has no Gaussian or too few test points).
void voxel_consensus_all(const VoxelResiduals& res, const ChiSquareTable& table,
                         const CvOptions& options, std::vector<double>& cv);

/// Eqs 10-13: G holds unit vectors from the sensor at `sensor_position` to the voxel means,
/// Omega = diag(Cv^2); Cm = DOP / CWDOP with DOP = sqrt(tr((G^T G)^-1)) and
/// CWDOP = sqrt(tr((G^T Omega G)^-1)). Voxels with NaN Cv are left out. Returns 0 when the
/// geometry or the consensus cannot fix a position (a singular matrix).
double localization_consensus(const VoxelGrid& grid, const std::vector<double>& cv,
                              const Eigen::Vector3d& sensor_position);

/// Cm, and whether the voxels with a Cv span the three directions G^T G needs. Where too few
/// voxels had enough test points for a Cv (a sparse scan: high rotor speed, heavy packet loss)
/// Cm is 0 for want of measurements, not because the scan disagrees with the reference or the
/// scene leaves the position free: `measured` is false then.
struct ConsensusMeasure {
  double cm = 0.0;
  bool measured = false;
};
ConsensusMeasure measure_localization_consensus(const VoxelGrid& grid,
                                                const std::vector<double>& cv,
                                                const Eigen::Vector3d& sensor_position);

/// The same from explicit directions and Cv values (for tests and the sweep tool).
double localization_consensus(std::span<const Eigen::Vector3d> directions,
                              std::span<const double> cv);

}  // namespace cndt::ndt
