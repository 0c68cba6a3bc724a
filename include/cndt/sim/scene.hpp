// Simulated scenes: a world, the sensor's trajectory through it, and traffic that moves along
// the same road so moving objects stay in view.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "cndt/sim/world.hpp"

namespace cndt::sim {

enum class SceneKind { kStreet, kCampus, kCorridor, kLoop };
std::optional<SceneKind> parse_scene(std::string_view name);
std::string_view scene_name(SceneKind kind);

/// A centre line sampled every `step` metres, smoothed so that heading and yaw rate are
/// continuous; position and heading by arc length.
class Path {
 public:
  Path() = default;
  Path(const std::vector<Eigen::Vector2d>& points, bool closed, double step = 0.25);
  /// Position (x, y) and heading at arc length s; wraps on a closed path, extends an open one
  /// along its end tangents.
  [[nodiscard]] Eigen::Vector3d at(double s) const;
  [[nodiscard]] double length() const { return length_; }
  [[nodiscard]] bool closed() const { return closed_; }
  /// Smallest distance from `p` to the path, looked up over its samples.
  [[nodiscard]] double distance_to(const Eigen::Vector2d& p) const;

 private:
  void smooth(bool closed);
  std::vector<Eigen::Vector3d> samples_;  // x, y, yaw
  double step_ = 0.25;
  double length_ = 0.0;
  bool closed_ = false;
};

/// Traffic that drives along the path relative to the sensor.
struct Mover {
  Box shape;                  ///< size and reflectivity; position and yaw are set per instant
  double lane = 0.0;          ///< lateral offset from the centre line, m (left positive)
  double speed = 0.0;         ///< along the path, m/s (negative: oncoming)
  double start_offset = 0.0;  ///< arc length ahead of the sensor at t = 0
  double window = 80.0;       ///< kept within +-window of the sensor (re-enters at the far end)
};

struct Scene {
  SceneKind kind = SceneKind::kStreet;
  World world;
  Path path;
  double speed = 8.0;                                          ///< mean sensor speed, m/s
  double sensor_height = 1.9;                                  ///< m above ground
  double lateral_amplitude = 1.0, lateral_wavelength = 140.0;  ///< lane changes
  double motion_scale = 1.0;  ///< scales pitch/roll/bounce (smaller indoors)
  /// How the sensor sits on the vehicle: T_vehicle_sensor's rotation (identity: level, x
  /// forward). The sensor stays at sensor_height; the ground truth is the sensor's pose.
  Eigen::Matrix3d mount = Eigen::Matrix3d::Identity();
  /// A stop: from stop_at_s the vehicle brakes to a standstill over stop_ramp_s, stands for
  /// stop_s and pulls away again over stop_ramp_s (stop_s = 0: no stop).
  double stop_at_s = 0.0, stop_s = 0.0, stop_ramp_s = 3.0;
  /// A start from rest: the vehicle stands for start_still_s and then pulls away over
  /// stop_ramp_s (0: it is at speed from the first instant). A stop still comes at stop_at_s
  /// when that is after the pull-away.
  double start_still_s = 0.0;
  std::vector<Mover> movers;

  /// T_world_sensor at `t` seconds after the start.
  [[nodiscard]] Eigen::Isometry3d sensor_pose(double t) const;
  /// The sensor's arc length along the path at `t`.
  [[nodiscard]] double sensor_arc(double t) const;
  /// The vehicle's own clock at `t`: t itself, less the time a stop held it (it runs at the
  /// vehicle's share of its usual speed, 0 while standing).
  [[nodiscard]] double drive_time(double t) const;
  /// Mover boxes placed for instant `t`.
  void movers_at(double t, std::vector<Box>& out) const;
};

/// Builds a scene long enough for `duration_s` of driving. Deterministic for a seed.
/// `world_seed` draws the static world (0: the same as `seed`); `seed` the movers. Two captures
/// of one world with different traffic share the world seed. `speed` (m/s) replaces the scene's
/// own mean speed when positive; the world is then drawn along a path long enough for it.
Scene build_scene(SceneKind kind, double duration_s, int movers, std::uint64_t seed,
                  std::uint64_t world_seed = 0, double speed = 0.0);

}  // namespace cndt::sim
