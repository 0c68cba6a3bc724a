#include "cndt/ndt/ndt_score.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cndt/core/resident.hpp"

namespace cndt::ndt {
namespace {

// Elementary rotations and their derivatives by the angle.
Eigen::Matrix3d rx(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << 1, 0, 0, 0, c, -s, 0, s, c;
  if (order == 1) m << 0, 0, 0, 0, -s, -c, 0, c, -s;
  if (order == 2) m << 0, 0, 0, 0, -c, s, 0, -s, -c;
  return m;
}
Eigen::Matrix3d ry(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << c, 0, s, 0, 1, 0, -s, 0, c;
  if (order == 1) m << -s, 0, c, 0, 0, 0, -c, 0, -s;
  if (order == 2) m << -c, 0, -s, 0, 0, 0, s, 0, -c;
  return m;
}
Eigen::Matrix3d rz(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << c, -s, 0, s, c, 0, 0, 0, 1;
  if (order == 1) m << -s, -c, 0, c, -s, 0, 0, 0, 0;
  if (order == 2) m << -c, s, 0, -s, -c, 0, 0, 0, 0;
  return m;
}

}  // namespace

PoseDerivatives::PoseDerivatives(const core::Pose6& x) : t_(x.head<3>()) {
  const double phi = x[3], theta = x[4], psi = x[5];
  // Derivative orders of (Rx, Ry, Rz) for R, the three first and the six second derivatives.
  auto R = [&](int a, int b, int c) -> Eigen::Matrix3d {
    return rx(phi, a) * ry(theta, b) * rz(psi, c);  // evaluated: no expression of temporaries
  };
  R_ = R(0, 0, 0);
  d1_ = {R(1, 0, 0), R(0, 1, 0), R(0, 0, 1)};
  d2_ = {R(2, 0, 0), R(1, 1, 0), R(1, 0, 1), R(0, 2, 0), R(0, 1, 1), R(0, 0, 2)};
  const double sphi = std::sin(phi), cphi = std::cos(phi);
  const double stheta = std::sin(theta), ctheta = std::cos(theta);
  W_ << 1.0, 0.0, stheta, 0.0, cphi, -sphi * ctheta, 0.0, sphi, cphi * ctheta;
}

namespace {
constexpr std::int32_t kUnset = std::numeric_limits<std::int32_t>::min();
}  // namespace

LookupCache::LookupCache(std::size_t points) : capacity_(points) {
  core::reserve_resident(keys_, points);
  core::reserve_resident(indices_, points * 7);
}

void LookupCache::reset(std::size_t points) {
  points = std::min(points, capacity_);
  keys_.assign(points, VoxelKey{kUnset, 0, 0});
  indices_.assign(points * 7, -1);
}

namespace {

// The Gaussian of voxel `idx` of `grid` when it has one the mask enables, else nullptr.
inline const Gaussian* enabled_gaussian(const VoxelGrid& grid, std::int32_t idx, VoxelMask mask) {
  const auto i = static_cast<std::size_t>(idx);
  const Gaussian& g = grid.gaussians()[i];
  if (g.valid == 0 || (mask != nullptr && (*mask)[i] == 0)) return nullptr;
  return &g;
}

// Beyond this squared Mahalanobis distance a term is 0 to the precision of the sums: e < 1e-13,
// and with the eigenvalue clamp bounding A, e a a^T < 1e-6 against Hessian entries of 1e3 and
// more for a scan.
constexpr double kFarSquared = 60.0;

// e = exp(-q^T A q / 2) for q = v - mu (eq 5's term without its sign), and a = A q; e = 0
// beyond kFarSquared, where the exponential is not evaluated.
inline double gaussian_term(const Gaussian& g, const Eigen::Vector3d& v, Eigen::Vector3d& a) {
  const double d2 = g.mahalanobis(v, a);
  return d2 < kFarSquared ? std::exp(-0.5 * d2) : 0.0;
}

// The six distinct entries (xx, xy, xz, yy, yz, zz) of a symmetric 3 x 3 matrix.
using Sym3 = Eigen::Matrix<double, 6, 1>;

// m += e (A - a a^T) for the Gaussian's A, in Sym3 entries.
inline void add_curvature(Sym3& m, double e, const Gaussian& g, const Eigen::Vector3d& a) {
  const double ea0 = e * a.x(), ea1 = e * a.y(), ea2 = e * a.z();
  m(0) += e * g.inv_cov[0] - ea0 * a.x();
  m(1) += e * g.inv_cov[1] - ea0 * a.y();
  m(2) += e * g.inv_cov[2] - ea0 * a.z();
  m(3) += e * g.inv_cov[3] - ea1 * a.y();
  m(4) += e * g.inv_cov[4] - ea1 * a.z();
  m(5) += e * g.inv_cov[5] - ea2 * a.z();
}

Eigen::Matrix3d full(const Sym3& m) {
  Eigen::Matrix3d out;
  out << m(0), m(1), m(2), m(1), m(3), m(4), m(2), m(4), m(5);
  return out;
}

}  // namespace

double point_terms(const VoxelGrid& grid, const Eigen::Vector3d& q, Neighbours neighbours,
                   VoxelMask mask, Eigen::Vector3d* b, Eigen::Matrix3d* M) {
  const VoxelKey key = grid.key_of(q);
  double score = 0.0;
  if (b != nullptr) b->setZero();
  if (M != nullptr) M->setZero();
  std::array<std::int32_t, 7> found{};
  grid.indices_around(key, static_cast<int>(neighbours), found.data());
  Sym3 m = Sym3::Zero();
  for (int n = 0; n < static_cast<int>(neighbours); ++n) {
    const std::int32_t idx = found[static_cast<std::size_t>(n)];
    if (idx < 0) continue;
    const Gaussian* g = enabled_gaussian(grid, idx, mask);
    if (g == nullptr) continue;
    Eigen::Vector3d a;
    const double e = gaussian_term(*g, q, a);
    score -= e;  // eq 5
    if (b != nullptr) *b += e * a;
    if (M != nullptr) add_curvature(m, e, *g, a);
  }
  if (M != nullptr) *M = full(m);
  return score;
}

namespace {

// A small direct-mapped table of the voxel indices around the keys looked up last: what
// VoxelGrid::indices_around gave for them, so that a repeated key costs no hash lookups.
class RecentLookups {
 public:
  RecentLookups() {
    for (Entry& e : entries_) e.key.x = kUnset;
  }
  // The indices stored for `key`, or nullptr.
  [[nodiscard]] const std::int32_t* find(const VoxelKey& key) const {
    const Entry& e = entries_[slot(key)];
    return e.key == key ? e.indices.data() : nullptr;
  }
  void store(const VoxelKey& key, const std::int32_t* indices, int n) {
    Entry& e = entries_[slot(key)];
    e.key = key;
    std::copy_n(indices, n, e.indices.data());
  }

