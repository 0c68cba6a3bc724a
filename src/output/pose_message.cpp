#include "cndt/output/pose_message.hpp"

#include <algorithm>
#include <cmath>

namespace cndt::output {

const char* to_string(PoseStatus status) noexcept {
  switch (status) {
    case PoseStatus::kValid:
      return "valid";
    case PoseStatus::kDegraded:
      return "degraded";
    case PoseStatus::kLost:
      return "lost";
  }
  return "unknown";
}

Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& R) noexcept {
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

Eigen::Matrix3d from_roll_pitch_yaw(double roll, double pitch, double yaw) noexcept {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace cndt::output
