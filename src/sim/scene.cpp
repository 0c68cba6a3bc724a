#include "cndt/sim/scene.hpp"

#include <cmath>
#include <numbers>

#include "cndt/sim/random.hpp"

namespace cndt::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// World point at arc length s and lateral offset `lat` (left positive) of the path.
Eigen::Vector2d beside(const Path& path, double s, double lat) {
  const Eigen::Vector3d p = path.at(s);
  return {p.x() - lat * std::sin(p.z()), p.y() + lat * std::cos(p.z())};
}

Box building(const Path& path, double s, double setback, double side, double frontage, double depth,
             double height, double yaw_jitter, double reflectivity) {
  Box b;
  b.center = beside(path, s + frontage / 2, side * (setback + depth / 2));
  b.yaw = path.at(s + frontage / 2).z() + yaw_jitter;
  b.half_x = frontage / 2;
  b.half_y = depth / 2;
  b.z_min = 0.0;
  b.z_max = height;
  b.reflectivity = reflectivity;
  return b;
}

void add_tree(World& w, Rng& rng, const Eigen::Vector2d& at) {
  const double trunk = rng.uniform(2.2, 3.5);
  const double crown = rng.uniform(1.4, 2.8);
  w.add(Cylinder{at, rng.uniform(0.12, 0.25), 0.0, trunk + crown * 0.5, rng.uniform(25, 45)});
  w.add(Foliage{Eigen::Vector3d(at.x(), at.y(), trunk + crown * 0.8), crown, rng.uniform(0.3, 0.6),
                rng.uniform(15, 35)});
}

// Street furniture along both sides of a road: buildings, poles, trees, parked cars.
void line_road(World& w, Rng& rng, const Path& path, double s0, double s1, double setback_lo,
               double setback_hi, double height_hi, double tree_offset, double parked_offset) {
  for (double side : {-1.0, 1.0}) {
    for (double s = s0; s < s1;) {
      const double frontage = rng.uniform(8, 30);
      if (!rng.chance(0.15)) {
        w.add(building(path, s, rng.uniform(setback_lo, setback_hi), side, frontage,
                       rng.uniform(8, 20), rng.uniform(5, height_hi), rng.uniform(-0.05, 0.05),
                       rng.uniform(40, 110)));
      }
      s += frontage + (rng.chance(0.2) ? rng.uniform(12, 30) : rng.uniform(1, 8));
    }
    for (double s = s0 + rng.uniform(0, 20); s < s1; s += rng.uniform(18, 32)) {
      w.add(Cylinder{beside(path, s, side * (tree_offset - 1.0)), 0.12, 0.0, 7.5, 70});
    }
    for (double s = s0 + rng.uniform(0, 10); s < s1; s += rng.uniform(7, 20)) {
      if (rng.chance(0.6))
        add_tree(w, rng, beside(path, s, side * (tree_offset + rng.uniform(0, 1))));
    }
    for (double s = s0; s < s1; s += 6.5) {
      if (parked_offset > 0 && rng.chance(0.35)) {
        Box car;
        car.center = beside(path, s, side * parked_offset);
        car.yaw = path.at(s).z();
        car.half_x = 2.25;
        car.half_y = 0.9;
        car.z_max = rng.uniform(1.4, 1.7);
        car.reflectivity = rng.uniform(30, 120);
        w.add(car);
      }
    }
  }
}

Path straight_path(double length) {
  return Path({Eigen::Vector2d(-200, 0), Eigen::Vector2d(length + 200, 0)}, false);
}

Path meander_path(double length, Rng& rng) {
  std::vector<Eigen::Vector2d> pts;
  const double p1 = rng.uniform(0, 2 * kPi), p2 = rng.uniform(0, 2 * kPi);
  Eigen::Vector2d p(-200, 0);
  double yaw = 0.0;
  for (double s = -200; s < length + 200; s += 1.0) {
    pts.push_back(p);
    const double kappa =
        0.012 * std::sin(2 * kPi * s / 220 + p1) + 0.008 * std::sin(2 * kPi * s / 97 + p2);
    yaw += kappa;
    p += Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  }
  return Path(pts, false);
}

Path loop_path(double w, double h, double r) {
  std::vector<Eigen::Vector2d> pts;
  const double cx[4] = {w / 2 - r, -w / 2 + r, -w / 2 + r, w / 2 - r};
  const double cy[4] = {h / 2 - r, h / 2 - r, -h / 2 + r, -h / 2 + r};
  for (int c = 0; c < 4; ++c) {
    for (int k = 0; k <= 16; ++k) {
      const double a = kPi / 2 * c + kPi / 2 * k / 16.0 - kPi / 2;
      pts.emplace_back(cx[c] + r * std::cos(a + kPi / 2), cy[c] + r * std::sin(a + kPi / 2));
    }
  }
  return Path(pts, true);
}

