#include "cndt/ndt/voxel_grid.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>

#include "cndt/core/resident.hpp"

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
  // Versions are unique across grids (the high half numbers the grid), so that a lookup cache
  // never mistakes a new grid at a reused address for the one it was filled from.
  static std::atomic<std::uint64_t> grids{0};
  version_ = (grids.fetch_add(1, std::memory_order_relaxed) + 1) << 32;
  if (options.resident) {
    core::reserve_resident(voxels_, options.capacity);
    core::reserve_resident(dirty_, options.capacity);
  } else {
    voxels_.reserve(options.capacity);
    dirty_.reserve(options.capacity);
  }
  // Load factor at most one half.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(16, options.capacity * 2));
  table_.assign(slots, -1);
  mask_ = slots - 1;
}

Eigen::Vector3d VoxelGrid::corner(const VoxelKey& k) const noexcept {
  return Eigen::Vector3d(k.x, k.y, k.z) * options_.voxel_size;
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

void VoxelGrid::mark_dirty(Voxel& v, std::size_t index) noexcept {
  if (v.dirty) return;
  v.dirty = true;
  dirty_.push_back(static_cast<std::uint32_t>(index));  // at most one entry per voxel
}

bool VoxelGrid::add(const Eigen::Vector3d& p) noexcept { return add_point(p) != nullptr; }

bool VoxelGrid::add(const Eigen::Vector3d& p, double consensus) noexcept {
  Voxel* v = add_point(p);
  if (v == nullptr) return false;
  // Running mean over the points added (count already includes this one).
  v->consensus += static_cast<float>((consensus - v->consensus) / v->count);
  return true;
}

bool VoxelGrid::restore(const VoxelKey& k, std::uint32_t count, const Eigen::Vector3d& sum,
                        const Eigen::Matrix3d& sum_outer, float consensus) noexcept {
  const std::size_t s = slot_of(k);
  if (count == 0 || table_[s] >= 0 || voxels_.size() == options_.capacity) return false;
  table_[s] = static_cast<std::int32_t>(voxels_.size());
  voxels_.emplace_back();
  Voxel& v = voxels_.back();
  v.key = k;
  v.count = count;
  v.sum = sum;
  v.sum_outer = sum_outer;
  v.consensus = consensus;
  ++version_;
  mark_dirty(v, voxels_.size() - 1);
  return true;
}

Voxel* VoxelGrid::add_point(const Eigen::Vector3d& p) noexcept {
  const VoxelKey k = key_of(p);
  const std::size_t s = slot_of(k);
  if (table_[s] < 0) {
    if (voxels_.size() == options_.capacity) {
      ++refused_;
      return nullptr;
    }
    table_[s] = static_cast<std::int32_t>(voxels_.size());
    voxels_.emplace_back();
    voxels_.back().key = k;
    ++version_;  // a lookup that found nothing here would now find this voxel
  } else if (voxels_[static_cast<std::size_t>(table_[s])].count == 0) {
    --empty_;  // a voxel emptied by remove() fills again
  }
  const auto index = static_cast<std::size_t>(table_[s]);
  Voxel& v = voxels_[index];
  const Eigen::Vector3d q = p - corner(k);
  ++v.count;                                   // eq 3
  v.sum += q;                                  // eq 1
  v.sum_outer.noalias() += q * q.transpose();  // eq 2
  mark_dirty(v, index);
  return &v;
}

bool VoxelGrid::remove(const Eigen::Vector3d& p) noexcept {
  const VoxelKey k = key_of(p);
  const std::int32_t i = table_[slot_of(k)];
  if (i < 0 || voxels_[static_cast<std::size_t>(i)].count == 0) return false;
  Voxel& v = voxels_[static_cast<std::size_t>(i)];
  if (--v.count == 0) {
    ++empty_;
    // Exact zeros, so that round-off cannot build up in a voxel that empties and refills.
    v.sum.setZero();
    v.sum_outer.setZero();
  } else {
    const Eigen::Vector3d q = p - corner(k);
    v.sum -= q;
    v.sum_outer.noalias() -= q * q.transpose();
  }
  mark_dirty(v, static_cast<std::size_t>(i));
  return true;
}

void VoxelGrid::derive(Voxel& v) const noexcept {
  v.has_gaussian = v.count >= options_.min_points;
  if (!v.has_gaussian) return;
  const double n = v.count;
  const Eigen::Vector3d m = v.sum / n;
  v.mean = corner(v.key) + m;                                 // eq 4, mean
  Eigen::Matrix3d cov = v.sum_outer / n - m * m.transpose();  // eq 4, covariance
  cov = 0.5 * (cov + cov.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.compute(cov);
  Eigen::Vector3d ev = es.eigenvalues();
  if (options_.drop_horizontal_lines && ev(1) < 0.05 * ev(2) &&
      std::abs(es.eigenvectors().col(2).z()) < 0.5) {
    v.has_gaussian = false;  // a ring arc: one dominant, nearly horizontal direction
    return;
  }
  const double floor = std::max(ev.maxCoeff(), 1e-12) * options_.eigen_floor;
  ev = ev.cwiseMax(floor);  // planes and lines would otherwise be singular
  v.inv_cov = es.eigenvectors() * ev.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
}

void VoxelGrid::finalize() noexcept {
  for (std::uint32_t i : dirty_) {
    Voxel& v = voxels_[i];
    v.dirty = false;
    derive(v);
  }
  dirty_.clear();
}

void VoxelGrid::compact() noexcept {
  finalize();
  std::erase_if(voxels_, [](const Voxel& v) { return v.count == 0; });  // keeps the capacity
  rebuild_table();
}

void VoxelGrid::rebuild_table() noexcept {
  ++version_;
  std::fill(table_.begin(), table_.end(), -1);
  empty_ = 0;
  for (std::size_t i = 0; i < voxels_.size(); ++i) {
    table_[slot_of(voxels_[i].key)] = static_cast<std::int32_t>(i);
    if (voxels_[i].count == 0) ++empty_;
  }
}

void VoxelGrid::clear() noexcept {
  voxels_.clear();
  dirty_.clear();
  std::fill(table_.begin(), table_.end(), -1);
  refused_ = 0;
  empty_ = 0;
  ++version_;
}

}  // namespace cndt::ndt
