#include "cndt/slam/odometry.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <vector>

#include "cndt/cli/cloud_io.hpp"
#include "cndt/output/pose_message.hpp"
#include "cndt/sim/lidar_sim.hpp"
#include "cndt/slam/sweep.hpp"
#include "cndt/slam/trajectory_eval.hpp"
#include "shared_data.hpp"
#include "sim_scans.hpp"
#include "temp_dir.hpp"

namespace cndt::slam {
namespace {

template <class Sink>
std::vector<sim::ScanStart> drive_street(double seconds, int movers, std::uint64_t seed,
                                         Sink&& sink) {
  return test::simulate_scans(sim::SceneKind::kStreet, seconds, movers, seed, sink);
}

// The simulator's scan starts from the first estimated pose on: the ground truth of `est`, pose
// for pose (at least as many).
std::vector<TimedPose> truth_from_first(const std::vector<sim::ScanStart>& starts,
                                        const std::vector<TimedPose>& est) {
  std::vector<TimedPose> gt;
  for (const auto& s : starts) {
    const double t = static_cast<double>(s.time_ns) * 1e-9;
    if (!est.empty() && t >= est.front().t - 1e-4) gt.push_back({t, s.pose});
  }
  return gt;
}

// Share of the matched scans of a drive flagged degenerate; checks that each flagged pose is
// reported with Cm = 0 and each other one has a well-conditioned Hessian, the first after a
// flagged one a ratio of at least degenerate_clear_conditioning.
double degenerate_share(sim::SceneKind kind, double seconds) {
  ConsensusOdometry odometry({});
  int matched = 0, degenerate = 0;
  bool after_flagged = false;
  test::simulate_scans(kind, seconds, 2, 1, [&](core::Scan& scan) {
    const OdometryResult r = odometry.process(scan);
    if ((r.flags & (kOdomSkipped | kOdomFirstScan | kOdomTooFewPoints)) != 0) return;
    ++matched;
    EXPECT_TRUE(std::isfinite(r.cm) && std::isfinite(r.conditioning));
    const bool flagged = (r.flags & kOdomDegenerate) != 0;
    if (flagged) {
      ++degenerate;
      EXPECT_EQ(r.cm, 0.0);
    } else {
      EXPECT_GE(r.conditioning, after_flagged ? odometry.options().degenerate_clear_conditioning
                                              : odometry.options().degenerate_conditioning);
      // Cm 0 only where too few voxels had a Cv to measure it.
      EXPECT_EQ(r.cm > 0.0, (r.flags & kOdomCmUnmeasured) == 0);
    }
    after_flagged = flagged;
  });
  EXPECT_GT(matched, 0);
  return matched > 0 ? static_cast<double>(degenerate) / matched : 0.0;
}

// A corridor (walls, floor and ceiling around the sensor, few features along it) does not fix
// the position along its axis: its poses are flagged degenerate with Cm = 0, while a street
// drive's are not. Without the report's hysteresis (degenerate_clear_conditioning) the share
// depended on whether the estimate stalled: 88-95 % of this drive's poses under most
// rounding-level jitter, 41 % in the unjittered replay, which happens to track the first 15 s
// (ATE 0.011 m), its ratio wandering about the threshold.
TEST(Odometry, FlagsTheCorridorDegenerateAndNotTheStreet) {
  const double corridor = degenerate_share(sim::SceneKind::kCorridor, 15.0);
  const double street = degenerate_share(sim::SceneKind::kStreet, 5.0);
  std::printf("degenerate poses: corridor %.0f %%, street %.0f %%\n", 100 * corridor, 100 * street);
  EXPECT_GE(corridor, 0.8);
  EXPECT_LE(street, 0.1);
}

// The default odometry on a simulated street drive at 8 m/s: about 0.8 m and up to 1 degree of
// pitch and yaw change between scans, with the ground in view (the rings that move with the
// sensor are the known trap of scan-to-scan NDT).
// The deskew references: the scan stamp (default); mid-revolution after ten clean matches and from
// the first scan, both with the acceleration check; and mid-revolution from the first scan without
// deskew refinements, where the start-up pair, matched undistorted, must still be matched again
// once both are deskewed with the motion that match measured.
TEST(Odometry, TracksAStreetDriveStartedAtSpeedFrameToFrame) {
  struct Setting {
    const char* name;
    bool mid;
    std::size_t mid_after;
    int refinements;
  };
  for (const Setting& setting :
       {Setting{"deskew to the stamp", false, 0, 2},
        Setting{"stamp, then mid-revolution", true, 10, 2},
        Setting{"mid-revolution from the first scan", true, 0, 2},
        Setting{"mid-revolution from the first scan, no deskew refinements", true, 0, 0}}) {
    SCOPED_TRACE(setting.name);
    OdometryOptions options;
    options.deskew_to_mid_scan = setting.mid;
    options.mid_scan_after_clean = setting.mid_after;
    options.max_acceleration = setting.mid ? 10.0 : 0.0;
    options.deskew_refinements = setting.refinements;
    ConsensusOdometry odometry(options);
    std::vector<TimedPose> est;
    int skipped = 0;
    const auto starts = drive_street(3.0, 2, 4, [&](core::Scan& scan) {
      const OdometryResult r = odometry.process(scan);
      EXPECT_TRUE(r.pose.matrix().allFinite());
      if ((r.flags & kOdomSkipped) != 0) {
        ++skipped;
        return;
      }
      est.push_back({static_cast<double>(scan.stamp.count()) * 1e-9, r.pose});
    });
    // Only the first scan, a partial revolution, is left out.
    EXPECT_EQ(skipped, 1);
    // The simulator's scan starts from the first tracked scan on.
    const std::vector<TimedPose> gt = truth_from_first(starts, est);
    ASSERT_GE(est.size(), 28u);
    ASSERT_GE(gt.size(), est.size());
    for (std::size_t i = 0; i < est.size(); ++i) ASSERT_NEAR(gt[i].t, est[i].t, 1e-4);
    // Frame-to-frame motion from the very first pair: the drive starts at full speed, so the first
    // match has no motion prior. Every pair is held to 10 cm (a start without a velocity used to
    // be off by 0.5-0.9 m per scan for several scans), the median to 2 cm. (Single pairs still
    // reach 5-8 cm, mostly in height: see the known weaknesses in docs/odometry.md.)
    std::vector<double> errors;
    for (std::size_t i = 0; i + 1 < est.size(); ++i) {
      const Eigen::Isometry3d dg = gt[i].pose.inverse() * gt[i + 1].pose;
      const Eigen::Isometry3d de = est[i].pose.inverse() * est[i + 1].pose;
      const Eigen::Isometry3d E = dg.inverse() * de;
      errors.push_back(E.translation().norm());
      if (i > 0) {
        EXPECT_GT(dg.translation().norm(), 0.5);  // the vehicle really moves that much
      }
    }
    std::sort(errors.begin(), errors.end());
    const double median = errors[errors.size() / 2];
    std::printf(
        "frame-to-frame translation error over %zu pairs: median %.4f m, p90 %.4f m, "
        "worst %.4f m\n",
        errors.size(), median, errors[errors.size() * 9 / 10], errors.back());
    EXPECT_LT(errors.back(), 0.10);
    EXPECT_LT(median, 0.02);
  }
}

// A slow vehicle in a corridor (1.2 m/s, 0.12 m per revolution): a scan's own ring pattern on
// floor and walls lines up with the next scans' when they are matched near its pose, and pulls
// their matches towards zero motion. With the default map_admit_distance the newest scans wait
// until the vehicle is away from them, and the estimated path keeps pace with the true one;
// taken in at once (0), the estimate stalls at the first scan that enters the map. The first
// second of the 60 s corridor of docs/accuracy.md (seed 1), whose first match finds the
// velocity (on other draws it does not, and neither setting tracks: docs/odometry.md). With the
// paper's voxel Gaussians (the default): with surface patches the rings pull no more, and the
// corridor's planes leave its axis to the openings (docs/odometry.md, "Surface patches").
double corridor_path_ratio(double admit_distance) {
  OdometryOptions o;
  o.surface_patches = false;
  o.map_admit_distance = admit_distance;
  ConsensusOdometry odometry(o);
  std::vector<TimedPose> est;
  std::size_t most_pending = 0;
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kCorridor, 60.0, 4, 1);
  const auto starts = test::simulate_scene(scene, 1.0, 1, [&](core::Scan& scan) {
    const OdometryResult r = odometry.process(scan);
    EXPECT_TRUE(r.pose.matrix().allFinite());
    most_pending = std::max(most_pending, odometry.pending_reference_scans());
    if ((r.flags & kOdomSkipped) == 0) {
      est.push_back({static_cast<double>(scan.stamp.count()) * 1e-9, r.pose});
    }
  });
  if (admit_distance > 0.0) {
    EXPECT_GT(most_pending, 0u);
  } else {
    EXPECT_EQ(most_pending, 0u);
  }
  const std::vector<TimedPose> gt = truth_from_first(starts, est);
  EXPECT_GE(est.size(), 8u);
  EXPECT_GE(gt.size(), est.size());
  if (est.size() < 2 || gt.size() < est.size()) return 0.0;
  const double truth = (gt.front().pose.inverse() * gt[est.size() - 1].pose).translation().norm();
  const double estimated = (est.front().pose.inverse() * est.back().pose).translation().norm();
  return estimated / truth;
}

TEST(Odometry, ASlowVehicleIsNotHeldByItsNewestReferenceScans) {
  const double waiting = corridor_path_ratio(OdometryOptions{}.map_admit_distance);
  const double at_once = corridor_path_ratio(0.0);
  std::printf(
      "corridor, first second: estimated over true distance %.3f (default), %.3f (at once)\n",
      waiting, at_once);
  EXPECT_NEAR(waiting, 1.0, 0.1);
  EXPECT_LT(at_once, 0.7);  // the pull this guards against
}

// A revolution that lost more packets than it received is not matched, however many points its
// sectors hold: it is flagged too-few-points and its pose is the constant-velocity prediction,
// which on this steady drive stays within a few centimetres of the truth; the scans after it
// are matched as before.
TEST(Odometry, AMostlyLostRevolutionIsNotMatched) {
  std::vector<core::Scan> scans;
  const auto starts = drive_street(2.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  ASSERT_GE(scans.size(), 15u);
  ConsensusOdometry odometry({});
  std::vector<OdometryResult> results;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    core::Scan scan = scans[i];
    if (i == 10) scan.lost_packets = scan.packets + 1;  // all its points kept
    results.push_back(odometry.process(scan));
  }
  EXPECT_NE(results[10].flags & kOdomTooFewPoints, 0u);
  for (std::size_t i = 2; i < results.size(); ++i) {
    if (i != 10 && scans[i].complete()) {  // not the stream's last, cut short
      EXPECT_EQ(results[i].flags & kOdomTooFewPoints, 0u) << "scan " << i;
    }
  }
  // Frame to frame against the truth, across the lost revolution and after it: scan i is
  // est[i - first].
  std::size_t first = 0;
  while (first < results.size() && (results[first].flags & kOdomSkipped) != 0) ++first;
  ASSERT_LE(first, 9u);
  std::vector<TimedPose> est;
  for (std::size_t i = first; i < results.size(); ++i) {
    est.push_back({static_cast<double>(scans[i].stamp.count()) * 1e-9, results[i].pose});
  }
  const std::vector<TimedPose> gt = truth_from_first(starts, est);
  ASSERT_GE(gt.size(), est.size());
  for (std::size_t k = 9 - first; k + 1 < est.size() && k + first < 14; ++k) {
    ASSERT_NEAR(gt[k].t, est[k].t, 1e-4);
    ASSERT_NEAR(gt[k + 1].t, est[k + 1].t, 1e-4);
    const Eigen::Isometry3d dg = gt[k].pose.inverse() * gt[k + 1].pose;
    const Eigen::Isometry3d de = est[k].pose.inverse() * est[k + 1].pose;
    EXPECT_LT((dg.inverse() * de).translation().norm(), 0.05)
        << "scans " << k + first << "-" << k + first + 1;
  }
}

// The second half of `scan` alone, flagged partial: what the assembler hands out where the data
// resumes mid-turn.
core::Scan resumed_mid_turn(const core::Scan& whole) {
  core::Scan scan = whole;
  const auto half = static_cast<std::ptrdiff_t>(scan.points.size() / 2);
  const auto skipped = scan.points[static_cast<std::size_t>(half)].time_ns;
  scan.points.erase(scan.points.begin(), scan.points.begin() + half);
  for (core::Point& p : scan.points) p.time_ns -= skipped;
  scan.stamp += std::chrono::nanoseconds(skipped);
  scan.flags |= core::kScanPartial;
  return scan;
}

// The first half of `scan` alone: a revolution ended early (by a gap or a clock jump).
core::Scan ended_mid_turn(const core::Scan& whole, std::uint32_t flag) {
  core::Scan scan = whole;
  scan.points.resize(scan.points.size() / 2);
  scan.end = scan.stamp + std::chrono::nanoseconds(scan.points.back().time_ns);
  scan.flags |= flag;
  return scan;
}

// The simulator's poses at the times `truth_t` (scan starts).
std::vector<Eigen::Isometry3d> truth_at(const std::vector<sim::ScanStart>& starts,
                                        const std::vector<double>& truth_t) {
  std::vector<Eigen::Isometry3d> gt;
  for (const double t : truth_t) {
    for (const auto& s : starts) {
      if (std::abs(static_cast<double>(s.time_ns) * 1e-9 - t) < 1e-4) gt.push_back(s.pose);
    }
  }
  return gt;
}

// A fresh odometry over the first `seconds` of `scene` (`seed` for the sensor's noise): the
// simulator's scan starts and the poses given (skipped scans left out, every pose finite), at
// the scans' stamps.
struct SceneRun {
  std::vector<sim::ScanStart> starts;
  std::vector<TimedPose> est;
  std::vector<double> truth_t;
  std::vector<std::uint32_t> flags;  // of each pose in est
};
SceneRun run_scene(const sim::Scene& scene, const sim::LidarSimOptions& sensor,
                   const OdometryOptions& options = {}) {
  ConsensusOdometry odometry(options);
  SceneRun run;
  run.starts = test::simulate_scene(scene, sensor, [&](core::Scan& scan) {
    const OdometryResult r = odometry.process(scan);
    EXPECT_TRUE(r.pose.matrix().allFinite());
    if ((r.flags & kOdomSkipped) != 0) return;
    const double t = static_cast<double>(scan.stamp.count()) * 1e-9;
    run.est.push_back({t, r.pose});
    run.truth_t.push_back(t);
    run.flags.push_back(r.flags);
  });
  return run;
}
// How far the estimate's motion from its first pose to its last lies from the truth's, m, with
// the truth at the stamps themselves (`t0` the sensor's start time, s): a scan whose first packets
// were lost starts later than the simulator's scan.
double end_error(const sim::Scene& scene, const SceneRun& run, double t0) {
  if (run.est.empty()) return std::numeric_limits<double>::infinity();
  const Eigen::Isometry3d dg = scene.sensor_pose(run.truth_t.front() - t0).inverse() *
                               scene.sensor_pose(run.truth_t.back() - t0);
  const Eigen::Isometry3d de = run.est.front().pose.inverse() * run.est.back().pose;
  return (dg.inverse() * de).translation().norm();
}
// A sensor turning at `rpm` for `seconds` (`seed` for its noise), losing `drop_rate` of packets.
sim::LidarSimOptions sensor_at(int rpm, double seconds, std::uint64_t seed,
                               double drop_rate = 0.0) {
  sim::LidarSimOptions o;
  o.rpm = rpm;
  o.duration_s = seconds;
  o.seed = seed;
  o.drop_rate = drop_rate;
  return o;
}
SceneRun run_scene(const sim::Scene& scene, double seconds, std::uint64_t seed) {
  sim::LidarSimOptions sensor;
  sensor.duration_s = seconds;
  sensor.seed = seed;
  return run_scene(scene, sensor);
}

// Every pair of consecutive poses in `est` (stamps in `truth_t`, the simulator's times) within
// 5 cm of the truth's motion; returns how many pairs span more than a second.
std::size_t expect_pairs_within_5cm(const std::vector<sim::ScanStart>& starts,
                                    const std::vector<TimedPose>& est,
                                    const std::vector<double>& truth_t) {
  const std::vector<Eigen::Isometry3d> gt = truth_at(starts, truth_t);
  EXPECT_EQ(gt.size(), est.size());
  std::size_t long_pairs = 0;
  for (std::size_t k = 0; k + 1 < est.size() && k + 1 < gt.size(); ++k) {
    const Eigen::Isometry3d dg = gt[k].inverse() * gt[k + 1];
    const Eigen::Isometry3d de = est[k].pose.inverse() * est[k + 1].pose;
    if (truth_t[k + 1] - truth_t[k] > 1.0) ++long_pairs;
    EXPECT_LT((dg.inverse() * de).translation().norm(), 0.05)
        << "scans at " << truth_t[k] << " and " << truth_t[k + 1];
  }
  return long_pairs;
}

// The odometry (default options unless given) over `scans` with those after `last` lost until
// `resume`, whose revolution the data resumes in mid-turn: the poses given, and their stamps in
// `truth_t`.
std::vector<TimedPose> odometry_across_gap(const std::vector<core::Scan>& scans, std::size_t last,
                                           std::size_t resume, std::vector<double>& truth_t,
                                           const OdometryOptions& options = {}) {
  ConsensusOdometry odometry(options);
  std::vector<TimedPose> est;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    if (i > last && i < resume) continue;
    const OdometryResult r = odometry.process(i == resume ? resumed_mid_turn(scans[i]) : scans[i]);
    EXPECT_TRUE(r.pose.matrix().allFinite()) << "scan " << i;
    if (i == resume) {
      EXPECT_NE(r.flags & kOdomSkipped, 0u);
    }
    if ((r.flags & kOdomSkipped) != 0) continue;
    const double t = static_cast<double>(scans[i].stamp.count()) * 1e-9;
    est.push_back({t, r.pose});
    truth_t.push_back(t);
  }
  return est;
}

