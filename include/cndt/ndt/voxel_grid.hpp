// NDT voxel grid (paper section 2.1, eqs 1-4): cubic voxels of edge L holding running sums of
// their points, so that points can be added and removed incrementally. Fixed capacity, open
// addressing, allocated once; adding, removing, finalizing and compacting never allocate.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cndt/core/cell.hpp"

namespace cndt::ndt {

class TaskRunner;  // ndt_score.hpp

/// Integer voxel coordinates packed into one key.
struct VoxelKey {
  std::int32_t x = 0, y = 0, z = 0;
  bool operator==(const VoxelKey&) const = default;
};

/// One voxel: running sums (eqs 1-3); the Gaussian derived from them (eq 4) is kept apart
/// (VoxelGrid::gaussians()). The sums are kept relative to the voxel's corner (key x L), so
/// that they stay exact far from the origin and after many additions and removals.
struct Voxel {
  VoxelKey key;
  std::uint32_t count = 0;  ///< N_j
  /// Set by VoxelGrid::finalize(): N_j >= min_points (and not dropped as a ring arc).
  bool has_gaussian = false;
  bool dirty = false;    ///< to derive again at the next finalize()
  bool changed = false;  ///< its own sums changed since the last finalize()
  bool patch = false;    ///< its Gaussian is a surface patch (VoxelGridOptions::surface_patches)
  /// Mean voxel consensus Cv of the points added with one (a map's voxels); 0 otherwise.
  float consensus = 0.0f;
  // Running sums, corner-relative: m_j = sum (p_i - c), S_j = sum (p_i - c)(p_i - c)^T.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();

  /// Eq 4's covariance of the points (count > 0), symmetrised.
  [[nodiscard]] Eigen::Matrix3d covariance() const noexcept {
    const Eigen::Vector3d m = sum / static_cast<double>(count);
    const Eigen::Matrix3d cov = sum_outer / static_cast<double>(count) - m * m.transpose();
    return 0.5 * (cov + cov.transpose());
  }
};

/// A voxel's Gaussian (eq 4) as scoring reads it, in one cache line: the mean, and the six
/// distinct entries of the inverse covariance in single precision (relative error 6e-8: the
/// same model for the score and its derivatives, a few nanometres from the double one).
struct alignas(64) Gaussian {
  double mean[3] = {0.0, 0.0, 0.0};
  float inv_cov[6] = {};    ///< A: xx, xy, xz, yy, yz, zz
  std::uint32_t valid = 0;  ///< the voxel has a Gaussian (Voxel::has_gaussian)

  [[nodiscard]] Eigen::Vector3d mean_vector() const noexcept { return {mean[0], mean[1], mean[2]}; }
  [[nodiscard]] Eigen::Matrix3d inv_cov_matrix() const noexcept {
    Eigen::Matrix3d A;
    A << inv_cov[0], inv_cov[1], inv_cov[2], inv_cov[1], inv_cov[3], inv_cov[4], inv_cov[2],
        inv_cov[4], inv_cov[5];
    return A;
  }

