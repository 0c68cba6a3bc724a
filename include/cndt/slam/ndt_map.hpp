// The map: NDT voxels with running sums (paper eqs 1-4) in the map frame, fed with the
// high-consensus points of refined scans (section 3.2). Memory is bounded twice: a voxel
// capacity allocated once, and a window around the vehicle beyond which voxels are evicted.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "cndt/ndt/voxel_grid.hpp"

namespace cndt::slam {

struct MapOptions {
  double voxel_size = 0.5;           ///< m, the paper's L
  std::size_t capacity = 2'000'000;  ///< voxels held at most (about 220 bytes each)
  /// Voxels whose centre is farther than this (horizontally) from the vehicle are evicted by
  /// evict_outside(); 0 keeps everything (a map built for saving, or a prior map).
  double window_radius = 0.0;
  std::uint32_t min_points = 5;  ///< points a voxel needs for a Gaussian (paper: 5)
  double eigen_floor = 0.001;    ///< eigenvalue clamp, fraction of the largest
  /// The map frame's origin in a world frame of the user's choice (for example UTM): kept in
  /// the map file, never used in matching.
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
};

class NdtMap {
 public:
  explicit NdtMap(const MapOptions& options);
  /// Adds a point (map frame) with the Cv of the voxel it came from. False when the map is
  /// full (the point is counted as refused).
  bool add(const Eigen::Vector3d& p, double cv) noexcept { return grid_.add(p, cv); }
  /// Derives the Gaussians of the voxels changed since the last call.
  void finalize() noexcept { grid_.finalize(); }
  /// Evicts the voxels outside the window around `position`; returns how many.
  std::size_t evict_outside(const Eigen::Vector3d& position) noexcept;
  void clear() noexcept { grid_.clear(); }

  [[nodiscard]] const ndt::VoxelGrid& grid() const noexcept { return grid_; }
  ndt::VoxelGrid& grid() noexcept { return grid_; }
  [[nodiscard]] const MapOptions& options() const noexcept { return options_; }
  [[nodiscard]] std::size_t size() const noexcept { return grid_.size(); }
  /// Points summed over all voxels.
  [[nodiscard]] std::uint64_t points() const noexcept;
  /// Voxels with a Gaussian (count >= min_points).
  [[nodiscard]] std::size_t gaussians() const noexcept;

 private:
  MapOptions options_;
  ndt::VoxelGrid grid_;
};

}  // namespace cndt::slam