// Two seconds without data (a cable pulled, a switch restarting): the revolution the data resumes
// in is a sector, and the vehicle has sped up or slowed down meanwhile. The sector is not
// matched, and the next whole revolution is found from a search along the way: the motion over
// the gap and every pair after it within 5 cm of the truth. (Matching the sector from the
// constant-velocity prediction put the first pose after a 3 s gap 2.3 m and 9 deg off.)
TEST(Odometry, ResumesAfterAGapInTheData) {
  std::vector<core::Scan> scans;
  const auto starts = drive_street(5.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  ASSERT_GE(scans.size(), 48u);
  constexpr std::size_t kLast = 19, kResume = 40;  // scans 20..39 are lost
  std::vector<double> truth_t;
  const std::vector<TimedPose> est = odometry_across_gap(scans, kLast, kResume, truth_t);
  EXPECT_EQ(expect_pairs_within_5cm(starts, est, truth_t), 1u);
  EXPECT_GT((starts[kResume + 1].pose.translation() - starts[kLast].pose.translation()).norm(),
            10.0);  // the gap is long enough to matter
}

// The same gap with the scans deskewed to mid-revolution: the deskew's period spans the last
// time step, the gap's for the first revolution after it, and mid-revolution lies half a
// revolution after the stamp, not half that period. (Taken as half the period, the pairs
// after this 2 s gap were 10 m off.)
TEST(Odometry, ResumesAfterAGapDeskewedToMidRevolution) {
  std::vector<core::Scan> scans;
  const auto starts = drive_street(5.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  ASSERT_GE(scans.size(), 48u);
  constexpr std::size_t kLast = 19, kResume = 40;  // scans 20..39 are lost
  OdometryOptions options;
  options.deskew_to_mid_scan = true;
  std::vector<double> truth_t;
  const std::vector<TimedPose> est = odometry_across_gap(scans, kLast, kResume, truth_t, options);
  EXPECT_EQ(expect_pairs_within_5cm(starts, est, truth_t), 1u);
}

// Data lost for 0.9 s while the vehicle ends a turn (a loop's corner, turning 2.3 deg per
// revolution until 4.4 s): the prediction carries that turn rate over the gap, 23 deg where the
// vehicle turned 12. Started from the turn halved and ended as well, the search finds the pose
// after the gap: every pair within 5 cm of the truth. (Searched from the carried turn alone, the
// motion over the gap was 2.83 m off, and the next pairs 0.29, 0.12 and 0.07 m.)
TEST(Odometry, ResumesAfterAGapInWhichTheTurnEnded) {
  std::vector<core::Scan> scans;
  const auto starts = test::simulate_scans(sim::SceneKind::kLoop, 6.0, 2, 3,
                                           [&](core::Scan& scan) { scans.push_back(scan); });
  ASSERT_GE(scans.size(), 58u);
  constexpr std::size_t kLast = 35, kResume = 44;  // scans 36..43 are lost
  std::vector<double> truth_t;
  const std::vector<TimedPose> est = odometry_across_gap(scans, kLast, kResume, truth_t);
  EXPECT_EQ(expect_pairs_within_5cm(starts, est, truth_t), 0u);
}

// The sensor clock steps 5 s back or on between two revolutions while the data keeps coming (a
// time source taking over): the assembler ends the scan there and flags it and the next one. The
// stamps after the step do not compare with those before, and the motion is still that of one
// revolution (OdometryResult::dt stays one revolution). (Before, a step back gave a negative time
// step and the trajectory ran off by kilometres; a step on was taken as 5 s of driving.)
TEST(Odometry, AClockJumpIsNotMotion) {
  std::vector<core::Scan> scans;
  const auto starts = drive_street(3.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  ASSERT_GE(scans.size(), 28u);
  constexpr std::size_t kJump = 15;
  for (const std::int64_t step_ns : {-5'000'000'000LL, 5'000'000'000LL}) {
    ConsensusOdometry odometry({});
    std::vector<TimedPose> est;
    std::vector<double> truth_t;
    auto shifted = [&](core::Scan scan) {
      scan.stamp += std::chrono::nanoseconds(step_ns);
      scan.end += std::chrono::nanoseconds(step_ns);
      return scan;
    };
    for (std::size_t i = 0; i < scans.size(); ++i) {
      // Revolution kJump: its first half ends at the step, its second half comes after it.
      const core::Scan scan = i < kJump    ? scans[i]
                              : i == kJump ? ended_mid_turn(scans[i], core::kScanTimeJump)
                                           : shifted(scans[i]);
      const OdometryResult r = odometry.process(scan);
      EXPECT_TRUE(r.pose.matrix().allFinite()) << "scan " << i;
      if (i == kJump) {
        core::Scan rest = shifted(resumed_mid_turn(scans[i]));
        rest.flags |= core::kScanTimeJump;
        EXPECT_NE(odometry.process(rest).flags & kOdomSkipped, 0u);
      }
      if ((r.flags & kOdomSkipped) != 0) continue;
      // The time step the motion model (and the published correction's blend) takes: one
      // revolution apart, the step of the clock left out.
      if (i > 1) {
        EXPECT_NEAR(r.dt, 0.1, 0.005) << "scan " << i;
      }
      est.push_back({static_cast<double>(scan.stamp.count()) * 1e-9, r.pose});
      truth_t.push_back(static_cast<double>(scans[i].stamp.count()) * 1e-9);
    }
    SCOPED_TRACE(step_ns);
    EXPECT_EQ(expect_pairs_within_5cm(starts, est, truth_t), 0u);
    EXPECT_GE(est.size(), scans.size() - 2);
  }
}

// A street drive that brakes to a standstill, stands for 4 s among moving traffic and pulls away:
// standing, the pose does not creep (the local map takes no scan, the movers are voted out);
// every pair, braking and pulling away included, within 5 cm of the truth.
TEST(Odometry, StandsStillThroughAStop) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 14.0, 4, 3);
  scene.stop_at_s = 2.0;  // braking 2-5 s, standing 5-9 s, pulling away 9-12 s
  scene.stop_s = 4.0;
  const SceneRun run = run_scene(scene, 14.0, 3);
  ASSERT_GE(run.est.size(), 130u);
  EXPECT_EQ(expect_pairs_within_5cm(run.starts, run.est, run.truth_t), 0u);
  // Standing: from 5.2 to 8.8 s after the start.
  const double t0 = static_cast<double>(run.starts.front().time_ns) * 1e-9;
  std::vector<Eigen::Isometry3d> standing;
  for (const TimedPose& e : run.est) {
    if (e.t > t0 + 5.2 && e.t < t0 + 8.8) standing.push_back(e.pose);
  }
  ASSERT_GE(standing.size(), 30u);
  for (const Eigen::Isometry3d& p : standing) {
    EXPECT_LT((standing.front().inverse() * p).translation().norm(), 0.01);
  }
}

// Started at 40 m/s (4 m per revolution, twice what the start search covers at first) on a
// street with traffic: the start search grows until the best offset lies inside it, and the
// first pairs of poses are within 10 cm of the truth's motion. With the search held at 2 m
// (max_speed 0) the first match lands 1.1 m short and the next ones follow it.
// The largest error of the motion between consecutive poses of `run`, each true motion
// asserted longer than `min_step` (m) when that is positive.
// `cndt eval` of a run against the simulator's truth.
EvalResult evaluate_run(const SceneRun& run) {
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  std::vector<TimedPose> truth;
  for (std::size_t i = 0; i < gt.size(); ++i) truth.push_back({run.truth_t[i], gt[i]});
  return evaluate(truth, run.est);
}

double worst_pair_error(const SceneRun& run, double min_step) {
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  EXPECT_EQ(gt.size(), run.est.size());
  double worst = 0.0;
  for (std::size_t k = 0; k + 1 < gt.size() && k + 1 < run.est.size(); ++k) {
    const Eigen::Isometry3d dg = gt[k].inverse() * gt[k + 1];
    const Eigen::Isometry3d de = run.est[k].pose.inverse() * run.est[k + 1].pose;
    if (min_step > 0.0) {
      EXPECT_GT(dg.translation().norm(), min_step);
    }
    worst = std::max(worst, (dg.inverse() * de).translation().norm());
  }
  return worst;
}

// A vehicle pitching on its suspension at twice the simulator's usual sway (pitch 1.2 deg at
// 2.3 s and 0.6 deg at 0.9 s): at 300 rpm its rate of pitch changes within a revolution. The
// mean velocity over the last period lags half a period behind the stamp; the velocity at the
// stamp from the last three poses deskews closer to the truth (deskew_acceleration).
TEST(Odometry, DeskewsWithTheVelocityAtTheStamp) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 6.0, 2, 42);
  scene.motion_scale = 2.0;
  const auto drive = [&](bool at_stamp) {
    OdometryOptions options;
    options.deskew_acceleration = at_stamp;
    return run_scene(scene, sensor_at(300, 6.0, 42), options);
  };
  const SceneRun run = drive(true);
  ASSERT_GE(run.est.size(), 25u);
  const double rms = evaluate_run(run).rpe_translation_rmse;
  const double rms_held = evaluate_run(drive(false)).rpe_translation_rmse;
  std::printf(
      "pair errors at 300 rpm, pitching: RMS %.4f m (velocity at the stamp), %.4f m "
      "(mean velocity of the last period)\n",
      rms, rms_held);
  EXPECT_LT(rms, 0.9 * rms_held);
  EXPECT_LT(worst_pair_error(run, 0.0), 0.05);
}

