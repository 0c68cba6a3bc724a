#include "cndt/slam/odometry.hpp"

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "cndt/core/mix64.hpp"
#include "cndt/core/resident.hpp"
#include "cndt/core/small_angle.hpp"

namespace cndt::slam {
namespace {

// A fraction `a` of a rigid motion (rotation about its axis, translation along the chord).
Eigen::Isometry3d scale_motion(const Eigen::Isometry3d& m, double a) {
  const Eigen::AngleAxisd aa(m.linear());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(aa.angle() * a, aa.axis()).toRotationMatrix();
  out.translation() = a * m.translation();
  return out;
}

bool finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

// search_start: the best offsets kept, and how many of them (apart) are solved.
constexpr std::size_t kSearchKept = 16, kSearchSolved = 4;
// search_gap_start: two solves ending closer in heading than this found the same minimum.
constexpr double kSameHeadingRad = std::numbers::pi / 180.0;
// The angular acceleration check's least allowance: the first turn rates of a campus drive at
// 1200 rpm (scans half as dense) put its matches up to 1.2 deg off the prediction.
constexpr double kMinTurnAllowance = 1.5 * std::numbers::pi / 180.0;

// Clean matches in a row that arm bound_degenerate_slide: a start whose every match is degenerate
// by the conditioning test (the ground seen from a sensor pitched 30 deg down) can still be
// right, and its prediction then has nothing better behind it than those matches.
constexpr std::size_t kSlideBoundCleanRun = 3;

// The rotation `r`'s turn about the z axis (the rotation vector's z component), rad.
double heading_change(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.angle() * aa.axis().z();
}

// Smallest over largest eigenvalue of the translation block of an NDT Hessian: how evenly the
// scene constrains the position. Below 0 when the match ended on a saddle; 0 for no Hessian.
double translation_conditioning(const ndt::Matrix6d& hessian) {
  const Eigen::Matrix3d h = hessian.topLeftCorner<3, 3>();
  if (!h.allFinite()) return 0.0;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(h, Eigen::EigenvaluesOnly);
  const double largest = es.eigenvalues()(2);
  return largest > 0.0 ? es.eigenvalues()(0) / largest : 0.0;
}

// The principal direction of the normals of `grid`'s planar voxels within `gate` (a cosine) of
// `about`, weighted by their points; nullopt when they hold fewer than 200 points.
std::optional<Eigen::Vector3d> plane_normal_near(const ndt::VoxelGrid& grid,
                                                 const Eigen::Vector3d& about, double gate) {
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  double weight = 0.0;
  for (const ndt::Voxel& v : grid.voxels()) {
    if (v.count < 10) continue;
    const double n = v.count;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(v.covariance());
    const Eigen::Vector3d ev = es.eigenvalues();
    // Thin across, spread both ways along: a piece of a plane, not a line or a blob.
    if (!(ev(0) < 0.05 * ev(1) && ev(1) > 0.1 * ev(2))) continue;
    const Eigen::Vector3d normal = es.eigenvectors().col(0);
    if (std::abs(normal.dot(about)) < gate) continue;
    scatter += n * normal * normal.transpose();
    weight += n;
  }
  if (weight < 200.0) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
  const Eigen::Vector3d up = es.eigenvectors().col(2);
  return up.dot(about) < 0.0 ? Eigen::Vector3d(-up) : up;
}

// The normal of the level surfaces (ground, floor, ceiling) in the frame of `grid`'s points; z
// when there are too few. First from the planar voxels within 45 deg of z (the walls of a
// level sensor's scene left out), then again, twice, from those within 10 deg of that. Voxels
// that fit a plane at 18-43 deg to the ground (four of them, 108 points, in the first scan of
// a street drive with the sensor 5.2 deg off level) turned the first estimate 1.2 deg further
// off; the second came within 0.05 deg of the truth.
// The start search lays its grid of offsets across it, so that a sensor mounted tilted on its
// vehicle searches along the ground, not into it; level_frame turns the scans by it.
Eigen::Vector3d level_normal(const ndt::VoxelGrid& grid) {
  const std::optional<Eigen::Vector3d> first =
      plane_normal_near(grid, Eigen::Vector3d::UnitZ(), std::sqrt(0.5));
  if (!first) return Eigen::Vector3d::UnitZ();
  Eigen::Vector3d up = *first;
  const double near = std::cos(10.0 * std::numbers::pi / 180.0);
  for (int pass = 0; pass < 2; ++pass) {
    const std::optional<Eigen::Vector3d> refined = plane_normal_near(grid, up, near);
    if (!refined) break;
    up = *refined;
  }
  return up.z() < 0.0 ? Eigen::Vector3d(-up) : up;
}

}  // namespace

std::size_t cv_dof_capacity(const OdometryOptions& o) {
  // The Cv points are map_cell centroids.
  return max_centroids_per_voxel(o.voxel_size, o.map_cell, o.max_scan_points);
}

ConsensusOdometry::ConsensusOdometry(const OdometryOptions& o)
    : options_(o),
      grid_({o.voxel_size, o.max_map_voxels, 5, 0.001, o.drop_ring_arcs, o.surface_patches,
             o.patch_max_tilt_deg}),
      chi2_(cv_dof_capacity(o)),
      lookup_cache_(o.max_scan_points),
      residual_accumulator_(o.max_scan_points),
      map_sampler_(o.map_cell, o.max_scan_points),
      scan_sampler_(o.scan_cell, o.max_scan_points),
      jitter_state_(o.guess_jitter_seed) {
  mid_active_ = o.deskew_to_mid_scan && o.mid_scan_after_clean == 0;
  // Every buffer resident from the start (core/resident.hpp).
  const TimedPoint timed{Eigen::Vector3d::Zero(), 0.0};
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (auto* v : {&raw_, &map_src_, &scan_src_, &newest_src_}) {
    core::reserve_resident(*v, o.max_scan_points, timed);
  }
  for (auto* v : {&test_, &cv_points_, &scratch_}) {
    core::reserve_resident(*v, o.max_scan_points, zero);
  }
  core::reserve_resident(lever_, o.max_scan_points, 0.0);
  if (o.deskew_to_mid_scan) core::reserve_resident(stamp_points_, o.max_scan_points, zero);
  if (o.level_frame) core::reserve_resident(sensor_points_, o.max_scan_points, zero);
  const std::size_t slots =
      o.reference == Reference::kPreviousScan ? 1 : std::max<std::size_t>(1, o.local_map_scans);
  history_.resize(slots);
  history_pose_.resize(slots);
  history_pool_.assign(std::max(o.local_map_points, o.max_scan_points), zero);  // written
  core::reserve_resident(mask_, o.max_map_voxels);
  core::reserve_resident(cv_, o.max_map_voxels);
  core::reserve_resident(residuals_.count, o.max_map_voxels);
  core::reserve_resident(residuals_.rss, o.max_map_voxels);
  for (double size : o.pyramid_voxel_sizes) {
    pyramid_.emplace_back(
        ndt::VoxelGridOptions{size, o.max_map_voxels / 4, 5, o.pyramid_eigen_floor, true});
  }
}

ConsensusOdometry::StartSearch ConsensusOdometry::search_start(const core::Pose6& x0,
                                                               const Eigen::Vector3d& heading,
                                                               double along_radius,
                                                               double grow_to) {
  // Without a velocity the coarse objective can be too flat near x0 for Newton to leave it (a
  // vehicle already moving when the first scans arrive); after a gap in the data the velocity
  // is old and the prediction off along the way. Score a horizontal grid of offsets on the
  // coarsest grid and start from the best. A best offset on the grid's edge may have a better
  // one beyond it (a vehicle faster than the grid reaches): the grid then grows by a ring.
  if (!start_search_on()) return {x0, x0, 0.0};
  const ndt::VoxelGrid& g = pyramid_.front();
  const double step = search_step();
  int n = static_cast<int>(std::floor(options_.start_search_radius / step));
  int m = std::max(n, static_cast<int>(std::floor(along_radius / step)));
  const int limit = static_cast<int>(std::floor(grow_to / step));
  // In the plane of the level surfaces (estimated once, from the first reference): for a level
  // sensor the x-y plane, kept exactly when the two are within 5 deg.
  if (!have_level_) {
    level_ = level_normal(g);
    if (level_.z() > std::cos(5.0 * std::numbers::pi / 180.0)) level_ = Eigen::Vector3d::UnitZ();
    have_level_ = true;
  }
  Eigen::Vector3d along = heading - heading.dot(level_) * level_;
  if (along.norm() <= 1e-9) along = Eigen::Vector3d::UnitX() - level_.x() * level_;
  along.normalize();
  const Eigen::Vector3d across = level_.cross(along);
  auto offset = [&](int i, int j) {
    core::Pose6 x = x0;
    x.head<3>() += step * (i * along + j * across);
    return x;
  };
  // The best offsets scored, best first (x0 itself is offset (0, 0)).
  struct Offset {
    double score;
    int i, j;
  };
  std::array<Offset, kSearchKept> kept;
  std::size_t n_kept = 0;
  auto keep = [&](double s, int i, int j) {
    std::size_t k = std::min(n_kept, kept.size() - 1);
    if (n_kept == kept.size() && !(s < kept[k].score)) return;
    for (; k > 0 && s < kept[k - 1].score; --k) kept[k] = kept[k - 1];
    kept[k] = {s, i, j};
    n_kept = std::min(n_kept + 1, kept.size());
  };
  keep(ndt::ndt_score(g, test_, x0, false, nullptr, options_.pyramid.neighbours, &lookup_cache_)
           .score,
       0, 0);
  // Offsets (i, j) within m along and n across, skipping those within (m_in, n_in).
  auto scan_ring = [&](int m_in, int n_in) {
    for (int i = -m; i <= m; ++i) {
      for (int j = -n; j <= n; ++j) {
        if (std::abs(i) <= m_in && std::abs(j) <= n_in) continue;
        keep(ndt::ndt_score(g, test_, offset(i, j), false, nullptr, options_.pyramid.neighbours,
                            &lookup_cache_)
                 .score,
             i, j);
      }
    }
  };
  scan_ring(0, 0);
  auto on_edge = [&] {
    return (m > 0 && std::abs(kept[0].i) == m) || (n > 0 && std::abs(kept[0].j) == n);
  };
  while (on_edge() && std::max(m, n) < limit) {
    ++m;
    ++n;
    scan_ring(m - 1, n - 1);
  }
  // A street's or corridor's valley in the score runs along it, narrower across than the
  // offsets' spacing: with the vehicle's heading off the grid's axes (a sensor turned on its
  // mount) an offset beside the valley's floor can score worse than zero motion, where the
  // rings of the first scan line up. So the best offsets in separate places (not next to a
  // better one) are each solved on the coarsest grid, and the offset whose solve ends lowest is
  // the start (the pyramid's first solve then repeats that descent); a solve that ends within
  // half a step of the chosen one's end (the same minimum) does not displace it, so a search
  // whose best-scored offset led to the right place is unchanged.
  std::size_t best = 0;
  double best_solved = std::numeric_limits<double>::infinity();
  core::Pose6 best_end = x0;
  std::size_t solved = 0;
  for (std::size_t k = 0; k < n_kept && solved < kSearchSolved; ++k) {
    bool beside_better = false;
    for (std::size_t b = 0; b < k; ++b) {
      beside_better |= std::abs(kept[b].i - kept[k].i) <= 1 && std::abs(kept[b].j - kept[k].j) <= 1;
    }
    if (beside_better) continue;
    ++solved;
    const ndt::NewtonResult r =
        ndt::newton_solve(g, test_, offset(kept[k].i, kept[k].j), options_.pyramid, nullptr,
                          &lookup_cache_, scan_motion());
    const bool apart = solved == 1 || (r.pose.head<3>() - best_end.head<3>()).norm() > 0.5 * step;
    if (r.score < best_solved && apart) {
      best_solved = r.score;
      best_end = r.pose;
      best = k;
    }
  }
  return {offset(kept[best].i, kept[best].j), best_end, best_solved};
}

core::Pose6 ConsensusOdometry::search_gap_start(const core::Pose6& x0,
                                                const Eigen::Isometry3d& predicted,
                                                const Eigen::Vector3d& heading,
                                                double along_radius) {
  StartSearch chosen = search_start(x0, heading, along_radius);
  // The prediction carries the last scan's turn rate over the whole gap, but a vehicle that was
  // turning may have ended its turn meanwhile (a corner taken while nothing arrived). Between
  // the turn kept up and the turn ended, starts with the turn over the gap cut to a half and to
  // nothing are searched too; the lowest solve wins, unless it ends in the same place and
  // heading as the chosen one (the same minimum).
  const Eigen::AngleAxisd turned(predicted.linear() * prev_pose_.linear().transpose());
  const double turn = turned.angle() * turned.axis().dot(level_);
  if (!start_search_on() || options_.gap_turn_hypothesis_rad < 0.0 ||
      std::abs(turn) < options_.gap_turn_hypothesis_rad) {
    return chosen.start;
  }
  for (double kept_fraction : {0.5, 0.0}) {
    Eigen::Isometry3d start = predicted;
    start.linear() = Eigen::AngleAxisd((kept_fraction - 1.0) * turn, level_).toRotationMatrix() *
                     predicted.linear();
    const StartSearch s = search_start(core::to_pose6(start), heading, along_radius);
    const Eigen::Isometry3d a = core::to_isometry(s.end), b = core::to_isometry(chosen.end);
    const bool apart =
        (a.translation() - b.translation()).norm() > 0.5 * search_step() ||
        Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle() > kSameHeadingRad;
    if (s.score < chosen.score && apart) chosen = s;
  }
  return chosen.start;
}

core::Pose6 ConsensusOdometry::coarse_to_fine(const core::Pose6& x0) {
  core::Pose6 x = x0;
  for (ndt::VoxelGrid& g : pyramid_) {
    x = ndt::newton_solve(g, test_, x, options_.pyramid, nullptr, &lookup_cache_, scan_motion())
            .pose;
  }
  return x;
}

namespace {
// Adds `points` to (or removes them from) grid g in order, with the table slot and the voxel
// each point will touch fetched into the cache 16 and 8 points before (the grids are far larger
// than the caches, and their voxels are touched in random order).
void change_grid(ndt::VoxelGrid& g, std::span<const Eigen::Vector3d> points, bool add) {
  constexpr std::size_t kSlotAhead = 16, kVoxelAhead = 8;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i + kSlotAhead < points.size()) g.prefetch_slot(points[i + kSlotAhead]);
    if (i + kVoxelAhead < points.size()) g.prefetch_voxel(points[i + kVoxelAhead]);
    if (add) {
      g.add(points[i]);  // a full grid refuses points: compacted in finalize_grids()
    } else {
      g.remove(points[i]);
    }
  }
}

