// NDT scan-matching objective (paper section 2.2, eqs 5-6) with its analytic gradient and
// Hessian (Magnusson's derivation with d1 = d2 = 1):
//   q = R(x) p + T(x) - mu_j,  s = -exp(-q^T Sigma_j^-1 q / 2),  S(x) = sum over points of s.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "cndt/core/pose.hpp"
#include "cndt/ndt/voxel_grid.hpp"

namespace cndt::ndt {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// R(x), its first and second derivatives by the three angles, for one pose.
class PoseDerivatives {
 public:
  explicit PoseDerivatives(const core::Pose6& x);
  [[nodiscard]] Eigen::Vector3d transform(const Eigen::Vector3d& p) const { return R_ * p + t_; }
  [[nodiscard]] const Eigen::Matrix3d& rotation() const { return R_; }
  [[nodiscard]] const Eigen::Vector3d& translation() const { return t_; }
  /// dR/d(angle k), k = 0 (phi), 1 (theta), 2 (psi).
  [[nodiscard]] const Eigen::Matrix3d& d1(int k) const { return d1_[static_cast<std::size_t>(k)]; }
  /// d2R/d(angle_a) d(angle_b) for (a, b) = (0,0) (0,1) (0,2) (1,1) (1,2) (2,2).
  [[nodiscard]] const Eigen::Matrix3d& d2(int i) const { return d2_[static_cast<std::size_t>(i)]; }
  /// The axes w_k the three angles turn about, as columns: x, y turned by phi, z turned by phi
  /// and theta. dR/d(angle k) p = w_k x (R p).
  [[nodiscard]] const Eigen::Matrix3d& axes() const { return W_; }

 private:
  Eigen::Matrix3d R_;
  Eigen::Vector3d t_;
  Eigen::Matrix3d W_;
  std::array<Eigen::Matrix3d, 3> d1_;
  std::array<Eigen::Matrix3d, 6> d2_;
};

class LookupCache;

/// Runs task(context, i) for every i in [0, count) and returns when all have run: on the calling
/// thread alone, or also on others (the runtime's scoring threads). The tasks of one call touch
/// disjoint data.
class TaskRunner {
 public:
  virtual void run(std::size_t count, void (*task)(void* context, std::size_t i),
                   void* context) = 0;