Box mover_box(bool pedestrian, Rng& rng) {
  Box b;
  if (pedestrian) {
    b.half_x = 0.25;
    b.half_y = 0.25;
    b.z_max = rng.uniform(1.6, 1.9);
  } else {
    b.half_x = rng.uniform(2.0, 2.5);
    b.half_y = rng.uniform(0.85, 1.0);
    b.z_max = rng.uniform(1.4, 2.2);
  }
  b.reflectivity = rng.uniform(40, 140);
  return b;
}

}  // namespace

std::optional<SceneKind> parse_scene(std::string_view name) {
  if (name == "street") return SceneKind::kStreet;
  if (name == "campus") return SceneKind::kCampus;
  if (name == "corridor") return SceneKind::kCorridor;
  if (name == "loop") return SceneKind::kLoop;
  return std::nullopt;
}

std::string_view scene_name(SceneKind kind) {
  switch (kind) {
    case SceneKind::kStreet:
      return "street";
    case SceneKind::kCampus:
      return "campus";
    case SceneKind::kCorridor:
      return "corridor";
    case SceneKind::kLoop:
      return "loop";
  }
  return "street";
}

Scene build_scene(SceneKind kind, double duration_s, int movers, std::uint64_t seed,
                  std::uint64_t world_seed, double speed) {
  Scene sc;
  sc.kind = kind;
  Rng rng(world_seed != 0 ? world_seed : seed, 0x5CE7E);
  double lane_same = -1.75, lane_other = 1.75;
  bool pedestrians = false;
  switch (kind) {
    case SceneKind::kStreet: {
      sc.speed = speed > 0.0 ? speed : 8.0;
      sc.lateral_amplitude = 1.0;
      sc.lateral_wavelength = 140.0;
      const double len = sc.speed * duration_s * 1.3 + 100;
      sc.path = straight_path(len);
      line_road(sc.world, rng, sc.path, -150, len + 150, 9, 14, 25, 6.5, 5.0);
      lane_same = -3.5;
      lane_other = 3.5;
      break;
    }
    case SceneKind::kCampus: {
      sc.speed = speed > 0.0 ? speed : 4.0;
      sc.lateral_amplitude = 0.5;
      sc.lateral_wavelength = 90.0;
      const double len = sc.speed * duration_s * 1.3 + 100;
      sc.path = meander_path(len, rng);
      World& w = sc.world;
      World staging;
      for (double s = -150; s < len + 150; s += rng.uniform(15, 35)) {
        const double side = rng.chance(0.5) ? 1.0 : -1.0;
        Box b = building(sc.path, s, rng.uniform(14, 35), side, rng.uniform(10, 40),
                         rng.uniform(10, 25), rng.uniform(4, 15), rng.uniform(-0.3, 0.3),
                         rng.uniform(40, 110));
        if (sc.path.distance_to(b.center) > std::hypot(b.half_x, b.half_y) + 4.0) w.add(b);
      }
      for (double s = -150; s < len + 150; s += rng.uniform(4, 9)) {
        const Eigen::Vector2d at =
            beside(sc.path, s, (rng.chance(0.5) ? 1 : -1) * rng.uniform(4, 12));
        if (sc.path.distance_to(at) > 3.5) add_tree(w, rng, at);
      }
      for (double s = -150; s < len + 150; s += rng.uniform(20, 30)) {
        w.add(Cylinder{beside(sc.path, s, 4.0), 0.1, 0.0, 4.5, 70});
      }
      pedestrians = true;
      lane_same = -2.5;
      lane_other = 2.5;
      break;
    }
    case SceneKind::kCorridor: {
      sc.speed = speed > 0.0 ? speed : 1.2;
      sc.sensor_height = 0.5;
      sc.lateral_amplitude = 0.25;
      sc.lateral_wavelength = 25.0;
      sc.motion_scale = 0.3;
      const double len = sc.speed * duration_s * 1.3 + 60;
      sc.path = straight_path(len);
      World& w = sc.world;
      w.set_ceiling(2.8);
      w.set_ground_reflectivity(35);
      for (double side : {-1.0, 1.0}) {
        for (double s = -100; s < len + 100;) {
          const double seg = rng.uniform(6, 15);
          Box wall;
          wall.center = beside(sc.path, s + seg / 2, side * 1.7);
          wall.half_x = seg / 2;
          wall.half_y = 0.1;
          wall.z_max = 2.8;
          wall.reflectivity = 60;
          w.add(wall);
          const bool cross = rng.chance(0.15);
          const double gap = cross ? 2.0 : 1.0;
          Box back = wall;  // the room or side corridor behind the opening
          back.center = beside(sc.path, s + seg + gap / 2, side * (cross ? 6.0 : 2.3));
          back.half_x = gap / 2 + 0.3;
          back.reflectivity = 50;
          w.add(back);
          if (rng.chance(0.3)) {
            w.add(Box{beside(sc.path, s + seg / 2, side * 1.45), 0.0, 0.15, 0.15, 0.0, 2.8, 80});
          }
          s += seg + gap;
        }
      }
      pedestrians = true;
      lane_same = -0.9;
      lane_other = 0.9;
      break;
    }
    case SceneKind::kLoop: {
      sc.speed = speed > 0.0 ? speed : 7.0;
      sc.lateral_amplitude = 0.8;
      sc.lateral_wavelength = 120.0;
      sc.path = loop_path(200, 120, 20);
      line_road(sc.world, rng, sc.path, 0, sc.path.length() - 10, 9, 13, 20, 6.5, 5.0);
      lane_same = -3.5;
      lane_other = 3.5;
      break;
    }
  }
  sc.world.finalize();
  Rng mrng(seed, 0x30E25);
  for (int i = 0; i < movers; ++i) {
    Mover m;
    m.shape = mover_box(pedestrians, mrng);
    const bool oncoming = i % 2 == 1;
    m.lane = oncoming ? lane_other : lane_same;
    if (pedestrians) {
      m.speed = (oncoming ? -1.0 : 1.0) * mrng.uniform(1.0, 1.6);
      m.window = 40.0;
    } else {
      m.speed = oncoming ? -mrng.uniform(6, 12) : sc.speed + mrng.uniform(-3, 3);
    }
    m.start_offset = (mrng.chance(0.5) ? 1 : -1) * mrng.uniform(8, m.window * 0.7);
    sc.movers.push_back(m);
  }
  return sc;
}