struct GridsJob {
  ndt::VoxelGrid* grid;
  std::vector<ndt::VoxelGrid>* pyramid;
  std::span<const Eigen::Vector3d> points;
  bool add;
};

// Task 0 changes the fine grid, task 1 the pyramid's: each grid sees the points in the same
// order whichever thread runs it.
void change_grids_task(void* context, std::size_t task) {
  const auto& job = *static_cast<const GridsJob*>(context);
  if (task == 0) {
    change_grid(*job.grid, job.points, job.add);
  } else {
    for (ndt::VoxelGrid& g : *job.pyramid) change_grid(g, job.points, job.add);
  }
}
}  // namespace

void ConsensusOdometry::change_grids(std::span<const Eigen::Vector3d> points, bool add) {
  GridsJob job{&grid_, &pyramid_, points, add};
  if (ndt::TaskRunner* runner = lookup_cache_.runner(); runner != nullptr) {
    runner->run(2, &change_grids_task, &job);
  } else {
    change_grids_task(&job, 0);
    change_grids_task(&job, 1);
  }
}

void ConsensusOdometry::finalize_grids() {
  auto finalize = [this](ndt::VoxelGrid& g) {
    g.finalize(lookup_cache_.runner());  // on the scorings' threads when there are any
    if (g.refused_points() > 0 || g.empty_voxels() * 4 > g.size()) g.compact();
  };
  // Surface patches once the local map holds enough scans to judge a plane by, and while the
  // matches are not flagged degenerate: where nothing else fixes the position, the texture the
  // rings give a level surface is what holds it.
  if (options_.surface_patches) {
    grid_.set_surface_patches(in_grids_ >= options_.patches_after_scans &&
                              clean_run_ >= options_.patches_clean_scans);
  }
  finalize(grid_);
  for (ndt::VoxelGrid& g : pyramid_) finalize(g);
}

