#include "cndt/slam/correction_blend.hpp"

#include <algorithm>
#include <cmath>

namespace cndt::slam {

const Eigen::Isometry3d& CorrectionBlend::step(const Eigen::Isometry3d& target,
                                               const Eigen::Isometry3d& T_odom_sensor, double dt) {
  if (!started_ || time_constant_ <= 0.0) {
    started_ = true;
    applied_ = target;
    return applied_;
  }
  // dt <= 0 moves nothing; a long gap in the data moves (almost) all the way.
  const double f = 1.0 - std::exp(-std::max(dt, 0.0) / time_constant_);
  const Eigen::Isometry3d from = applied_ * T_odom_sensor;  // published pose, applied correction
  const Eigen::Isometry3d delta = from.inverse() * target * T_odom_sensor;  // vehicle frame
  const Eigen::Quaterniond q(delta.linear());
  Eigen::Isometry3d part = Eigen::Isometry3d::Identity();
  part.linear() = Eigen::Quaterniond::Identity().slerp(f, q).normalized().toRotationMatrix();
  part.translation() = f * delta.translation();
  applied_ = from * part * T_odom_sensor.inverse();
  // Keeps the rotation orthonormal over hours of small steps.
  applied_.linear() = Eigen::Quaterniond(applied_.linear()).normalized().toRotationMatrix();
  return applied_;
}

}  // namespace cndt::slam
