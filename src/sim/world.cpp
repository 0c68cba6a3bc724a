#include "cndt/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cndt/sim/random.hpp"

namespace cndt::sim {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMargin = 150.0;  // grid reaches beyond the objects so every ray starts inside
}  // namespace

double intersect(const Ray& ray, const Box& b) {
  // Into the box frame: rotate by -yaw about z around the box centre.
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  const double ox = ray.origin.x() - b.center.x(), oy = ray.origin.y() - b.center.y();
  const double o[3] = {c * ox + s * oy, -s * ox + c * oy, ray.origin.z()};
  const double d[3] = {c * ray.direction.x() + s * ray.direction.y(),
                       -s * ray.direction.x() + c * ray.direction.y(), ray.direction.z()};
  const double lo[3] = {-b.half_x, -b.half_y, b.z_min};
  const double hi[3] = {b.half_x, b.half_y, b.z_max};
  double t0 = -kInf, t1 = kInf;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-12) {
      if (o[i] < lo[i] || o[i] > hi[i]) return -1.0;
      continue;
    }
    double a = (lo[i] - o[i]) / d[i], z = (hi[i] - o[i]) / d[i];
    if (a > z) std::swap(a, z);
    t0 = std::max(t0, a);
    t1 = std::min(t1, z);
    if (t0 > t1) return -1.0;
  }
  if (t1 < 0.0) return -1.0;
  return t0 >= 0.0 ? t0 : -1.0;  // a ray starting inside a box sees nothing of it
}

double intersect(const Ray& ray, const Cylinder& c) {
  const double ox = ray.origin.x() - c.center.x(), oy = ray.origin.y() - c.center.y();
  const double dx = ray.direction.x(), dy = ray.direction.y();
  const double a = dx * dx + dy * dy;
  if (a < 1e-12) return -1.0;
  const double bq = ox * dx + oy * dy;
  const double cq = ox * ox + oy * oy - c.radius * c.radius;
  const double disc = bq * bq - a * cq;
  if (disc < 0.0 || cq < 0.0) return -1.0;
  const double t = (-bq - std::sqrt(disc)) / a;
  if (t < 0.0) return -1.0;
  const double z = ray.origin.z() + t * ray.direction.z();
  return (z >= c.z_min && z <= c.z_max) ? t : -1.0;
}

bool intersect(const Ray& ray, const Foliage& f, double& t0, double& t1) {
  const Eigen::Vector3d oc = ray.origin - f.center;
  const double b = oc.dot(ray.direction);
  const double c = oc.squaredNorm() - f.radius * f.radius;
  const double disc = b * b - c;
  if (disc < 0.0) return false;
  const double r = std::sqrt(disc);
  t0 = std::max(0.0, -b - r);
  t1 = -b + r;
  return t1 > 0.0;
}

void World::finalize(double cell_m) {
  cell_ = cell_m;
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  auto grow = [&](const Eigen::Vector2d& c, double r) {
    lo = lo.cwiseMin(c - Eigen::Vector2d(r, r));
    hi = hi.cwiseMax(c + Eigen::Vector2d(r, r));
  };
  for (const auto& b : boxes_) grow(b.center, std::hypot(b.half_x, b.half_y));
  for (const auto& c : cylinders_) grow(c.center, c.radius);
  for (const auto& f : foliage_) grow(f.center.head<2>(), f.radius);
  if (lo.x() > hi.x()) lo = hi = Eigen::Vector2d::Zero();
  grid_min_ = lo - Eigen::Vector2d(kMargin, kMargin);
  nx_ = static_cast<int>(std::ceil((hi.x() - lo.x() + 2 * kMargin) / cell_)) + 1;
  ny_ = static_cast<int>(std::ceil((hi.y() - lo.y() + 2 * kMargin) / cell_)) + 1;
  cells_.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_), Cell{});
  auto insert = [&](const Eigen::Vector2d& c, double r, auto member, std::uint32_t index) {
    const int x0 = static_cast<int>((c.x() - r - grid_min_.x()) / cell_);
    const int x1 = static_cast<int>((c.x() + r - grid_min_.x()) / cell_);
    const int y0 = static_cast<int>((c.y() - r - grid_min_.y()) / cell_);
    const int y1 = static_cast<int>((c.y() + r - grid_min_.y()) / cell_);
    for (int x = std::max(0, x0); x <= std::min(nx_ - 1, x1); ++x) {
      for (int y = std::max(0, y0); y <= std::min(ny_ - 1, y1); ++y) {
        (cells_[static_cast<std::size_t>(y * nx_ + x)].*member).push_back(index);
      }
    }
  };
  for (std::uint32_t i = 0; i < boxes_.size(); ++i) {
    insert(boxes_[i].center, std::hypot(boxes_[i].half_x, boxes_[i].half_y), &Cell::boxes, i);
  }
  for (std::uint32_t i = 0; i < cylinders_.size(); ++i) {
    insert(cylinders_[i].center, cylinders_[i].radius, &Cell::cylinders, i);
  }
  for (std::uint32_t i = 0; i < foliage_.size(); ++i) {
    insert(foliage_[i].center.head<2>(), foliage_[i].radius, &Cell::foliage, i);
  }
}