void ConsensusOdometry::jitter(core::Pose6& x) {
  for (int k = 0; k < 6; ++k) {
    x(k) += 1e-9 * (core::unit_fraction(core::mix64(jitter_state_)) - 0.5);
    jitter_state_ += 0x9E3779B97F4A7C15ULL;  // the splitmix64 sequence from the seed
  }
}

namespace {
// One deskew: the motion over a period as axis, angle and translation (Rodrigues' formula).
struct DeskewJob {
  std::span<const TimedPoint> in;
  Eigen::Vector3d* out;
  Eigen::Vector3d k, t;
  double angle, inv_period;
  bool mid;
  Eigen::Isometry3d to_mid;
};

// TaskRunner's task: chunk `chunk` of the DeskewJob at `context`.
void deskew_chunk(void* context, std::size_t chunk) {
  const DeskewJob& job = *static_cast<DeskewJob*>(context);
  const ndt::ChunkRange r = ndt::chunk_range(job.in.size(), chunk);
  for (std::size_t i = r.begin; i < r.end; ++i) {
    const TimedPoint& p = job.in[i];
    const double a = p.t * job.inv_period;
    double s = 0.0, c1 = 0.0;
    core::sin_versine(a * job.angle, s, c1);
    const Eigen::Vector3d kxv = job.k.cross(p.p);
    const Eigen::Vector3d at_stamp = p.p + s * kxv + c1 * job.k.cross(kxv) + a * job.t;
    job.out[i] = job.mid ? Eigen::Vector3d(job.to_mid * at_stamp) : at_stamp;
  }
}
}  // namespace

void ConsensusOdometry::deskew(std::span<const TimedPoint> in, const Eigen::Isometry3d& motion,
                               std::vector<Eigen::Vector3d>& out) const {
  out.clear();
  if (!options_.deskew || period_s_ <= 0.0) {
    for (const TimedPoint& p : in) out.push_back(p.p);
    return;
  }
  // Sensor pose at a point's firing time relative to the scan stamp: the fraction a = t / period
  // of the motion over one scan period, its rotation by Rodrigues' formula about the fixed axis.
  // Once deskewing to mid-revolution, then into the frame there, half the motion on. Points
  // are independent: in chunks, on the scorings' runner when there is one.
  const Eigen::AngleAxisd aa(motion.linear());
  const bool mid = mid_active_;
  out.resize(in.size());  // within the resident capacity
  DeskewJob job{.in = in,
                .out = out.data(),
                .k = aa.axis(),
                .t = motion.translation(),
                .angle = aa.angle(),
                .inv_period = 1.0 / period_s_,
                .mid = mid,
                .to_mid = mid ? scale_motion(motion, mid_fraction()).inverse()
                              : Eigen::Isometry3d::Identity()};
  ndt::run_chunks(lookup_cache_.runner(), in.size(), &deskew_chunk, &job);
}