// A vehicle pitching the same way for 12 s, deskewed to mid-revolution (deskew_to_mid_scan, once
// ten clean matches have measured the velocity) against the default. Deskewed to the stamp, the
// pose there comes out as the true pitch smoothed over three scans, even with the velocity at the
// stamp: the body's pitch changes while a 0.2 s revolution lasts. At mid-revolution a deskew
// error distorts the scan symmetrically and leaves the pose where it is, so the turn from one
// pose to the next is nearer the truth.
TEST(Odometry, DeskewsToMidRevolutionAPitchingVehicle) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 12.0, 2, 42);
  scene.motion_scale = 2.0;
  const sim::LidarSimOptions sensor = sensor_at(300, 12.0, 42);
  OdometryOptions mid;
  mid.deskew_to_mid_scan = true;
  const SceneRun run = run_scene(scene, sensor, mid);
  ASSERT_GE(run.est.size(), 55u);
  const EvalResult mid_errors = evaluate_run(run);
  const EvalResult stamp_errors = evaluate_run(run_scene(scene, sensor));
  std::printf(
      "pair errors at 300 rpm, pitching: rotation RMS %.3f deg, translation %.4f m "
      "(mid-revolution); %.3f deg, %.4f m (stamp)\n",
      mid_errors.rpe_rotation_rmse_deg, mid_errors.rpe_translation_rmse,
      stamp_errors.rpe_rotation_rmse_deg, stamp_errors.rpe_translation_rmse);
  EXPECT_LT(mid_errors.rpe_rotation_rmse_deg, 0.85 * stamp_errors.rpe_rotation_rmse_deg);
  EXPECT_LT(worst_pair_error(run, 0.0), 0.05);
}

