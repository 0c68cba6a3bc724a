// A synthetic world for ray casting: flat ground, oriented boxes (buildings, walls, parked cars),
// vertical cylinders (poles, trunks), porous spheres (foliage) and moving boxes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace cndt::sim {

struct Box {
  Eigen::Vector2d center{0, 0};
  double yaw = 0.0;  ///< rad, about z
  double half_x = 1.0, half_y = 1.0;
  double z_min = 0.0, z_max = 1.0;
  double reflectivity = 60;  ///< calibrated reflectivity 0..255
};

struct Cylinder {
  Eigen::Vector2d center{0, 0};
  double radius = 0.1;
  double z_min = 0.0, z_max = 5.0;
  double reflectivity = 40;
};

/// Foliage: a ray entering it returns with probability 1 - porosity from a random depth.
struct Foliage {
  Eigen::Vector3d center{0, 0, 3};
  double radius = 2.0;
  double porosity = 0.4;
  double reflectivity = 25;
};

struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;  ///< unit
};

/// A return along a ray. A ray can give a weak partial return (foliage) before a solid one.
struct Hit {
  double range = 0.0;
  double reflectivity = 0.0;
  double strength = 0.0;  ///< relative echo strength, for strongest/last selection
};

struct RayReturns {
  int count = 0;
  Hit hits[2];  ///< in range order; at most a partial return then the terminating one
};

class World {
 public:
  void add(const Box& b) { boxes_.push_back(b); }
  void add(const Cylinder& c) { cylinders_.push_back(c); }
  void add(const Foliage& f) { foliage_.push_back(f); }
  void set_ceiling(double z) { ceiling_z_ = z; }
  void set_ground_reflectivity(double r) { ground_reflectivity_ = r; }
  /// Builds the acceleration grid; call once after adding static objects.
  void finalize(double cell_m = 8.0);

  /// Casts `ray` against the static world and `movers` (boxes placed for this instant).
  /// `ray_id` seeds the foliage draw so results are reproducible.
  RayReturns cast(const Ray& ray, double max_range, const std::vector<Box>& movers,
                  std::uint64_t seed, std::uint64_t ray_id) const;

  [[nodiscard]] std::size_t object_count() const {
    return boxes_.size() + cylinders_.size() + foliage_.size();
  }

 private:
  struct Cell {
    std::vector<std::uint32_t> boxes, cylinders, foliage;
  };
  template <class Fn>
  void for_cells_on_ray(const Ray& ray, double max_range, Fn&& fn) const;

  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Foliage> foliage_;
  double ceiling_z_ = 0.0;  ///< 0 = open sky
  double ground_reflectivity_ = 20;
  double cell_ = 8.0;
  Eigen::Vector2d grid_min_{0, 0};
  int nx_ = 0, ny_ = 0;
  std::vector<Cell> cells_;
};

/// Ray/box intersection distance (entry), or a negative value for a miss.
double intersect(const Ray& ray, const Box& b);
double intersect(const Ray& ray, const Cylinder& c);
/// Entry and exit distances of a sphere; false on a miss.
bool intersect(const Ray& ray, const Foliage& f, double& t0, double& t1);

}  // namespace cndt::sim