 private:
  static constexpr std::size_t kEntries = 64;
  struct Entry {
    VoxelKey key;
    std::array<std::int32_t, 7> indices;
  };
  static std::size_t slot(const VoxelKey& k) {
    const auto h = static_cast<std::uint32_t>(k.x) * 73856093u ^
                   static_cast<std::uint32_t>(k.y) * 19349663u ^
                   static_cast<std::uint32_t>(k.z) * 83492791u;
    return (h ^ (h >> 13)) & (kEntries - 1);
  }
  std::array<Entry, kEntries> entries_;
};

// One chunk's share of a scoring: ndt_score's sums over the chunk's points. Aligned so that two
// chunks' results never share a cache line.
struct alignas(64) Partial {
  double score = 0.0;
  std::size_t terms = 0, matched = 0;
  Eigen::Vector3d g_t = Eigen::Vector3d::Zero();
  Sym3 h_tt = Sym3::Zero();  // sum M
  Sym3 N = Sym3::Zero();     // sum [r]x M [r]x
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero(), Bg = Eigen::Matrix3d::Zero(),
                  Bh = Eigen::Matrix3d::Zero();  // sum M [r]x, sum b p^T (twice)
};

// What every chunk of one scoring reads; cache_keys and cache_indices are null when the scoring
// goes without the cache.
struct ScoreJob {
  const VoxelGrid* grid;
  std::span<const Eigen::Vector3d> points;
  const PoseDerivatives* pd;
  Eigen::Vector3d mv, mw;
  bool derivatives;
  VoxelMask mask;
  int lookups;
  std::vector<VoxelKey>* cache_keys;  // the cache's entries, or null
  std::vector<std::int32_t>* cache_indices;
  const ScanMotion* motion;
  std::array<Partial, kScoreChunks>* partials;
};

// Points [begin, end) of the job, summed into `out` (a local of the thread that runs it). Chunks
// write disjoint cache entries (by point index), so they may run at the same time.
void score_range(const ScoreJob& job, std::size_t begin, std::size_t end, Partial& out) {
  std::vector<VoxelKey>* cache_keys = job.cache_keys;
  std::vector<std::int32_t>* cache_indices = job.cache_indices;
  const VoxelGrid& grid = *job.grid;
  const std::span<const Eigen::Vector3d> points = job.points;
  const PoseDerivatives& pd = *job.pd;
  const ScanMotion* motion = job.motion;
  const int lookups = job.lookups;
  const bool cached = cache_keys != nullptr;
  // With e_v = exp(-q_v^T A_v q_v / 2) and a_v = A_v q_v for each voxel v a point is scored
  // against, the point adds (eq 5 and its derivatives, J = dq/dx, the same for every v):
  //   S -= sum e_v;  gradient += J^T b;  Hessian += J^T M J + b^T d2q/dx_k dx_l,
  // where b = sum e_v a_v and M = sum e_v (A_v - a_v a_v^T). Summing b and M over the voxels
  // first leaves one Jacobian product per point.
  // J's rotation columns dR/dangle_k p are w_k x r for r = R p and the fixed axes w_k of the
  // Euler angles (PoseDerivatives::axes(), the columns of W): J_r = -[r]x W.
  // So J_r^T M J_r = -W^T ([r]x M [r]x) W and M J_r = -(M [r]x) W: per point only the
  // symmetric N = [r]x M [r]x and C = M [r]x are summed, and W applied once per scoring.
  // The terms linear in b are sums of b^T D p for matrices D fixed by the pose (dR/dangle_k for
  // the gradient, d2R/dangle_k dangle_l for the Hessian): b^T D p is the entrywise product of D
  // with b p^T, so only the outer products are summed per point, Bg = sum b p^T with the
  // gradient's b and Bh with the Hessian's (they differ by the scan motion's factor), and
  // multiplied with the D at the end.
  // The scoring reads voxels in random order from a grid far larger than the caches, so each
  // point goes through a short pipeline: kPlace points ahead it is placed and the table slots
  // of the voxels around it are fetched (when its voxel changed); kFind points ahead they are
  // looked up and the voxels fetched; then it is scored.
  constexpr std::size_t kPlace = 16, kFind = 8, kRing = kPlace + 1;  // i's entry outlives i + 16
  std::array<Eigen::Vector3d, kRing> placed;
  std::array<Eigen::Vector3d, kRing> moved;  // with a scan motion: the points it moves
  std::array<VoxelKey, kRing> keys;
  std::array<std::array<std::int32_t, 7>, kRing> local{};
  // The voxels around recently looked-up keys: a scan's points come sweep by sweep, and the
  // next sweeps fall in much the same voxels, so most of a scoring's first lookups are repeats.
  RecentLookups recent;
  auto place = [&](std::size_t j) {
    if (motion != nullptr) {
      moved[j % kRing] = points[j] + motion->lever[j] * (job.mv + job.mw.cross(points[j]));
    }
    const Eigen::Vector3d v = pd.transform(motion != nullptr ? moved[j % kRing] : points[j]);
    const VoxelKey key = grid.key_of(v);
    placed[j % kRing] = v;
    keys[j % kRing] = key;
    if ((!cached || !((*cache_keys)[j] == key)) && recent.find(key) == nullptr) {
      grid.prefetch_around(key, lookups);
    }
  };
  auto find = [&](std::size_t j) {
    const VoxelKey& key = keys[j % kRing];
    std::int32_t* found = cached ? &(*cache_indices)[j * 7] : local[j % kRing].data();
    if (!cached || !((*cache_keys)[j] == key)) {  // not the voxel this point was in last time
      if (cached) (*cache_keys)[j] = key;
      if (const std::int32_t* known = recent.find(key)) {
        std::copy_n(known, lookups, found);
      } else {
        grid.indices_around(key, lookups, found);
        recent.store(key, found, lookups);
      }
    }
    for (int n = 0; n < lookups; ++n) {
      if (found[n] >= 0) grid.prefetch_gaussian(found[n]);
    }
  };
  for (std::size_t j = begin; j < std::min(begin + kPlace, end); ++j) place(j);
  for (std::size_t j = begin; j < std::min(begin + kFind, end); ++j) find(j);
  for (std::size_t i = begin; i < end; ++i) {
    const Eigen::Vector3d& p = motion != nullptr ? moved[i % kRing] : points[i];
    const Eigen::Vector3d v = placed[i % kRing];
    const std::int32_t* found = cached ? &(*cache_indices)[i * 7] : local[i % kRing].data();
    if (i + kPlace < end) place(i + kPlace);
    if (i + kFind < end) find(i + kFind);
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    Sym3 m = Sym3::Zero();
    bool any = false;
    for (int n = 0; n < lookups; ++n) {
      const std::int32_t idx = found[n];
      if (idx < 0) continue;
      const Gaussian* g = enabled_gaussian(grid, idx, job.mask);
      if (g == nullptr) continue;
      Eigen::Vector3d a;
      const double e = gaussian_term(*g, v, a);
      out.score -= e;  // eq 5
      ++out.terms;
      any = true;
      if (!job.derivatives || e == 0.0) continue;
      b += e * a;
      add_curvature(m, e, *g, a);
    }
    if (any) ++out.matched;
    if (!job.derivatives || !any) continue;
    // With a scan motion the Jacobian is (1 + lever) J: the gradient takes b that many times,
    // the Hessian's terms the square of it.
    if (motion != nullptr) {
      const double scale = 1.0 + motion->lever[i];
      b *= scale;
      out.g_t += b;
      out.Bg.noalias() += b * p.transpose();
      b *= scale;
      m *= scale * scale;
      out.Bh.noalias() += b * p.transpose();
    } else {
      out.g_t += b;
      out.Bg.noalias() += b * p.transpose();  // Bh is Bg
    }
    out.h_tt += m;
    // C += M [r]x: row i is M's row i crossed with r. N += [r]x (M [r]x): column j is r crossed
    // with column j of M [r]x (symmetric: six entries).
    const Eigen::Vector3d& t = pd.translation();
    const double r0 = v.x() - t.x(), r1 = v.y() - t.y(), r2 = v.z() - t.z();
    Eigen::Matrix3d K;
    K << m(1) * r2 - m(2) * r1, m(2) * r0 - m(0) * r2, m(0) * r1 - m(1) * r0,  //
        m(3) * r2 - m(4) * r1, m(4) * r0 - m(1) * r2, m(1) * r1 - m(3) * r0,   //
        m(4) * r2 - m(5) * r1, m(5) * r0 - m(2) * r2, m(2) * r1 - m(4) * r0;
    out.C += K;
    out.N(0) += r1 * K(2, 0) - r2 * K(1, 0);
    out.N(1) += r1 * K(2, 1) - r2 * K(1, 1);
    out.N(2) += r1 * K(2, 2) - r2 * K(1, 2);
    out.N(3) += r2 * K(0, 1) - r0 * K(2, 1);
    out.N(4) += r2 * K(0, 2) - r0 * K(2, 2);
    out.N(5) += r0 * K(1, 2) - r1 * K(0, 2);
  }
}

// TaskRunner's task: chunk `chunk` of the ScoreJob at `context`.
void score_chunk(void* context, std::size_t chunk) {
  const ScoreJob& job = *static_cast<ScoreJob*>(context);
  const std::size_t n = job.points.size();
  Partial sums;
  const ChunkRange r = chunk_range(n, chunk);
  score_range(job, r.begin, r.end, sums);
  (*job.partials)[chunk] = sums;
}

}  // namespace

ScoreResult ndt_score(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                      const core::Pose6& x, bool derivatives, VoxelMask mask, Neighbours neighbours,
                      LookupCache* cache, const ScanMotion* motion) {
  const PoseDerivatives pd(x);
  // The pose's change from motion->base in the sensor frame, (v, w): each point moves by its
  // lever times v + w x p (ScanMotion).
  Eigen::Vector3d mv = Eigen::Vector3d::Zero(), mw = Eigen::Vector3d::Zero();
  if (motion != nullptr) {
    const Eigen::Isometry3d rel = core::to_isometry(motion->base).inverse() * core::to_isometry(x);
    const Eigen::AngleAxisd aa(rel.linear());
    mv = rel.translation();
    mw = aa.angle() * aa.axis();
  }
  const int lookups = static_cast<int>(neighbours);
  bool cached = cache != nullptr;
  if (cached && (cache->grid_ != &grid || cache->version_ != grid.version() ||
                 cache->lookups_ != lookups || cache->keys_.size() < points.size())) {
    cached = points.size() <= cache->capacity_;
    if (cached) {
      cache->reset(points.size());
      cache->grid_ = &grid;
      cache->version_ = grid.version();
      cache->lookups_ = lookups;
    }
  }
  // The points go in kScoreChunks fixed chunks whose sums are added in chunk order, so the
  // result is the same whether the chunks run one after the other or on several threads.
  std::array<Partial, kScoreChunks> partials;
  ScoreJob job{&grid,
               points,
               &pd,
               mv,
               mw,
               derivatives,
               mask,
               lookups,
               cached ? &cache->keys_ : nullptr,
               cached ? &cache->indices_ : nullptr,
               motion,
               &partials};
  TaskRunner* runner = cache != nullptr ? cache->runner_ : nullptr;
  run_chunks(runner, points.size(), &score_chunk, &job);
  ScoreResult r;
  Partial sum;
  for (const Partial& p : partials) {
    r.score += p.score;
    r.terms += p.terms;
    r.matched += p.matched;
    sum.g_t += p.g_t;
    sum.h_tt += p.h_tt;
    sum.N += p.N;
    sum.C += p.C;
    sum.Bg += p.Bg;
    sum.Bh += p.Bh;
  }
  if (derivatives) {
    constexpr int kPair[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    if (motion == nullptr) sum.Bh = sum.Bg;
    Eigen::Vector3d g_r;
    for (int k = 0; k < 3; ++k) g_r(k) = pd.d1(k).cwiseProduct(sum.Bg).sum();
    const Eigen::Matrix3d& W = pd.axes();  // score_range
    const Eigen::Matrix3d h_tr = -sum.C * W;
    Eigen::Matrix3d h_rr = -W.transpose() * full(sum.N) * W;
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) {
        h_rr(k, l) += pd.d2(kPair[k][l]).cwiseProduct(sum.Bh).sum();
      }
    }
    r.gradient << sum.g_t, g_r;
    r.hessian.topLeftCorner<3, 3>() = full(sum.h_tt);
    r.hessian.topRightCorner<3, 3>() = h_tr;
    r.hessian.bottomLeftCorner<3, 3>() = h_tr.transpose();
    r.hessian.bottomRightCorner<3, 3>() = h_rr;
  }
  return r;
}

}  // namespace cndt::ndt