// A street drive with the sensor pitched 10 deg up on its mount (levelled by level_frame),
// deskewed to mid-revolution. From the first scan on, the start-up matches against a reference of
// one or two scans went off: worst pair in the first 4 s 0.74 m (0.19-0.53 m with the guesses
// jittered at the level of rounding; the 20 s drive ended 0.12-0.30 m off, against 0.004-0.009 m
// deskewed to the stamp). Deskewed to the stamp until ten clean matches have measured the
// velocity, the start is the stamp deskew's: 0.011 m.
TEST(Odometry, DeskewsToMidRevolutionOnlyOnceTheVelocityIsMeasured) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 4, 1);
  scene.mount = output::from_roll_pitch_yaw(0.0, -10.0 * std::numbers::pi / 180.0, 0.0);
  const auto worst = [&](std::size_t after) {
    OdometryOptions options;
    options.deskew_to_mid_scan = true;
    options.mid_scan_after_clean = after;
    const SceneRun run = run_scene(scene, sensor_at(600, 4.0, 1), options);
    EXPECT_GE(run.est.size(), 35u);
    return worst_pair_error(run, 0.0);
  };
  const double measured_first = worst(10);
  const double from_start = worst(0);
  std::printf("worst pair over 4 s: %.3f m after ten clean matches, %.3f m from the first scan\n",
              measured_first, from_start);
  EXPECT_LT(measured_first, 0.05);
}

// A campus drive braking from 15 m/s to a stop (3 s, up to 7.8 m/s^2) among pedestrians, the
// sensor in dual-return mode. The constant-velocity prediction runs 5-6 cm a revolution ahead of
// a vehicle braking this hard; with the position prior centred there, a match the scene held
// only weakly along the way stayed near it, the next matches followed and the pairs went 0.1-0.2
// m off (worst 0.204 m with prior_acceleration_threshold 0). While the speed changes faster than
// prior_acceleration_threshold the prior's centre moves on by that change.
TEST(Odometry, BrakingIsNotHeldToTheSpeedItHad) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 12, 61021, 0, 14.9);
  scene.sensor_height = 1.94;
  scene.motion_scale = 0.2;
  scene.stop_at_s = 5.2;  // braking 5.2-8.2 s
  scene.stop_s = 3.3;
  sim::LidarSimOptions sensor = sensor_at(600, 8.5, 61021);
  sensor.dual = true;
  const auto worst = [&](double threshold) {
    OdometryOptions options;
    options.prior_acceleration_threshold = threshold;
    const SceneRun run = run_scene(scene, sensor, options);
    EXPECT_GE(run.est.size(), 80u);
    return worst_pair_error(run, 0.0);
  };
  const double followed = worst(OdometryOptions{}.prior_acceleration_threshold);
  const double held = worst(0.0);
  std::printf(
      "worst pair braking: %.3f m (the prior's centre with the change of speed), %.3f m "
      "(at constant velocity)\n",
      followed, held);
  EXPECT_LT(followed, 0.05);
}

// A campus drive pulling away from rest among twelve pedestrians, with 2.2 cm of range noise and
// a fifth of the packets lost (`accuracy_random.sh --draw 63:24`, d63-21). Half a second into
// the pull-away, with the local map still the scans taken at rest, the match turned the sensor
// by 4.8 deg in one scan (the rings of a reference taken where the sensor stands turn
// into themselves and leave the yaw to the few other features) and the estimate never
// recovered (ATE 48 m over the 20 s drive). The angular acceleration check matches such a scan
// again from the prediction. The pull-away's pairs stay poor (0.47 m at worst: the rest scans'
// rings hold the next matches back for a few scans, "Starts from rest" in docs/odometry.md);
// asserted are the turns and where the drive ends.
TEST(Odometry, PullingAwayAMatchDoesNotTurnByDegreesInOneScan) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 12, 63021, 0, 14.7);
  scene.start_still_s = 2.4;
  sim::LidarSimOptions sensor = sensor_at(600, 5.0, 63021, 0.20);
  sensor.noise_m = 0.022;
  // A scan whose first packets were lost starts later than the simulator's scan: the truth at
  // the stamps themselves.
  const double t0 = static_cast<double>(sensor.start_time_ns) * 1e-9;
  struct Errors {
    double worst_turn_deg = 0.0, end_m = 0.0;
  };
  const auto errors = [&](double max_angular_acceleration) {
    OdometryOptions options;
    options.max_angular_acceleration = max_angular_acceleration;
    const SceneRun run = run_scene(scene, sensor, options);
    EXPECT_GE(run.est.size(), 45u);
    Errors e;
    const auto truth = [&](std::size_t k) { return scene.sensor_pose(run.truth_t[k] - t0); };
    for (std::size_t k = 0; k + 1 < run.est.size(); ++k) {
      const Eigen::Isometry3d dg = truth(k).inverse() * truth(k + 1);
      const Eigen::Isometry3d de = run.est[k].pose.inverse() * run.est[k + 1].pose;
      e.worst_turn_deg =
          std::max(e.worst_turn_deg, Eigen::AngleAxisd((dg.inverse() * de).linear()).angle() *
                                         180.0 / std::numbers::pi);
    }
    e.end_m = end_error(scene, run, t0);
    return e;
  };
  const Errors checked = errors(OdometryOptions{}.max_angular_acceleration);
  const Errors unchecked = errors(0.0);
  std::printf(
      "pulling away: worst turn of a pair %.2f deg, %.3f m off at the end (turns checked); "
      "%.2f deg, %.3f m (not checked)\n",
      checked.worst_turn_deg, checked.end_m, unchecked.worst_turn_deg, unchecked.end_m);
  EXPECT_LT(checked.worst_turn_deg, 1.5);
  EXPECT_LT(checked.end_m, 0.3);
}

// A campus drive pulling away from rest towards 10.7 m/s at 720 rpm, the body pitching and rolling
// 2.35 times as much as the scene's own (`accuracy_random.sh --draw 66:24`, d66-18). Its first
// metre is open ground, where the matches against the scans taken at rest are degenerate along
// the motion, and those matches slid by up to half a metre a scan (the prediction untrusted after
// each, so the acceleration check did not apply); the drive was lost (ATE 21.5 m over 20 s).
// A degenerate match's position along the directions left free stays within max_acceleration
// dt^2 of the prediction (bound_degenerate_slide). Asserted is where the drive's first 5 s end.
TEST(Odometry, ADegenerateMatchSlidesNoFartherThanTheVehicleCanAccelerate) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 2, 66018, 0, 10.7);
  scene.start_still_s = 0.7;
  scene.motion_scale = 2.35;
  sim::LidarSimOptions sensor = sensor_at(720, 5.0, 66018);
  sensor.noise_m = 0.004;
  const double t0 = static_cast<double>(sensor.start_time_ns) * 1e-9;
  struct Ends {
    double end_m = 0.0;
    std::size_t bounded = 0;
  };
  const auto drive = [&](bool bound) {
    OdometryOptions options;
    options.bound_degenerate_slide = bound;
    const SceneRun run = run_scene(scene, sensor, options);
    EXPECT_GE(run.est.size(), 50u);
    Ends e;
    for (const std::uint32_t f : run.flags) e.bounded += (f & kOdomSlideBounded) != 0;
    e.end_m = end_error(scene, run, t0);
    return e;
  };
  const Ends bounded = drive(true);
  const Ends free = drive(false);
  std::printf(
      "pulling away on open ground: %.3f m off after 5 s, %zu scans bounded; %.3f m without the "
      "bound\n",
      bounded.end_m, bounded.bounded, free.end_m);
  EXPECT_GE(bounded.bounded, 1u);
  EXPECT_EQ(free.bounded, 0u);
  EXPECT_LT(bounded.end_m, 2.0);
}

