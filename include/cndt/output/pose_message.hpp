// What cndt publishes for every scan: the sensor pose, its consensus metric Cm and a status the
// vehicle controller acts on. Encoded for CAN (can_codec.hpp, config/cndt.dbc) and UDP
// (udp_codec.hpp, docs/protocol.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace cndt::output {

/// How far the controller may trust the pose.
enum class PoseStatus : std::uint8_t {
  kValid = 0,     ///< matched, Cm at or above the configured threshold
  kDegraded = 1,  ///< matched, but Cm below the threshold (or the solver hit its iteration cap)
  kLost = 2,      ///< not matched (too few points, degenerate geometry): the pose is a prediction
};
const char* to_string(PoseStatus status) noexcept;

enum PoseFlags : std::uint16_t {
  kPoseMapCorrected = 1u << 0,    ///< the mapper's correction T_map_odom is applied
  kPoseNotConverged = 1u << 1,    ///< the solver reached its iteration cap
  kPoseTooFewPoints = 1u << 2,    ///< too few points to match
  kPoseDegenerate = 1u << 3,      ///< the geometry does not fix the pose (Cm = 0)
  kPoseScanIncomplete = 1u << 4,  ///< the revolution was partial or lost packets
  kPoseFirstScan = 1u << 5,       ///< the first pose of the trajectory (the origin)
  kPoseOutOfRange = 1u << 6,      ///< a value exceeded a CAN signal's range and was clamped
  /// Cm could not be measured (too few voxels with enough points for a Cv; Cm = 0)
  kPoseCmUnmeasured = 1u << 7,
};

struct PoseMessage {
  std::int64_t stamp_ns = 0;        ///< the scan's start time, ns since the Unix epoch
  std::uint32_t scan_sequence = 0;  ///< scans since the start of the stream
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< sensor in the map frame, m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  double cm = 0.0;  ///< localization consensus metric, 0..1
  PoseStatus status = PoseStatus::kLost;
  std::uint16_t flags = 0;   ///< PoseFlags
  std::uint32_t points = 0;  ///< points matched
};

/// Roll, pitch and yaw (radians) of a rotation in the aerospace / REP-103 convention:
/// R = Rz(yaw) Ry(pitch) Rx(roll); pitch in [-pi/2, pi/2], roll and yaw in (-pi, pi].
Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& R) noexcept;
/// The rotation with these roll, pitch and yaw (the inverse of roll_pitch_yaw).
Eigen::Matrix3d from_roll_pitch_yaw(double roll, double pitch, double yaw) noexcept;

}  // namespace cndt::output