  /// Returns q^T A q and sets a = A q, for q = v - mean.
  double mahalanobis(const Eigen::Vector3d& v, Eigen::Vector3d& a) const noexcept {
    const double q0 = v.x() - mean[0], q1 = v.y() - mean[1], q2 = v.z() - mean[2];
    const double A00 = inv_cov[0], A01 = inv_cov[1], A02 = inv_cov[2], A11 = inv_cov[3],
                 A12 = inv_cov[4], A22 = inv_cov[5];
    a = Eigen::Vector3d(A00 * q0 + A01 * q1 + A02 * q2, A01 * q0 + A11 * q1 + A12 * q2,
                        A02 * q0 + A12 * q1 + A22 * q2);
    return q0 * a.x() + q1 * a.y() + q2 * a.z();
  }
};
static_assert(sizeof(Gaussian) == 64);

struct VoxelGridOptions {
  double voxel_size = 0.5;         ///< L, metres (paper: 0.5 m)
  std::size_t capacity = 200'000;  ///< voxels held at most
  std::uint32_t min_points = 5;    ///< Gaussians need redundant points (paper: N >= 5)
  double eigen_floor = 0.001;      ///< eigenvalues raised to this fraction of the largest
  /// Voxels whose points lie on a nearly horizontal line (a single ring arc) get no Gaussian
  /// when set: such arcs move with the sensor and pull scan matching towards zero motion.
  bool drop_horizontal_lines = false;
  /// Surface patches: a voxel whose neighbourhood (itself and its 26 neighbours) holds a plane
  /// gets that plane's orientation for its Gaussian: its own spread along the plane's normal,
  /// and along the plane at least L^2 (reaching over its neighbours). What a scan leaves
  /// in one voxel of a surface is where its rings crossed it (an arc, or stripes), which moves
  /// with the sensor; matched as such, scans align their rings instead of their surfaces.
  bool surface_patches = false;
  /// Surface patches only for planes whose normal is within this angle of the grid's z axis
  /// (level surfaces: ground, floors, roofs); steeper planes keep eq 4's Gaussian. 90: every
  /// plane.
  double patch_max_tilt_deg = 90.0;
  /// The voxel array resident from the start (core/resident.hpp): for grids filled on a
  /// real-time thread. Otherwise reserved only, and mapped in as it fills.
  bool resident = true;
};

class VoxelGrid {
 public:
  explicit VoxelGrid(const VoxelGridOptions& options);

  /// Adds one point (metres, grid frame). False when a new voxel would exceed the capacity.
  bool add(const Eigen::Vector3d& p) noexcept;
  /// The same for a point that carries a voxel consensus Cv: the voxel keeps their mean.
  bool add(const Eigen::Vector3d& p, double consensus) noexcept;
  /// Re-creates a voxel from its stored running sums (a map read back from a file). False when
  /// the key is already present, count is 0, or the grid is full.
  bool restore(const VoxelKey& key, std::uint32_t count, const Eigen::Vector3d& sum,
               const Eigen::Matrix3d& sum_outer, float consensus) noexcept;
  /// Drops every voxel for which pred(voxel) holds and rebuilds the table (indices change).
  /// Changes not yet finalized are finalized first. Returns the number dropped.
  template <class Pred>
  std::size_t erase_voxels_if(Pred pred) noexcept {
    finalize();
    const std::size_t n = remove_voxels_if(pred);
    if (n > 0) rebuild_table();
    return n;
  }
  /// Takes back a point added before (the same coordinates). A voxel left empty stays in the
  /// table, without a Gaussian, until compact(). False when no voxel holds `p`.
  bool remove(const Eigen::Vector3d& p) noexcept;
  /// Derives mean and inverse covariance for every voxel changed since the last call that has
  /// enough points: mu = m / N; Sigma = S / N - mu mu^T (population covariance, divisor N), with
  /// every eigenvalue below eigen_floor x the largest raised to that value. With a `runner`, the
  /// voxels are derived in chunks on its threads (the same Gaussians to the bit).
  void finalize(TaskRunner* runner = nullptr) noexcept;
  /// Turns surface patches on or off for the voxels held and those to come: every held voxel
  /// is judged again at the next finalize() (those a patch neither before nor after keep their
  /// Gaussians). Allocates nothing.
  void set_surface_patches(bool on) noexcept;
  void clear() noexcept;
  /// Drops the empty voxels left by remove() and rebuilds the table (indices change). Changes
  /// not yet finalized are finalized first.
  void compact() noexcept;
  /// Voxels left empty by remove(), still occupying a slot.
  [[nodiscard]] std::size_t empty_voxels() const noexcept { return empty_; }

