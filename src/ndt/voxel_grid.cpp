#include "cndt/ndt/voxel_grid.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <numbers>

#include "cndt/core/resident.hpp"
#include "cndt/ndt/ndt_score.hpp"

namespace cndt::ndt {
namespace {
std::uint64_t hash(const VoxelKey& k) {
  std::uint64_t h = static_cast<std::uint32_t>(k.x) * 0x9E3779B97F4A7C15ULL;
  h ^= static_cast<std::uint32_t>(k.y) * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2);
  h ^= static_cast<std::uint32_t>(k.z) * 0x165667B19E3779F9ULL + (h << 6) + (h >> 2);
  return h ^ (h >> 29);
}
// Neighbour i of `key` in the order of VoxelGrid::kFaceOffsets.
VoxelKey face_neighbour(const VoxelKey& key, int i) {
  const auto& o = VoxelGrid::kFaceOffsets[i];
  return {key.x + o[0], key.y + o[1], key.z + o[2]};
}
}  // namespace

VoxelGrid::VoxelGrid(const VoxelGridOptions& options)
    : options_(options),
      inv_size_(1.0 / options.voxel_size),
      patch_min_normal_z_(options.patch_max_tilt_deg >= 90.0
                              ? -1.0
                              : std::cos(options.patch_max_tilt_deg * std::numbers::pi / 180.0)),
      listed_(options.surface_patches) {
  // Versions are unique across grids (the high half numbers the grid), so that a lookup cache
  // never mistakes a new grid at a reused address for the one it was filled from.
  static std::atomic<std::uint64_t> grids{0};
  version_ = (grids.fetch_add(1, std::memory_order_relaxed) + 1) << 32;
  if (options.resident) {
    core::reserve_resident(voxels_, options.capacity);
    core::reserve_resident(gaussians_, options.capacity);
    core::reserve_resident(dirty_, options.capacity);
    if (listed_) core::reserve_resident(around_, options.capacity);
  } else {
    voxels_.reserve(options.capacity);
    gaussians_.reserve(options.capacity);
    dirty_.reserve(options.capacity);
    if (listed_) around_.reserve(options.capacity);
  }
  if (listed_) renumber_.assign(options.capacity, -1);
  // Load factor at most one half, also when full.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(16, options.capacity * 2));
  table_.assign(slots, Slot{});
  mask_ = 15;
}

Eigen::Vector3d VoxelGrid::corner(const VoxelKey& k) const noexcept {
  return Eigen::Vector3d(k.x, k.y, k.z) * options_.voxel_size;
}

std::size_t VoxelGrid::slot_of(const VoxelKey& k, std::uint64_t h) const noexcept {
  std::size_t s = h & mask_;
  for (;;) {
    const Slot& slot = table_[s];
    if (slot.index < 0 || slot.key == k) return s;
    s = (s + 1) & mask_;
  }
}

std::size_t VoxelGrid::slot_of(const VoxelKey& k) const noexcept { return slot_of(k, hash(k)); }

std::int64_t VoxelGrid::index_of(const VoxelKey& k) const noexcept {
  return table_[slot_of(k)].index;
}

void VoxelGrid::indices_around(const VoxelKey& key, int n, std::int32_t* out) const noexcept {
  std::array<VoxelKey, 7> keys;
  std::array<std::uint64_t, 7> h;
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<std::size_t>(i);
    keys[u] = face_neighbour(key, i);
    h[u] = hash(keys[u]);
    __builtin_prefetch(&table_[h[u] & mask_]);
  }
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<std::size_t>(i);
    out[i] = table_[slot_of(keys[u], h[u])].index;
  }
}

void VoxelGrid::prefetch_slot(const Eigen::Vector3d& p) const noexcept {
  __builtin_prefetch(&table_[hash(key_of(p)) & mask_]);
}

void VoxelGrid::prefetch_voxel(const Eigen::Vector3d& p) const noexcept {
  const std::int32_t i = table_[slot_of(key_of(p))].index;
  if (i >= 0) __builtin_prefetch(&voxels_[static_cast<std::size_t>(i)].sum);
}

void VoxelGrid::prefetch_around(const VoxelKey& key, int n) const noexcept {
  for (int i = 0; i < n; ++i) __builtin_prefetch(&table_[hash(face_neighbour(key, i)) & mask_]);
}