template <class Fn>
void World::for_cells_on_ray(const Ray& ray, double max_range, Fn&& fn) const {
  // 2-D grid walk (Amanatides & Woo) parametrised by the 3-D ray distance t.
  const double px = (ray.origin.x() - grid_min_.x()) / cell_;
  const double py = (ray.origin.y() - grid_min_.y()) / cell_;
  int x = static_cast<int>(std::floor(px)), y = static_cast<int>(std::floor(py));
  const double dx = ray.direction.x() / cell_, dy = ray.direction.y() / cell_;
  const int sx = dx > 0 ? 1 : -1, sy = dy > 0 ? 1 : -1;
  double tx = std::abs(dx) < 1e-15 ? kInf : ((dx > 0 ? x + 1 - px : px - x) / std::abs(dx));
  double ty = std::abs(dy) < 1e-15 ? kInf : ((dy > 0 ? y + 1 - py : py - y) / std::abs(dy));
  const double stepx = std::abs(dx) < 1e-15 ? kInf : 1.0 / std::abs(dx);
  const double stepy = std::abs(dy) < 1e-15 ? kInf : 1.0 / std::abs(dy);
  double t_enter = 0.0;
  while (t_enter <= max_range && x >= 0 && y >= 0 && x < nx_ && y < ny_) {
    if (!fn(cells_[static_cast<std::size_t>(y * nx_ + x)], t_enter)) return;
    if (tx < ty) {
      t_enter = tx;
      tx += stepx;
      x += sx;
    } else {
      t_enter = ty;
      ty += stepy;
      y += sy;
    }
  }
}

RayReturns World::cast(const Ray& ray, double max_range, const std::vector<Box>& movers,
                       std::uint64_t seed, std::uint64_t ray_id) const {
  double best = max_range;
  double best_refl = 0.0;
  double partial = kInf, partial_refl = 0.0;
  auto take = [&](double t, double refl) {
    if (t > 0.0 && t < best) {
      best = t;
      best_refl = refl;
    }
  };
  if (ray.direction.z() < -1e-9) take(-ray.origin.z() / ray.direction.z(), ground_reflectivity_);
  if (ceiling_z_ > 0.0 && ray.direction.z() > 1e-9) {
    take((ceiling_z_ - ray.origin.z()) / ray.direction.z(), 45.0);
  }
  for (const auto& m : movers) take(intersect(ray, m), m.reflectivity);
  for_cells_on_ray(ray, max_range, [&](const Cell& cell, double t_enter) {
    if (t_enter > best) return false;
    for (auto i : cell.boxes) take(intersect(ray, boxes_[i]), boxes_[i].reflectivity);
    for (auto i : cell.cylinders) {
      take(intersect(ray, cylinders_[i]), cylinders_[i].reflectivity);
    }
    for (auto i : cell.foliage) {
      const Foliage& f = foliage_[i];
      double t0 = 0.0, t1 = 0.0;
      if (!intersect(ray, f, t0, t1) || t0 >= best) continue;
      const double u = uniform(seed, ray_id, i);
      const double depth = t0 + uniform(seed, ray_id, i + (1ULL << 40)) * (t1 - t0) * 0.6;
      if (u < 0.5 * (1.0 - f.porosity)) {
        take(depth, f.reflectivity);  // dense enough to stop the beam
      } else if (u < 1.0 - f.porosity && depth < partial) {
        partial = depth;  // a weak echo; the beam goes on
        partial_refl = f.reflectivity * 0.6;
      }
    }
    return true;
  });
  RayReturns out;
  if (partial < best && partial < max_range) {
    out.hits[out.count++] = Hit{partial, partial_refl, 0.3 * partial_refl};
  }
  if (best < max_range) out.hits[out.count++] = Hit{best, best_refl, best_refl};
  return out;
}

}  // namespace cndt::sim