double ConsensusOdometry::mid_fraction() const {
  // The deskew's period spans the last time step: after a gap in the data that is the gap, and
  // half of it would lie far past this revolution's middle.
  return mid_active_ ? 0.5 * revolution_s_ / period_s_ : 0.0;
}

void ConsensusOdometry::deskew_for(const Eigen::Isometry3d& motion, const core::Pose6& base) {
  test_motion_ = motion;
  deskew(scan_src_, motion, test_);
  scan_motion_.base = base;
}

void ConsensusOdometry::deskew_scan(const Eigen::Isometry3d& motion) {
  deskewed_with_ = motion;
  deskew(map_src_, motion, cv_points_);
}

Eigen::Isometry3d ConsensusOdometry::deskew_motion(const Eigen::Isometry3d& pose) const {
  const Eigen::Isometry3d held = scale_motion(prev_pose_.inverse() * pose, to_period_);
  if (extrapolate_ == 0.0) return held;
  // Rotation vectors and translations per period combine linearly: the motions are small.
  // prev_motion_ spans prev_period_s_, which is period_s_: its velocity per period.
  const Eigen::AngleAxisd aa(held.linear());
  const Eigen::AngleAxisd last(prev_motion_.linear());
  const Eigen::Vector3d turn =
      (1.0 + extrapolate_) * aa.angle() * aa.axis() - extrapolate_ * (last.angle() * last.axis());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  if (const double angle = turn.norm(); angle > 0.0) {
    out.linear() = Eigen::AngleAxisd(angle, turn / angle).toRotationMatrix();
  }
  out.translation() =
      (1.0 + extrapolate_) * held.translation() - extrapolate_ * prev_motion_.translation();
  return out;
}

void ConsensusOdometry::deskew_at(const Eigen::Isometry3d& pose) {
  deskew_for(deskew_motion(pose), core::to_pose6(pose));
}

const ndt::ScanMotion* ConsensusOdometry::scan_motion() const {
  return solve_motion_ ? &scan_motion_ : nullptr;
}

ndt::ConsensusMeasure ConsensusOdometry::consensus_at(const core::Pose6& x,
                                                      std::vector<double>& cv) {
  residuals_.reset(grid_.size());
  residual_accumulator_.run(grid_, cv_points_, x, residuals_, lookup_cache_.runner());
  ndt::voxel_consensus_all(residuals_, chi2_, {}, cv);
  return ndt::measure_localization_consensus(grid_, cv, x.head<3>());
}

void ConsensusOdometry::drop_oldest() {
  if (in_grids_ > 0) {
    change_grids(history_points(history_[history_head_]), false);
    --in_grids_;
  }
  history_head_ = (history_head_ + 1) % history_.size();
  --history_size_;
}

void ConsensusOdometry::push_history(const std::vector<Eigen::Vector3d>& points,
                                     const Eigen::Isometry3d& pose) {
  const std::size_t capacity = history_pool_.size();
  const std::size_t n = std::min(points.size(), capacity);
  if (history_size_ == history_.size()) drop_oldest();
  // Right after the newest scan, or at the start of the buffer when it does not fit before the
  // end. The scans lie in the buffer in the order they came, so the oldest ones are those
  // after the newest: they leave, oldest first, while they lie where the new scan goes or, when
  // it goes to the start, in the end of the buffer it skips (older than any at the start).
  const std::size_t end =
      history_size_ > 0 ? history_[(history_head_ + history_size_ - 1) % history_.size()].end() : 0;
  const core::RingRegion region = core::next_region(end, n, capacity);
  const bool wraps = region.offset != end;
  while (history_size_ > 0) {
    const core::RingRegion& oldest = history_[history_head_];
    if (!oldest.overlaps(region) && !(wraps && oldest.offset >= end)) break;
    drop_oldest();
  }
  const std::size_t slot = (history_head_ + history_size_) % history_.size();
  history_[slot] = region;
  history_pose_[slot] = pose;
  ++history_size_;
  for (std::size_t i = 0; i < n; ++i) history_pool_[region.offset + i] = pose * points[i];
}

void ConsensusOdometry::admit_pending(const Eigen::Isometry3d& next) {
  bool added = false;
  while (in_grids_ < history_size_) {
    const std::size_t k = (history_head_ + in_grids_) % history_.size();
    const Eigen::Isometry3d d = history_pose_[k].inverse() * next;
    const bool far = d.translation().norm() >= options_.map_admit_distance ||
                     Eigen::AngleAxisd(d.linear()).angle() >= options_.map_min_rotation;
    if (!far && in_grids_ > 0) break;
    change_grids(history_points(history_[k]), true);
    ++in_grids_;
    added = true;
  }
  if (added) finalize_grids();
}

void ConsensusOdometry::reference_points(std::vector<Eigen::Vector3d>& out) const {
  for (std::size_t i = 0; i < in_grids_; ++i) {
    const auto pts = history_points(history_[(history_head_ + i) % history_.size()]);
    out.insert(out.end(), pts.begin(), pts.end());
  }
}

void ConsensusOdometry::replace_newest(const std::vector<Eigen::Vector3d>& points,
                                       const Eigen::Isometry3d& pose) {
  // The newest scan leaves, and `points` take its place.
  const std::size_t newest = (history_head_ + history_size_ - 1) % history_.size();
  if (in_grids_ == history_size_) {
    change_grids(history_points(history_[newest]), false);
    --in_grids_;
  }
  --history_size_;
  push_history(points, pose);
  admit_pending(pose);  // back into the grids if it was the only scan there
}

void ConsensusOdometry::update_reference(const Eigen::Isometry3d& pose) {
  const Eigen::Isometry3d since = last_keyframe_pose_.inverse() * pose;
  // A young map takes scans closer together, so that the first matches have a reference.
  const double min_translation =
      history_size_ < options_.map_warmup_scans
          ? std::min(options_.map_warmup_translation, options_.map_min_translation)
          : options_.map_min_translation;
  const bool due = history_size_ == 0 || options_.reference == Reference::kPreviousScan ||
                   since.translation().norm() >= min_translation ||
                   Eigen::AngleAxisd(since.linear()).angle() >= options_.map_min_rotation;
  if (due) {
    push_history(cv_points_, pose);
    last_keyframe_pose_ = pose;
  }
  // At the next scan's pose under constant velocity (prev_motion_ is this scan's motion). The
  // first scan, and every scan of the previous-scan reference (which holds one), find the grids
  // empty and go in at once.
  admit_pending(pose * prev_motion_);
}

