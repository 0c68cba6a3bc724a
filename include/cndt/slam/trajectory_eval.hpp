// Trajectory accuracy: absolute trajectory error after an SE(3) alignment, per-frame relative
// pose error, KITTI-style relative errors over path segments, and the drift of dead reckoning
// from the first pose (height and tilt).
#pragma once

#include <Eigen/Geometry>
#include <limits>
#include <vector>

namespace cndt::slam {

struct TimedPose {
  double t = 0.0;  ///< seconds
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

struct FrameError {
  double t = 0.0;
  double translation = 0.0;  ///< m, relative pose error to the next frame
  double rotation_deg = 0.0;
};

struct EvalResult {
  std::size_t matched = 0;   ///< estimated poses with a ground-truth pose at their time
  double path_length = 0.0;  ///< m, along the ground truth
  double ate_rmse = 0.0,
         ate_max = 0.0;  ///< m, after aligning the estimate (rotation + translation)
  /// Mean translational error over segments, % of their length; NaN when the path is shorter
  /// than two of the shortest segment (20 m) and so holds none.
  double rte_percent = std::numeric_limits<double>::quiet_NaN();
  /// Mean rotational error over segments, deg per metre; NaN likewise.
  double rre_deg_per_m = std::numeric_limits<double>::quiet_NaN();
  double rpe_translation_rmse = 0.0, rpe_rotation_rmse_deg = 0.0;  ///< frame to frame
  /// Dead reckoning from a known start: the estimate placed on the ground truth by its first
  /// pose alone, as a vehicle sees it, without the hindsight fit of the ATE. A tilt picked up
  /// early moves every later pose but hardly any relative pose, and the ATE fit rotates it
  /// away; here it shows as height running off with the distance.
  double end_error = 0.0;         ///< m, position error at the last pose
  double height_error_end = 0.0;  ///< m, estimated minus true height at the last pose
  double height_error_max = 0.0;  ///< m, largest |height error| over the poses
  /// Roll and pitch error at the last pose: the angle between the world's up as the estimated
  /// and the true sensor orientation see it (a heading error leaves it at 0).
  double tilt_end_deg = 0.0;
  std::vector<double> segment_lengths;  ///< the lengths the segment errors used
  std::vector<FrameError> frames;
};

/// Pairs each estimated pose with the ground truth at its time (interpolated between ground-truth
/// samples; poses outside the ground-truth span are left out) and computes the errors. Segment
/// lengths are the KITTI ones scaled to the path: 10, 20, 40, ... m shorter than half the path.
EvalResult evaluate(const std::vector<TimedPose>& ground_truth,
                    const std::vector<TimedPose>& estimate);

}  // namespace cndt::slam
