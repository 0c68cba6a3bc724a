// The simulator's capture decodes back to the simulator's own points and scan times.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <numbers>
#include <sstream>

#include "cndt/cli/capture.hpp"
#include "cndt/sim/lidar_sim.hpp"
#include "cndt/vlp16/decoder.hpp"
#include "sim_scans.hpp"
#include "slurp.hpp"
#include "temp_dir.hpp"

namespace cndt::sim {
namespace {

// Tolerance of one decoded point: half a 2 mm range step, plus the azimuth error that 0.01 deg
// block azimuths allow after interpolation (under 0.015 deg), plus float rounding.
double tolerance(double range) { return 1.0e-3 + range * 0.015 * 3.14159265 / 180.0 + 1e-5; }

struct PointCheck {
  std::size_t compared = 0;
  double worst_ratio = 0.0;  // largest error / tolerance
};

PointCheck compare_points(const Scene& scene, const LidarSimOptions& o, std::size_t packets) {
  LidarSimulator sim(scene, o);
  vlp16::DecoderOptions dopt;
  dopt.min_range_m = 0.0;
  dopt.max_range_m = 200.0;
  const vlp16::Decoder dec(vlp16::Model::kVlp16, dopt);
  PointCheck check;
  SimPacket pkt;
  std::vector<TruePoint> truth;
  vlp16::DecodedPacket dp;
  for (std::size_t k = 0; k < packets && sim.next(pkt, &truth); ++k) {
    vlp16::PacketHeader h;
    EXPECT_EQ(vlp16::validate_data_packet(core::ByteSpan(pkt.payload), h),
              vlp16::PacketError::kNone);
    dec.decode(core::ByteSpan(pkt.payload), h, dp);
    EXPECT_EQ(static_cast<std::size_t>(dp.point_count), truth.size()) << "packet " << k;
    const std::size_t n = std::min(truth.size(), static_cast<std::size_t>(dp.point_count));
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = dp.points[i];
      const auto& t = truth[i];
      EXPECT_EQ(p.return_type, t.type);
      const double err = (Eigen::Vector3d(p.x, p.y, p.z) - t.sensor_point).norm();
      check.worst_ratio = std::max(check.worst_ratio, err / tolerance(t.range));
      // The decoded time is the firing time the simulator used.
      EXPECT_EQ(p.time_ns, static_cast<std::uint32_t>(t.sequence * 55296 + t.laser * 2304));
    }
    check.compared += n;
    truth.clear();
  }
  return check;
}

TEST(SimRoundTrip, SingleReturnPointsComeBackWithinQuantisation) {
  const Scene scene = build_scene(SceneKind::kStreet, 3.0, 4, 7);
  LidarSimOptions o;
  o.duration_s = 3.0;
  o.seed = 7;
  const PointCheck c = compare_points(scene, o, 800);
  EXPECT_GT(c.compared, 200'000u);
  EXPECT_LE(c.worst_ratio, 1.0);
  std::printf("single return: %zu points, worst error %.2f of tolerance\n", c.compared,
              c.worst_ratio);
}

TEST(SimRoundTrip, DualReturnPointsComeBackWithinQuantisation) {
  const Scene scene = build_scene(SceneKind::kCampus, 2.0, 4, 3);  // foliage gives two echoes
  LidarSimOptions o;
  o.duration_s = 2.0;
  o.seed = 3;
  o.dual = true;
  const PointCheck c = compare_points(scene, o, 1500);
  EXPECT_GT(c.compared, 200'000u);
  EXPECT_LE(c.worst_ratio, 1.0);
}

struct Decoded {
  cli::CaptureReport report;
  std::vector<std::int64_t> gt_times;
};

Decoded simulate_and_decode(const test::TempDir& dir, SceneKind kind, const LidarSimOptions& o) {
  const Scene scene = build_scene(kind, o.duration_s, 4, o.seed);
  auto sum = write_simulation(scene, o, dir.path().string());
  EXPECT_TRUE(sum) << (sum ? "" : sum.error().message);
  Decoded d;
  std::ifstream gt(dir.file("groundtruth.tum"));
  for (std::string line; std::getline(gt, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string t;
    ls >> t;
    const auto dot = t.find('.');
    d.gt_times.push_back(std::stoll(t.substr(0, dot)) * 1'000'000'000 +
                         std::stoll(t.substr(dot + 1)));
  }
  auto r = cli::read_capture(dir.file("capture.pcap"), {});
  EXPECT_TRUE(r);
  d.report = r.value();
  return d;
}

// Index of the ground-truth start within one firing sequence of `t`, or -1.
int match(const std::vector<std::int64_t>& gt, std::int64_t t) {
  for (std::size_t i = 0; i < gt.size(); ++i) {
    if (std::llabs(gt[i] - t) <= 55'296) return static_cast<int>(i);
  }
  return -1;
}

TEST(SimRoundTrip, ScanTimesMatchTheGroundTruth) {
  test::TempDir dir;
  LidarSimOptions o;
  o.duration_s = 3.0;
  const Decoded d = simulate_and_decode(dir, SceneKind::kStreet, o);
  ASSERT_EQ(d.report.scans.size(), d.gt_times.size());
  // The packet clock counts whole microseconds, so stamps agree to within one.
  for (std::size_t i = 0; i < d.gt_times.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(d.report.scans[i].stamp.count() - d.gt_times[i]), 0.0, 1000.0)
        << "scan " << i;
  }
  EXPECT_EQ(d.report.assembler.lost_packets, 0u);
  EXPECT_EQ(d.report.driver.position_packets, d.report.pcap.position);
  EXPECT_EQ(d.report.driver.rejected_total(), 0u);
}

TEST(SimRoundTrip, PacketLossIsCountedAndScanTimesHold) {
  test::TempDir dir;
  LidarSimOptions o;
  o.duration_s = 5.0;
  o.drop_rate = 0.05;
  o.seed = 11;
  const Decoded d = simulate_and_decode(dir, SceneKind::kLoop, o);
  const auto expected_packets = static_cast<std::uint64_t>(std::ceil(5.0 / 1327.104e-6));
  const std::uint64_t received = d.report.driver.data_packets;
  const std::uint64_t dropped = expected_packets - received;
  EXPECT_NEAR(static_cast<double>(dropped) / static_cast<double>(expected_packets), 0.05, 0.015);
  // Every gap inside the stream is found; only losses before the first packet are invisible.
  EXPECT_LE(d.report.assembler.lost_packets, dropped);
  EXPECT_GE(d.report.assembler.lost_packets + 3, dropped);
  int matched = 0;
  for (const auto& s : d.report.scans) {
    if (match(d.gt_times, s.stamp.count()) >= 0) {
      ++matched;
    } else {
      // A scan can only start late when the packet at its cut was lost.
      EXPECT_NE(s.flags & core::kScanPacketLoss, 0u);
    }
  }
  EXPECT_GE(matched, static_cast<int>(d.gt_times.size()) * 8 / 10);
}

// An outage loses every packet for its length: the assembler sees one gap, cuts the revolution
// in progress there and starts a partial one where the data resumes; the ground truth keeps
// every scan.
TEST(SimRoundTrip, AnOutageIsOneGapTheAssemblerCuts) {
  test::TempDir dir;
  LidarSimOptions o;
  o.duration_s = 3.0;
  o.outage_start_s = 1.23;
  o.outage_s = 0.5;
  const Decoded d = simulate_and_decode(dir, SceneKind::kStreet, o);
  EXPECT_EQ(d.report.assembler.gaps, 1u);
  EXPECT_NEAR(static_cast<double>(d.report.assembler.lost_packets), 0.5 / 1327.104e-6, 2.0);
  EXPECT_NEAR(static_cast<double>(d.gt_times.size()), 31.0, 1.0);
  const auto t0 = o.start_time_ns;
  int cut = 0, resumed = 0;
  for (const auto& s : d.report.scans) {
    const double from = static_cast<double>(s.stamp.count() - t0) * 1e-9;
    const double to = static_cast<double>(s.end.count() - t0) * 1e-9;
    EXPECT_FALSE(to > 1.23 + 1e-3 && from < 1.73 - 1e-3) << "a scan from " << from << " to " << to;
    if ((s.flags & core::kScanGapCut) != 0) {
      ++cut;
      EXPECT_NEAR(to, 1.23, 2e-3);
    }
    if ((s.flags & core::kScanPartial) != 0 && from > 1.0) {
      ++resumed;
      EXPECT_NEAR(from, 1.73, 2e-3);
    }
  }
  EXPECT_EQ(cut, 1);
  EXPECT_EQ(resumed, 1);
}

// A clock step is no outage: every packet arrives, the assembler counts one clock jump and no
// loss, and the scans after the step carry stamps that much later.
TEST(SimRoundTrip, AClockStepIsAJumpNotLoss) {
  for (const double step : {-2.0, 0.7}) {
    test::TempDir dir;
    LidarSimOptions o;
    o.duration_s = 3.0;
    o.clock_step_at_s = 1.23;
    o.clock_step_s = step;
    const Decoded d = simulate_and_decode(dir, SceneKind::kStreet, o);
    SCOPED_TRACE(step);
    EXPECT_EQ(d.report.assembler.time_jumps, 1u);
    EXPECT_EQ(d.report.assembler.gaps, 0u);
    EXPECT_EQ(d.report.assembler.lost_packets, 0u);
    const std::int64_t shift = std::llround(step * 1e9);
    int stepped = 0;
    bool past = false;  // the scan the step began has come
    for (const auto& s : d.report.scans) {
      if ((s.flags & core::kScanTimeJump) != 0) {
        past = past || (s.flags & core::kScanPartial) != 0;
        continue;
      }
      if (s.flags != 0) continue;
      // Every whole scan starts where a true scan starts, on the clock it was stamped with.
      EXPECT_GE(match(d.gt_times, s.stamp.count() - (past ? shift : 0)), 0) << s.stamp.count();
      stepped += past ? 1 : 0;
    }
    EXPECT_NEAR(stepped, 17, 1);  // the whole turns after 1.23 s
  }
}

TEST(SimRoundTrip, DualReturnCaptureAcrossTheHour) {
  test::TempDir dir;
  LidarSimOptions o;
  o.duration_s = 2.0;
  o.dual = true;
  o.start_time_ns = 1'767'229'199'500'000'000;  // 00:59:59.5, so the sensor clock wraps
  const Decoded d = simulate_and_decode(dir, SceneKind::kStreet, o);
  EXPECT_EQ(d.report.driver.hour_rollovers, 1u);
  EXPECT_EQ(d.report.assembler.time_jumps, 0u);
  EXPECT_EQ(*d.report.driver.return_mode, vlp16::ReturnMode::kDual);
  ASSERT_EQ(d.report.scans.size(), d.gt_times.size());
  for (std::size_t i = 0; i < d.gt_times.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(d.report.scans[i].stamp.count() - d.gt_times[i]), 0.0, 1000.0)
        << "scan " << i;
  }
}

TEST(SimRoundTrip, RotationSpeedIsHonoured) {
  test::TempDir dir;
  LidarSimOptions o;
  o.duration_s = 2.0;
  o.rpm = 1200;
  const Decoded d = simulate_and_decode(dir, SceneKind::kCorridor, o);
  EXPECT_NEAR(d.report.driver.rpm(), 1200.0, 1.0);
  EXPECT_NEAR(static_cast<double>(d.report.scans.size()), 41.0, 1.0);
}

TEST(SimRoundTrip, DeterministicPerSeed) {
  test::TempDir a, b, c;
  LidarSimOptions o;
  o.duration_s = 1.0;
  o.drop_rate = 0.02;
  const Scene s1 = build_scene(SceneKind::kCampus, 1.0, 4, 5);
  const Scene s2 = build_scene(SceneKind::kCampus, 1.0, 4, 5);
  o.seed = 5;
  ASSERT_TRUE(write_simulation(s1, o, a.path().string()));
  ASSERT_TRUE(write_simulation(s2, o, b.path().string()));
  EXPECT_EQ(test::slurp(a.file("capture.pcap")), test::slurp(b.file("capture.pcap")));
  EXPECT_EQ(test::slurp(a.file("groundtruth.tum")), test::slurp(b.file("groundtruth.tum")));
  o.seed = 6;
  const Scene s3 = build_scene(SceneKind::kCampus, 1.0, 4, 6);
  ASSERT_TRUE(write_simulation(s3, o, c.path().string()));
  EXPECT_NE(test::slurp(a.file("capture.pcap")), test::slurp(c.file("capture.pcap")));
}

// Largest change of the sensor's yaw rate from one 50 ms step to the next, deg/s^2. A steered
// vehicle's heading turns smoothly: the rate ramps into and out of a corner.
double peak_yaw_acceleration(const Scene& scene, double duration_s) {
  constexpr double kStep = 0.05;
  auto yaw = [&](double t) {
    const Eigen::Matrix3d R = scene.sensor_pose(t).linear();
    return std::atan2(R(1, 0), R(0, 0));
  };
  auto wrap = [](double a) { return std::remainder(a, 2.0 * std::numbers::pi); };
  double peak = 0.0, last_rate = 0.0;
  for (int k = 0; k * kStep < duration_s; ++k) {
    const double t = k * kStep;
    const double rate = wrap(yaw(t + kStep) - yaw(t)) / kStep;
    if (k > 0) peak = std::max(peak, std::abs(rate - last_rate) / kStep);
    last_rate = rate;
  }
  return peak * 180.0 / std::numbers::pi;
}

// A stop: the sensor stands still for the stop's length, its speed falls to 0 and comes back
// without a jump (at most 0.3 m/s from one 50 ms step to the next at 8 m/s), and after it the
// drive goes on as before, the stop's length later.
TEST(SimScene, AStopHoldsTheSensorStillBetweenSmoothRamps) {
  Scene plain = build_scene(SceneKind::kStreet, 20.0, 0, 2);
  Scene stopping = plain;
  stopping.stop_at_s = 4.0;
  stopping.stop_s = 5.0;
  const double r = stopping.stop_ramp_s;
  const Eigen::Vector3d still = stopping.sensor_pose(4.0 + r).translation();
  for (double t = 4.0 + r; t <= 9.0 + r; t += 0.5) {
    EXPECT_LT((stopping.sensor_pose(t).translation() - still).norm(), 1e-9) << t;
  }
  constexpr double kStep = 0.05;
  double last_speed = plain.speed, peak_change = 0.0;
  for (double t = kStep; t < 20.0; t += kStep) {
    const double speed = (stopping.sensor_arc(t) - stopping.sensor_arc(t - kStep)) / kStep;
    peak_change = std::max(peak_change, std::abs(speed - last_speed));
    last_speed = speed;
  }
  EXPECT_LT(peak_change, 0.3);
  EXPECT_LT(
      (stopping.sensor_pose(18.0).translation() - plain.sensor_pose(18.0 - 5.0 - r).translation())
          .norm(),
      1e-6);
}

// A start from rest: the sensor stands (its sway frozen) until start_still_s, its speed then
// rises without a jump, and once up to speed the drive is the plain one, later by the standing
// time and half the ramp.
TEST(SimScene, AStartFromRestStandsThenPullsAwaySmoothly) {
  const Scene plain = build_scene(SceneKind::kStreet, 20.0, 0, 2);
  Scene resting = plain;
  resting.start_still_s = 2.0;
  const double r = resting.stop_ramp_s;
  const Eigen::Isometry3d first = resting.sensor_pose(0.0);
  for (double t = 0.0; t <= 2.0; t += 0.25) {
    const Eigen::Isometry3d d = first.inverse() * resting.sensor_pose(t);
    EXPECT_LT(d.translation().norm(), 1e-12) << t;
    EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 1e-12) << t;
  }
  EXPECT_GT((resting.sensor_pose(2.5).translation() - first.translation()).norm(), 0.0);
  constexpr double kStep = 0.05;
  double last_speed = 0.0, peak_change = 0.0;
  for (double t = kStep; t < 20.0; t += kStep) {
    const double speed = (resting.sensor_arc(t) - resting.sensor_arc(t - kStep)) / kStep;
    peak_change = std::max(peak_change, std::abs(speed - last_speed));
    last_speed = speed;
  }
  EXPECT_LT(peak_change, 0.3);
  EXPECT_LT((resting.sensor_pose(12.0).translation() -
             plain.sensor_pose(12.0 - 2.0 - 0.5 * r).translation())
                .norm(),
            1e-6);
}

// A speed given replaces the scene's own: the mean over the 17 s cycle of +-20 % is that speed,
// and the path is long enough for the whole drive. Without one the street keeps its 8 m/s.
TEST(SimScene, AGivenSpeedReplacesTheScenesOwn) {
  const Scene plain = build_scene(SceneKind::kStreet, 20.0, 0, 2);
  const Scene fast = build_scene(SceneKind::kStreet, 20.0, 0, 2, 0, 25.0);
  EXPECT_DOUBLE_EQ(plain.speed, 8.0);
  EXPECT_NEAR(plain.sensor_arc(17.0) / 17.0, 8.0, 1e-9);
  EXPECT_NEAR(fast.sensor_arc(17.0) / 17.0, 25.0, 1e-9);
  EXPECT_GT(fast.path.length(), fast.sensor_arc(20.0) + 50.0);
  // Still moving at the end of the drive: the path has not run out under it.
  const double last =
      (fast.sensor_pose(20.0).translation() - fast.sensor_pose(19.9).translation()).norm();
  EXPECT_NEAR(last, 0.1 * fast.speed, 0.3 * 0.1 * fast.speed);
}

// Without body motion the sensor keeps its height and stays level: only the path turns it.
TEST(SimScene, WithoutBodyMotionTheSensorStaysLevelAtItsHeight) {
  Scene scene = build_scene(SceneKind::kStreet, 10.0, 0, 2);
  double moving = 0.0;
  for (double t = 0.0; t < 10.0; t += 0.37) {
    moving =
        std::max(moving, std::abs(scene.sensor_pose(t).translation().z() - scene.sensor_height));
  }
  EXPECT_GT(moving, 0.005);  // the scene's own sways
  scene.motion_scale = 0.0;
  for (double t = 0.0; t < 10.0; t += 0.37) {
    const Eigen::Isometry3d T = scene.sensor_pose(t);
    EXPECT_NEAR(T.translation().z(), scene.sensor_height, 1e-12) << t;
    EXPECT_NEAR((T.linear() * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-12) << t;  // level
  }
}

// A mount turns the sensor on the vehicle and nothing else: tilted 10 deg nose down, its x axis
// points 10 deg below the horizon all along a drive without body motion, from the same place.
TEST(SimScene, AMountTurnsTheSensorOnTheVehicle) {
  Scene level = build_scene(SceneKind::kStreet, 10.0, 0, 2);
  level.motion_scale = 0.0;
  Scene tilted = level;
  const double tilt = 10.0 * 3.14159265358979323846 / 180.0;
  tilted.mount = Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (double t = 0.0; t < 10.0; t += 0.37) {
    const Eigen::Isometry3d a = level.sensor_pose(t), b = tilted.sensor_pose(t);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-12) << t;
    EXPECT_NEAR((b.linear() * Eigen::Vector3d::UnitX()).z(), -std::sin(tilt), 1e-12) << t;
    EXPECT_TRUE((a.linear().transpose() * b.linear()).isApprox(tilted.mount, 1e-12)) << t;
  }
}

// `cndt sim --height`: the sensor rides at the scene's sensor_height above the ground, and the
// ground returns, decoded, lie that far below it.
TEST(SimScene, TheSensorHeightSetsWhereTheGroundIs) {
  Scene low = build_scene(SceneKind::kStreet, 2.0, 0, 2);
  low.motion_scale = 0.0;
  low.sensor_height = 0.5;
  for (double t = 0.0; t < 2.0; t += 0.37) {
    EXPECT_NEAR(low.sensor_pose(t).translation().z(), 0.5, 1e-12) << t;
  }
  LidarSimOptions o;
  o.duration_s = 0.3;
  o.noise_m = 0.0;
  std::size_t ground = 0;
  double lowest = 0.0, highest = -1e9;
  test::simulate_scene(low, o, [&](core::Scan& scan) {
    for (const core::Point& p : scan.points) {
      // Near the sensor and below it: the road (the lowest laser, -15 deg, meets it 1.9 m out).
      if (std::hypot(p.x, p.y) > 4.0 || p.z > -0.25) continue;
      ++ground;
      lowest = std::min(lowest, static_cast<double>(p.z));
      highest = std::max(highest, static_cast<double>(p.z));
    }
  });
  std::printf("%zu ground returns within 4 m, z from %.4f to %.4f m\n", ground, lowest, highest);
  EXPECT_GT(ground, 500u);
  EXPECT_NEAR(lowest, -0.5, 0.01);
  EXPECT_NEAR(highest, -0.5, 0.01);
}

TEST(SimScene, YawRateIsContinuousThroughCorners) {
  // The loop's corners have a 20 m radius: 20 deg/s at 7 m/s, entered over a few metres.
  const Scene loop = build_scene(SceneKind::kLoop, 60.0, 0, 1);
  const Scene campus = build_scene(SceneKind::kCampus, 60.0, 0, 1);
  const double loop_peak = peak_yaw_acceleration(loop, 60.0);
  const double campus_peak = peak_yaw_acceleration(campus, 60.0);
  RecordProperty("loop_peak_yaw_acceleration_deg_s2", std::to_string(loop_peak));
  RecordProperty("campus_peak_yaw_acceleration_deg_s2", std::to_string(campus_peak));
  EXPECT_LT(loop_peak, 100.0);
  EXPECT_LT(campus_peak, 100.0);
  std::printf("peak yaw acceleration: loop %.1f, campus %.1f deg/s^2\n", loop_peak, campus_peak);
}

}  // namespace
}  // namespace cndt::sim