TEST(Odometry, StartsAtMotorwaySpeed) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 4, 5, 0, 40.0);
  const SceneRun run = run_scene(scene, 2.0, 5);
  ASSERT_GE(run.est.size(), 18u);
  const double worst = worst_pair_error(run, 3.0);
  std::printf("worst pair over the first 2 s: %.3f m\n", worst);
  EXPECT_LT(worst, 0.1);
}

// A campus drive from rest: standing 2 s among pedestrians, then pulling away over 3 s. While the
// vehicle creeps its first half metre the reference is the first scan alone, whose rings lie where
// the new scan's own do (docs/odometry.md, "Starts from rest"): the pairs there are the drive's
// worst, but standing does not creep and the estimate is not held at the start. Worst pair
// 0.041 m (0.019 m when the check below came in; later changes to the start moved it); 0.111 m
// before the matches falling short of the pyramid's motion took its pose.
TEST(Odometry, PullsAwayFromRest) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 9.0, 4, 6);
  scene.start_still_s = 2.0;
  const SceneRun run = run_scene(scene, 9.0, 6);
  ASSERT_GE(run.est.size(), 85u);
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  ASSERT_EQ(gt.size(), run.est.size());
  const double worst = worst_pair_error(run, 0.0);
  for (std::size_t k = 1; k < gt.size() && run.truth_t[k] - run.truth_t.front() < 1.9; ++k) {
    // standing
    EXPECT_LT((run.est.front().pose.inverse() * run.est[k].pose).translation().norm(), 0.01);
  }
  // Over the whole drive, along the ground (the height drifts as in every drive:
  // docs/odometry.md, "Tilt at the start").
  const Eigen::Isometry3d dg = gt.front().inverse() * gt.back();
  const Eigen::Isometry3d de = run.est.front().pose.inverse() * run.est.back().pose;
  const Eigen::Vector3d err = (dg.inverse() * de).translation();
  std::printf("worst pair %.3f m; after %.1f m, %.3f m off along the ground\n", worst,
              dg.translation().norm(), err.head<2>().norm());
  EXPECT_GT(dg.translation().norm(), 15.0);
  EXPECT_LT(err.head<2>().norm(), 0.1);
  EXPECT_LT(worst, 0.1);
}

// A sensor tilted 30 deg nose down on a car already driving: the forward motion has a large
// component along the sensor's z, and the start search looks along the ground the first scan
// shows instead of in the sensor's x-y plane (there the first pairs stayed at zero motion,
// 0.8 m off on this drive).
TEST(Odometry, StartsMovingWithTheSensorTiltedDown) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 4, 2);
  scene.mount = Eigen::AngleAxisd(30.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY())
                    .toRotationMatrix();
  const SceneRun run = run_scene(scene, 2.0, 2);
  ASSERT_GE(run.est.size(), 18u);
  const double worst = worst_pair_error(run, 0.5);
  std::printf("worst pair over the first 2 s: %.3f m\n", worst);
  EXPECT_LT(worst, 0.1);
}

// A sensor pitched 30 deg down: the first scan's ground gives the up direction and every scan is
// matched turned level (level_frame), so that the level patches and the start search see the
// ground as for a level sensor; poses and points are reported in the sensor's own frame. The
// campus drive of docs/accuracy.md's mounting table (seed 1) was lost from its start without it
// (ATE 21.8 m over 20 s; 0.035 m with it).
TEST(Odometry, ATiltedSensorIsMatchedLevelAndReportedInItsOwnFrame) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 4, 1);
  const double tilt = 30.0 * std::numbers::pi / 180.0;
  scene.mount = Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()).toRotationMatrix();
  sim::LidarSimOptions sensor;
  sensor.duration_s = 4.0;
  sensor.seed = 1;
  ConsensusOdometry odometry{OdometryOptions{}};
  SceneRun run;
  double placed = 0.0;  // share of the last scan's points that land in reference Gaussians
  run.starts = test::simulate_scene(scene, sensor, [&](core::Scan& scan) {
    const OdometryResult r = odometry.process(scan);
    if ((r.flags & kOdomSkipped) != 0) return;
    const double t = static_cast<double>(scan.stamp.count()) * 1e-9;
    run.est.push_back({t, r.pose});
    run.truth_t.push_back(t);
    run.flags.push_back(r.flags);
    // The mapper's contract: scan_points() go into the reference frame by level_rotation() *
    // pose (the reference holds this scan now, or scans a metre or less away).
    const Eigen::Isometry3d to_reference = Eigen::Isometry3d(odometry.level_rotation()) * r.pose;
    std::size_t in = 0;
    const auto pts = odometry.scan_points();
    for (const Eigen::Vector3d& p : pts) {
      const ndt::Voxel* v = odometry.reference_grid().find(to_reference * p);
      in += v != nullptr && v->has_gaussian ? 1 : 0;
    }
    placed = pts.empty() ? 0.0 : static_cast<double>(in) / static_cast<double>(pts.size());
  });
  ASSERT_GE(run.est.size(), 38u);
  const double turned = Eigen::AngleAxisd(odometry.level_rotation()).angle();
  const double worst = worst_pair_error(run, 0.0);
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  const double moved = (run.est.front().pose.inverse() * run.est.back().pose).translation().norm();
  const double truth = (gt.front().inverse() * gt.back()).translation().norm();
  std::printf(
      "turned level by %.2f deg; over 4 s %.2f m of %.2f m, worst pair %.3f m; %.2f of "
      "the last scan's points in reference Gaussians\n",
      turned * 180.0 / std::numbers::pi, moved, truth, worst, placed);
  EXPECT_NEAR(turned, tilt, 1.0 * std::numbers::pi / 180.0);
  EXPECT_TRUE(run.est.front().pose.isApprox(Eigen::Isometry3d::Identity()));
  // Unturned the estimate stalled: 5.5 m of 17.6 m, worst pair 0.68 m. Turned, the early
  // matches are flagged degenerate (the campus's ground seen from 30 deg) but keep pace.
  EXPECT_NEAR(moved, truth, 0.05 * truth);
  EXPECT_LT(worst, 0.3);
  // In the wrong frame (the level one with the sensor's pose) 0.02-0.08 of them.
  EXPECT_GT(placed, 0.5);
  // A level sensor is not turned at all.
  ConsensusOdometry level{OdometryOptions{}};
  const sim::Scene flat = sim::build_scene(sim::SceneKind::kCampus, 20.0, 4, 1);
  sensor.duration_s = 0.3;
  test::simulate_scene(flat, sensor, [&](core::Scan& scan) { level.process(scan); });
  EXPECT_TRUE(level.level_rotation() == Eigen::Matrix3d::Identity());
}

// The angle between two directions, in degrees.
double degrees_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

// A sensor mounted 5.2 deg off level and turned to face backwards on a street (a drive of
// random settings): the level surfaces' normal was first taken from every plane within 45 deg
// of the sensor's z, and planes at 10-45 deg put it 6.5 deg off instead of 5.2. Turned by that,
// the first matches tilted the estimate by 1.8 deg, which it kept (its height 4.8 m off after
// 20 s). The normal is now taken again from the planes near the first estimate.
TEST(Odometry, TheLevelFrameComesFromTheLevelPlanesAlone) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 0, 41003);
  constexpr double kDeg = std::numbers::pi / 180.0;
  // As `cndt sim --mount -4.9 -0.4 -116.5`.
  scene.mount = output::from_roll_pitch_yaw(-4.9 * kDeg, -0.4 * kDeg, -116.5 * kDeg);
  ConsensusOdometry odometry{OdometryOptions{}};
  SceneRun run;
  run.starts = test::simulate_scene(scene, sensor_at(720, 1.5, 41003), [&](core::Scan& scan) {
    const OdometryResult r = odometry.process(scan);
    if ((r.flags & kOdomSkipped) != 0) return;
    const double t = static_cast<double>(scan.stamp.count()) * 1e-9;
    run.est.push_back({t, r.pose});
    run.truth_t.push_back(t);
  });
  ASSERT_GE(run.est.size(), 15u);
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  ASSERT_EQ(gt.size(), run.est.size());
  // The world's up in the first scan's frame, as the odometry found it and as it is.
  const Eigen::Vector3d up_found = odometry.level_rotation().transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_true = gt.front().linear().transpose() * Eigen::Vector3d::UnitZ();
  // The estimate's up at the last scan against the truth's, the estimate placed on the truth by
  // its first pose.
  const Eigen::Matrix3d last = gt.front().linear() * run.est.back().pose.linear();
  const double tilt = degrees_between(last.transpose() * Eigen::Vector3d::UnitZ(),
                                      gt.back().linear().transpose() * Eigen::Vector3d::UnitZ());
  std::printf(
      "up found %.2f deg from the truth (which is %.2f deg off the sensor's z); tilt "
      "after 1.5 s %.2f deg\n",
      degrees_between(up_found, up_true), degrees_between(up_true, Eigen::Vector3d::UnitZ()), tilt);
  EXPECT_LT(degrees_between(up_found, up_true), 0.3);  // 1.3 deg with every plane within 45 deg
  EXPECT_LT(tilt, 0.5);                                // 1.8 deg then
}

