// Consensus-NDT LiDAR odometry (paper section 3.1, Figure 2): for each scan, deskew with the
// predicted motion, downsample, match coarsely against the reference with all voxels, compute
// the voxel consensus Cv, drop voxels with Cv < eta, match finely with the rest, and report the
// localization consensus Cm. The naive mode is the same without the Cv cut (one optimisation).
#pragma once

#include <Eigen/Geometry>
#include <chrono>
#include <cstdint>
#include <deque>
#include <vector>

#include "cndt/core/scan.hpp"
#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/newton.hpp"
#include "cndt/ndt/voxel_grid.hpp"
#include "cndt/slam/downsample.hpp"

namespace cndt::slam {

enum class OdometryMode { kConsensus, kNaive };
/// What a scan is matched against: the previous scan (the paper) or the recent scans merged in
/// the odometry frame (a local map).
enum class Reference { kPreviousScan, kLocalMap };

struct OdometryOptions {
  OdometryMode mode = OdometryMode::kConsensus;
  Reference reference = Reference::kLocalMap;
  std::size_t local_map_scans = 10;           ///< scans merged into the local map
  double voxel_size = 0.5;                    ///< L of the reference NDT, m (paper: 0.5)
  double scan_cell = 0.3;                     ///< downsampling of the scan being matched, m
  double map_cell = 0.05;                     ///< downsampling of scans added to the reference, m
  double eta = 0.7;                           ///< Cv threshold (paper: 0.7)
  double min_range = 1.0, max_range = 100.0;  ///< m; nearer points are the vehicle itself
  bool deskew = true;                         ///< undistort with the constant-velocity prediction
  int deskew_refinements = 2;  ///< re-deskew with the estimated motion and match again
  std::size_t max_scan_points = 150'000;
  std::size_t max_map_voxels = 400'000;
  std::size_t min_points = 200;  ///< fewer matched points: the scan is not matched
  bool drop_ring_arcs = false;   ///< reference voxels holding a single ring arc get no Gaussian
  /// Without a motion prior (the first scans, or after a failed match) the scan is first matched
  /// on these coarser grids, widening the basin of convergence (ground rings that move with the
  /// sensor otherwise hold a match near zero motion).
  std::vector<double> bootstrap_voxel_sizes = {2.0, 1.0};
  ndt::NewtonOptions coarse{.max_iterations = 15};
  ndt::NewtonOptions fine{.max_iterations = 15};
  ndt::NewtonOptions naive{.max_iterations = 30};
};

enum OdometryFlags : std::uint32_t {
  kOdomFirstScan = 1u << 0,       ///< starts the trajectory: identity pose
  kOdomNotConverged = 1u << 1,    ///< iteration cap reached
  kOdomTooFewPoints = 1u << 2,    ///< not matched; the prediction is reported
  kOdomDegenerate = 1u << 3,      ///< Cm = 0: the geometry does not fix the pose
  kOdomScanIncomplete = 1u << 4,  ///< the scan was partial, lossy or cut
};

struct OdometryResult {
  std::chrono::nanoseconds stamp{0};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< T_odom_sensor at the scan stamp
  double cm = 0.0;
  int coarse_iterations = 0;
  int fine_iterations = 0;        ///< naive mode: its single optimisation
  std::size_t voxels_before = 0;  ///< reference voxels the scan's points fell in (coarse pose)
  std::size_t voxels_after = 0;   ///< of those, kept by the Cv cut
  std::size_t points = 0;         ///< points matched (after downsampling)
  std::size_t raw_points = 0;     ///< points of the scan within range
  std::uint32_t flags = 0;
};

class ConsensusOdometry {
 public:
  explicit ConsensusOdometry(const OdometryOptions& options);
  OdometryResult process(const core::Scan& scan);
  [[nodiscard]] const OdometryOptions& options() const { return options_; }

 private:
  void deskew(const core::Scan& scan, const Eigen::Isometry3d& motion, double scan_period_s);
  // Adds the current scan, placed at `pose`, to the reference and rebuilds its grid.
  void update_reference(const Eigen::Isometry3d& pose);
  core::Pose6 bootstrap(const core::Pose6& x0);
  // Coarse match, Cv cut, fine match (or the naive single match) from x0; fills res.
  bool match(const core::Pose6& x0, OdometryResult& res);
  double consensus_at(const core::Pose6& x, std::vector<double>& cv);

  OdometryOptions options_;
  ndt::VoxelGrid grid_;
  std::vector<ndt::VoxelGrid> bootstrap_grids_;
  bool have_motion_prior_ = false;
  ndt::ChiSquareTable chi2_;
  Downsampler scan_sampler_, map_sampler_;
  std::vector<Eigen::Vector3d> raw_, test_, map_points_;
  std::deque<std::vector<Eigen::Vector3d>> history_;  // reference scans, odometry frame
  std::vector<std::uint8_t> mask_;
  std::vector<double> cv_;
  ndt::VoxelResiduals residuals_;
  bool have_prev_ = false, have_prev2_ = false;
  Eigen::Isometry3d prev_pose_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d prev_motion_ = Eigen::Isometry3d::Identity();  // between the last two scans
  std::chrono::nanoseconds prev_stamp_{0};
  double prev_period_s_ = 0.1;
};

}  // namespace cndt::slam
