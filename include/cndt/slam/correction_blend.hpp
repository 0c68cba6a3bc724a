// Published poses under a changing map correction. Each closed keyframe gives the mapper a new
// T_map_odom; applied at once, the change shows in the published trajectory as a jump of a few
// centimetres, which a vehicle controller takes for motion. CorrectionBlend moves the applied
// correction towards the newest one gradually, with a time constant: per scan, the published
// pose covers the fraction 1 - exp(-dt / tau) of the way from where the applied correction puts
// it to where the newest one would, its rotation turned about the vehicle (not about the map
// origin, which may be far away).
#pragma once

#include <Eigen/Geometry>

namespace cndt::slam {

class CorrectionBlend {
 public:
  /// `time_constant` in seconds; 0 applies every new correction at once.
  explicit CorrectionBlend(double time_constant = 0.0) : time_constant_(time_constant) {}

  /// The correction to publish the odometry pose `T_odom_sensor` with, `dt` seconds after the
  /// last pose published (OdometryResult::dt: across a jump of the sensor clock, one revolution,
  /// not the stamps' difference), the mapper's newest being `target`. The first call takes
  /// `target` as it is.
  const Eigen::Isometry3d& step(const Eigen::Isometry3d& target,
                                const Eigen::Isometry3d& T_odom_sensor, double dt);

  [[nodiscard]] const Eigen::Isometry3d& applied() const { return applied_; }

 private:
  double time_constant_;
  bool started_ = false;
  Eigen::Isometry3d applied_ = Eigen::Isometry3d::Identity();
};

}  // namespace cndt::slam
