#include "cndt/ndt/voxel_grid.hpp"

#include <Eigen/Eigenvalues>
#include <bit>
#include <cmath>

namespace cndt::ndt {
namespace {
std::uint64_t hash(const VoxelKey& k) {
  std::uint64_t h = static_cast<std::uint32_t>(k.x) * 0x9E3779B97F4A7C15ULL;
  h ^= static_cast<std::uint32_t>(k.y) * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2);
  h ^= static_cast<std::uint32_t>(k.z) * 0x165667B19E3779F9ULL + (h << 6) + (h >> 2);
  return h ^ (h >> 29);
}
}  // namespace

VoxelGrid::VoxelGrid(const VoxelGridOptions& options)
    : options_(options), inv_size_(1.0 / options.voxel_size) {
  voxels_.reserve(options.capacity);
  // Load factor at most one half.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(16, options.capacity * 2));
  table_.assign(slots, -1);
  mask_ = slots - 1;
}

VoxelKey VoxelGrid::key_of(const Eigen::Vector3d& p) const noexcept {
  return {static_cast<std::int32_t>(std::floor(p.x() * inv_size_)),
          static_cast<std::int32_t>(std::floor(p.y() * inv_size_)),
          static_cast<std::int32_t>(std::floor(p.z() * inv_size_))};
}

std::size_t VoxelGrid::slot_of(const VoxelKey& k) const noexcept {
  std::size_t s = hash(k) & mask_;
  while (table_[s] >= 0 && !(voxels_[static_cast<std::size_t>(table_[s])].key == k)) {
    s = (s + 1) & mask_;
  }
  return s;
}

std::int64_t VoxelGrid::index_of(const VoxelKey& k) const noexcept { return table_[slot_of(k)]; }

const Voxel* VoxelGrid::find(const VoxelKey& k) const noexcept {
  const std::int32_t i = table_[slot_of(k)];
  return i >= 0 ? &voxels_[static_cast<std::size_t>(i)] : nullptr;
}

bool VoxelGrid::add(const Eigen::Vector3d& p) noexcept {
  const VoxelKey k = key_of(p);
  const std::size_t s = slot_of(k);
  if (table_[s] < 0) {
    if (voxels_.size() == options_.capacity) {
      ++refused_;
      return false;
    }
    table_[s] = static_cast<std::int32_t>(voxels_.size());
    voxels_.emplace_back();
    voxels_.back().key = k;
  }
  Voxel& v = voxels_[static_cast<std::size_t>(table_[s])];
  ++v.count;                                   // eq 3
  v.sum += p;                                  // eq 1
  v.sum_outer.noalias() += p * p.transpose();  // eq 2
  return true;
}

void VoxelGrid::finalize() noexcept {
  for (Voxel& v : voxels_) {
    v.has_gaussian = v.count >= options_.min_points;
    if (!v.has_gaussian) continue;
    const double n = v.count;
    v.mean = v.sum / n;                                                   // eq 4, mean
    Eigen::Matrix3d cov = v.sum_outer / n - v.mean * v.mean.transpose();  // eq 4, covariance
    cov = 0.5 * (cov + cov.transpose());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    Eigen::Vector3d ev = es.eigenvalues();
    if (options_.drop_horizontal_lines && ev(1) < 0.05 * ev(2) &&
        std::abs(es.eigenvectors().col(2).z()) < 0.5) {
      v.has_gaussian = false;  // a ring arc: one dominant, nearly horizontal direction
      continue;
    }
    const double floor = std::max(ev.maxCoeff(), 1e-12) * options_.eigen_floor;
    ev = ev.cwiseMax(floor);  // planes and lines would otherwise be singular
    v.inv_cov = es.eigenvectors() * ev.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
  }
}

void VoxelGrid::clear() noexcept {
  voxels_.clear();
  std::fill(table_.begin(), table_.end(), -1);
  refused_ = 0;
}

}  // namespace cndt::ndt