const Voxel* VoxelGrid::find(const VoxelKey& k) const noexcept {
  const std::int32_t i = table_[slot_of(k)].index;
  return i >= 0 ? &voxels_[static_cast<std::size_t>(i)] : nullptr;
}

void VoxelGrid::insert_slot(const VoxelKey& k, std::int32_t index) noexcept {
  const std::uint64_t h = hash(k);
  std::size_t s = h & mask_;
  while (table_[s].index >= 0) s = (s + 1) & mask_;
  table_[s] = {k, index};
}

void VoxelGrid::grow_table_for(std::size_t voxels) noexcept {
  if (voxels * 2 <= mask_ + 1 || mask_ + 1 == table_.size()) return;
  std::fill_n(table_.begin(), mask_ + 1, Slot{});
  mask_ = std::min(table_.size(), (mask_ + 1) * 2) - 1;
  for (std::size_t i = 0; i < voxels_.size(); ++i) {
    insert_slot(voxels_[i].key, static_cast<std::int32_t>(i));
  }
}

void VoxelGrid::link_new(std::size_t index) noexcept {
  if (!listed_) return;
  around_.emplace_back();  // within the capacity reserved
  const VoxelKey key = voxels_[index].key;
  const auto self = static_cast<std::int32_t>(index);
  for (int p = 0; p < 27; ++p) {
    if (p == kCentre) continue;
    const std::int64_t j = index_of(around_key(key, p));
    around_[index][around_entry(p)] = static_cast<std::int32_t>(j);
    if (j >= 0) around_[static_cast<std::size_t>(j)][around_entry(26 - p)] = self;
  }
}

void VoxelGrid::mark_dirty(Voxel& v, std::size_t index, bool own) noexcept {
  if (own) v.changed = true;
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
  if (count == 0 || table_[slot_of(k)].index >= 0 || voxels_.size() == options_.capacity) {
    return false;
  }
  grow_table_for(voxels_.size() + 1);
  insert_slot(k, static_cast<std::int32_t>(voxels_.size()));
  voxels_.emplace_back();
  gaussians_.emplace_back();
  Voxel& v = voxels_.back();
  v.key = k;
  v.count = count;
  v.sum = sum;
  v.sum_outer = sum_outer;
  v.consensus = consensus;
  ++version_;
  link_new(voxels_.size() - 1);
  mark_dirty(v, voxels_.size() - 1, true);
  return true;
}

Voxel* VoxelGrid::add_point(const Eigen::Vector3d& p) noexcept {
  const VoxelKey k = key_of(p);
  std::int32_t found = table_[slot_of(k)].index;
  if (found < 0) {
    if (voxels_.size() == options_.capacity) {
      ++refused_;
      return nullptr;
    }
    grow_table_for(voxels_.size() + 1);
    found = static_cast<std::int32_t>(voxels_.size());
    insert_slot(k, found);
    voxels_.emplace_back();
    gaussians_.emplace_back();
    voxels_.back().key = k;
    ++version_;  // a lookup that found nothing here would now find this voxel
    link_new(voxels_.size() - 1);
  } else if (voxels_[static_cast<std::size_t>(found)].count == 0) {
    --empty_;  // a voxel emptied by remove() fills again
  }
  const auto index = static_cast<std::size_t>(found);
  Voxel& v = voxels_[index];
  const Eigen::Vector3d q = p - corner(k);
  ++v.count;                                   // eq 3
  v.sum += q;                                  // eq 1
  v.sum_outer.noalias() += q * q.transpose();  // eq 2
  mark_dirty(v, index, true);
  return &v;
}

bool VoxelGrid::remove(const Eigen::Vector3d& p) noexcept {
  const VoxelKey k = key_of(p);
  const std::int32_t i = table_[slot_of(k)].index;
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
  mark_dirty(v, static_cast<std::size_t>(i), true);
  return true;
}

