#include "cndt/slam/downsample.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "cndt/core/cell.hpp"
#include "cndt/core/resident.hpp"

namespace cndt::slam {

std::size_t max_centroids_per_voxel(double voxel, double cell, std::size_t limit) {
  if (!(cell > 0.0)) return limit;
  const double per_axis = std::ceil((voxel + 2.0 * std::sqrt(3.0) * cell) / cell);
  const double cells = per_axis * per_axis * per_axis;
  return cells >= static_cast<double>(limit) ? limit : static_cast<std::size_t>(cells);
}

Downsampler::Downsampler(double cell, std::size_t capacity)
    : inv_cell_(1.0 / cell), capacity_(capacity) {
  core::reserve_resident(cells_, capacity, Cell{0, Eigen::Vector3d::Zero(), 0.0, 0});
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(16, capacity * 2));
  table_.assign(slots, -1);
  core::reserve_resident(used_slots_, capacity);
  mask_ = slots - 1;
}

std::int64_t Downsampler::key_of(const Eigen::Vector3d& p) const {
  const std::int64_t x = core::cell_index(p.x() * inv_cell_);
  const std::int64_t y = core::cell_index(p.y() * inv_cell_);
  const std::int64_t z = core::cell_index(p.z() * inv_cell_);
  return ((x & 0x1FFFFF) << 42) | ((y & 0x1FFFFF) << 21) | (z & 0x1FFFFF);
}

std::size_t Downsampler::home_slot(std::int64_t key) const {
  return static_cast<std::size_t>((static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ULL) >> 20) &
         mask_;
}

std::size_t Downsampler::recent_slot(std::int64_t key) {
  return static_cast<std::size_t>((static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ULL) >>
                                  (64 - kRecentBits));
}

void Downsampler::prefetch(const Eigen::Vector3d& p) const {
  __builtin_prefetch(&table_[home_slot(key_of(p))]);
}

std::int32_t Downsampler::find_or_add(std::int64_t key) {
  std::size_t s = home_slot(key);
  while (table_[s] >= 0 && cells_[static_cast<std::size_t>(table_[s])].key != key) {
    s = (s + 1) & mask_;
  }
  if (table_[s] < 0) {
    if (cells_.size() == capacity_) return -1;  // not cells_.capacity(): a copy reserves its size
    table_[s] = static_cast<std::int32_t>(cells_.size());
    used_slots_.push_back(s);
    cells_.push_back(Cell{key, Eigen::Vector3d::Zero(), 0.0, 0});
  }
  return table_[s];
}

void Downsampler::bin(const Eigen::Vector3d& p, double t) {
  const std::int64_t key = key_of(p);
  Recent& recent = recent_[recent_slot(key)];
  std::int32_t index = recent.index;
  if (recent.key != key) {
    index = find_or_add(key);
    if (index < 0) {
      ++dropped_;
      return;
    }
    recent = {key, index};
  }
  Cell& c = cells_[static_cast<std::size_t>(index)];
  c.sum += p;
  c.time_sum += t;
  ++c.count;
}

void Downsampler::size_table(std::size_t points) {
  // Load at most one half for this run's points; a small run keeps a small table in the caches.
  const std::size_t cells = std::min(points, capacity_);
  mask_ = std::min(table_.size(), std::bit_ceil(std::max<std::size_t>(16, cells * 2))) - 1;
}

void Downsampler::reset() {
  recent_.fill(Recent{});
  for (std::size_t s : used_slots_) table_[s] = -1;
  used_slots_.clear();
  cells_.clear();
}

void Downsampler::run(std::span<const Eigen::Vector3d> in, std::vector<Eigen::Vector3d>& out) {
  dropped_ = 0;
  size_table(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (i + kAhead < in.size()) prefetch(in[i + kAhead]);
    bin(in[i], 0.0);
  }
  out.clear();
  for (const Cell& c : cells_) out.push_back(c.sum / c.count);
  reset();
}

void Downsampler::run(std::span<const TimedPoint> in, std::vector<TimedPoint>& out) {
  dropped_ = 0;
  size_table(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (i + kAhead < in.size()) prefetch(in[i + kAhead].p);
    bin(in[i].p, in[i].t);
  }
  out.clear();
  for (const Cell& c : cells_) out.push_back({c.sum / c.count, c.time_sum / c.count});
  reset();
}

}  // namespace cndt::slam
