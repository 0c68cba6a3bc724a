#include "cndt/slam/correction_blend.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cndt::slam {
namespace {

Eigen::Isometry3d pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

double angle(const Eigen::Isometry3d& T) { return Eigen::AngleAxisd(T.linear()).angle(); }

TEST(CorrectionBlend, WithoutTimeConstantEveryCorrectionAppliesAtOnce) {
  CorrectionBlend blend(0.0);
  const Eigen::Isometry3d odom = pose(40, -3, 1, 0.3);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Isometry3d target = pose(0.1 * k, 0.2, 0.0, 0.01 * k);
    EXPECT_TRUE(blend.step(target, odom, 0.1).isApprox(target, 1e-15));
  }
}

TEST(CorrectionBlend, TheFirstCorrectionAppliesAtOnce) {
  // Localization in a prior map starts with the initial pose: nothing to blend from.
  CorrectionBlend blend(0.5);
  const Eigen::Isometry3d target = pose(250, 120, 3, 1.2);
  EXPECT_TRUE(blend.step(target, pose(1, 2, 0, 0.1), 0.0).isApprox(target, 1e-15));
}

// A new correction that moves the published pose 0.1 m and turns it 2 degrees, the vehicle
// (standing) 1 km from the odometry origin: per scan the published pose covers 1 - exp(-dt / tau)
// of what is left, on the straight line between the two poses (turned about the map origin
// instead, the step would swing it along an arc 1 km wide).
TEST(CorrectionBlend, PublishedPoseMovesTheExpectedFractionTowardsTheNewCorrection) {
  const double tau = 0.3, dt = 0.1, yaw = 2.0 * M_PI / 180.0;
  CorrectionBlend blend(tau);
  const Eigen::Isometry3d odom = pose(1000, 0, 0, 0.7);
  const Eigen::Isometry3d old_c = pose(3, -2, 0.1, 0.05);
  const Eigen::Isometry3d start = old_c * odom;
  const Eigen::Isometry3d target = start * pose(0.06, -0.08, 0.0, yaw);
  const Eigen::Isometry3d new_c = target * odom.inverse();
  blend.step(old_c, odom, 0.0);
  double remaining = 1.0;
  const Eigen::Vector3d line = (target.translation() - start.translation()).normalized();
  for (int k = 0; k < 60; ++k) {
    const Eigen::Isometry3d published = blend.step(new_c, odom, dt) * odom;
    remaining *= std::exp(-dt / tau);
    EXPECT_NEAR((target.translation() - published.translation()).norm(), remaining * 0.1, 1e-9)
        << "scan " << k;
    EXPECT_NEAR(angle(target.inverse() * published), remaining * yaw, 1e-9) << "scan " << k;
    EXPECT_LT((published.translation() - start.translation()).cross(line).norm(), 1e-9)
        << "scan " << k;
  }
  EXPECT_TRUE(blend.applied().isApprox(new_c, 1e-6));
}

// Driving on at 8 m/s: the published pose still reaches the new correction, and between two
// scans it moves by the odometry's step plus at most the share of the jump due on that scan.
TEST(CorrectionBlend, ReachesTheNewCorrectionWhileDriving) {
  const double tau = 0.3, dt = 0.1;
  CorrectionBlend blend(tau);
  const Eigen::Isometry3d new_c = pose(0.3, -0.1, 0.05, 0.02);
  blend.step(Eigen::Isometry3d::Identity(), pose(10, 0, 0, 0), 0.0);
  Eigen::Isometry3d previous = pose(10, 0, 0, 0);
  double jump = 0.0;
  for (int k = 1; k <= 40; ++k) {
    const Eigen::Isometry3d odom = pose(10 + 0.8 * k, 0, 0, 0);
    const Eigen::Isometry3d before = blend.applied() * odom;
    const double left = ((new_c * odom).translation() - before.translation()).norm();
    if (k == 1) jump = left;
    const Eigen::Isometry3d published = blend.step(new_c, odom, dt) * odom;
    EXPECT_LT((published.translation() - previous.translation()).norm(),
              0.8 + (1.0 - std::exp(-dt / tau)) * left + 1e-9)
        << "scan " << k;
    previous = published;
  }
  EXPECT_GT(jump, 0.3);
  EXPECT_TRUE(blend.applied().isApprox(new_c, 1e-5));
}

TEST(CorrectionBlend, StaysARigidTransformOverAnHourOfScans) {
  CorrectionBlend blend(0.3);
  for (int k = 0; k < 36000; ++k) {
    const double s = 1e-3 * std::sin(0.01 * k);
    blend.step(pose(s, -s, 0.5 * s, 20 * s), pose(0.8 * k, 0.0, 0.0, 0.0), 0.1);
  }
  const Eigen::Matrix3d R = blend.applied().linear();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
}

}  // namespace
}  // namespace cndt::slam