// A street drive already at 8 m/s when the capture starts, the sensor mounted 0.97 m high,
// turned 24.8 deg and tilted 4 deg (not turned level: under 5 deg), 8 movers, dual returns,
// 2.2 cm of range noise (`cndt sim --scene street --seed 44019 --duration 20 --movers 8
// --height 0.97 --noise 0.022 --mount -2.5 -3.1 24.8 --dual`). Scored on the 2 m grid, the
// first scan's offsets form a valley along the street about 0.25 m wide, at 25 deg to the
// start search's 0.5 m grid of offsets: the offsets beside its floor scored worse than zero
// motion, the search started there, and the estimate covered 0.03-0.3 m per revolution of the
// true 0.8 m for 4.5 s (ATE 8.9 m over 20 s). The best offsets apart are now each solved on
// that grid and the lowest solve wins.
TEST(Odometry, TheStartSearchSolvesItsBestOffsets) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 8, 44019);
  constexpr double kDeg = std::numbers::pi / 180.0;
  scene.sensor_height = 0.97;
  scene.mount = output::from_roll_pitch_yaw(-2.5 * kDeg, -3.1 * kDeg, 24.8 * kDeg);
  sim::LidarSimOptions sensor = sensor_at(600, 1.0, 44019);
  sensor.dual = true;
  sensor.noise_m = 0.022;
  const SceneRun run = run_scene(scene, sensor);
  ASSERT_GE(run.est.size(), 8u);
  const double worst = worst_pair_error(run, 0.5);
  std::printf("worst pair over the first second: %.3f m\n", worst);
  EXPECT_LT(worst, 0.05);
}

// At 1200 rpm a street drive moves 0.4 m per revolution. On the first match (a one-scan
// reference) the Cv cut at the coarse pose left little that fixes the motion along the street,
// and the fine match slid 0.41 m from there to zero motion, where the scans' own rings line up;
// the estimate then stayed at the start. The fine match may not leave the coarse pose by more
// than fine_reach: beyond it, it is matched again with every voxel.
TEST(Odometry, TheFineMatchStaysNearTheCoarsePoseItsCutWasMadeAt) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 3.0, 4, 3);
  const SceneRun run = run_scene(scene, sensor_at(1200, 1.5, 3));
  ASSERT_GE(run.est.size(), 25u);
  const double worst = worst_pair_error(run, 0.3);
  std::printf("worst pair over the first 1.5 s at 1200 rpm: %.3f m\n", worst);
  EXPECT_LT(worst, 0.05);
}

// How many poses of `run` carry `flag`.
std::size_t scans_flagged(const SceneRun& run, std::uint32_t flag) {
  return static_cast<std::size_t>(std::count_if(
      run.flags.begin(), run.flags.end(), [flag](std::uint32_t f) { return (f & flag) != 0; }));
}

// A campus drive at 1200 rpm moves 0.2 m per revolution: the first scans are matched against a
// reference of scans taken less than 0.5 m away, whose ring arcs on the fine grid lie where the
// new scan has its own. There the coarse match went from the pyramid's 0.19 m (true 0.20 m) to
// 0.14 m, the next ones stayed short, and the start was lost (pairs 0.1-0.6 m off). With
// pyramid_while_near, while every reference scan is that near, the pose comes from the finest
// pyramid grid.
// With the default's level patches its degenerate matches are matched again without them
// (0.045 m); with patches regardless of degeneracy the start was lost (0.82 m; docs/odometry.md,
// "Level patches").
TEST(Odometry, ASlowStartIsMatchedOnThePyramidUntilTheFirstScanIsBehind) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 4.0, 4, 5);
  OdometryOptions options;
  options.pyramid_while_near = true;
  const SceneRun run = run_scene(scene, sensor_at(1200, 2.0, 5), options);
  const std::size_t pyramid_only = scans_flagged(run, kOdomPyramidOnly);
  ASSERT_GE(run.est.size(), 35u);
  const double worst = worst_pair_error(run, 0.1);
  std::printf(
      "worst pair over the first 2 s of a campus drive at 1200 rpm: %.3f m; %zu scans "
      "on the pyramid alone\n",
      worst, pyramid_only);
  EXPECT_GE(pyramid_only, 1u);
  EXPECT_LE(pyramid_only, 4u);  // until the vehicle is 0.5 m from the first scan
  EXPECT_LT(worst, 0.08);
}

// A campus drive at 4 m/s (0.4 m per revolution) matched from its first scans: the pyramid put
// the second scan 0.39 m on, and the coarse and fine matches against the one-scan reference
// pulled it back to 0.05 m (the fine grid's ring arcs), and the next scans likewise, with turns
// of 4 deg. The match falling that far short of the pyramid's motion while the reference is
// near, the pyramid's pose is taken; the scans whose matches agree with it keep the fine grid.
// Worst pair 0.028 m (0.437 m with near_shortfall_fraction = 0).
TEST(Odometry, AStartAtSpeedIsNotPulledBackByTheFirstScansRings) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 4.0, 2, 105);
  const SceneRun run = run_scene(scene, sensor_at(600, 2.0, 105));
  const std::size_t pyramid_only = scans_flagged(run, kOdomPyramidOnly);
  ASSERT_GE(run.est.size(), 18u);
  const double worst = worst_pair_error(run, 0.3);
  std::printf(
      "worst pair over the first 2 s of a campus drive at 4 m/s: %.3f m; %zu of %zu scans on "
      "the pyramid alone\n",
      worst, pyramid_only, run.est.size());
  EXPECT_GE(pyramid_only, 1u);  // the check took the pyramid's pose
  EXPECT_LE(pyramid_only, 2u);  // only while the first scan is within 0.5 m
  EXPECT_LT(worst, 0.05);
}

// The angle between the estimate's up and the truth's at the last pose, the estimate placed on
// the truth by its first pose: the tilt the drive picked up.
double tilt_at_end_deg(const SceneRun& run) { return evaluate_run(run).tilt_end_deg; }

// A street drive at 3.2 m/s with the sensor 1.19 m high, 420 rpm: the ground's ring arcs lie
// dense and near, and tilting the sensor by a few tenths of a degree lines its far rings up
// with the reference scans'. As eq 4's Gaussians they tilt the estimate by 0.1-1.0 deg in 4 s
// (it moves with rounding from build to build); as level patches (the default) they hold
// height, roll and pitch only: 0.03 deg.
TEST(Odometry, LevelPatchesKeepALowSlowSensorLevel) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 20.0, 2, 7001, 0, 3.2);
  sim::Scene low = scene;
  low.sensor_height = 1.19;
  OdometryOptions gaussians;
  gaussians.surface_patches = false;
  const SceneRun with = run_scene(low, sensor_at(420, 4.0, 7001));
  const SceneRun without = run_scene(low, sensor_at(420, 4.0, 7001), gaussians);
  ASSERT_GE(with.est.size(), 25u);
  const double tilt = tilt_at_end_deg(with), tilt_gaussians = tilt_at_end_deg(without);
  std::printf("tilt after 4 s: %.2f deg with level patches, %.2f deg without; worst pair %.3f m\n",
              tilt, tilt_gaussians, worst_pair_error(with, 0.0));
  EXPECT_LT(tilt, 0.3);
  EXPECT_LT(worst_pair_error(with, 0.0), 0.05);
}

// Level patches leave the position along the ground to the rest of the scene. A campus drive at
// 1200 rpm (0.2 m per revolution, sparse rings), pulling away from rest with the sensor turned
// 129 deg on its mount: 3 s in, the rest was too little, the match slid 0.3 m, flagged
// degenerate, and the estimate was lost (22 m off after 20 s). A match degenerate with patches
// is matched again on eq 4's Gaussians, and the patches wait for three clean matches.
TEST(Odometry, ADegenerateMatchWithLevelPatchesIsMatchedAgainWithout) {
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 2, 108);
  scene.mount = (Eigen::AngleAxisd(129.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()) *
                 Eigen::AngleAxisd(0.1 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY()) *
                 Eigen::AngleAxisd(-1.8 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()))
                    .toRotationMatrix();
  scene.start_still_s = 1.1;
  OdometryOptions regardless;
  regardless.patches_clean_scans = 0;
  const SceneRun run = run_scene(scene, sensor_at(1200, 5.0, 108));
  const SceneRun without = run_scene(scene, sensor_at(1200, 5.0, 108), regardless);
  const double worst = worst_pair_error(run, 0.0);
  std::printf(
      "worst pair over 5 s: %.3f m, %zu matches again without patches; %.3f m with patches "
      "regardless\n",
      worst, scans_flagged(run, kOdomWithoutPatches), worst_pair_error(without, 0.0));
  EXPECT_GE(scans_flagged(run, kOdomWithoutPatches), 1u);
  EXPECT_LT(worst, 0.05);
}

// Packets lost inside a revolution leave it whole: its span is still the rotor's period. Taken
// for an incomplete scan, the start assumed 0.1 s (600 rpm) and at 1200 rpm deskewed and
// predicted with half the true velocity.
TEST(Odometry, StartsAt1200RpmWithPacketsLost) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kStreet, 4.0, 4, 1);
  const SceneRun run = run_scene(scene, sensor_at(1200, 2.0, 1, 0.05));
  ASSERT_GE(run.est.size(), 25u);
  const double worst = worst_pair_error(run, 0.3);
  std::printf("worst pair over the first 2 s at 1200 rpm, 5 %% of packets lost: %.3f m\n", worst);
  EXPECT_LT(worst, 0.05);
}

