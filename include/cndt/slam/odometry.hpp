// Consensus-NDT LiDAR odometry (paper section 3.1, Figure 2): for each scan, deskew with the
// predicted motion, downsample, match coarsely against the reference with all voxels, compute
// the voxel consensus Cv, drop voxels with Cv < eta, match finely with the rest, and report the
// localization consensus Cm. The naive mode is the same without the Cv cut (one optimisation).
#pragma once

#include <Eigen/Geometry>
#include <chrono>
#include <cstdint>
#include <numbers>
#include <span>
#include <vector>

#include "cndt/core/ring_region.hpp"
#include "cndt/core/scan.hpp"
#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/newton.hpp"
#include "cndt/ndt/voxel_grid.hpp"
#include "cndt/slam/downsample.hpp"

namespace cndt::slam {

enum class OdometryMode { kConsensus, kNaive };
/// What a scan is matched against: the previous scan (the paper) or the recent scans merged in
/// the odometry frame (a local map).
enum class Reference { kPreviousScan, kLocalMap };

struct OdometryOptions {
  OdometryMode mode = OdometryMode::kConsensus;
  Reference reference = Reference::kLocalMap;
  /// Scans the local map holds. A scan enters it once the sensor has moved map_min_translation
  /// or turned map_min_rotation since the last one that did (always with kPreviousScan), so a
  /// slow or stopped vehicle keeps a map spread over distance.
  std::size_t local_map_scans = 60;
  /// Points the local map's scans hold together (one buffer, allocated once; at least
  /// max_scan_points). When a new scan does not fit, the oldest scans leave until it does.
  std::size_t local_map_points = 1'500'000;
  /// 1 m: 2 m costs less time but lost steeply tilted mounts (docs/odometry.md, "Why 60 scans
  /// 1 m apart"; configuration key odometry.map_min_translation_m).
  double map_min_translation = 1.0;  ///< m
  double map_min_rotation = 0.035;   ///< rad (2 deg)
  /// Until the local map holds this many scans, they enter after map_warmup_translation.
  std::size_t map_warmup_scans = 10;
  double map_warmup_translation = 0.3;  ///< m
  /// A scan taken into the local map is matched against only once the predicted sensor pose is
  /// this far from where it was taken (or turned map_min_rotation from it); the first scan at
  /// once. Near its own pose a scan's sampling pattern (ring arcs on the floor, ring lines on
  /// walls) lines up with the next scans' and pulls their matches towards zero motion; a slow
  /// vehicle would be held there (docs/odometry.md). 0 = at once.
  double map_admit_distance = 0.5;  ///< m
  double voxel_size = 0.5;          ///< L of the reference NDT, m (paper: 0.5)
  /// Downsampling of the scan being matched, m. The cell centroids of a surface sampled evenly
  /// lie at the cell centres; with cells as large as the voxels they line up with the voxel
  /// means once per cell of motion, and the score ripples along every plane with that period
  /// (along an evenly sampled wall it swings by 76 % of its mean at 0.5 m cells, 0.8 % at
  /// 0.25 m; docs/odometry.md).
  double scan_cell = 0.25;
  double map_cell = 0.1;  ///< downsampling of scans added to the reference and used for Cv, m
  double eta = 0.7;       ///< Cv threshold (paper: 0.7)
  /// How far the fine match may take the pose from the coarse one, m (a point at the scan's RMS
  /// range moved this far by a turn counts the same; 0 = any distance). Cv judged the voxels
  /// with the points where the coarse pose put them; a fine match that goes farther has left
  /// what the cut was made for, usually along a direction only the dropped voxels fixed (a young
  /// reference's rings then pull it towards zero motion). It is then matched again from the
  /// coarse pose with every voxel.
  double fine_reach = 0.125;
  double min_range = 1.0, max_range = 100.0;  ///< m; nearer points are the vehicle itself
  /// Undistort every scan with the estimated motion (constant-velocity prediction, refined).
  bool deskew = true;
  /// Deskew to the sensor pose at mid-revolution instead of the scan stamp (from the
  /// mid_scan_after_clean-th clean match on): the matches then estimate that pose and the
  /// reported pose is moved back to the stamp. At mid-scan an error in the deskew's motion
  /// distorts the scan symmetrically and does not move the matched pose (deskewed to the stamp,
  /// half of a height-rate error goes into the height), and a body pitching within the
  /// revolution is not smoothed over three scans. deskew_acceleration does not apply with it.
  /// Off by default: it lowers RTE on most simulated drives, but some lose more than the rest
  /// gain (a street with the sensor pitched 10 deg down, a fast pull-away with packet loss, a gap
  /// in a turn; docs/odometry.md, "Deskew to mid-revolution", measured on 2026-12-07).
  bool deskew_to_mid_scan = false;
  /// With deskew_to_mid_scan: scans are deskewed to the stamp until this many clean matches in a
  /// row (none across a gap) have measured the velocity, and to mid-revolution from then on
  /// (0 = from the first scan). Deskewed to mid-revolution from the start, the first matches
  /// against a reference of one or two scans went 0.1-0.4 m off on some drives that the stamp
  /// deskew starts cleanly (a street with the sensor pitched 10 deg up, a campus with 8
  /// movers).
  std::size_t mid_scan_after_clean = 10;
  /// A sensor mounted more than 5 deg off level (pitched down to see the ground, say): the
  /// level surfaces (ground, floor) of the first scan used give the up direction, and every scan is
  /// turned by the rotation that brings it to z before anything else, so that the matches, the
  /// start search and the level patches see a level sensor. The poses and points reported are
  /// turned back: sensor poses in the first scan's sensor frame, as for a level sensor. Within
  /// 5 deg of level nothing is turned.
  bool level_frame = true;
  /// Deskew with the velocity at the stamp, from the last three poses (the second-order
  /// backward difference; for equal steps 1.5 x the motion from the last pose - 0.5 x the
  /// motion before it), instead of the mean velocity over the last period, which lags half a
  /// period behind it; only after a clean match. A vehicle pitching on its suspension (about
  /// 1 Hz) changes its rate of pitch within a period, most at 300-420 rpm (docs/odometry.md,
  /// "Deskew velocity"). Not with deskew_to_mid_scan: with it, drives with the sensor turned in
  /// yaw were lost (a 420 rpm campus with the sensor facing back: 0.95 m against 0.004 m).
  bool deskew_acceleration = true;
  /// A partial revolution (the stream's first, where the receiver started mid-turn, or the first
  /// after a gap in the data) is not matched: flag kOdomSkipped, no pose. As the first reference
  /// it covers only a sector and the start-up matches drift off by decimetres; after a gap it is
  /// a sector seen from metres past the local map, and matched it took the next scans with it
  /// (docs/odometry.md, "Gaps in the data"). The trajectory goes on at the next whole revolution.
  bool skip_partial_scans = true;
  /// After a gap in the data (more than half a scan period without firings) the
  /// constant-velocity prediction is off by what the vehicle sped up or slowed down meanwhile:
  /// it is not trusted (no position prior, no acceleration check), and the start search looks
  /// along the heading up to start_search_radius + gap_acceleration dt^2 / 2 from it (dt the
  /// time since the last scan; at most gap_search_radius), across it start_search_radius.
  double gap_acceleration = 2.0;    ///< m/s^2
  double gap_search_radius = 10.0;  ///< m
  /// After a gap over which the prediction turns by more than this (the last scan's turn rate
  /// times the gap), starts with that turn cut to a half and to nothing are searched as well: a
  /// vehicle may have ended its turn while nothing arrived. 0 searches them after every gap; a
  /// negative value never. 3 deg.
  double gap_turn_hypothesis_rad = 3.0 * std::numbers::pi / 180.0;
  /// The matches solve for the scan's motion with its pose (ndt::ScanMotion). A match ending
  /// beyond that model's first-order range (0.1 m / 0.01 rad from the pose the scan was
  /// deskewed for) is deskewed again and matched again, at most this many times.
  int deskew_refinements = 2;
  std::size_t max_scan_points = 150'000;
  std::size_t max_map_voxels = 400'000;
  std::size_t min_points = 200;  ///< fewer matched points: the scan is not matched
  bool drop_ring_arcs = false;   ///< reference voxels holding a single ring arc get no Gaussian
  /// Reference voxels in a planar neighbourhood are matched as pieces of the plane
  /// (ndt::VoxelGridOptions::surface_patches; docs/odometry.md, "Surface patches"). On by
  /// default for level planes only, once the local map holds patches_after_scans scans and
  /// patches_clean_scans matches in a row were not degenerate, checked when the local map takes
  /// a scan (from the fourth scan of a drive at speed; patch_max_tilt_deg; docs/odometry.md,
  /// "Level patches"): they take out most of the tilt the ground's ring arcs give. false: the
  /// paper's Gaussians (eq 4) everywhere.
  bool surface_patches = true;
  /// Surface patches only once the local map holds this many scans: a plane judged from the sums
  /// of one or two sparse scans (900-1200 rpm) may be a few unrelated ring arcs; a campus drive
  /// at 1200 rpm was lost at its sixth scan with patches once the map held two.
  std::size_t patches_after_scans = 4;
  /// With surface_patches, patches only for level planes (normal within this angle of the
  /// odometry frame's z, the first scan's): the ground's ring arcs, which tilt the start,
  /// become patches, while walls and the flat sides of movers keep the paper's Gaussians (and
  /// with them the Cv cut's lead over naive). 90: every plane.
  double patch_max_tilt_deg = 25.0;
  /// Surface patches only after this many matches in a row not flagged degenerate, at the start
  /// of a drive too. A match degenerate with patches is matched again without them
  /// (kOdomWithoutPatches), and they stay off (the map's voxels keep eq 4's Gaussians) until
  /// then. Where the rest of the scene leaves the position free (sparse campus scans at
  /// 1200 rpm), the texture the rings give the ground is what holds it; with level patches alone
  /// such drives were lost. 0: patches regardless.
  std::size_t patches_clean_scans = 3;
  /// Coarser grids of the same reference the scan is matched on first, coarsest first. Their
  /// Gaussians are blurred (eigenvalues floored at pyramid_eigen_floor x the largest) and voxels
  /// holding a single ring arc get none, so they pull from much farther than the fine grid,
  /// whose ground planes have no restoring force beyond a few centimetres (and whose ring arcs
  /// hold a match near zero motion). Always used without a motion prior (the first scans, or
  /// after a failed match); on every scan with pyramid_every_scan.
  std::vector<double> pyramid_voxel_sizes = {2.0, 1.0};
  double pyramid_eigen_floor = 0.05;
  /// Before the first match there is no velocity: horizontal offsets up to this far (m) from
  /// the start are scored on the coarsest grid and the best one is the start. While the best
  /// lies on the edge of the offsets scored, the search grows outwards, up to what max_speed
  /// covers between the first two scans.
  double start_search_radius = 2.0;  ///< after a gap in the data see gap_acceleration
  /// The platform's top speed, m/s (40 = 144 km/h): how far the start search may reach.
  double max_speed = 40.0;
  bool pyramid_every_scan = true;
  /// With the local-map reference: while every scan in it lies within map_admit_distance of the
  /// pose the pyramid found (at the start, until the vehicle is that far from its first scan),
  /// that pose is refined on the finest pyramid grid instead of the coarse and fine matches, and
  /// flagged kOdomPyramidOnly. On the fine grid the Gaussians of a scan taken that near hold
  /// its ring arcs where the new scan has its own, and pull the match towards zero motion.
  /// It saves slow, from-rest and 900-1200 rpm starts (docs/odometry.md, "Pyramid while
  /// near"); off by default, as without surface patches it costs the consensus mode on a
  /// 600 rpm campus drive. Turn both on together.
  bool pyramid_while_near = false;
  /// While every scan in the local map lies within map_admit_distance of the pyramid's pose (as
  /// for pyramid_while_near), the fine grid's ring arcs may pull the coarse and fine matches
  /// back towards the reference scans: the match then moves the sensor less far from the
  /// previous pose than the pyramid did. When the match's motion, measured along the pyramid's,
  /// falls short of the pyramid's motion by more than near_shortfall_fraction of it and at
  /// least near_shortfall (m), the pyramid's pose is refined on the finest pyramid grid instead
  /// and flagged kOdomPyramidOnly | kOdomShortOfPyramid, unless the fine match's Hessian fails
  /// the degeneracy test (then neither pose is fixed, and the match stays, flagged). 0 = no
  /// check. A campus drive at 4 m/s (0.4 m per revolution) whose first fine matches landed at
  /// 0.05 m keeps the pyramid's 0.4 m; where the two agree the fine match stands
  /// (docs/odometry.md, "Pyramid while near").
  double near_shortfall_fraction = 0.2;
  double near_shortfall = 0.02;
  /// The coarse grids' solves: one voxel per point, stopped at 5 mm / 0.05 deg steps.
  ndt::NewtonOptions pyramid{.max_iterations = 10,
                             .translation_eps = 5e-3,
                             .rotation_eps = 1e-3,
                             .score_eps = 1e-5,
                             .neighbours = ndt::Neighbours::kOne};
  ndt::NewtonOptions coarse{.max_iterations = 15, .translation_eps = 3e-3, .rotation_eps = 5e-4};
  ndt::NewtonOptions fine{.max_iterations = 15};
  ndt::NewtonOptions naive{.max_iterations = 30};
  /// Degeneracy: the final match's Hessian, translation block, has its smallest eigenvalue
  /// below this fraction of its largest (or one not positive): the scene does not fix the
  /// position along some direction (a featureless corridor, a tunnel). The pose is flagged
  /// kOdomDegenerate and its Cm reported as 0. Measured (docs/odometry.md): the simulated
  /// corridor's median ratio is about 0.0011; the 60 s street, campus and loop drives have
  /// medians of 0.13-0.25 and none below 0.01.
  double degenerate_conditioning = 0.003;
  /// Hysteresis of the report: after a pose flagged kOdomDegenerate, the next ones are flagged
  /// too (Cm 0) until a match's ratio reaches this. In a corridor the ratio wanders about the
  /// threshold (median 0.0011, 99th percentile 0.010), and the matches that crossed it were
  /// published as valid with a motion as wrong as their flagged neighbours'; well-posed drives
  /// stay far above it (60 s street, campus, loop: 1st percentile 0.045-0.061;
  /// docs/odometry.md, "Degeneracy check"). Only the report: such a match counts as clean for
  /// the odometry's own decisions (the prediction's trust, the level patches). At or below
  /// degenerate_conditioning: no hysteresis.
  double degenerate_clear_conditioning = 0.01;
  /// Largest acceleration the platform can have, m/s^2 (about 1 g; 0 = no check). A match that
  /// lands farther from the constant-velocity prediction than a dt^2 (0.1 m at 10 m/s^2 and
  /// 10 Hz) has jumped to a wrong minimum (rings that move with the sensor hold a young reference
  /// near zero motion): the scan is matched again from the prediction, without the pyramid, and
  /// flagged kOdomRematched.
  double max_acceleration = 10.0;
  /// Largest angular acceleration about the sensor's axis the platform can have, rad/s^2
  /// (300 deg/s^2; 0 = no check): the same check for the match's turn about its z axis, which
  /// may lie no farther from the prediction's than a dt^2 (3 deg at 10 Hz; at least 1.5 deg,
  /// for the scatter of the turn rates measured on sparse scans at 1200 rpm). Rings turned about
  /// the axis lie on themselves and leave that turn to the few other features, so a match
  /// pulling away among pedestrians can turn by degrees in one scan. Roll and pitch are not
  /// checked: the ground holds them, and a sparse scan's scatter in them is not a wrong minimum.
  double max_angular_acceleration = 300.0 * std::numbers::pi / 180.0;
  /// A degenerate match (degenerate_conditioning) has no evidence along the directions its
  /// Hessian leaves free: where it ends up along them is the solver's slide (the rings of a
  /// young reference, a mover), not the motion. Along each such direction its position is kept
  /// within max_acceleration dt^2 of the prediction (the prior's centre), the distance the
  /// acceleration check allows; within it the match stands. Flagged kOdomSlideBounded. Needs
  /// max_acceleration > 0, and a prediction clean matches measured: only once three matches in
  /// a row were clean, and not from a gap or a clock jump until three are again (a start whose
  /// every match is degenerate by the test, as on the ground seen from a sensor pitched 30 deg
  /// down, can be right while its prediction lags).
  bool bound_degenerate_slide = true;
  /// Weight of the pull of each match towards the constant-velocity prediction's position,
  /// relative to the scene's strongest constraint on it (ndt::PositionPrior; 0 = none). Applied
  /// when the prediction is trusted (the last scan matched cleanly). At the default, equal to
  /// degenerate_conditioning, the pull's curvature equals the scene's along a direction at the
  /// degeneracy threshold and exceeds it below.
  double prior_weight = 0.003;
  /// While the speed changes faster than this, m/s^2, the same way at two scans in a row
  /// (braking, pulling away), the prior's centre moves on by the change of speed (the smaller of
  /// the two): the constant-velocity prediction is a dt^2 / 2 off such a vehicle, and the pull
  /// would hold a weakly held match there. 0 = the centre always at constant velocity.
  double prior_acceleration_threshold = 2.0;
  /// For evaluation only (0, the default: off). Moves the initial guess of every scan's match by
  /// a pseudo-random amount of at most 0.5e-9 (m, rad) per coordinate drawn from this seed: a
  /// match that is well posed lands within its convergence tolerance of the same pose, so
  /// replays under a few seeds show how far a result depends on chance at the level of
  /// rounding (docs/accuracy.md, "Sensitivity").
  std::uint64_t guess_jitter_seed = 0;
};

/// Most test points one reference voxel can hold after downsampling to map_cell (about 600
/// with the defaults): the degrees of freedom the Cv chi-square table is filled for.
std::size_t cv_dof_capacity(const OdometryOptions& options);

enum OdometryFlags : std::uint32_t {
  kOdomFirstScan = 1u << 0,     ///< starts the trajectory: identity pose
  kOdomNotConverged = 1u << 1,  ///< iteration cap reached
  /// Not matched (too few points, more of the revolution's packets lost than received, or less
  /// than half of the turn swept: a stream's last revolution, one cut short by a gap); the
  /// prediction is reported.
  kOdomTooFewPoints = 1u << 2,
  kOdomDegenerate = 1u << 3,      ///< the geometry does not fix the pose (Cm reported as 0)
  kOdomScanIncomplete = 1u << 4,  ///< the scan was partial, lossy or cut
  kOdomSkipped = 1u << 5,  ///< a partial first revolution, not used: no pose (the next one starts)
  kOdomRematched = 1u << 6,  ///< matched again from the prediction (see max_acceleration)
  /// The fine match left the coarse pose by more than fine_reach: matched again without the cut.
  kOdomFineBeyondReach = 1u << 7,
  /// Matched on the finest pyramid grid alone: every reference scan was near, and
  /// pyramid_while_near is on or the match fell short of the pyramid (near_shortfall_fraction).
  kOdomPyramidOnly = 1u << 8,
  /// The coarse and fine matches fell short of the pyramid's motion while every reference scan
  /// was near (near_shortfall_fraction): the pyramid's pose, with kOdomPyramidOnly. Published
  /// as degraded: the fine grid disagreed with it.
  kOdomShortOfPyramid = 1u << 9,
  /// Degenerate with surface patches in the reference: matched again on eq 4's Gaussians
  /// (patches_clean_scans).
  kOdomWithoutPatches = 1u << 10,
  /// Too few reference voxels got enough of the scan's points for a Cv (ndt::CvOptions) to
  /// give Cm directions in 3-D (a sparse scan: 1200 rpm, heavy packet loss), while the match
  /// itself is well posed: Cm reported as 0, and the pose not flagged degenerate.
  kOdomCmUnmeasured = 1u << 11,
  /// Degenerate, and moved along a direction its Hessian leaves free back to within
  /// max_acceleration dt^2 of the prediction (bound_degenerate_slide).
  kOdomSlideBounded = 1u << 12,
};

struct OdometryResult {
  std::chrono::nanoseconds stamp{0};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< T_odom_sensor at the scan stamp
  double cm = 0.0;
  int coarse_iterations = 0;
  int fine_iterations = 0;        ///< naive mode: its single optimisation
  std::size_t voxels_before = 0;  ///< reference voxels the scan's points fell in (coarse pose)
  /// Of those, kept by the Cv cut (with kOdomFineBeyondReach the final fine match used them all).
  std::size_t voxels_after = 0;
  std::size_t points = 0;      ///< points matched (after downsampling)
  std::size_t raw_points = 0;  ///< points of the scan within range
  /// Smallest over largest eigenvalue of the final match's Hessian, translation block (see
  /// OdometryOptions::degenerate_conditioning); 0 when the scan was not matched.
  double conditioning = 0.0;
  /// Seconds since the last scan given a pose, as the motion model takes them: the stamps'
  /// difference, or one revolution across a jump of the sensor clock; 0 for the first scan.
  double dt = 0.0;
  std::uint32_t flags = 0;
};

class ConsensusOdometry {
 public:
  explicit ConsensusOdometry(const OdometryOptions& options);
  /// estimate(scan), then commit(): the whole step for one scan.
  OdometryResult process(const core::Scan& scan);
  /// The scan's pose, Cm and flags. The scan enters the reference (when due) only at commit(),
  /// so that a real-time caller can publish the pose first; the next estimate() commits a scan
  /// left pending. Between the two, reference_grid() and reference_points() do not hold it yet,
  /// and scan_points() already holds it.
  OdometryResult estimate(const core::Scan& scan);
  /// Adds the last estimated scan to the reference when it is due (nothing if already done).
  void commit();
  [[nodiscard]] const OdometryOptions& options() const { return options_; }
  /// Runs the chunks of the scorings, Cv's residuals and the deskews on `runner` (e.g. several
  /// threads; null = the calling thread). The results do not change (ndt::kScoreChunks).
  void set_score_runner(ndt::TaskRunner* runner) { lookup_cache_.set_runner(runner); }
  /// The last processed scan's points (downsampled to map_cell, deskewed with the final motion
  /// estimate), in the sensor frame at its stamp: what the mapper takes. Stale after a skipped
  /// scan.
  [[nodiscard]] std::span<const Eigen::Vector3d> scan_points() const {
    if (tilted_) return sensor_points_;
    return mid_active_ ? stamp_points_ : cv_points_;
  }
  /// The rotation from the sensor's frame into the odometry's own (level_frame; the identity
  /// for a sensor within 5 deg of level): reference_grid() and reference_points() lie in the
  /// odometry frame turned by it, so scan_points() go there by
  /// level_rotation() * pose * p for a reported pose.
  [[nodiscard]] const Eigen::Matrix3d& level_rotation() const { return level_rotation_; }
  /// Scans the reference holds now (local map: at most local_map_scans, and fewer when their
  /// points fill local_map_points), not counting those waiting for map_admit_distance.
  [[nodiscard]] std::size_t reference_scans() const { return in_grids_; }
  /// Scans taken into the local map that wait for map_admit_distance.
  [[nodiscard]] std::size_t pending_reference_scans() const { return history_size_ - in_grids_; }
  /// The reference grid and the points of the scans it holds now (odometry frame), appended to
  /// `out`: the grid's sums are those of exactly these points.
  [[nodiscard]] const ndt::VoxelGrid& reference_grid() const { return grid_; }
  void reference_points(std::vector<Eigen::Vector3d>& out) const;