  [[nodiscard]] VoxelKey key_of(const Eigen::Vector3d& p) const noexcept {
    return {core::cell_index(p.x() * inv_size_), core::cell_index(p.y() * inv_size_),
            core::cell_index(p.z() * inv_size_)};
  }
  /// The voxel holding `p`, or nullptr.
  [[nodiscard]] const Voxel* find(const Eigen::Vector3d& p) const noexcept {
    return find(key_of(p));
  }
  [[nodiscard]] const Voxel* find(const VoxelKey& k) const noexcept;
  /// Index of the voxel in voxels(), or -1.
  [[nodiscard]] std::int64_t index_of(const VoxelKey& k) const noexcept;
  /// index_of() for the first `n` (at most 7) of `key` and its six face neighbours in the order
  /// of kFaceOffsets, into out[0..n). The table slots are fetched together, not one after the
  /// other.
  void indices_around(const VoxelKey& key, int n, std::int32_t* out) const noexcept;
  /// Fetches the table slots indices_around(key, n, ...) will read into the cache.
  void prefetch_around(const VoxelKey& key, int n) const noexcept;
  /// Hints for adding or removing many points: prefetch_slot(p) fetches the table slot where
  /// p's voxel is looked up; prefetch_voxel(p), issued later, looks it up and fetches the voxel.
  /// Neither changes anything, so a point between the hint and its use may still be added.
  void prefetch_slot(const Eigen::Vector3d& p) const noexcept;
  void prefetch_voxel(const Eigen::Vector3d& p) const noexcept;
  /// Fetches gaussians()[index] into the cache.
  void prefetch_gaussian(std::int32_t index) const noexcept {
    __builtin_prefetch(gaussians_.data() + index);
  }
  /// A voxel and its six face neighbours: (0,0,0), then +-x, +-y, +-z.
  static constexpr std::int32_t kFaceOffsets[7][3] = {{0, 0, 0},  {1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                                      {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

  /// Occupied voxels, in insertion order.
  [[nodiscard]] const std::vector<Voxel>& voxels() const noexcept { return voxels_; }
  /// The Gaussians of voxels() as of the last finalize(), index for index (valid = 0 where a
  /// voxel has none).
  [[nodiscard]] const std::vector<Gaussian>& gaussians() const noexcept { return gaussians_; }
  [[nodiscard]] std::size_t size() const noexcept { return voxels_.size(); }
  [[nodiscard]] std::uint64_t refused_points() const noexcept { return refused_; }
  [[nodiscard]] const VoxelGridOptions& options() const noexcept { return options_; }
  /// Changes whenever a lookup could give another index (a new voxel, compact, clear): voxel
  /// indices cached at one version stay right while it holds. Unique across grids.
  [[nodiscard]] std::uint64_t version() const noexcept { return version_; }

 private:
  // One hash table slot: the voxel's key and index (-1: empty). With the key in the slot a
  // lookup reads no voxel: one cache line per key, however many keys it passes.
  struct Slot {
    VoxelKey key;
    std::int32_t index = -1;
  };
  static_assert(sizeof(Slot) == 16);
  [[nodiscard]] std::size_t slot_of(const VoxelKey& k) const noexcept;
  [[nodiscard]] std::size_t slot_of(const VoxelKey& k, std::uint64_t h) const noexcept;
  void insert_slot(const VoxelKey& k, std::int32_t index) noexcept;  // k not in the table
  void grow_table_for(std::size_t voxels) noexcept;     // rehashes when the table gets too full
  Voxel* add_point(const Eigen::Vector3d& p) noexcept;  // nullptr when full
  void rebuild_table() noexcept;
  [[nodiscard]] Eigen::Vector3d corner(const VoxelKey& k) const noexcept;
  // Voxel `index` is derived again at the next finalize(); `own`: its own sums changed.
  void mark_dirty(Voxel& v, std::size_t index, bool own) noexcept;
  void derive(std::size_t index) noexcept;  // gaussians_[index] from voxels_[index]'s sums
  static void derive_chunk(void* context, std::size_t chunk);  // finalize()'s task
  // surface_patches: whether the voxels around voxel `index` (with it) hold a plane tilted at
  // most patch_max_tilt_deg, and its normal.
  bool neighbourhood_plane(std::size_t index, Eigen::Vector3d& normal) const noexcept;
  // surface_patches: the inverse covariance of a voxel with covariance `cov` in a plane.
  Eigen::Matrix3d surface_patch(const Eigen::Matrix3d& cov,
                                const Eigen::Vector3d& normal) const noexcept;
  // The 26 neighbours of a voxel, position p = 9 (dx + 1) + 3 (dy + 1) + (dz + 1) for offsets in
  // -1..1 (13, the voxel itself, left out: entry p - (p > 13)); -1 where none is in the grid.
  // The neighbour at position p sees this voxel at position 26 - p.
  using Around = std::array<std::int32_t, 26>;
  static constexpr int kCentre = 13;
  static constexpr VoxelKey around_key(const VoxelKey& key, int p) noexcept {
    return {key.x + p / 9 - 1, key.y + (p / 3) % 3 - 1, key.z + p % 3 - 1};
  }
  static constexpr std::size_t around_entry(int p) noexcept {
    return static_cast<std::size_t>(p < kCentre ? p : p - 1);
  }
  // Fills the new voxel `index`'s neighbour list and enters it in its neighbours' lists.
  void link_new(std::size_t index) noexcept;
  // f(index) for voxel `index` and each of its 26 neighbours that is in the grid, in the order
  // of their positions (the voxel itself 14th): from the neighbour lists when the grid keeps
  // them, otherwise by lookups.
  template <class F>
  void for_each_around(std::size_t index, F f) const noexcept {
    for (int p = 0; p < 27; ++p) {
      std::int64_t j;
      if (p == kCentre) {
        j = static_cast<std::int64_t>(index);
      } else if (listed_) {
        j = around_[index][around_entry(p)];
      } else {
        j = index_of(around_key(voxels_[index].key, p));
      }
      if (j >= 0) f(static_cast<std::size_t>(j));
    }
  }
  // Drops the voxels for which pred holds, with their Gaussians, keeping the order and the
  // capacity; the table is left to rebuild.
  template <class Pred>
  std::size_t remove_voxels_if(Pred pred) noexcept {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < voxels_.size(); ++i) {
      if (pred(voxels_[i])) {
        if (listed_) renumber_[i] = -1;
        continue;
      }
      if (kept != i) {
        voxels_[kept] = voxels_[i];
        gaussians_[kept] = gaussians_[i];
        if (listed_) around_[kept] = around_[i];
      }
      if (listed_) renumber_[i] = static_cast<std::int32_t>(kept);
      ++kept;
    }
    const std::size_t removed = voxels_.size() - kept;
    voxels_.resize(kept);  // shrinking: no allocation
    gaussians_.resize(kept);
    if (listed_) {
      around_.resize(kept);
      for (Around& a : around_) {
        for (std::int32_t& j : a) {
          if (j >= 0) j = renumber_[static_cast<std::size_t>(j)];
        }
      }
    }
    return removed;
  }

  VoxelGridOptions options_;
  double inv_size_;
  double patch_min_normal_z_;        // cos(patch_max_tilt_deg); -1 when every plane may be one
  std::vector<Voxel> voxels_;        // capacity reserved once
  std::vector<Gaussian> gaussians_;  // one per voxel, the same capacity
  // Open addressing with linear probing. All slots for the capacity are allocated once; only
  // the first mask_ + 1 are in use, sized to keep the load at most one half for the voxels
  // held, so that a grid far below its capacity keeps a small table in the caches.
  std::vector<Slot> table_;
  std::vector<std::uint32_t> dirty_;  // voxels changed since the last finalize()
  // Set when the grid was made with surface_patches: each voxel's neighbour list is kept, index
  // for index with voxels_ (a plane judged over a voxel's neighbourhood reads 26 neighbours for
  // every voxel derived, and marks them at every change: lookups cost more than the lists'
  // upkeep), with the new index of each voxel while remove_voxels_if() renumbers them.
  bool listed_;
  std::vector<Around> around_;
  std::vector<std::int32_t> renumber_;
  std::size_t mask_ = 15;
  std::size_t empty_ = 0;
  std::uint64_t refused_ = 0;
  std::uint64_t version_ = 0;
};

}  // namespace cndt::ndt