 protected:
  ~TaskRunner() = default;
};

/// A scoring splits its points into this many fixed chunks (contiguous, equal up to one point)
/// and adds the chunks' sums in chunk order: its result does not depend on whether, or on how
/// many threads, the chunks ran on.
inline constexpr std::size_t kScoreChunks = 8;
/// Smaller scorings run on the calling thread alone (same result).
inline constexpr std::size_t kParallelMinPoints = 1024;

/// Points [begin, end) of chunk `chunk` of a set of `points` (contiguous, equal up to one).
struct ChunkRange {
  std::size_t begin, end;
};
inline ChunkRange chunk_range(std::size_t points, std::size_t chunk) {
  return {points * chunk / kScoreChunks, points * (chunk + 1) / kScoreChunks};
}

/// Runs task(context, c) for the kScoreChunks chunks of a set of `points`: on `runner` when
/// there is one and the set has at least kParallelMinPoints, else on the calling thread in
/// chunk order.
inline void run_chunks(TaskRunner* runner, std::size_t points,
                       void (*task)(void* context, std::size_t chunk), void* context) {
  if (runner != nullptr && points >= kParallelMinPoints) {
    runner->run(kScoreChunks, task, context);
  } else {
    for (std::size_t c = 0; c < kScoreChunks; ++c) task(context, c);
  }
}

/// The scan's own motion, solved with its pose. A scan is undistorted (deskewed) with the motion
/// that the pose `base` implies under constant velocity; at another pose x that motion changes
/// by the pose's change from `base`, (v, w) = log(X(base)^-1 X(x)) in the sensor frame, and each
/// point moves on by lever[i] times that change: p_i + lever_i (v + w x p_i), to first order
/// (lever_i is the point's firing time over the time between scans, 0 at the scan's reference
/// time). Matching then solves for the pose and the undistortion it implies together instead of
/// alternating between them. The Jacobian of the moved point is (1 + lever_i) times the rigid
/// one (exact at `base`); the Hessian takes (1 + lever_i)^2 times the rigid terms.
struct ScanMotion {
  core::Pose6 base = core::Pose6::Zero();
  std::span<const double> lever;  ///< one per point
};

struct ScoreResult {
  double score = 0.0;
  Vector6d gradient = Vector6d::Zero();
  Matrix6d hessian = Matrix6d::Zero();
  std::size_t matched = 0;  ///< points scored against at least one enabled Gaussian
  std::size_t terms = 0;    ///< point-voxel pairs scored (up to `neighbours` per point)
};

/// Which reference voxels take part: nullptr = all with a Gaussian; otherwise mask[i] != 0
/// enables voxel i of grid.voxels().
using VoxelMask = const std::vector<std::uint8_t>*;

/// Which voxels a point is scored against: the one it falls in (the paper's single grid), or
/// that one and its six face neighbours, which widens the basin of convergence.
enum class Neighbours { kOne = 1, kSeven = 7 };

/// Remembers, per point index, the voxel key the point last fell in and the voxel indices found
/// around it, so that repeated scoring (Newton iterations, passes over re-deskewed points, which
/// move most points by less than a voxel) skips the hash lookups. Entries are checked against
/// the point's current key, and the whole cache is dropped when the grid changes (its version)
/// or another grid is scored, so a cache never gives a wrong voxel.
class LookupCache {
 public:
  /// Room for `points` points; nothing is allocated afterwards. Larger sets are scored
  /// without the cache.
  explicit LookupCache(std::size_t points);
  [[nodiscard]] std::size_t capacity() const { return capacity_; }
  /// Scorings through this cache run their chunks on `runner` (null: on the calling thread).
  /// The results are the same either way.
  void set_runner(TaskRunner* runner) { runner_ = runner; }
  [[nodiscard]] TaskRunner* runner() const { return runner_; }

 private:
  friend ScoreResult ndt_score(const VoxelGrid&, std::span<const Eigen::Vector3d>,
                               const core::Pose6&, bool, VoxelMask, Neighbours, LookupCache*,
                               const ScanMotion*);
  void reset(std::size_t points);
  std::size_t capacity_;
  TaskRunner* runner_ = nullptr;
  const VoxelGrid* grid_ = nullptr;
  std::uint64_t version_ = 0;
  int lookups_ = 0;
  std::vector<VoxelKey> keys_;         // per point; x = INT32_MIN: not looked up yet
  std::vector<std::int32_t> indices_;  // 7 per point: the voxels around keys_[i], -1 none
};

/// One point's share of S at q (grid frame): -sum e_v over the enabled Gaussians of the voxels
/// `neighbours` selects around q, with e_v = exp(-q_v^T A_v q_v / 2), q_v = q - mu_v. With `b`
/// and `M`, also dS/dq = sum e_v A_v q_v and d2S/dq2 = sum e_v (A_v - A_v q_v q_v^T A_v), from
/// which a caller builds the derivatives for its own pose parametrisation (the mapper's).
double point_terms(const VoxelGrid& grid, const Eigen::Vector3d& q, Neighbours neighbours,
                   VoxelMask mask, Eigen::Vector3d* b = nullptr, Eigen::Matrix3d* M = nullptr);

/// S(x) for `points` (sensor frame) against `grid`; with `derivatives`, also its gradient and
/// Hessian. Each point adds one term per Gaussian of the voxels `neighbours` selects. A cache
/// saves voxel lookups across calls on the same grid. With `motion`, the points move with the
/// pose's change from motion->base as ScanMotion describes.
ScoreResult ndt_score(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                      const core::Pose6& x, bool derivatives, VoxelMask mask = nullptr,
                      Neighbours neighbours = Neighbours::kOne, LookupCache* cache = nullptr,
                      const ScanMotion* motion = nullptr);

}  // namespace cndt::ndt
