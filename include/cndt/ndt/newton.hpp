// Newton's method with a backtracking line search for the NDT objective (paper section 2.2).
#pragma once

#include <span>

#include "cndt/ndt/ndt_score.hpp"

namespace cndt::ndt {

struct NewtonOptions {
  int max_iterations = 30;
  double translation_eps = 1e-3;      ///< m: converged when the step moves less than this ...
  double rotation_eps = 2e-4;         ///< rad: ... and turns less than this
  double score_eps = 1e-7;            ///< or when S changes by less than this fraction
  double max_translation_step = 0.5;  ///< m, a single step is scaled down to this
  double max_rotation_step = 0.1;     ///< rad
  Neighbours neighbours = Neighbours::kSeven;  ///< voxels each point is scored against
};

struct NewtonResult {
  core::Pose6 pose = core::Pose6::Zero();
  int iterations = 0;
  bool converged = false;
  double score = 0.0;
  std::size_t matched = 0;              ///< points matched at the final pose (ScoreResult::matched)
  Matrix6d hessian = Matrix6d::Zero();  ///< at the final pose
};

/// A weak pull of the position towards a predicted one, for the directions the scene leaves
/// free: S(x) + w |t(x) - t(center)|^2 / 2, w = relative_weight times the largest eigenvalue of
/// the translation block of S's Hessian at the start. Where the scene constrains the position
/// it moves the minimum by about relative_weight times the prediction's error; along a
/// direction it barely constrains (a corridor's or a bare street's axis) the pull's curvature
/// can exceed the score's, and the solve stays nearer the prediction instead of sliding on the
/// score's ripples.
struct PositionPrior {
  core::Pose6 center = core::Pose6::Zero();
  double relative_weight = 0.0;
};

/// Minimises S(x) from `initial`. Never throws; a pose where no point matches returns
/// converged = false with the initial pose. A cache saves voxel lookups between iterations.
/// With `motion`, the scan's undistortion is solved with the pose (ScanMotion); with `prior`,
/// S plus the prior's term is minimised (NewtonResult::score and hessian are S's alone).
NewtonResult newton_solve(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& initial, const NewtonOptions& options,
                          VoxelMask mask = nullptr, LookupCache* cache = nullptr,
                          const ScanMotion* motion = nullptr, const PositionPrior* prior = nullptr);

}  // namespace cndt::ndt