// A campus at 1200 rpm is sparse: while the vehicle stands, at most a few reference voxels get
// the ten test points a Cv needs, and Cm, computed from those alone, cannot be measured (0).
// Flagged degenerate for it, no match counted as clean, the prediction was never trusted and the
// level patches never started; pulling away at 10 m/s, the drive this one is cut from
// (`accuracy_random.sh --draw 12:30`, d12-06) was lost 2.2 s in (here 11.3 m off after 11.5 m;
// over its 20 s an ATE of 52.7 m). Such poses are flagged as not measured, and the well-posed
// matches count as clean. Whether the pull-away is then tracked is left to chance: replayed with
// four guess_jitter_seed values (`cndt replay --jitter-seed`), it was lost within 2.2-3.5 s
// under three of them with either deskew velocity (docs/odometry.md, "Deskew velocity"), so
// only the flags are asserted here.
TEST(Odometry, ASparseScanWithoutCmIsNotCountedDegenerate) {
  const double deg = std::numbers::pi / 180.0;
  sim::Scene scene = sim::build_scene(sim::SceneKind::kCampus, 20.0, 2, 12006, 0, 10.1);
  scene.mount = (Eigen::AngleAxisd(-90.9 * deg, Eigen::Vector3d::UnitZ()) *
                 Eigen::AngleAxisd(2.9 * deg, Eigen::Vector3d::UnitX()))
                    .toRotationMatrix();
  scene.start_still_s = 1.4;
  const SceneRun run = run_scene(scene, sensor_at(1200, 4.0, 12006));
  ASSERT_GE(run.est.size(), 75u);
  const std::size_t unmeasured = scans_flagged(run, kOdomCmUnmeasured);
  const std::size_t degenerate = scans_flagged(run, kOdomDegenerate);
  const double worst = worst_pair_error(run, 0.0);
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  ASSERT_EQ(gt.size(), run.est.size());
  const Eigen::Isometry3d dg = gt.front().inverse() * gt.back();
  const Eigen::Isometry3d de = run.est.front().pose.inverse() * run.est.back().pose;
  const double end_error = (dg.inverse() * de).translation().norm();
  std::printf(
      "%zu of %zu poses with Cm not measured, %zu degenerate; worst pair %.3f m; after %.1f m, "
      "%.3f m off\n",
      unmeasured, run.est.size(), degenerate, worst, dg.translation().norm(), end_error);
  EXPECT_GE(unmeasured, 20u);
  EXPECT_EQ(scans_flagged(run, kOdomDegenerate | kOdomCmUnmeasured), degenerate + unmeasured);
  EXPECT_GT(dg.translation().norm(), 10.0);
}

// A stream's last revolution is cut where the data ends. Less than half a turn of it (here a
// tenth, at 300 rpm on the loop) left few sectors to fix the pose: matched, it landed 0.11 m
// off. It gets the constant-velocity prediction and the flag that it was not matched.
TEST(Odometry, AShortLastRevolutionIsNotMatched) {
  const sim::Scene scene = sim::build_scene(sim::SceneKind::kLoop, 4.0, 4, 6);
  const SceneRun run = run_scene(scene, sensor_at(300, 4.0, 6));
  const std::vector<std::uint32_t>& flags = run.flags;
  ASSERT_GE(run.est.size(), 19u);
  EXPECT_NE(flags.back() & kOdomScanIncomplete, 0u);
  EXPECT_NE(flags.back() & kOdomTooFewPoints, 0u);
  const std::vector<Eigen::Isometry3d> gt = truth_at(run.starts, run.truth_t);
  ASSERT_EQ(gt.size(), run.est.size());
  const std::size_t n = gt.size();
  const Eigen::Isometry3d dg = gt[n - 2].inverse() * gt[n - 1];
  const Eigen::Isometry3d de = run.est[n - 2].pose.inverse() * run.est[n - 1].pose;
  const double last = (dg.inverse() * de).translation().norm();
  std::printf("last pair of a 4 s loop at 300 rpm, the last revolution cut short: %.3f m\n", last);
  EXPECT_LT(last, 0.05);
}

// The reference grid holds exactly the points of the scans in the local map: rebuilt from them,
// every voxel has the same count and sums (up to the round-off of adding and removing).
void expect_grid_holds(const ConsensusOdometry& odometry) {
  std::vector<Eigen::Vector3d> points;
  odometry.reference_points(points);
  const ndt::VoxelGrid& grid = odometry.reference_grid();
  ndt::VoxelGridOptions fo = grid.options();
  fo.capacity = grid.size() + 16;
  fo.resident = false;
  ndt::VoxelGrid fresh(fo);
  for (const auto& p : points) ASSERT_TRUE(fresh.add(p));
  std::size_t in_grid = 0;
  for (const ndt::Voxel& v : grid.voxels()) {
    in_grid += v.count;
    if (v.count == 0) continue;
    const ndt::Voxel* f = fresh.find(v.key);
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(f->count, v.count);
    ASSERT_LT((f->sum - v.sum).norm(), 1e-6 * (1.0 + f->sum.norm()));
  }
  ASSERT_EQ(in_grid, points.size());
}

// The evaluation jitter (guess_jitter_seed) moves each match's initial guess by at most half a
// nanometre: a seed gives the same poses every time and another seed other poses (the option
// takes effect). How far they move is what the option measures, not a property to assert: on
// this 2 s drive the start-up scans differ by centimetres (docs/accuracy.md, "Sensitivity").
TEST(Odometry, GuessJitterIsRepeatableAndTakesEffect) {
  std::vector<core::Scan> scans;
  drive_street(2.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  auto run = [&](std::uint64_t seed) {
    OdometryOptions o;
    o.guess_jitter_seed = seed;
    ConsensusOdometry odometry(o);
    std::vector<Eigen::Isometry3d> poses;
    for (const core::Scan& scan : scans) {
      const OdometryResult r = odometry.process(scan);
      if ((r.flags & kOdomSkipped) == 0) poses.push_back(r.pose);
    }
    return poses;
  };
  const auto plain = run(0), a = run(7), again = run(7), b = run(8);
  ASSERT_GE(plain.size(), 15u);
  ASSERT_EQ(a.size(), plain.size());
  ASSERT_EQ(b.size(), plain.size());
  bool a_differs = false, b_differs = false;
  double largest = 0.0;
  std::size_t where = 0;
  for (std::size_t i = 0; i < plain.size(); ++i) {
    ASSERT_TRUE(a[i].matrix().allFinite() && b[i].matrix().allFinite());
    EXPECT_TRUE(a[i].matrix() == again[i].matrix()) << "scan " << i;
    a_differs = a_differs || !(a[i].matrix() == plain[i].matrix());
    b_differs = b_differs || !(b[i].matrix() == a[i].matrix());
    for (const auto* other : {&a, &b}) {
      const double d = ((*other)[i].translation() - plain[i].translation()).norm();
      if (d > largest) {
        largest = d;
        where = i;
      }
    }
  }
  std::printf(
      "guess jitter: largest position difference to the plain run %.3f m (pose %zu of %zu)\n",
      largest, where, plain.size());
  EXPECT_TRUE(a_differs);
  EXPECT_TRUE(b_differs);
}

// estimate() leaves the scan's entry into the reference to commit() (a real-time caller
// publishes the pose in between): until then the reference is that of the scans before, and
// the poses equal process()'s, whether commit() is called or left to the next estimate().
TEST(Odometry, EstimateThenCommitEqualsProcess) {
  std::vector<core::Scan> scans;
  drive_street(2.0, 2, 3, [&](core::Scan& scan) { scans.push_back(scan); });
  OdometryOptions o;
  ConsensusOdometry whole(o), split(o), uncommitted(o);
  std::size_t entered = 0;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const OdometryResult a = whole.process(scans[i]);
    const std::size_t before = split.reference_scans();
    std::vector<Eigen::Vector3d> held_before, held_after;
    split.reference_points(held_before);
    const OdometryResult b = split.estimate(scans[i]);
    split.reference_points(held_after);
    EXPECT_EQ(split.reference_scans(), before) << "scan " << i;
    EXPECT_EQ(held_after.size(), held_before.size()) << "scan " << i;
    split.commit();
    split.commit();  // nothing left to do
    expect_grid_holds(split);
    EXPECT_EQ(split.reference_scans(), whole.reference_scans()) << "scan " << i;
    if (split.reference_scans() > before) ++entered;
    const OdometryResult c = uncommitted.estimate(scans[i]);
    EXPECT_TRUE(a.pose.matrix() == b.pose.matrix()) << "scan " << i;
    EXPECT_TRUE(a.pose.matrix() == c.pose.matrix()) << "scan " << i;
    EXPECT_EQ(a.cm, b.cm);
    EXPECT_EQ(a.cm, c.cm);
    EXPECT_EQ(a.flags, b.flags);
  }
  EXPECT_GE(entered, 5u);  // the reference grew at commit(), not at estimate()
}

