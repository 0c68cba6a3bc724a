#include "cndt/slam/ndt_map.hpp"

namespace cndt::slam {

NdtMap::NdtMap(const MapOptions& o)
    : options_(o),
      grid_({o.voxel_size, o.capacity, o.min_points, o.eigen_floor, false, false, false}) {}

std::size_t NdtMap::evict_outside(const Eigen::Vector3d& position) noexcept {
  if (!(options_.window_radius > 0.0)) return 0;
  const double r2 = options_.window_radius * options_.window_radius;
  const double half = 0.5 * options_.voxel_size;
  return grid_.erase_voxels_if([&](const ndt::Voxel& v) {
    const double dx = (v.key.x * options_.voxel_size + half) - position.x();
    const double dy = (v.key.y * options_.voxel_size + half) - position.y();
    return dx * dx + dy * dy > r2;
  });
}

std::uint64_t NdtMap::points() const noexcept {
  std::uint64_t n = 0;
  for (const ndt::Voxel& v : grid_.voxels()) n += v.count;
  return n;
}

std::size_t NdtMap::gaussians() const noexcept {
  std::size_t n = 0;
  for (const ndt::Voxel& v : grid_.voxels()) n += v.has_gaussian ? 1 : 0;
  return n;
}

}  // namespace cndt::slam