 private:
  // Deskews `in` (sensor frame, timed) with `motion` over this scan's period into `out`: every
  // point moved to where the sensor was at the scan stamp, or once deskewing to mid-revolution
  // there, half a revolution after the stamp (mid_fraction() of `motion`).
  void deskew(std::span<const TimedPoint> in, const Eigen::Isometry3d& motion,
              std::vector<Eigen::Vector3d>& out) const;
  // Deskews the points the matches use (test_) over this scan's period with `motion`, which the
  // pose `base` implies: the base of the scan motion the matches solve for.
  void deskew_for(const Eigen::Isometry3d& motion, const core::Pose6& base);
  // Once deskewing to mid-revolution, where it lies as a fraction of this scan's deskew period
  // (half a revolution after the stamp); 0 before and without deskew_to_mid_scan.
  [[nodiscard]] double mid_fraction() const;
  // Deskews the map_cell points (cv_points_: Cv, Cm, the reference and the mapper) with `motion`.
  void deskew_scan(const Eigen::Isometry3d& motion);
  // The deskew motion over one period that `pose` implies: the motion from prev_pose_, with
  // extrapolate_ the velocity at the stamp (deskew_acceleration).
  Eigen::Isometry3d deskew_motion(const Eigen::Isometry3d& pose) const;
  // deskew_for with deskew_motion(pose).
  void deskew_at(const Eigen::Isometry3d& pose);
  // The scan's motion solved with its pose (ndt::ScanMotion) about the last deskew_for, or
  // nullptr when the scan is not deskewed.
  const ndt::ScanMotion* scan_motion() const;
  // Adds the current scan (cv_points_, placed at `pose`) to the reference when it is due.
  void update_reference(const Eigen::Isometry3d& pose);
  // Replaces the newest reference scan by `points` placed at `pose`.
  void replace_newest(const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose);
  core::Pose6 coarse_to_fine(const core::Pose6& x0);  // through the pyramid
  void jitter(core::Pose6& x);  // guess_jitter_seed: moves x by at most 0.5e-9 per coordinate
  // The best of a grid of offsets from x0 on the coarsest grid, in the plane of the level
  // surfaces (level_; the x-y plane for a level sensor): along `heading` up to
  // max(along_radius, start_search_radius), across it start_search_radius; grown one step
  // outwards at a time while the best lies on its edge, up to grow_to (m) from x0; of the best
  // offsets in separate places, the one whose solve on the coarsest grid ends lowest.
  struct StartSearch {
    core::Pose6 start;  // the chosen offset from x0
    core::Pose6 end;    // where its solve on the coarsest grid ended
    double score;       // and that solve's score
  };
  StartSearch search_start(const core::Pose6& x0, const Eigen::Vector3d& heading,
                           double along_radius, double grow_to = 0.0);
  bool start_search_on() const { return !pyramid_.empty() && options_.start_search_radius > 0.0; }
  // The spacing of the search's offsets: a quarter of the coarsest grid's voxel.
  double search_step() const { return 0.25 * pyramid_.front().options().voxel_size; }
  // After a gap in the data: search_start from the prediction (heading: its step from the last
  // pose), and with its turn over the gap cut (gap_turn_hypothesis_rad).
  core::Pose6 search_gap_start(const core::Pose6& x0, const Eigen::Isometry3d& predicted,
                               const Eigen::Vector3d& heading, double along_radius);
  // Adds `points` to the fine and the pyramid's grids (or removes them), on the scorings'
  // threads when there are any.
  void change_grids(std::span<const Eigen::Vector3d> points, bool add);
  void finalize_grids();
  // Coarse match, Cv cut, fine match (or the naive single match) from x0; fills res. With
  // kOdomPyramidOnly in res.flags, a match on the finest pyramid grid instead. With
  // near_pyramid (every reference scan near the pyramid's pose), a match falling short of that
  // pose's motion is replaced by the pyramid grid's (near_shortfall_fraction).
  bool match(const core::Pose6& x0, OdometryResult& res, const core::Pose6* near_pyramid);
  // Whether every scan in the reference grids lies within map_admit_distance of `pose`.
  [[nodiscard]] bool reference_near(const core::Pose6& pose) const;
  // Whether the match at `pose` fell short of the pyramid's motion to `pyramid_pose` from the
  // previous pose (near_shortfall_fraction).
  [[nodiscard]] bool short_of_pyramid(const core::Pose6& pose,
                                      const core::Pose6& pyramid_pose) const;
  // Whether a match's translation conditioning fails the degeneracy test (degenerate_conditioning;
  // a saddle or no Hessian included).
  [[nodiscard]] bool degenerate(double conditioning) const {
    return !(conditioning >= options_.degenerate_conditioning);
  }
  // bound_degenerate_slide: moves `pose` along the directions the last match's Hessian leaves
  // free to within `room` of the prior's centre; whether it moved.
  bool bound_slide(double room, Eigen::Isometry3d& pose) const;
  // Whether b lies farther than fine_reach from a (a turn counted at the scan's RMS range).
  [[nodiscard]] bool beyond_reach(const core::Pose6& a, const core::Pose6& b) const;
  ndt::ConsensusMeasure consensus_at(const core::Pose6& x, std::vector<double>& cv);