bool VoxelGrid::neighbourhood_plane(std::size_t index, Eigen::Vector3d& normal) const noexcept {
  // The neighbours' sums moved to this voxel's corner: sum (p - c) = m_j + n_j d and
  // sum (p - c)(p - c)^T = S_j + m_j d^T + d m_j^T + n_j d d^T, for d = c_j - c.
  const Eigen::Vector3d c = corner(voxels_[index].key);
  double n = 0.0;
  Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
  for_each_around(index, [&](std::size_t j) {
    const Voxel& u = voxels_[j];
    if (u.count == 0) return;
    const double nj = u.count;
    const Eigen::Vector3d d = corner(u.key) - c;
    n += nj;
    s1 += u.sum + nj * d;
    s2 += u.sum_outer + u.sum * d.transpose() + d * u.sum.transpose() + nj * d * d.transpose();
  });
  const Eigen::Vector3d mu = s1 / n;
  Eigen::Matrix3d cov = s2 / n - mu * mu.transpose();
  cov = 0.5 * (cov + cov.transpose());
  // A plane is thin (e0 < 0.02 e1 for the eigenvalues e0 <= e1 <= e2), wide (e1 at least half
  // the spread of a surface filling one voxel) and level (its normal v0 within the tilt).
  const double filled = options_.voxel_size * options_.voxel_size / 12.0;
  // Most neighbourhoods fail on one of three bounds that need no eigenvalues, each taken with
  // a margin of two over round-off. With the trace T, the sum of the principal 2 x 2 minors M
  // (e0 e1 + e0 e2 + e1 e2 >= e1 e2) and the determinant D = e0 e1 e2, a plane has
  // D / M <= e0 < 0.02 e1 <= 0.01 T; e1 <= M / e2 <= 3 M / T; and cov_zz = sum e_i v_i,z^2 <=
  // e0 + e2 (1 - v0,z^2) <= (0.01 + 1 - z^2) T for the least |v0,z| = z allowed.
  const double trace = cov.trace();
  const double minors = cov(0, 0) * cov(1, 1) - cov(0, 1) * cov(0, 1) + cov(0, 0) * cov(2, 2) -
                        cov(0, 2) * cov(0, 2) + cov(1, 1) * cov(2, 2) - cov(1, 2) * cov(1, 2);
  if (cov.determinant() > 0.02 * trace * minors) return false;  // not thin
  if (3.0 * minors < 0.25 * filled * trace) return false;       // a line or a point
  const double z = patch_min_normal_z_;
  if (z > 0.0 && cov(2, 2) > (0.02 + 2.0 * (1.0 - z * z)) * trace) return false;  // steep
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev(0) < 0.02 * ev(1) && ev(1) > 0.5 * filled)) return false;
  normal = es.eigenvectors().col(0);
  return std::abs(normal.z()) >= patch_min_normal_z_;
}

void VoxelGrid::derive(std::size_t index) noexcept {
  Voxel& v = voxels_[index];
  Gaussian& g = gaussians_[index];
  const bool was_patch = v.patch;
  v.patch = false;
  if (v.count < options_.min_points) {
    v.has_gaussian = false;
    g.valid = 0;
    return;
  }
  Eigen::Vector3d normal;
  const bool patch = options_.surface_patches && neighbourhood_plane(index, normal);
  // Derived again only because a neighbour changed, and neither a patch before nor now: its
  // Gaussian, from its own sums alone, is the one it has.
  if (!patch && !was_patch && !v.changed) return;
  v.has_gaussian = false;
  g.valid = 0;
  const double n = v.count;
  const Eigen::Vector3d m = v.sum / n;
  const Eigen::Vector3d mean = corner(v.key) + m;  // eq 4, mean
  const Eigen::Matrix3d cov = v.covariance();      // eq 4, covariance
  Eigen::Matrix3d A;
  if (patch) {
    A = surface_patch(cov, normal);
    v.patch = true;
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);  // closed form for 3 x 3
    Eigen::Vector3d ev = es.eigenvalues();
    if (options_.drop_horizontal_lines && ev(1) < 0.05 * ev(2) &&
        std::abs(es.eigenvectors().col(2).z()) < 0.5) {
      return;  // a ring arc: one dominant, nearly horizontal direction
    }
    const double floor = std::max(ev.maxCoeff(), 1e-12) * options_.eigen_floor;
    ev = ev.cwiseMax(floor);  // planes and lines would otherwise be singular
    // Assigned rather than initialised: Eigen evaluates the two forms of this product in a
    // different order, and the inverse covariance moves in its last bits.
    A = es.eigenvectors() * ev.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
  }
  v.has_gaussian = true;
  g.valid = 1;
  for (int i = 0; i < 3; ++i) g.mean[i] = mean(i);
  const double upper[6] = {A(0, 0), A(0, 1), A(0, 2), A(1, 1), A(1, 2), A(2, 2)};
  for (int i = 0; i < 6; ++i) g.inv_cov[i] = static_cast<float>(upper[i]);
}

