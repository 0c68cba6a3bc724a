// NDT voxel grid (paper section 2.1, eqs 1-4): cubic voxels of edge L holding running sums of
// their points, so that points can be added incrementally. Fixed capacity, open addressing,
// allocated once; inserting never allocates.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace cndt::ndt {

/// Integer voxel coordinates packed into one key.
struct VoxelKey {
  std::int32_t x = 0, y = 0, z = 0;
  bool operator==(const VoxelKey&) const = default;
};

/// One voxel: running sums (eqs 1-3) and the Gaussian derived from them (eq 4).
struct Voxel {
  VoxelKey key;
  std::uint32_t count = 0;                              ///< N_j
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();        ///< m_j = sum p_i
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();  ///< S_j = sum p_i p_i^T
  // Derived by VoxelGrid::finalize():
  bool has_gaussian = false;  ///< N_j >= min_points
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inv_cov = Eigen::Matrix3d::Zero();
};

struct VoxelGridOptions {
  double voxel_size = 0.5;         ///< L, metres (paper: 0.5 m)
  std::size_t capacity = 200'000;  ///< voxels held at most
  std::uint32_t min_points = 5;    ///< Gaussians need redundant points (paper: N >= 5)
  double eigen_floor = 0.001;      ///< eigenvalues raised to this fraction of the largest
  /// Voxels whose points lie on a nearly horizontal line (a single ring arc) get no Gaussian
  /// when set: such arcs move with the sensor and pull scan matching towards zero motion.
  bool drop_horizontal_lines = false;
};

class VoxelGrid {
 public:
  explicit VoxelGrid(const VoxelGridOptions& options);

  /// Adds one point (metres, grid frame). False when a new voxel would exceed the capacity.
  bool add(const Eigen::Vector3d& p) noexcept;
  /// Derives mean and inverse covariance for every voxel with enough points:
  /// mu = m / N; Sigma = S / N - mu mu^T (population covariance, divisor N), with every
  /// eigenvalue below eigen_floor x the largest raised to that value.
  void finalize() noexcept;
  void clear() noexcept;

  [[nodiscard]] VoxelKey key_of(const Eigen::Vector3d& p) const noexcept;
  /// The voxel holding `p`, or nullptr.
  [[nodiscard]] const Voxel* find(const Eigen::Vector3d& p) const noexcept {
    return find(key_of(p));
  }
  [[nodiscard]] const Voxel* find(const VoxelKey& k) const noexcept;
  /// Index of the voxel in voxels(), or -1.
  [[nodiscard]] std::int64_t index_of(const VoxelKey& k) const noexcept;

  /// Occupied voxels, in insertion order.
  [[nodiscard]] const std::vector<Voxel>& voxels() const noexcept { return voxels_; }
  [[nodiscard]] std::size_t size() const noexcept { return voxels_.size(); }
  [[nodiscard]] std::uint64_t refused_points() const noexcept { return refused_; }
  [[nodiscard]] const VoxelGridOptions& options() const noexcept { return options_; }

 private:
  [[nodiscard]] std::size_t slot_of(const VoxelKey& k) const noexcept;

  VoxelGridOptions options_;
  double inv_size_;
  std::vector<Voxel> voxels_;        // capacity reserved once
  std::vector<std::int32_t> table_;  // open addressing: index into voxels_, -1 empty
  std::size_t mask_;
  std::uint64_t refused_ = 0;
};

}  // namespace cndt::ndt