double Scene::drive_time(double t) const {
  const double r = stop_ramp_s, w = kPi / r;
  // The drive time `x` seconds into a pull-away that starts at drive time `base`:
  // d(drive time)/dt rises from 0 to 1 as (1 - cos) / 2 over the ramp.
  auto pull_away = [&](double base, double x) {
    return x < r ? base + 0.5 * x - 0.5 * std::sin(w * x) / w : base + 0.5 * r + (x - r);
  };
  double d = t;
  if (stop_s > 0.0 && t > stop_at_s) {
    // d(drive time)/dt falls from 1 to 0 as (1 + cos) / 2 over the ramp, stays 0 for stop_s and
    // rises back.
    const double braked = 0.5 * r;  // drive time passed while braking
    const double x = t - stop_at_s;
    if (x < r) {
      d = stop_at_s + 0.5 * x + 0.5 * std::sin(w * x) / w;
    } else {
      const double after = x - (r + stop_s);
      d = after < 0.0 ? stop_at_s + braked : pull_away(stop_at_s + braked, after);
    }
  }
  // A start from rest: standing, then pulling away.
  if (start_still_s > 0.0) d = d <= start_still_s ? 0.0 : pull_away(0.0, d - start_still_s);
  return d;
}

double Scene::sensor_arc(double t_true) const {
  // Speed varies +-20 % over 17 s: s(t) = v (t + a T / 2pi (1 - cos(2 pi t / T))), t on the
  // vehicle's own clock.
  const double t = drive_time(t_true);
  constexpr double a = 0.2, T = 17.0;
  return speed * (t + a * T / (2 * kPi) * (1.0 - std::cos(2 * kPi * t / T)));
}

Eigen::Isometry3d Scene::sensor_pose(double t_true) const {
  const double s = sensor_arc(t_true);
  const double t = drive_time(t_true);  // the body's sway stops with the vehicle
  const Eigen::Vector3d c = path.at(s);
  const double k = 2 * kPi / lateral_wavelength;
  const double lat = lateral_amplitude * std::sin(k * s);
  const double dlat = lateral_amplitude * k * std::cos(k * s);
  const double yaw = c.z() + std::atan(dlat);
  const double m = motion_scale;
  const double deg = kPi / 180.0;
  const double pitch =
      m * (0.6 * std::sin(2 * kPi * t / 2.3) + 0.3 * std::sin(2 * kPi * t / 0.9 + 1.0)) * deg;
  const double roll = m * (0.5 * std::sin(2 * kPi * t / 3.1 + 0.5)) * deg;
  const double bounce = m * 0.02 * std::sin(2 * kPi * t / 1.7);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(c.x() - lat * std::sin(c.z()), c.y() + lat * std::cos(c.z()),
                                    sensor_height + bounce);
  const Eigen::Matrix3d body = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  T.linear() = body * mount;
  return T;
}

void Scene::movers_at(double t, std::vector<Box>& out) const {
  out.clear();
  const double s_sensor = sensor_arc(t);
  for (const auto& m : movers) {
    // Position relative to the sensor, wrapped into the window so traffic stays in view.
    double rel = m.start_offset + m.speed * t - (s_sensor);
    const double span = 2 * m.window;
    rel = std::fmod(rel + m.window, span);
    if (rel < 0) rel += span;
    rel -= m.window;
    const double s = s_sensor + rel;
    Box b = m.shape;
    b.center = beside(path, s, m.lane);
    b.yaw = path.at(s).z() + (m.speed < 0 ? kPi : 0.0);
    out.push_back(b);
  }
}

}  // namespace cndt::sim