bool ConsensusOdometry::beyond_reach(const core::Pose6& a, const core::Pose6& b) const {
  const Eigen::Isometry3d d = core::to_isometry(a).inverse() * core::to_isometry(b);
  const double moved = d.translation().norm() + Eigen::AngleAxisd(d.linear()).angle() * rms_range_;
  return !(moved <= options_.fine_reach);
}

bool ConsensusOdometry::short_of_pyramid(const core::Pose6& pose,
                                         const core::Pose6& pyramid_pose) const {
  const Eigen::Vector3d from = prev_pose_.translation();
  const Eigen::Vector3d pyramid = core::to_isometry(pyramid_pose).translation() - from;
  const double moved = pyramid.norm();
  if (!(moved > 0.0)) return false;
  const double along = (core::to_isometry(pose).translation() - from).dot(pyramid) / moved;
  return moved - along >
         std::max(options_.near_shortfall, options_.near_shortfall_fraction * moved);
}

bool ConsensusOdometry::bound_slide(double room, Eigen::Isometry3d& pose) const {
  const Eigen::Matrix3d& h = match_translation_hessian_;
  if (!h.allFinite()) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(h);
  const double largest = es.eigenvalues()(2);
  const Eigen::Vector3d off = pose.translation() - prior_.center.head<3>();
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  for (int i = 0; i < 2; ++i) {  // the largest eigenvalue's direction is the best fixed
    if (es.eigenvalues()(i) >= options_.degenerate_conditioning * largest) continue;
    const Eigen::Vector3d free = es.eigenvectors().col(i);
    const double along = free.dot(off);
    if (std::abs(along) > room) shift += free * (along - std::copysign(room, along));
  }
  if (shift.isZero(0.0)) return false;
  pose.translation() -= shift;
  return true;
}

bool ConsensusOdometry::reference_near(const core::Pose6& pose) const {
  const Eigen::Isometry3d at = core::to_isometry(pose);
  for (std::size_t i = 0; i < in_grids_; ++i) {
    const std::size_t k = (history_head_ + i) % history_.size();
    if (!((history_pose_[k].inverse() * at).translation().norm() < options_.map_admit_distance)) {
      return false;
    }
  }
  return in_grids_ > 0;
}

bool ConsensusOdometry::match(const core::Pose6& x0, OdometryResult& res,
                              const core::Pose6* near_pyramid) {
  auto on_pyramid = [&] {
    return ndt::newton_solve(pyramid_.back(), test_, x0, options_.pyramid, nullptr, &lookup_cache_,
                             scan_motion(), &prior_);
  };
  ndt::NewtonResult r;
  if ((res.flags & kOdomPyramidOnly) != 0) {
    r = on_pyramid();
  } else if (options_.mode == OdometryMode::kNaive) {
    r = ndt::newton_solve(grid_, test_, x0, options_.naive, nullptr, &lookup_cache_, scan_motion(),
                          &prior_);
  } else {
    const ndt::NewtonResult coarse = ndt::newton_solve(grid_, test_, x0, options_.coarse, nullptr,
                                                       &lookup_cache_, scan_motion(), &prior_);
    res.coarse_iterations += coarse.iterations;
    // The points as the coarse pose undistorts them: for Cv, and the base of the fine match.
    if (solve_motion_) deskew_at(core::to_isometry(coarse.pose));
    deskew_scan(test_motion_);
    // Cv of every reference voxel at the coarse pose (eqs 8-9), then the cut at eta.
    consensus_at(coarse.pose, cv_);
    mask_.assign(grid_.size(), 1);
    res.voxels_before = res.voxels_after = 0;
    for (std::size_t i = 0; i < grid_.size(); ++i) {
      if (!std::isnan(cv_[i]) && cv_[i] < options_.eta) mask_[i] = 0;
      if (residuals_.count[i] > 0) {
        ++res.voxels_before;
        if (mask_[i] != 0) ++res.voxels_after;
      }
    }
    r = ndt::newton_solve(grid_, test_, coarse.pose, options_.fine, &mask_, &lookup_cache_,
                          scan_motion(), &prior_);
    if (options_.fine_reach > 0.0 && beyond_reach(coarse.pose, r.pose)) {
      res.fine_iterations += r.iterations;
      res.flags |= kOdomFineBeyondReach;
      r = ndt::newton_solve(grid_, test_, coarse.pose, options_.fine, nullptr, &lookup_cache_,
                            scan_motion(), &prior_);
    }
  }
  // Pulled back towards the reference scans: the pyramid's pose, as with pyramid_while_near.
  // Not where the fine grid finds the scene degenerate: there neither pose is fixed along the
  // free direction, and the match stays (to be flagged) rather than the 1 m grid's pose, whose
  // blurred Gaussians hide that.
  if (near_pyramid != nullptr && (res.flags & kOdomPyramidOnly) == 0 &&
      short_of_pyramid(r.pose, *near_pyramid) && !degenerate(translation_conditioning(r.hessian))) {
    res.fine_iterations += r.iterations;
    res.flags |= kOdomPyramidOnly | kOdomShortOfPyramid;
    r = on_pyramid();
  }
  res.fine_iterations += r.iterations;
  res.conditioning = translation_conditioning(r.hessian);  // the last match's counts
  match_translation_hessian_ = r.hessian.topLeftCorner<3, 3>();
  res.points = r.matched;
  res.pose = core::to_isometry(r.pose);
  return r.converged;
}

OdometryResult ConsensusOdometry::process(const core::Scan& scan) {
  OdometryResult res = estimate(scan);
  commit();
  return res;
}

void ConsensusOdometry::commit() {
  if (!reference_due_) return;
  reference_due_ = false;
  update_reference(prev_pose_);  // the scan's pose (at mid-revolution once deskewed there)
}

OdometryResult ConsensusOdometry::estimate(const core::Scan& scan) {
  OdometryResult res = estimate_levelled(scan);
  if (tilted_) {
    // Odometry frame O' = R O for the rotation R into the level frame: T_O = R^T T_O' R.
    const Eigen::Matrix3d& r = level_rotation_;
    res.pose.linear() = r.transpose() * res.pose.linear() * r;
    res.pose.translation() = r.transpose() * res.pose.translation();
    sensor_points_.clear();
    for (const Eigen::Vector3d& p : mid_active_ ? stamp_points_ : cv_points_) {
      sensor_points_.push_back(r.transpose() * p);
    }
  }
  return res;
}

