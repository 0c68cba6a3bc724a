// Voxel-grid downsampling: one point (the centroid) per occupied cell. Buffers are sized once.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace cndt::slam {

/// A point with its firing time, seconds after the scan's stamp.
struct TimedPoint {
  Eigen::Vector3d p;
  double t = 0.0;
};

/// Most centroids of `cell` downsampling (one per cell) that a cube of edge `voxel` can hold, in
/// any orientation to the cells: the cells it meets fit in the cube grown by a cell diagonal each
/// way, ((voxel + 2 sqrt(3) cell) / cell)^3. `limit` when that is larger or cell is not positive.
std::size_t max_centroids_per_voxel(double voxel, double cell, std::size_t limit);

class Downsampler {
 public:
  /// `cell` metres; at most `capacity` output points (further cells are dropped and counted).
  Downsampler(double cell, std::size_t capacity);
  /// Replaces `out` with the centroids of `in`'s occupied cells, in first-seen order.
  void run(std::span<const Eigen::Vector3d> in, std::vector<Eigen::Vector3d>& out);
  /// The same for timed points: each centroid carries the mean firing time of its points.
  void run(std::span<const TimedPoint> in, std::vector<TimedPoint>& out);
  [[nodiscard]] std::size_t dropped() const { return dropped_; }

 private:
  struct Cell {
    std::int64_t key;
    Eigen::Vector3d sum;
    double time_sum;
    std::uint32_t count;
  };
  // Points are binned in order; the table slot of the point kAhead later is fetched meanwhile.
  static constexpr std::size_t kAhead = 16;
  // The cells of the keys seen last, direct-mapped by key: a scan's next point on a ring comes
  // one firing sequence (16 points) after the one before it, often in the same cell, and is then
  // found here without a probe of the table. Cells stay where they are until reset().
  struct Recent {
    std::int64_t key = -1;  // keys are never negative
    std::int32_t index = -1;
  };
  static constexpr int kRecentBits = 8;
  [[nodiscard]] std::int64_t key_of(const Eigen::Vector3d& p) const;
  [[nodiscard]] std::size_t home_slot(std::int64_t key) const;
  [[nodiscard]] static std::size_t recent_slot(std::int64_t key);  // in recent_
  void prefetch(const Eigen::Vector3d& p) const;
  // The cell of `key`, a new one when there is room; -1 when the cells are full.
  std::int32_t find_or_add(std::int64_t key);
  void bin(const Eigen::Vector3d& p, double t);
  void size_table(std::size_t points);
  void reset();
  double inv_cell_;
  std::size_t capacity_;
  std::vector<Cell> cells_;
  std::vector<std::int32_t> table_;  // slots for the capacity; the first mask_ + 1 in use
  std::vector<std::size_t> used_slots_;
  std::array<Recent, std::size_t{1} << kRecentBits> recent_{};
  std::size_t mask_;
  std::size_t dropped_ = 0;
};

}  // namespace cndt::slam
