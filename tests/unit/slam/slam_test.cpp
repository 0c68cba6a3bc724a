#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "cndt/core/small_angle.hpp"
#include "cndt/ndt/ndt_score.hpp"
#include "cndt/ndt/voxel_grid.hpp"
#include "cndt/slam/downsample.hpp"
#include "cndt/slam/odometry.hpp"
#include "cndt/slam/trajectory_eval.hpp"

namespace cndt::slam {
namespace {

// The deskew's sine and versine: within a few units in the last place of the library's values
// over the polynomial's range (1 - cos x taken as 2 sin^2(x/2), which has no cancellation), and
// the library's own values beyond it.
TEST(SmallAngle, SineAndVersineEqualTheLibraryToRounding) {
  constexpr double kUlp = 2.220446049250313e-16;
  double worst_sin = 0.0, worst_versine = 0.0;
  for (int i = -50000; i <= 50000; ++i) {
    const double x = 0.5 * i / 50000.0;
    double s = 0.0, v = 0.0;
    core::sin_versine(x, s, v);
    const double half = std::sin(0.5 * x);
    const double ref_v = 2.0 * half * half;
    if (x == 0.0) {
      EXPECT_EQ(s, 0.0);
      EXPECT_EQ(v, 0.0);
      continue;
    }
    worst_sin = std::max(worst_sin, std::abs(s - std::sin(x)) / std::abs(std::sin(x)));
    worst_versine = std::max(worst_versine, std::abs(v - ref_v) / ref_v);
  }
  EXPECT_LT(worst_sin, 2.0 * kUlp);
  EXPECT_LT(worst_versine, 4.0 * kUlp);
  for (double x : {0.5000001, -0.7, 1.0, 3.0, -6.0, 100.0}) {
    double s = 0.0, v = 0.0;
    core::sin_versine(x, s, v);
    EXPECT_EQ(s, std::sin(x)) << x;
    EXPECT_EQ(v, 1.0 - std::cos(x)) << x;
  }
  double s = 1.0, v = 1.0;
  core::sin_versine(std::nan(""), s, v);
  EXPECT_TRUE(std::isnan(s) && std::isnan(v));
}

TEST(Downsampler, OneCentroidPerCellAndABoundedOutput) {
  std::vector<Eigen::Vector3d> in = {
      {0.1, 0.1, 0.1}, {0.3, 0.1, 0.1}, {1.2, 0.1, 0.1}, {1.4, 0.3, 0.1}, {-0.1, 0.0, 0.0}};
  std::vector<Eigen::Vector3d> out;
  Downsampler d(1.0, 100);
  d.run(in, out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_LT((out[0] - Eigen::Vector3d(0.2, 0.1, 0.1)).norm(), 1e-12);
  EXPECT_LT((out[1] - Eigen::Vector3d(1.3, 0.2, 0.1)).norm(), 1e-12);
  Downsampler small(1.0, 2);
  small.run(in, out);
  EXPECT_EQ(out.size(), 2u);
  EXPECT_EQ(small.dropped(), 1u);
}

// Rings interleaved as a scan delivers them (many points in a row falling in cells seen a few
// points before, hundreds of cells in all), binned twice by one downsampler: each time the same
// centroids, in first-seen order and to the bit, as a plain reference that sums every cell's
// points in input order. With room for fewer cells than occur, the cells seen first are kept and
// every point of the others is counted as dropped.
TEST(Downsampler, EqualsAPlainReferenceToTheBitOnInterleavedRings) {
  std::vector<TimedPoint> in;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.004, 0.004);
  for (int step = 0; step < 600; ++step) {
    for (int ring = 0; ring < 16; ++ring) {
      const double azimuth = 0.004 * step, range = 2.0 + 0.7 * ring;
      in.push_back({Eigen::Vector3d(range * std::cos(azimuth) + noise(rng),
                                    range * std::sin(azimuth) + noise(rng), 0.1 * ring - 0.8),
                    1e-5 * (16 * step + ring)});
    }
  }
  const double cell = 0.1;
  const auto reference = [&](std::size_t room, std::size_t& dropped) {
    std::vector<std::array<std::int64_t, 3>> keys;
    std::vector<TimedPoint> sums;
    std::vector<int> counts;
    dropped = 0;
    for (const TimedPoint& q : in) {
      const Eigen::Vector3d c = q.p * (1.0 / cell);  // as the downsampler scales
      const std::array<std::int64_t, 3> k{static_cast<std::int64_t>(std::floor(c.x())),
                                          static_cast<std::int64_t>(std::floor(c.y())),
                                          static_cast<std::int64_t>(std::floor(c.z()))};
      const auto it = std::find(keys.begin(), keys.end(), k);
      std::size_t i = static_cast<std::size_t>(it - keys.begin());
      if (it == keys.end()) {
        if (keys.size() == room) {
          ++dropped;
          continue;
        }
        keys.push_back(k);
        sums.push_back({Eigen::Vector3d::Zero(), 0.0});
        counts.push_back(0);
      }
      sums[i].p += q.p;
      sums[i].t += q.t;
      ++counts[i];
    }
    for (std::size_t i = 0; i < sums.size(); ++i) {
      sums[i] = {sums[i].p / counts[i], sums[i].t / counts[i]};
    }
    return sums;
  };
  for (const std::size_t room : {in.size(), std::size_t{300}}) {
    std::size_t ref_dropped = 0;
    const std::vector<TimedPoint> expected = reference(room, ref_dropped);
    ASSERT_GT(expected.size(), 250u);
    Downsampler d(cell, room);
    std::vector<TimedPoint> out;
    for (int pass = 0; pass < 2; ++pass) {
      d.run(in, out);
      ASSERT_EQ(out.size(), expected.size()) << room;
      EXPECT_EQ(d.dropped(), ref_dropped) << room;
      for (std::size_t i = 0; i < out.size(); ++i) {
        ASSERT_EQ(out[i].p, expected[i].p) << room << " cell " << i;
        ASSERT_EQ(out[i].t, expected[i].t) << room << " cell " << i;
      }
    }
  }
}

TEST(Downsampler, NoVoxelHoldsMoreCentroidsThanTheConsensusTableCovers) {
  // A dense cube downsampled at map_cell, turned and shifted at random, binned into reference
  // voxels: no voxel may hold more points than cv_dof_capacity() (else its Cv would use a wrong
  // chi-square quantile).
  const OdometryOptions o;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 3.0);
  std::vector<Eigen::Vector3d> dense(400'000);
  for (auto& p : dense) p = {u(rng), u(rng), u(rng)};
  std::vector<Eigen::Vector3d> centroids;
  Downsampler d(o.map_cell, dense.size());
  d.run(dense, centroids);
  std::uint32_t most = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(u(rng) - 1.5, u(rng) - 1.5, u(rng) - 1.5, u(rng) - 1.5).normalized();
    const Eigen::Vector3d t(u(rng), u(rng), u(rng));
    ndt::VoxelGrid grid({o.voxel_size, 10'000, 5, 0.001, false});
    for (const auto& p : centroids) grid.add(q * p + t);
    for (const auto& v : grid.voxels()) most = std::max(most, v.count);
  }
  EXPECT_GT(most, 125u);  // more than (L / cell)^3: turned cells overlap voxel edges
  EXPECT_LE(most, cv_dof_capacity(o));
}

std::vector<TimedPose> line(int n, double step, double yaw_rate = 0.0) {
  std::vector<TimedPose> v;
  for (int i = 0; i < n; ++i) {
    TimedPose p;
    p.t = 0.1 * i;
    p.pose.linear() = Eigen::AngleAxisd(yaw_rate * i, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.pose.translation() = Eigen::Vector3d(step * i, 0, 0);
    v.push_back(p);
  }
  return v;
}

// A wall sampled evenly, matched against its own NDT while the pose slides along it: the score
// should not care where the sensor stands along a plane. The matched points are the centroids of
// scan_cell cells, which lie at the cell centres on an even surface; with cells as large as the
// voxels they line up with the voxel means once per cell of motion and the score ripples with
// that period (held the corridor's matches on a ripple, docs/odometry.md). With the default
// cell the ripple is gone. The window is one voxel of motion: right for cells that divide the
// voxel size; others ripple with longer periods than it sees.
double ripple_along_a_wall(double scan_cell) {
  std::vector<Eigen::Vector3d> wall, scan;
  for (int i = -500; i < 500; ++i) {
    for (int k = -50; k < 100; ++k) wall.emplace_back(0.02 * i + 0.01, 2.0, 0.02 * k + 0.01);
  }
  const double sensor_x = 0.13;  // anywhere along the wall
  for (const Eigen::Vector3d& p : wall) {
    if (std::abs(p.x()) < 6.0) scan.push_back(p - Eigen::Vector3d(sensor_x, 0.0, 0.0));
  }
  std::vector<Eigen::Vector3d> map_points, matched;
  Downsampler(0.1, wall.size()).run(wall, map_points);
  Downsampler(scan_cell, scan.size()).run(scan, matched);
  ndt::VoxelGrid grid({0.5, 10'000});
  for (const Eigen::Vector3d& p : map_points) grid.add(p);
  grid.finalize();
  double lo = 0.0, hi = -1e300, sum = 0.0;
  const int steps = 40;
  for (int i = 0; i < steps; ++i) {
    core::Pose6 x = core::Pose6::Zero();
    x(0) = sensor_x + 0.5 * i / steps;  // one voxel of motion
    const double s =
        ndt::ndt_score(grid, matched, x, false, nullptr, ndt::Neighbours::kSeven).score;
    lo = i == 0 ? s : std::min(lo, s);
    hi = std::max(hi, s);
    sum += s;
  }
  return (hi - lo) / std::abs(sum / steps);
}

TEST(Downsampler, DefaultScanCellLeavesNoRippleAlongAPlane) {
  const double at_default = ripple_along_a_wall(OdometryOptions{}.scan_cell);
  const double at_voxel_size = ripple_along_a_wall(OdometryOptions{}.voxel_size);
  std::printf(
      "score ripple along a wall over one voxel of motion: %.4f with %.2f m cells, "
      "%.4f with %.2f m cells\n",
      at_default, OdometryOptions{}.scan_cell, at_voxel_size, OdometryOptions{}.voxel_size);
  EXPECT_LT(at_default, 0.02);
  EXPECT_GT(at_voxel_size, 0.1);  // the ripple this guards against
}

TEST(TrajectoryEval, IdenticalAndRigidlyMovedEstimatesHaveNoError) {
  const auto gt = line(300, 0.5, 0.002);
  auto moved = gt;
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  offset.translation() = Eigen::Vector3d(5, -3, 1);
  for (auto& p : moved) p.pose = offset * p.pose;
  const EvalResult r = evaluate(gt, moved);
  EXPECT_EQ(r.matched, 300u);
  EXPECT_NEAR(r.path_length, 149.5, 0.5);
  EXPECT_LT(r.ate_rmse, 1e-9);
  EXPECT_LT(r.rte_percent, 1e-7);
  EXPECT_LT(r.rpe_translation_rmse, 1e-9);
  EXPECT_LT(r.end_error, 1e-9);
  EXPECT_LT(r.height_error_max, 1e-9);
  EXPECT_LT(r.tilt_end_deg, 1e-5);
}

TEST(TrajectoryEval, APathShorterThanTwoSegmentsHasNoSegmentErrors) {
  const auto gt = line(30, 0.5);  // 14.5 m: a 10 m segment does not fit twice
  const auto est = line(30, 0.505);
  const EvalResult r = evaluate(gt, est);
  EXPECT_TRUE(r.segment_lengths.empty());
  EXPECT_TRUE(std::isnan(r.rte_percent));
  EXPECT_TRUE(std::isnan(r.rre_deg_per_m));
  EXPECT_GT(r.ate_rmse, 0.01);                                         // measured all the same
  const EvalResult longer = evaluate(line(41, 0.5), line(41, 0.505));  // 20 m
  ASSERT_EQ(longer.segment_lengths.size(), 1u);
  EXPECT_NEAR(longer.rte_percent, 1.0, 1e-6);
}

TEST(TrajectoryEval, ScaleErrorShowsAsRelativeTranslationError) {
  const auto gt = line(300, 0.5);
  const auto est = line(300, 0.505);  // 1 % too long
  const EvalResult r = evaluate(gt, est);
  EXPECT_NEAR(r.rte_percent, 1.0, 1e-6);
  EXPECT_NEAR(r.rpe_translation_rmse, 0.005, 1e-9);
  EXPECT_GT(r.ate_rmse, 0.1);
}

TEST(TrajectoryEval, ATiltPickedUpAtTheStartShowsInTheHeightNotInTheAte) {
  // One bad pitch in the first step, every later step right: the odometry's typical height
  // failure. The ATE fit rotates it away; dead reckoning from the first pose does not.
  const auto gt = line(300, 0.5);
  auto est = gt;
  const double tilt = 0.5 * 3.14159265358979323846 / 180.0;
  const Eigen::Isometry3d nose_up(Eigen::AngleAxisd(-tilt, Eigen::Vector3d::UnitY()));
  for (std::size_t i = 1; i < est.size(); ++i) est[i].pose = nose_up * gt[i].pose;
  const EvalResult r = evaluate(gt, est);
  const double length = 0.5 * 299;
  EXPECT_LT(r.ate_rmse, 1e-9);
  EXPECT_NEAR(r.rpe_rotation_rmse_deg, 0.5 / std::sqrt(299.0), 1e-6);  // one frame in 299
  EXPECT_NEAR(r.height_error_end, length * std::sin(tilt), 1e-9);
  EXPECT_NEAR(r.height_error_max, length * std::sin(tilt), 1e-9);
  EXPECT_NEAR(r.tilt_end_deg, 0.5, 1e-6);
  EXPECT_NEAR(r.end_error, 2.0 * length * std::sin(tilt / 2.0), 1e-9);
  // A heading error of a sensor mounted tilted is no tilt: the world's up stays where it was.
  auto tilted_mount = gt;
  const Eigen::Matrix3d mount(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()));
  for (auto& p : tilted_mount) p.pose.linear() = p.pose.linear() * mount;
  auto turned = tilted_mount;
  const Eigen::Isometry3d yaw(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()));
  for (std::size_t i = 1; i < turned.size(); ++i) turned[i].pose = yaw * tilted_mount[i].pose;
  const EvalResult t = evaluate(tilted_mount, turned);
  EXPECT_LT(t.tilt_end_deg, 1e-5);
  EXPECT_LT(t.height_error_max, 1e-9);
}

TEST(TrajectoryEval, InterpolatesGroundTruthAndSkipsPosesOutsideIt) {
  const auto gt = line(100, 1.0);
  std::vector<TimedPose> est;
  for (int i = 0; i < 120; ++i) {
    TimedPose p;
    p.t = 0.05 + 0.1 * i;  // between ground-truth samples; the last 21 after its end
    p.pose.translation() = Eigen::Vector3d(10.0 * p.t, 0, 0);
    est.push_back(p);
  }
  const EvalResult r = evaluate(gt, est);
  EXPECT_EQ(r.matched, 99u);
  EXPECT_LT(r.ate_rmse, 1e-9);
}

}  // namespace
}  // namespace cndt::slam
