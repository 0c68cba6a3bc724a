// The paper's Figure 9 experiment: hold the reference, move the test scan away from its true
// pose along one axis, and watch the localization consensus Cm fall.
#pragma once

#include <Eigen/Geometry>
#include <span>
#include <vector>

#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/voxel_grid.hpp"
#include "cndt/slam/odometry.hpp"

namespace cndt::slam {

struct SweepSample {
  double perturbation = 0.0;  ///< m for translation axes, rad for rotation axes
  double cm = 0.0;
  std::size_t voxels = 0;  ///< voxels with a Cv
};

/// Cm of `test` (its own sensor frame) against `reference` at T_ref_test perturbed by each of
/// `values` along `axis` (0-2: x y z in metres, 3-5: roll pitch yaw in radians, the pose
/// parametrisation of core/pose.hpp).
std::vector<SweepSample> sweep_cm(const ndt::VoxelGrid& reference,
                                  std::span<const Eigen::Vector3d> test,
                                  const Eigen::Isometry3d& T_ref_test, int axis,
                                  std::span<const double> values, const ndt::ChiSquareTable& chi2);

/// The same for the scan the odometry has just estimated (`result`, from estimate() without
/// commit()): against the reference it was matched with, its points as the odometry left them
/// (scan_points(): the 0.1 m cells Cv and Cm read, deskewed with the final motion), moved from
/// its estimated pose. At 0 this is the scan's own Cm (eqs 10-13; the odometry reports 0 instead
/// where it flags the pose degenerate).
std::vector<SweepSample> sweep_cm(const ConsensusOdometry& odometry, const OdometryResult& result,
                                  int axis, std::span<const double> values);

/// Spearman rank correlation of two equally long series (ties get their mean rank).
double spearman(std::span<const double> a, std::span<const double> b);

}  // namespace cndt::slam