Eigen::Matrix3d VoxelGrid::surface_patch(const Eigen::Matrix3d& cov,
                                         const Eigen::Vector3d& normal) const noexcept {
  // Along the plane the voxel's own spread, at least L^2: a patch reaching over its
  // neighbours, so that a plane's patches overlap and score evenly along it (at L^2 / 12, a
  // filled voxel's, the score still rippled with the voxel spacing and kept a third of the
  // rings' pull). Along the normal its own, at least eigen_floor of the largest (eq 4's clamp).
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - normal * normal.transpose();
  Eigen::Matrix3d in_plane = across * cov * across;
  in_plane = 0.5 * (in_plane + in_plane.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ep;
  ep.computeDirect(in_plane);  // eigenvalue 0 along the normal, then the two in the plane
  const double reach = options_.voxel_size * options_.voxel_size;
  const double e1 = std::max(ep.eigenvalues()(1), reach);
  const double e2 = std::max(ep.eigenvalues()(2), reach);
  const double en = std::max(normal.dot(cov * normal), e2 * options_.eigen_floor);
  const Eigen::Vector3d u1 = ep.eigenvectors().col(1), u2 = ep.eigenvectors().col(2);
  Eigen::Matrix3d A;
  A = normal * normal.transpose() / en + u1 * u1.transpose() / e1 + u2 * u2.transpose() / e2;
  return A;
}

void VoxelGrid::set_surface_patches(bool on) noexcept {
  if (on == options_.surface_patches) return;
  options_.surface_patches = on;
  for (std::size_t i = 0; i < voxels_.size(); ++i) {
    // Their sums are as they were: a voxel that is a patch neither before nor after keeps its
    // Gaussian (derive()).
    if (voxels_[i].count > 0) mark_dirty(voxels_[i], i, false);
  }
}

void VoxelGrid::derive_chunk(void* context, std::size_t chunk) {
  // Each voxel's derivation writes only that voxel's flags and Gaussian and reads its
  // neighbours' sums, which no derivation writes: the chunks are independent.
  auto& grid = *static_cast<VoxelGrid*>(context);
  const ChunkRange r = chunk_range(grid.dirty_.size(), chunk);
  for (std::size_t d = r.begin; d < r.end; ++d) {
    const std::uint32_t i = grid.dirty_[d];
    grid.derive(i);
    grid.voxels_[i].dirty = false;
    grid.voxels_[i].changed = false;
  }
}

void VoxelGrid::finalize(TaskRunner* runner) noexcept {
  if (options_.surface_patches) {
    // A voxel's Gaussian reads its neighbours' sums: theirs change with it.
    const std::size_t changed = dirty_.size();
    for (std::size_t d = 0; d < changed; ++d) {
      for_each_around(dirty_[d], [&](std::size_t j) { mark_dirty(voxels_[j], j, false); });
    }
  }
  run_chunks(runner, dirty_.size(), &VoxelGrid::derive_chunk, this);
  dirty_.clear();
}

void VoxelGrid::compact() noexcept {
  finalize();
  remove_voxels_if([](const Voxel& v) { return v.count == 0; });
  rebuild_table();
}

void VoxelGrid::rebuild_table() noexcept {
  ++version_;
  std::fill_n(table_.begin(), mask_ + 1, Slot{});
  mask_ = std::min(table_.size(), std::bit_ceil(std::max<std::size_t>(16, voxels_.size() * 2))) - 1;
  empty_ = 0;
  for (std::size_t i = 0; i < voxels_.size(); ++i) {
    insert_slot(voxels_[i].key, static_cast<std::int32_t>(i));
    if (voxels_[i].count == 0) ++empty_;
  }
}

void VoxelGrid::clear() noexcept {
  voxels_.clear();
  gaussians_.clear();
  around_.clear();
  dirty_.clear();
  std::fill_n(table_.begin(), mask_ + 1, Slot{});
  mask_ = 15;
  refused_ = 0;
  empty_ = 0;
  ++version_;
}

}  // namespace cndt::ndt
