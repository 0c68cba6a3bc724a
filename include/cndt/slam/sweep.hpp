// The paper's Figure 9 experiment: hold the reference, move the test scan away from its true
// pose along one axis, and watch the localization consensus Cm fall.
#pragma once

#include <Eigen/Geometry>
#include <span>
#include <vector>

#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/voxel_grid.hpp"

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

/// Spearman rank correlation of two equally long series (ties get their mean rank).
double spearman(std::span<const double> a, std::span<const double> b);

}  // namespace cndt::slam
