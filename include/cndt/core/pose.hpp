// 6-DoF pose as the paper parametrises it (section 2.2): x = [Tx, Ty, Tz, phi, theta, psi],
// translation in metres and rotations in radians about x, y and z, composed intrinsically:
// R(x) = Rx(phi) Ry(theta) Rz(psi), so a point p maps to R(x) p + T(x).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace cndt::core {

using Pose6 = Eigen::Matrix<double, 6, 1>;

inline Eigen::Matrix3d rotation(double phi, double theta, double psi) {
  return (Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

inline Eigen::Isometry3d to_isometry(const Pose6& x) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotation(x[3], x[4], x[5]);
  T.translation() = x.head<3>();
  return T;
}

/// Inverse of to_isometry for rotations away from the theta = +-90 deg singularity.
inline Pose6 to_pose6(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  // R = Rx Ry Rz: R(0,2) = sin(theta); R(1,2) = -sin(phi) cos(theta); R(0,1) = -cos(theta) sin(psi)
  Pose6 x;
  x.head<3>() = T.translation();
  x[4] = std::asin(std::clamp(R(0, 2), -1.0, 1.0));
  x[3] = std::atan2(-R(1, 2), R(2, 2));
  x[5] = std::atan2(-R(0, 1), R(0, 0));
  return x;
}

}  // namespace cndt::core