// The local map's scans share one buffer of local_map_points, fewer than local_map_scans would
// fill: new scans push the oldest ones out and the buffer wraps around, also past scans left at
// its end. After every scan the grid holds exactly the points of the scans in the map. With
// room for about thirteen scans (200k points) tracking stays as good as with a local map of that
// many scans. With room for a few (50k points; frame-to-frame errors then reach 0.25-0.32 m
// whether the buffer or the scan count bounds the map) and scans thinned to a third, a half or
// all of their points in turn, scans are left at the end of the buffer when it wraps: that run
// checks the bookkeeping only (it failed when those scans were not made to leave first).
TEST(Odometry, LocalMapBoundedByPointsWrapsAndStillTracks) {
  for (const std::size_t pool : {std::size_t{50'000}, std::size_t{200'000}}) {
    OdometryOptions o;
    o.max_scan_points = 40'000;
    o.local_map_points = pool;
    ConsensusOdometry odometry(o);
    std::vector<TimedPose> est;
    std::size_t most_scans = 0;
    std::size_t n = 0;
    const auto starts = drive_street(4.0, 2, 4, [&](core::Scan& scan) {
      if (pool < 100'000) {
        // Scans of varying size (all, every other, every third point), so that scans are left
        // at the end of the buffer when it wraps.
        const std::size_t keep = 1 + n++ % 3;
        std::size_t w = 0;
        for (std::size_t i = 0; i < scan.points.size(); i += keep)
          scan.points[w++] = scan.points[i];
        scan.points.resize(w);
      }
      const OdometryResult r = odometry.process(scan);
      ASSERT_TRUE(r.pose.matrix().allFinite());
      ASSERT_TRUE(std::isfinite(r.cm));
      most_scans = std::max(most_scans, odometry.reference_scans());
      expect_grid_holds(odometry);
      if ((r.flags & kOdomSkipped) == 0) {
        est.push_back({static_cast<double>(scan.stamp.count()) * 1e-9, r.pose});
      }
    });
    ASSERT_GE(est.size(), 38u);
    if (pool < 100'000) {
      EXPECT_LE(most_scans, 8u);  // 50k points of 5-18k-point scans
      continue;
    }
    EXPECT_LE(most_scans, 14u);  // 200k points of 14-18k-point scans
    EXPECT_GE(most_scans, 10u);
    const std::vector<TimedPose> gt = truth_from_first(starts, est);
    ASSERT_GE(gt.size(), est.size());
    std::vector<double> errors;
    for (std::size_t i = 0; i + 1 < est.size(); ++i) {
      const Eigen::Isometry3d dg = gt[i].pose.inverse() * gt[i + 1].pose;
      const Eigen::Isometry3d de = est[i].pose.inverse() * est[i + 1].pose;
      errors.push_back((dg.inverse() * de).translation().norm());
    }
    std::sort(errors.begin(), errors.end());
    std::printf(
        "bounded local map: at most %zu scans; frame-to-frame error median %.4f m, "
        "worst %.4f m\n",
        most_scans, errors[errors.size() / 2], errors.back());
    EXPECT_LT(errors.back(), 0.10);
    EXPECT_LT(errors[errors.size() / 2], 0.02);
  }
}

// Paper Figure 9: with the reference held, Cm falls as the test scan is moved away from its true
// pose, in x (0 to 2 m) and in roll (0 to 5 deg). Street scene, a pair of consecutive scans.
TEST(Figure9, CmFallsWithThePerturbation) {
  std::vector<std::vector<std::pair<Eigen::Vector3d, double>>> scans;  // point, seconds
  const auto starts = drive_street(1.2, 4, 9, [&](core::Scan& scan) {
    std::vector<std::pair<Eigen::Vector3d, double>> pts;
    for (const auto& p : scan.points) {
      const Eigen::Vector3d v(p.x, p.y, p.z);
      if (v.norm() > 1.0) pts.emplace_back(v, static_cast<double>(p.time_ns) * 1e-9);
    }
    scans.push_back(std::move(pts));
  });
  ASSERT_GE(scans.size(), 9u);
  // Undistort scan i with the true motion to the next scan start, as the paper's data was.
  auto deskewed = [&](std::size_t i) {
    const Eigen::Isometry3d m = starts[i].pose.inverse() * starts[i + 1].pose;
    const double period = static_cast<double>(starts[i + 1].time_ns - starts[i].time_ns) * 1e-9;
    const Eigen::AngleAxisd aa(m.linear());
    std::vector<Eigen::Vector3d> out;
    for (const auto& [v, t] : scans[i]) {
      const double a = t / period;
      out.push_back(Eigen::AngleAxisd(aa.angle() * a, aa.axis()) * v + a * m.translation());
    }
    return out;
  };
  // The reference is what cndt matches against: the recent scans merged (here k-4 .. k, placed
  // with the true poses in scan k's frame). A single VLP-16 scan leaves most ground voxels with
  // one ring arc, whose Gaussian another ring sample never agrees with.
  const std::size_t k = 6;
  ndt::VoxelGrid reference({0.5, 400'000, 5, 0.001});
  for (std::size_t j = k - 4; j <= k; ++j) {
    const Eigen::Isometry3d T_k_j = starts[k].pose.inverse() * starts[j].pose;
    for (const auto& v : deskewed(j)) reference.add(T_k_j * v);
  }
  reference.finalize();
  const std::vector<Eigen::Vector3d> test = deskewed(k + 1);
  const Eigen::Isometry3d T = starts[k].pose.inverse() * starts[k + 1].pose;
  const ndt::ChiSquareTable chi2(100'000);
  std::vector<double> xs, rolls;
  for (int i = 0; i <= 20; ++i) {
    xs.push_back(0.1 * i);
    rolls.push_back(0.25 * i * 3.14159265358979 / 180.0);
  }
  for (const auto& [axis, values] : {std::pair{0, xs}, std::pair{3, rolls}}) {
    const auto samples = sweep_cm(reference, test, T, axis, values, chi2);
    std::vector<double> cms;
    for (const auto& s : samples) cms.push_back(s.cm);
    const double rho = spearman(values, cms);
    std::printf("axis %d: Cm %.3f at 0, %.3f at the largest perturbation, Spearman %.3f\n", axis,
                cms.front(), cms.back(), rho);
    EXPECT_LE(rho, -0.9);
    EXPECT_GT(cms.front(), cms.back());
  }
}

// A real drive: 100 consecutive KITTI HDL-64E scans (PCD, about 120k points each, no firing
// times, no ground truth). The trajectory must be continuous and its length within 10 % of the
// rough 2-D ICP estimate stored beside the scans.
TEST(KittiDrive, ContinuousAndAsLongAsTheRoughEstimate) {
  CNDT_REQUIRE_SHARED(archive, "kitti-hdl64-udacity-drive/data_2_frames_000-099.tar.xz");
  CNDT_REQUIRE_SHARED(rough,
                      "kitti-hdl64-udacity-drive/rough_2d_icp_estimate_NOT_GROUND_TRUTH.txt");
  const test::TempDir dir;
  const std::string cmd = "tar xJf '" + archive + "' -C '" + dir.path().string() + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  auto folder = cli::list_cloud_folder(dir.file("data_2_frames_000-099"), 0.1);
  ASSERT_TRUE(folder) << folder.error().message;
  ASSERT_EQ(folder.value().files.size(), 100u);
  // The rough estimate's length over the same 99 steps (section data_2, frames 1-99).
  double rough_length = 0.0;
  {
    std::ifstream in(rough);
    std::string line;
    bool data2 = false;
    int steps = 0;
    while (std::getline(in, line)) {
      if (line.rfind("## data_2", 0) == 0) data2 = true;
      if (!data2 || line.empty() || line[0] == '#' || steps == 99) continue;
      double dx = 0, dy = 0;
      ASSERT_EQ(std::sscanf(line.c_str(), "%*s dx=%lf dy=%lf", &dx, &dy), 2) << line;
      rough_length += std::hypot(dx, dy);
      ++steps;
    }
    ASSERT_EQ(steps, 99);
  }
  ConsensusOdometry odometry({});
  core::Scan scan(150'000);
  std::vector<Eigen::Vector3d> positions;
  for (std::size_t i = 0; i < folder.value().files.size(); ++i) {
    ASSERT_FALSE(cli::read_cloud(folder.value().files[i], scan).has_value());
    scan.stamp = std::chrono::nanoseconds(static_cast<std::int64_t>(i) * 100'000'000);
    const OdometryResult r = odometry.process(scan);
    ASSERT_TRUE(r.pose.matrix().allFinite());
    positions.push_back(r.pose.translation());
  }
  double length = 0.0, longest = 0.0;
  for (std::size_t i = 1; i < positions.size(); ++i) {
    const double step = (positions[i] - positions[i - 1]).norm();
    length += step;
    longest = std::max(longest, step);
  }
  std::printf("length %.2f m (rough estimate %.2f m), longest step %.3f m\n", length, rough_length,
              longest);
  EXPECT_NEAR(length, rough_length, 0.1 * rough_length);
  EXPECT_LT(longest, 1.0);  // 3-6 m/s at 10 Hz: no jump
}

TEST(Spearman, RanksWithTies) {
  const std::vector<double> a = {1, 2, 3, 4, 5};
  const std::vector<double> b = {5, 4, 4, 2, 1};
  EXPECT_NEAR(spearman(a, b), -0.975, 1e-3);
  EXPECT_NEAR(spearman(a, a), 1.0, 1e-12);
}

}  // namespace
}  // namespace cndt::slam