  OdometryOptions options_;
  Eigen::Vector3d level_ = Eigen::Vector3d::UnitZ();  // normal of the ground, odometry frame
  bool have_level_ = false;
  ndt::VoxelGrid grid_;
  std::vector<ndt::VoxelGrid> pyramid_;  // coarse grids of the reference
  bool have_motion_prior_ = false;
  ndt::ChiSquareTable chi2_;
  ndt::LookupCache lookup_cache_;
  ndt::ResidualAccumulator residual_accumulator_;
  Downsampler map_sampler_, scan_sampler_;
  std::vector<TimedPoint> raw_;                // in range, sensor frame
  std::vector<TimedPoint> map_src_;            // raw_ at map_cell
  std::vector<TimedPoint> scan_src_;           // map_src_ at scan_cell
  std::vector<Eigen::Vector3d> test_;          // scan_src_ deskewed: matched
  std::vector<double> lever_;                  // per test_ point: its ndt::ScanMotion lever
  double rms_range_ = 0.0;                     // of scan_src_, in the sensor frame
  ndt::ScanMotion scan_motion_;                // base: the pose test_ was deskewed for (deskew_for)
  bool solve_motion_ = false;                  // matches solve the scan's motion (deskew)
  double period_s_ = 0.1, to_period_ = 1.0;    // this scan's period; period over time step
  std::vector<Eigen::Vector3d> cv_points_;     // map_src_ deskewed: Cv, and added to the reference
  std::vector<Eigen::Vector3d> stamp_points_;  // deskew_to_mid_scan: cv_points_ at the stamp
  // level_frame: decided at the first scan used; the rotation into the level frame, and the
  // scan's points turned back into the sensor's frame for scan_points().
  bool level_decided_ = false;
  bool tilted_ = false;
  Eigen::Matrix3d level_rotation_ = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector3d> sensor_points_;
  OdometryResult estimate_levelled(const core::Scan& scan);
  void decide_level();
  Eigen::Isometry3d test_motion_ = Eigen::Isometry3d::Identity();    // last deskew_for motion
  Eigen::Isometry3d deskewed_with_ = Eigen::Isometry3d::Identity();  // last deskew_scan motion
  // The local map's scans in the odometry frame: a ring of up to local_map_scans entries, oldest
  // first, whose points lie one after the other in a circular buffer of local_map_points.
  std::span<const Eigen::Vector3d> history_points(const core::RingRegion& h) const {
    return std::span<const Eigen::Vector3d>(history_pool_).subspan(h.offset, h.count);
  }
  void drop_oldest();  // the oldest scan leaves the reference
  // Appends a scan to the local map; it waits for admit_pending to enter the grids.
  void push_history(const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose);
  // Adds the waiting scans, oldest first, that lie map_admit_distance or more from `next` (the
  // predicted pose of the next scan) to the grids; any when the grids hold none.
  void admit_pending(const Eigen::Isometry3d& next);
  std::vector<Eigen::Vector3d> history_pool_;
  std::vector<core::RingRegion> history_;
  std::vector<Eigen::Isometry3d> history_pose_;  // where each scan was taken
  // The local map's scans, oldest first; the first in_grids_ of them are in the grids, the
  // rest wait for admit_pending.
  std::size_t history_head_ = 0, history_size_ = 0, in_grids_ = 0;
  Eigen::Isometry3d last_keyframe_pose_ = Eigen::Isometry3d::Identity();
  // estimate() has left the reference update of its scan, at prev_pose_, to commit().
  bool reference_due_ = false;
  // The newest reference scan was added without a motion estimate (first scan): kept in the
  // sensor frame so it can be deskewed once the motion is known.
  bool newest_unskewed_ = false;
  std::vector<TimedPoint> newest_src_;
  std::vector<Eigen::Vector3d> scratch_;
  std::vector<std::uint8_t> mask_;
  std::vector<double> cv_;
  ndt::VoxelResiduals residuals_;
  bool have_prev_ = false, have_prev2_ = false;
  // Once deskewing to mid-revolution (mid_active_), the poses and motions chained here are those
  // there.
  Eigen::Isometry3d prev_pose_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d prev_motion_ = Eigen::Isometry3d::Identity();  // between the last two scans
  // deskew_acceleration for this scan: the deskew motion is (1 + extrapolate_) times the motion
  // from prev_pose_ less extrapolate_ times prev_motion_ (rotation vectors and translations per
  // period); 0 when the last match was not clean or the option is off, 0.5 for equal steps.
  double extrapolate_ = 0.0;
  std::size_t clean_run_ = 0;        // matches since the last one flagged degenerate
  bool degenerate_latched_ = false;  // the last scan matched was flagged degenerate
  bool slide_bound_armed_ = false;   // see kSlideBoundCleanRun (odometry.cpp)
  // The last scan was matched cleanly after an earlier one (so a velocity is known): see
  // max_acceleration.
  bool prediction_trusted_ = false;
  // deskew_to_mid_scan: deskewing to mid-revolution (from the first scan, or from the scan after
  // trusted_run_, the clean matches in a row, reached mid_scan_after_clean: the last pose then
  // moves on to its mid-revolution before that scan is matched).
  bool mid_active_ = false;
  std::size_t trusted_run_ = 0;
  ndt::PositionPrior prior_;  // the matches' pull towards this scan's prediction
  // The translation block of the last match's Hessian (match()): bound_slide reads it.
  Eigen::Matrix3d match_translation_hessian_ = Eigen::Matrix3d::Zero();
  // guess_jitter_seed's generator: the next counter value for core::mix64.
  std::uint64_t jitter_state_ = 0;
  std::chrono::nanoseconds prev_stamp_{0};
  std::chrono::nanoseconds last_seen_end_{0};  // the last firing of the last scan seen
  double silence_s_ = 0.0;     // the longest silence between scans since the last given a pose
  bool clock_jumped_ = false;  // since the last scan given a pose
  double revolution_s_ = 0.1;  // span of the last whole revolution
  double prev_period_s_ = 0.1;
  // The change of speed, m/s^2, over the last two steps beyond prior_acceleration_threshold
  // (else 0), and the one the prior's centre takes (the smaller of the last two, if alike).
  double last_change_ = 0.0, acceleration_ = 0.0;
};

}  // namespace cndt::slam