void ConsensusOdometry::decide_level() {
  level_decided_ = true;
  if (!options_.level_frame) return;
  // The first scan's 0.1 m points in the coarsest grid, empty before the first reference.
  ndt::VoxelGrid& g = pyramid_.empty() ? grid_ : pyramid_.front();
  for (const TimedPoint& p : map_src_) g.add(p.p);
  const Eigen::Vector3d up = level_normal(g);
  g.clear();
  if (up.z() > std::cos(5.0 * std::numbers::pi / 180.0)) return;
  tilted_ = true;
  level_rotation_ =
      Eigen::Quaterniond::FromTwoVectors(up, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (TimedPoint& p : raw_) p.p = level_rotation_ * p.p;
  map_sampler_.run(raw_, map_src_);
  scan_sampler_.run(map_src_, scan_src_);
}

OdometryResult ConsensusOdometry::estimate_levelled(const core::Scan& scan) {
  commit();  // the previous scan's, when the caller has not
  // mid_scan_after_clean: the velocity measured by that many clean matches in a row, none across
  // a gap or a clock jump (trusted_run_, counted by the last scan).
  if (options_.deskew_to_mid_scan && !mid_active_ &&
      trusted_run_ >= options_.mid_scan_after_clean) {
    // From here on deskewed to mid-revolution: the last pose, committed to the reference at its
    // stamp, moves on to the middle of its revolution (with the motion it was deskewed with and
    // its revolution, not yet this scan's), where the poses chained from now on lie.
    mid_active_ = true;
    prev_pose_ = prev_pose_ * scale_motion(deskewed_with_, mid_fraction());
  }
  OdometryResult res;
  // The match is degenerate (as kOdomDegenerate without the hysteresis of its report).
  bool degenerate_match = false;
  res.stamp = scan.stamp;
  if (!scan.complete()) res.flags |= kOdomScanIncomplete;
  // The sensor clock jumped (back, or on while the data kept coming) before this revolution:
  // its stamp does not compare with the last one's.
  if ((scan.flags & (core::kScanTimeJump | core::kScanPartial)) ==
      (core::kScanTimeJump | core::kScanPartial)) {
    clock_jumped_ = true;
  }
  // The longest silence between scans (seen or skipped) since the last one given a pose.
  if (last_seen_end_.count() != 0) {
    silence_s_ =
        std::max(silence_s_, static_cast<double>((scan.stamp - last_seen_end_).count()) * 1e-9);
  }
  last_seen_end_ = scan.end;
  if (options_.skip_partial_scans && (scan.flags & core::kScanPartial) != 0) {
    res.flags |= kOdomSkipped;
    return res;
  }
  // Constant-velocity prediction (rescaled to this scan's time step). Across a clock jump the
  // data kept coming: this revolution follows the last one.
  const bool jumped = have_prev_ && (clock_jumped_ || scan.stamp <= prev_stamp_);
  clock_jumped_ = false;
  const double dt = !have_prev_ ? 0.1
                    : jumped    ? revolution_s_
                                : static_cast<double>((scan.stamp - prev_stamp_).count()) * 1e-9;
  // One scan period: the time between the last two stamps, or at the start this scan's own
  // span when it is a whole revolution.
  const double span = static_cast<double>((scan.end - scan.stamp).count()) * 1e-9;
  // A revolution with packets lost inside it still spans the whole turn (short by at most the
  // packets lost at its end).
  const bool whole_turn = scan.whole_turn();
  period_s_ = have_prev2_ ? prev_period_s_ : (whole_turn && span > 0.01 ? span : 0.1);
  const Eigen::Isometry3d motion =
      have_prev2_ ? scale_motion(prev_motion_, dt / period_s_) : Eigen::Isometry3d::Identity();
  // More than half a period without firings since the last scan: a gap in the data.
  const bool after_gap = have_prev2_ && !jumped && silence_s_ > 0.5 * period_s_;
  silence_s_ = 0.0;
  // Less than half of the turn swept (a stream's last revolution, or one cut short by a gap).
  const bool short_sweep = !whole_turn && span < 0.5 * revolution_s_;
  if (whole_turn && span > 0.01) revolution_s_ = span;
  // The prediction holds a velocity from before a gap, or a time step assumed across a jump.
  const bool trusted = prediction_trusted_ && !after_gap && !jumped;
  // In range, then downsampled: map_cell for the reference and Cv, scan_cell for matching.
  raw_.clear();
  const double min2 = options_.min_range * options_.min_range;
  const double max2 = options_.max_range * options_.max_range;
  for (const core::Point& p : scan.points) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    const double r2 = v.squaredNorm();
    if (r2 < min2 || r2 > max2 || !v.allFinite()) continue;
    raw_.push_back({tilted_ ? Eigen::Vector3d(level_rotation_ * v) : v,
                    static_cast<double>(p.time_ns) * 1e-9});
  }
  res.raw_points = raw_.size();
  map_sampler_.run(raw_, map_src_);
  scan_sampler_.run(map_src_, scan_src_);
  if (!level_decided_) decide_level();
  // The deskew motion spans one scan period; `motion` spans dt.
  to_period_ = period_s_ / std::max(dt, 1e-3);
  // The velocity at the stamp (deskew_acceleration). The motion from prev_pose_ is the mean
  // velocity over the dt that ends at the stamp, dt / 2 behind it; the last motion, the mean
  // over the h before. Under constant acceleration (a quadratic through the last three poses,
  // the second-order backward difference) the velocity at the stamp is the newer mean plus
  // dt / (dt + h) times its change from the older: half of it for equal steps, next to nothing
  // when the older motion spans a gap in the data. Not with deskew_to_mid_scan: there it lost
  // drives with the sensor turned in yaw on its mount (docs/odometry.md).
  extrapolate_ =
      options_.deskew_acceleration && !options_.deskew_to_mid_scan && have_prev2_ && trusted
          ? dt / (dt + prev_period_s_)
          : 0.0;
  // A point fired t after the stamp moves t / dt times the pose's change with the undistortion
  // (measured from mid-revolution once deskewed there), 1 + extrapolate_ times that with
  // the velocity at the stamp: its lever in the matches.
  const double lever_origin = mid_fraction();
  const double lever_scale = 1.0 + extrapolate_;
  lever_.clear();
  double range2 = 0.0;
  for (const TimedPoint& p : scan_src_) {
    lever_.push_back((p.t / period_s_ - lever_origin) * to_period_ * lever_scale);
    range2 += p.p.squaredNorm();
  }
  rms_range_ = scan_src_.empty() ? 0.0 : std::sqrt(range2 / static_cast<double>(scan_src_.size()));
  scan_motion_.lever = lever_;
  const Eigen::Isometry3d predicted = prev_pose_ * motion;
  const Eigen::Vector3d predicted_step = predicted.translation() - prev_pose_.translation();
  const Eigen::Isometry3d predicted_deskew =  // over one period
      extrapolate_ == 0.0 ? scale_motion(motion, to_period_) : deskew_motion(predicted);
  deskew_for(predicted_deskew, core::to_pose6(predicted));
  res.points = test_.size();
  if (!have_prev_) {
    deskew_scan(predicted_deskew);  // the identity: no motion is known yet
    res.flags |= kOdomFirstScan;
    res.pose = Eigen::Isometry3d::Identity();
    reference_due_ = true;  // at prev_pose_, set below
    newest_unskewed_ = options_.deskew;
    newest_src_ = map_src_;
    prev_pose_ = res.pose;
    // Not deskewed: the stamp and mid-revolution frames coincide.
    if (mid_active_) stamp_points_ = cv_points_;
    prev_stamp_ = scan.stamp;
    have_prev_ = true;
    return res;
  }
  // Not while the newest reference scan is still undistorted (below).
  solve_motion_ = options_.deskew && period_s_ > 0.0 && !newest_unskewed_;
  std::optional<Eigen::Isometry3d> first_velocity;  // motion per period, from the first match
  // A revolution mostly lost or mostly not swept is not matched: what is left can still be many
  // points, but from a few sectors, which leave the pose poorly fixed and the deskew little to
  // go by.
  if (test_.size() < options_.min_points || scan.lost_packets > scan.packets || short_sweep) {
    res.flags |= kOdomTooFewPoints;
    res.pose = predicted;
    deskew_scan(predicted_deskew);
  } else {
    core::Pose6 x0 = core::to_pose6(predicted);
    prior_.center = x0;
    prior_.relative_weight = trusted ? options_.prior_weight : 0.0;
    // The prediction keeps a constant velocity. While the vehicle brakes or pulls away faster
    // than prior_acceleration_threshold it is a dt^2 / 2 ahead of or behind it, and the prior
    // would hold a weakly held match there: the prior's centre then moves on by the change of
    // speed (acceleration_ along the motion).
    if (acceleration_ != 0.0 && predicted_step.norm() > 1e-3) {
      prior_.center.head<3>() +=
          0.5 * acceleration_ * dt * (prev_period_s_ + dt) * predicted_step.normalized();
    }
    if (options_.guess_jitter_seed != 0) jitter(x0);
    if (!have_prev2_) {
      x0 = search_start(x0, Eigen::Vector3d::UnitX(), 0.0,
                        std::min(options_.max_speed * dt, options_.gap_search_radius))
               .start;
    } else if (after_gap || jumped) {
      // Along the predicted motion, as far as the vehicle may have sped up or slowed down.
      const double along =
          std::min(options_.gap_search_radius,
                   options_.start_search_radius + 0.5 * options_.gap_acceleration * dt * dt);
      x0 = search_gap_start(x0, predicted, predicted_step, along);
    }
    if (!have_motion_prior_ || options_.pyramid_every_scan) x0 = coarse_to_fine(x0);
    // While every reference scan is near, the pyramid's pose: the match either takes it
    // (pyramid_while_near; match() reads the flag) or is checked against it.
    const bool near = options_.reference == Reference::kLocalMap && !pyramid_.empty() &&
                      (options_.pyramid_while_near || options_.near_shortfall_fraction > 0.0) &&
                      reference_near(x0);
    const core::Pose6 pyramid_pose = x0;
    const core::Pose6* near_pyramid = near ? &pyramid_pose : nullptr;
    if (near && options_.pyramid_while_near) res.flags |= kOdomPyramidOnly;
    bool converged = false;
    int passes = 1 + options_.deskew_refinements;
    for (int pass = 0; pass < passes; ++pass) {
      converged = match(x0, res, near_pyramid);
      const Eigen::Isometry3d estimated = prev_pose_.inverse() * res.pose;
      if (newest_unskewed_ && converged) {
        // The first reference scan went in undistorted, and so did this one: the match measured
        // how far apart points fired at the same azimuth are, one scan period apart. That is the
        // motion per period, not per dt (shorter when the first scan was partial). Deskew both
        // with it and match again from the pose it gives at this scan's stamp.
        newest_unskewed_ = false;
        first_velocity = estimated;
        deskew(newest_src_, estimated, scratch_);
        // The first scan's pose at its stamp is the identity; at mid-revolution, half a period on.
        if (mid_active_) {
          last_keyframe_pose_ = scale_motion(estimated, 0.5);
          prev_pose_ = last_keyframe_pose_;
        }
        replace_newest(scratch_, last_keyframe_pose_);
        x0 = core::to_pose6(prev_pose_ * scale_motion(estimated, dt / period_s_));
        deskew_for(estimated, x0);
        solve_motion_ = options_.deskew;
        passes = std::max(passes, pass + 2);  // matched again even with no refinements
        continue;
      }
      // The match moved the undistortion with the pose to first order (ndt::ScanMotion).
      // Deskew again and match from there only when the pose ended so far from the base
      // that the second order counts: 0.1 m moves a point fired at the end of the period by
      // about |w| x 0.1 m more than modelled; 0.01 rad by 0.005 % of its range.
      const Eigen::Isometry3d diff = core::to_isometry(scan_motion_.base).inverse() * res.pose;
      const bool linear =
          diff.translation().norm() < 0.1 && Eigen::AngleAxisd(diff.linear()).angle() < 0.01;
      if (!solve_motion_ || linear || pass + 1 == passes) break;
      deskew_at(res.pose);
      x0 = core::to_pose6(res.pose);
    }
    // A match that implies an impossible acceleration, linear or about the sensor's axis:
    // matched again from the prediction (deskewed with it), without the pyramid. Constant
    // acceleration a moves the pose a dt^2 / 2 off the constant-velocity prediction; the other
    // half of the allowance is for the error of the velocity itself. A turn rate from sparse
    // scans (1200 rpm) is off by up to a degree per scan, whatever dt: the turn's allowance is
    // at least kMinTurnAllowance. Only the turn about the axis: rings turned about it lie on
    // themselves, so nothing but the few other features holds it; roll and pitch move the rings
    // and the ground holds them (their scatter on sparse scans is not a wrong minimum).
    const bool jumped_away =
        (options_.max_acceleration > 0.0 &&
         (res.pose.translation() - predicted.translation()).norm() >
             options_.max_acceleration * dt * dt) ||
        (options_.max_angular_acceleration > 0.0 &&
         std::abs(heading_change(predicted.linear().transpose() * res.pose.linear())) >
             std::max(options_.max_angular_acceleration * dt * dt, kMinTurnAllowance));
    if (trusted && jumped_away) {
      res.flags |= kOdomRematched;
      deskew_for(predicted_deskew, core::to_pose6(predicted));
      converged = match(core::to_pose6(predicted), res, near_pyramid);
    }
    // Surface patches leave the position along a level surface to the rest of the scene. Where
    // that is too little (the match degenerate), the scan is matched again from its start with
    // the plain Gaussians, whose ring texture holds it; the patches stay off until
    // patches_clean_scans matches in a row are not degenerate.
    if (grid_.options().surface_patches && options_.patches_clean_scans > 0 &&
        degenerate(res.conditioning)) {
      grid_.set_surface_patches(false);
      grid_.finalize(lookup_cache_.runner());
      clean_run_ = 0;
      res.flags |= kOdomWithoutPatches;
      deskew_at(core::to_isometry(x0));
      converged = match(x0, res, near_pyramid);
    }
    // Degenerate: along the free directions the match slid as far as nothing held it, and the
    // vehicle cannot have left the prediction by more than the acceleration check allows. Only
    // once clean matches have measured the velocity (slide_bound_armed_), not across a gap.
    if (options_.bound_degenerate_slide && options_.max_acceleration > 0.0 && slide_bound_armed_ &&
        have_prev2_ && !after_gap && !jumped && degenerate(res.conditioning) &&
        bound_slide(options_.max_acceleration * dt * dt, res.pose)) {
      res.flags |= kOdomSlideBounded;
    }
    if (!converged) res.flags |= kOdomNotConverged;
    have_motion_prior_ = converged;
    if (!finite(res.pose)) {
      res.pose = predicted;
      res.flags |= kOdomNotConverged;
    }
    // The reference and Cm take the scan deskewed with the final estimate.
    deskew_scan(deskew_motion(res.pose));
    const ndt::ConsensusMeasure consensus = consensus_at(core::to_pose6(res.pose), cv_);
    res.cm = consensus.cm;
    // Cm weighs the directions to the voxels, not what their surfaces constrain: a corridor's
    // walls, floor and ceiling surround the sensor (Cm stays high) but leave its axis free.
    // A Cm of 0 for want of voxels with a Cv says nothing of the match: flagged apart, so
    // that a sparse scan whose match is well posed still counts as clean.
    degenerate_match = degenerate(res.conditioning) || (res.cm <= 0.0 && consensus.measured);
    // Reported with hysteresis (degenerate_clear_conditioning): a match just past the threshold
    // right after a degenerate one is reported degenerate too, but counts as clean below (the
    // prediction, the patches), as it would without the hysteresis.
    const bool held =
        degenerate_latched_ && !(res.conditioning >= options_.degenerate_clear_conditioning);
    if (degenerate_match || held) {
      res.flags |= kOdomDegenerate;
      res.cm = 0.0;
    } else if (res.cm <= 0.0) {
      res.flags |= kOdomCmUnmeasured;
    }
    degenerate_latched_ = (res.flags & kOdomDegenerate) != 0;
  }
  // Past the first scan (returned above), so the motion between the last two scans is known.
  res.dt = dt;
  // The last step's mean speed, and whether its match was clean (not yet updated for this one).
  const double older_speed = prev_motion_.translation().norm() / prev_period_s_;
  const double older_period_s = prev_period_s_;
  const bool have_older = have_prev2_ && prediction_trusted_;
  prev_motion_ = prev_pose_.inverse() * res.pose;
  prev_period_s_ = std::max(dt, 1e-3);
  if (first_velocity && dt < 0.5 * period_s_) {
    // A short partial first scan: a centimetre of error over a few hundredths of a second would
    // be a large velocity error. The first match measured the motion over a whole period.
    prev_motion_ = *first_velocity;
    prev_period_s_ = period_s_;
  }
  // The next prediction is trusted when this scan's match was clean: a scan rematched, flagged
  // degenerate or not matched may carry a wrong motion, and gating on it would keep it.
  prediction_trusted_ = !degenerate_match &&
                        (res.flags & (kOdomTooFewPoints | kOdomNotConverged | kOdomRematched)) == 0;
  clean_run_ = degenerate_match ? 0 : clean_run_ + 1;
  // Clean matches in a row, none across a gap or a clock jump: mid_scan_after_clean reads it.
  trusted_run_ = prediction_trusted_ && !after_gap && !jumped ? trusted_run_ + 1 : 0;
  // The slide bound needs a prediction measured by clean matches: armed by kSlideBoundCleanRun
  // of them in a row (counted across a gap), disarmed by a gap or a clock jump.
  if (after_gap || jumped) slide_bound_armed_ = false;
  if (clean_run_ >= kSlideBoundCleanRun) slide_bound_armed_ = true;
  // The change of speed between the mean speeds of the last two steps, (h1 + h2) / 2 apart, per
  // second. acceleration_ takes it while two such changes in a row exceed the threshold with
  // the same sign (the smaller of the two): a match's error makes one step long and the next
  // short, which changes the speed one way and then back.
  double change = 0.0;
  if (have_older && prediction_trusted_ && options_.prior_acceleration_threshold > 0.0) {
    const double h1 = older_period_s, h2 = prev_period_s_;
    change = (prev_motion_.translation().norm() / h2 - older_speed) / (0.5 * (h1 + h2));
    if (std::abs(change) <= options_.prior_acceleration_threshold) change = 0.0;
  }
  acceleration_ = change * last_change_ > 0.0
                      ? std::copysign(std::min(std::abs(change), std::abs(last_change_)), change)
                      : 0.0;
  last_change_ = change;
  have_prev2_ = true;
  newest_unskewed_ = false;
  reference_due_ = true;  // at prev_pose_, set next
  prev_pose_ = res.pose;
  prev_stamp_ = scan.stamp;
  if (options_.deskew && mid_active_) {
    // Reported at the scan stamp, half a revolution's motion before mid-revolution; the points
    // for the mapper likewise.
    const Eigen::Isometry3d half = scale_motion(deskewed_with_, mid_fraction());
    res.pose = res.pose * half.inverse();
    stamp_points_.clear();
    for (const Eigen::Vector3d& p : cv_points_) stamp_points_.push_back(half * p);
  }
  return res;
}

}  // namespace cndt::slam
