#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <tuple>

#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/ndt_score.hpp"
#include "cndt/ndt/newton.hpp"
#include "cndt/ndt/voxel_grid.hpp"

namespace cndt::ndt {
namespace {

using core::Pose6;

TEST(VoxelGrid, RunningSumsGiveMeanAndCovariance) {
  VoxelGrid g({1.0, 100, 5, 0.001});
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 400; ++i) {
    pts.emplace_back(0.5 + 0.1 * n(rng), 0.5 + 0.05 * n(rng), 0.5 + 0.02 * n(rng));
    pts.back() = pts.back().cwiseMax(0.01).cwiseMin(0.99);
    ASSERT_TRUE(g.add(pts.back()));
  }
  g.finalize();
  ASSERT_EQ(g.size(), 1u);
  ASSERT_TRUE(g.voxels()[0].has_gaussian);
  const Gaussian& v = g.gaussians()[0];
  ASSERT_EQ(v.valid, 1u);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p;
  mean /= 400.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
  cov /= 400.0;  // population covariance, as documented
  EXPECT_LT((v.mean_vector() - mean).norm(), 1e-12);
  // The inverse covariance is kept in single precision.
  EXPECT_LT((v.inv_cov_matrix() - cov.inverse()).norm() / cov.inverse().norm(), 1e-7);
}

TEST(VoxelGrid, RaisesSmallEigenvaluesAndNeedsFivePoints) {
  VoxelGrid g({1.0, 100, 5, 0.001});
  // A perfect plane: the normal eigenvalue is 0 and must be raised to 0.001 x the largest.
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) g.add(Eigen::Vector3d(0.05 + 0.09 * i, 0.05 + 0.09 * j, 0.5));
  }
  for (int i = 0; i < 4; ++i) g.add(Eigen::Vector3d(1.5, 0.5, 0.5));  // 4 points: no Gaussian
  g.finalize();
  ASSERT_EQ(g.size(), 2u);
  const Voxel& plane = *g.find(Eigen::Vector3d(0.5, 0.5, 0.5));
  ASSERT_TRUE(plane.has_gaussian);
  const Gaussian& gp = g.gaussians()[static_cast<std::size_t>(g.index_of(plane.key))];
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(gp.inv_cov_matrix().inverse());
  EXPECT_NEAR(es.eigenvalues()(0) / es.eigenvalues()(2), 0.001, 1e-7);  // single precision
  EXPECT_FALSE(g.find(Eigen::Vector3d(1.5, 0.5, 0.5))->has_gaussian);
}

TEST(VoxelGrid, NeverGrowsPastItsCapacity) {
  VoxelGrid g({1.0, 3, 5, 0.001});
  for (int i = 0; i < 10; ++i) g.add(Eigen::Vector3d(i + 0.5, 0.5, 0.5));
  EXPECT_EQ(g.size(), 3u);
  EXPECT_EQ(g.refused_points(), 7u);
}

// A sliding reference: points added and later removed must leave exactly the grid the remaining
// points alone give, far from the origin too (the sums are kept relative to each voxel).
TEST(VoxelGrid, RemovingPointsLeavesTheGridOfTheRest) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 3.0);
  const Eigen::Vector3d far(4000.25, -2500.75, 30.0);
  std::vector<Eigen::Vector3d> a, b;
  for (int i = 0; i < 3000; ++i) a.push_back(far + Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng)));
  for (int i = 0; i < 3000; ++i) b.push_back(far + Eigen::Vector3d(u(rng), 0.3 * u(rng), u(rng)));
  VoxelGrid sliding({0.5, 1000, 5, 0.001});
  for (const auto& p : a) ASSERT_TRUE(sliding.add(p));
  for (const auto& p : b) ASSERT_TRUE(sliding.add(p));
  sliding.finalize();
  const std::uint64_t before = sliding.version();
  for (const auto& p : a) ASSERT_TRUE(sliding.remove(p));
  EXPECT_FALSE(sliding.remove(far + Eigen::Vector3d(-7, -7, -7)));  // never added
  sliding.finalize();
  VoxelGrid fresh({0.5, 1000, 5, 0.001});
  for (const auto& p : b) fresh.add(p);
  fresh.finalize();
  auto compare = [&] {
    std::size_t gaussians = 0;
    for (std::size_t i = 0; i < fresh.size(); ++i) {
      const Voxel& v = fresh.voxels()[i];
      const std::int64_t j = sliding.index_of(v.key);
      ASSERT_GE(j, 0);
      const Voxel& w = sliding.voxels()[static_cast<std::size_t>(j)];
      ASSERT_EQ(w.count, v.count);
      ASSERT_EQ(w.has_gaussian, v.has_gaussian);
      if (!v.has_gaussian) continue;
      ++gaussians;
      const Gaussian& gv = fresh.gaussians()[i];
      const Gaussian& gw = sliding.gaussians()[static_cast<std::size_t>(j)];
      EXPECT_LT((gw.mean_vector() - gv.mean_vector()).norm(), 1e-9);
      EXPECT_LT((gw.inv_cov_matrix() - gv.inv_cov_matrix()).norm(),
                1e-6 * gv.inv_cov_matrix().norm());
    }
    EXPECT_GT(gaussians, 10u);
  };
  compare();
  EXPECT_GT(sliding.empty_voxels(), 0u);  // a's voxels that b does not share
  EXPECT_EQ(sliding.size(), fresh.size() + sliding.empty_voxels());
  sliding.compact();
  EXPECT_EQ(sliding.size(), fresh.size());
  EXPECT_EQ(sliding.empty_voxels(), 0u);
  EXPECT_NE(sliding.version(), before);  // indices changed: cached lookups are void
  compare();
}

// The lookup table grows with the voxels it holds (from 16 slots up to twice the capacity) and
// shrinks when compacted or cleared: through every size, each voxel is found at its index, a key
// never added is not found, and the neighbour lookup agrees with single lookups.
TEST(VoxelGrid, LookupsHoldWhileTheTableGrowsAndShrinks) {
  constexpr std::size_t kCapacity = 5000;
  VoxelGrid g({0.5, kCapacity, 5, 0.001});
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> coord(-60, 60);
  std::map<std::tuple<int, int, int>, std::int64_t> expected;  // key -> index
  std::vector<Eigen::Vector3d> added;
  auto check = [&](const char* when) {
    SCOPED_TRACE(when);
    ASSERT_EQ(g.size(), expected.size());
    for (const auto& [k, index] : expected) {
      const VoxelKey key{std::get<0>(k), std::get<1>(k), std::get<2>(k)};
      ASSERT_EQ(g.index_of(key), index);
      std::array<std::int32_t, 7> around{};
      g.indices_around(key, 7, around.data());
      for (int n = 0; n < 7; ++n) {
        const VoxelKey nk{key.x + VoxelGrid::kFaceOffsets[n][0],
                          key.y + VoxelGrid::kFaceOffsets[n][1],
                          key.z + VoxelGrid::kFaceOffsets[n][2]};
        ASSERT_EQ(around[static_cast<std::size_t>(n)], g.index_of(nk));
      }
    }
    for (int i = 0; i < 2000; ++i) {
      const VoxelKey key{coord(rng) + 1000, coord(rng), coord(rng)};  // never added
      ASSERT_EQ(g.index_of(key), -1);
      ASSERT_EQ(g.find(key), nullptr);
    }
  };
  // Grows one voxel at a time through every table size up to the capacity.
  while (expected.size() < kCapacity) {
    const Eigen::Vector3d p(0.5 * coord(rng) + 0.25, 0.5 * coord(rng) + 0.25,
                            0.5 * coord(rng) + 0.25);
    const VoxelKey key = g.key_of(p);
    const auto k = std::make_tuple(key.x, key.y, key.z);
    const bool is_new = !expected.contains(k);
    ASSERT_TRUE(g.add(p));
    added.push_back(p);
    if (is_new) expected[k] = static_cast<std::int64_t>(expected.size());
    if (std::has_single_bit(expected.size())) check("growing");
  }
  check("full");
  EXPECT_FALSE(g.add(Eigen::Vector3d(1000.25, 0.25, 0.25)));  // a new voxel past the capacity
  // Emptied voxels leave with compact(); the rest are renumbered in order.
  for (std::size_t i = 0; i < added.size(); i += 3) {
    while (g.remove(added[i])) {
    }
  }
  g.compact();
  std::map<std::tuple<int, int, int>, std::int64_t> kept;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const VoxelKey& key = g.voxels()[i].key;
    kept[std::make_tuple(key.x, key.y, key.z)] = static_cast<std::int64_t>(i);
  }
  ASSERT_LT(kept.size(), expected.size());
  expected = kept;
  check("compacted");
  g.clear();
  expected.clear();
  check("cleared");
  ASSERT_TRUE(g.add(Eigen::Vector3d(0.25, 0.25, 0.25)));
  expected[std::make_tuple(0, 0, 0)] = 0;
  check("refilled");
}

// Clusters at the centres of 4 m voxels, so that small pose changes never move a point into
// another voxel and S is smooth where the finite differences are taken.
struct Scene {
  VoxelGrid grid{{4.0, 1000, 5, 0.001}};
  std::vector<Eigen::Vector3d> test;
};

Scene random_scene(std::uint32_t seed) {
  Scene s;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> cell(-3, 3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int c = 0; c < 25; ++c) {
    const Eigen::Vector3d centre(4.0 * cell(rng) + 2.0, 4.0 * cell(rng) + 2.0, 4.0 * (c % 2) + 2.0);
    const Eigen::Vector3d sd(0.1 + 0.4 * std::abs(n(rng)), 0.1 + 0.4 * std::abs(n(rng)),
                             0.05 + 0.2 * std::abs(n(rng)));
    for (int i = 0; i < 40; ++i) {
      Eigen::Vector3d p = centre + sd.cwiseProduct(Eigen::Vector3d(n(rng), n(rng), n(rng)));
      p = p.cwiseMax(centre - Eigen::Vector3d::Constant(1.9))
              .cwiseMin(centre + Eigen::Vector3d::Constant(1.9));
      s.grid.add(p);
    }
    for (int i = 0; i < 15; ++i) {
      const Eigen::Vector3d d(n(rng), n(rng), n(rng));
      s.test.push_back(centre + 0.3 * d.cwiseMin(Eigen::Vector3d::Constant(2.0))
                                          .cwiseMax(Eigen::Vector3d::Constant(-2.0)));
    }
  }
  s.grid.finalize();
  return s;
}

class Derivatives : public ::testing::TestWithParam<std::uint32_t> {};

TEST_P(Derivatives, AnalyticGradientAndHessianEqualFiniteDifferences) {
  const std::uint32_t seed = GetParam();
  const Scene s = random_scene(seed);
  std::mt19937 rng(seed + 1000);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Pose6 x;
  x << 0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng), 0.03 * u(rng), 0.03 * u(rng), 0.03 * u(rng);
  // Test points are given in the sensor frame: undo the pose so they land near the clusters.
  std::vector<Eigen::Vector3d> pts;
  const Eigen::Isometry3d T = core::to_isometry(x);
  for (const auto& p : s.test) pts.push_back(T.inverse() * p);
  // Even seeds score against seven voxels per point, odd seeds against one.
  const Neighbours nb = seed % 2 == 0 ? Neighbours::kSeven : Neighbours::kOne;
  const ScoreResult r = ndt_score(s.grid, pts, x, true, nullptr, nb);
  ASSERT_GT(r.matched, 300u);
  const double h = 1e-6;
  Vector6d g_fd;
  Matrix6d h_fd;
  for (int k = 0; k < 6; ++k) {
    Pose6 a = x, b = x;
    a[k] += h;
    b[k] -= h;
    const ScoreResult ra = ndt_score(s.grid, pts, a, true, nullptr,
                                     GetParam() % 2 == 0 ? Neighbours::kSeven : Neighbours::kOne);
    const ScoreResult rb = ndt_score(s.grid, pts, b, true, nullptr,
                                     GetParam() % 2 == 0 ? Neighbours::kSeven : Neighbours::kOne);
    ASSERT_EQ(ra.terms, r.terms);  // the same point-voxel pairs on both sides
    ASSERT_EQ(rb.terms, r.terms);
    g_fd[k] = (ra.score - rb.score) / (2 * h);
    h_fd.col(k) = (ra.gradient - rb.gradient) / (2 * h);
  }
  const double g_err = (r.gradient - g_fd).norm() / g_fd.norm();
  const double h_err = (r.hessian - h_fd).norm() / h_fd.norm();
  std::printf("seed %u: gradient relative error %.2e, Hessian relative error %.2e\n", seed, g_err,
              h_err);
  EXPECT_LT(g_err, 1e-4);
  EXPECT_LT(h_err, 1e-4);
}

INSTANTIATE_TEST_SUITE_P(RandomPoses, Derivatives, ::testing::Range(1u, 11u));

// A point counts once as matched however many voxels it is scored against; each pair counts as
// a term. Three voxels in a row, each with a Gaussian; the points sit in the middle one.
TEST(NdtScore, CountsMatchedPointsAndTermsApart) {
  VoxelGrid g({1.0, 100, 5, 0.001});
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int v = 0; v < 3; ++v) {
    for (int i = 0; i < 50; ++i) g.add(Eigen::Vector3d(v + u(rng), u(rng), u(rng)));
  }
  g.finalize();
  const std::vector<Eigen::Vector3d> pts = {{1.5, 0.5, 0.5}, {1.4, 0.6, 0.5}, {9.5, 9.5, 9.5}};
  const ScoreResult seven = ndt_score(g, pts, Pose6::Zero(), true, nullptr, Neighbours::kSeven);
  EXPECT_EQ(seven.matched, 2u);  // the third point is far from every voxel
  EXPECT_EQ(seven.terms, 6u);    // each of the two: its own voxel and the two beside it
  const ScoreResult one = ndt_score(g, pts, Pose6::Zero(), false, nullptr, Neighbours::kOne);
  EXPECT_EQ(one.matched, 2u);
  EXPECT_EQ(one.terms, 2u);
}

// Scoring with a lookup cache gives what scoring without one gives, across poses, across a
// change of the grid and across grids.
TEST(LookupCache, GivesTheSameScoresAsFreshLookups) {
  Scene s = random_scene(11);
  Scene other = random_scene(12);
  LookupCache cache(s.test.size());
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 0.3);
  for (int round = 0; round < 30; ++round) {
    Pose6 x;
    for (int k = 0; k < 6; ++k) x[k] = n(rng) * (k < 3 ? 2.0 : 0.1);
    const VoxelGrid& g = round % 3 == 2 ? other.grid : s.grid;
    for (Neighbours nb : {Neighbours::kOne, Neighbours::kSeven}) {
      const ScoreResult plain = ndt_score(g, s.test, x, true, nullptr, nb);
      const ScoreResult cached = ndt_score(g, s.test, x, true, nullptr, nb, &cache);
      EXPECT_EQ(plain.matched, cached.matched);
      EXPECT_EQ(plain.terms, cached.terms);
      EXPECT_DOUBLE_EQ(plain.score, cached.score);
      EXPECT_LT((plain.hessian - cached.hessian).norm(), 1e-12 * (1 + plain.hessian.norm()));
    }
    if (round == 10) {  // the grid grows: a lookup that found nothing may now find a voxel
      for (const auto& p : s.test) s.grid.add(p + Eigen::Vector3d(0.5, 0.5, 0.5));
      s.grid.finalize();
    }
  }
}

// A scoring finds each point's voxels once per key and reuses them for the points after it in
// the same voxel: its score and translation gradient are still the sums of point_terms (which
// looks every point up afresh) over its points. Thousands of voxels (far more keys than a
// scoring keeps), points in runs within one voxel broken by points elsewhere, with and without
// the lookup cache, before and after the grid grows.
TEST(NdtScore, EqualsPointTermsSummedOverItsPoints) {
  VoxelGrid grid({0.5, 20000, 5, 0.001});
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> n(0.0, 0.1);
  auto fill = [&](double x0, double x1) {
    for (int i = 0; i < 60000; ++i) {  // a rough slab: about 12 points per voxel
      const double x = x0 + (x1 - x0) * u(rng), y = 10.0 * u(rng);
      grid.add(Eigen::Vector3d(x, y, 0.5 * std::sin(x) * std::cos(y) + 0.3 * u(rng)));
    }
    grid.finalize();
  };
  fill(0.0, 10.0);
  std::vector<Eigen::Vector3d> points;
  for (int run = 0; run < 1500; ++run) {
    const Eigen::Vector3d centre(12.0 * u(rng) - 1.0, 10.0 * u(rng), 0.5 * u(rng));
    for (int i = 0; i < 1 + run % 4; ++i) {
      points.push_back(centre + Eigen::Vector3d(n(rng), n(rng), n(rng)));
    }
  }
  LookupCache cache(points.size());
  for (int round = 0; round < 4; ++round) {
    Pose6 x;
    for (int k = 0; k < 6; ++k) x[k] = n(rng) * (k < 3 ? 1.0 : 0.1);
    const Eigen::Isometry3d T = core::to_isometry(x);
    for (Neighbours nb : {Neighbours::kOne, Neighbours::kSeven}) {
      double score = 0.0;
      Eigen::Vector3d g_t = Eigen::Vector3d::Zero();
      for (const auto& p : points) {
        Eigen::Vector3d b;
        score += point_terms(grid, T * p, nb, nullptr, &b);
        g_t += b;
      }
      ASSERT_LT(score, -100.0);
      for (LookupCache* c : {static_cast<LookupCache*>(nullptr), &cache}) {
        const ScoreResult r = ndt_score(grid, points, x, true, nullptr, nb, c);
        EXPECT_NEAR(r.score, score, 1e-9 * std::abs(score));
        EXPECT_LT((r.gradient.head<3>() - g_t).norm(), 1e-9 * (1.0 + g_t.norm()));
      }
    }
    if (round == 1) fill(10.0, 12.0);  // new voxels: lookups that found nothing now find them
  }
}

// Runs a scoring's chunks last to first, as another thread might finish them, and counts them.
class ReverseRunner final : public TaskRunner {
 public:
  void run(std::size_t count, void (*task)(void*, std::size_t), void* context) override {
    for (std::size_t i = count; i-- > 0;) task(context, i);
    tasks += count;
  }
  std::size_t tasks = 0;
};

// At least three times kParallelMinPoints points: the scene's test points repeated, each copy
// moved by 5 cm noise.
std::vector<Eigen::Vector3d> many_points(const Scene& s, std::mt19937& rng) {
  std::vector<Eigen::Vector3d> points;
  std::normal_distribution<double> n(0.0, 0.05);
  while (points.size() < 3 * kParallelMinPoints) {
    for (const auto& p : s.test) points.push_back(p + Eigen::Vector3d(n(rng), n(rng), n(rng)));
  }
  return points;
}

// The chunks' sums are added in chunk order whoever runs them: a runner changes nothing, to
// the bit, with and without derivatives, the cache and a scan motion.
TEST(LookupCache, ScoringsThroughARunnerEqualThoseWithout) {
  Scene s = random_scene(13);
  std::mt19937 rng(7);
  const std::vector<Eigen::Vector3d> points = many_points(s, rng);
  std::normal_distribution<double> n(0.0, 0.05);
  std::vector<double> lever(points.size());
  for (std::size_t i = 0; i < lever.size(); ++i) {
    lever[i] = static_cast<double>(i) / static_cast<double>(lever.size());
  }
  ReverseRunner runner;
  LookupCache plain_cache(points.size()), run_cache(points.size());
  run_cache.set_runner(&runner);
  std::size_t calls = 0;
  for (int round = 0; round < 6; ++round) {
    Pose6 x;
    for (int k = 0; k < 6; ++k) x[k] = n(rng) * (k < 3 ? 4.0 : 0.4);
    const ScanMotion motion{Pose6::Zero(), lever};
    for (const ScanMotion* m : {static_cast<const ScanMotion*>(nullptr), &motion}) {
      for (bool derivatives : {false, true}) {
        const ScoreResult a =
            ndt_score(s.grid, points, x, derivatives, nullptr, Neighbours::kSeven, &plain_cache, m);
        const ScoreResult b =
            ndt_score(s.grid, points, x, derivatives, nullptr, Neighbours::kSeven, &run_cache, m);
        ++calls;
        EXPECT_GT(a.matched, 0u);
        EXPECT_EQ(a.matched, b.matched);
        EXPECT_EQ(a.terms, b.terms);
        EXPECT_EQ(a.score, b.score);
        EXPECT_TRUE(a.gradient == b.gradient);
        EXPECT_TRUE(a.hessian == b.hessian);
      }
    }
  }
  EXPECT_EQ(runner.tasks, calls * kScoreChunks);
  // Below kParallelMinPoints the calling thread scores alone.
  ndt_score(s.grid, std::span(points).first(kParallelMinPoints - 1), Pose6::Zero(), true, nullptr,
            Neighbours::kSeven, &run_cache);
  EXPECT_EQ(runner.tasks, calls * kScoreChunks);
}

// Cv's residual sums through ResidualAccumulator equal accumulate_residuals' to the bit, on a
// runner or not, and a set of points larger than its buffers is still accumulated whole.
TEST(ResidualAccumulator, SumsEqualTheSerialOnesToTheBit) {
  Scene s = random_scene(17);
  std::mt19937 rng(9);
  const std::vector<Eigen::Vector3d> points = many_points(s, rng);
  std::normal_distribution<double> n(0.0, 0.05);
  ReverseRunner runner;
  ResidualAccumulator accumulator(points.size());
  ResidualAccumulator small(kParallelMinPoints);
  for (int round = 0; round < 4; ++round) {
    Pose6 x;
    for (int k = 0; k < 6; ++k) x[k] = n(rng) * (k < 3 ? 1.0 : 0.1);
    VoxelResiduals serial, threaded, alone, overflow;
    for (VoxelResiduals* r : {&serial, &threaded, &alone, &overflow}) r->reset(s.grid.size());
    accumulate_residuals(s.grid, points, x, serial);
    accumulator.run(s.grid, points, x, threaded, &runner);
    accumulator.run(s.grid, points, x, alone, nullptr);
    small.run(s.grid, points, x, overflow, &runner);
    std::uint32_t counted = 0;
    for (std::uint32_t c : serial.count) counted += c;
    EXPECT_GT(counted, points.size() / 2);
    for (const VoxelResiduals* r : {&threaded, &alone, &overflow}) {
      EXPECT_TRUE(r->count == serial.count);
      EXPECT_TRUE(r->rss == serial.rss);
    }
  }
  EXPECT_EQ(runner.tasks, 4 * kScoreChunks);  // `small` ran on the calling thread
}

// Ground, two walls and a box, sampled densely (1 cm noise).
std::vector<Eigen::Vector3d> structured_world(std::uint32_t seed) {
  std::vector<Eigen::Vector3d> world;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 0.01);
  for (double a = -10; a <= 10; a += 0.1) {
    for (double b = -10; b <= 10; b += 0.1) world.emplace_back(a, b, -1.8 + n(rng));
    for (double z = -1.8; z <= 2; z += 0.1) {
      world.emplace_back(a, 6.0 + n(rng), z);
      world.emplace_back(8.0 + n(rng), a, z);
    }
  }
  for (double a = 0; a <= 2; a += 0.05) {
    for (double z = -1.8; z <= 0; z += 0.05) {
      world.emplace_back(3 + a, -4.0 + n(rng), z);
      world.emplace_back(3 + n(rng), -4.0 - a, z);
    }
  }
  return world;
}

TEST(Newton, RecoversAKnownMotionOfAStructuredScene) {
  // The test scan sees the world from a moved sensor.
  const std::vector<Eigen::Vector3d> world = structured_world(3);
  VoxelGrid grid({0.5, 200'000, 5, 0.001});
  for (const auto& p : world) grid.add(p);
  grid.finalize();
  Pose6 truth;
  truth << 0.3, -0.2, 0.05, 0.01, -0.015, 0.035;
  const Eigen::Isometry3d T = core::to_isometry(truth);
  std::vector<Eigen::Vector3d> scan;
  for (std::size_t i = 0; i < world.size(); i += 3) scan.push_back(T.inverse() * world[i]);
  NewtonOptions seven;
  const NewtonResult r = newton_solve(grid, scan, Pose6::Zero(), seven);
  NewtonOptions one;
  one.neighbours = Neighbours::kOne;
  const NewtonResult r1 = newton_solve(grid, scan, Pose6::Zero(), one);
  std::printf(
      "7 voxels: %d iterations, error %.4f m %.5f rad; 1 voxel: %d iterations, error "
      "%.4f m %.5f rad\n",
      r.iterations, (r.pose.head<3>() - truth.head<3>()).norm(),
      (r.pose.tail<3>() - truth.tail<3>()).norm(), r1.iterations,
      (r1.pose.head<3>() - truth.head<3>()).norm(), (r1.pose.tail<3>() - truth.tail<3>()).norm());
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.pose.head<3>() - truth.head<3>()).norm(), 0.01);
  EXPECT_LT((r.pose.tail<3>() - truth.tail<3>()).norm(), 0.001);
  EXPECT_LE(r.iterations, 30);
}

TEST(Newton, PositionPriorHoldsWhatTheSceneLeavesFreeAndLittleElse) {
  // A corridor: floor and two walls, nothing along x. Points drawn uniformly on each surface,
  // for the reference and the scan apart (a lattice of them, or the same points in both, would
  // itself fix x). Along x the score has only the ripples of the random Gaussians, and the
  // match slides on them; a prior that outweighs them holds x at the prediction while y, z
  // and the rotation are solved. The prediction is off along x only: the 1 cm thin walls and
  // floor pull from a few centimetres at most, so from farther off where the match ends in y
  // and z would depend on the draw of the points (from a prediction at the origin, 3 of 8
  // draws ended more than 2 cm off in x or y, at weights 0.1 and 0.3 alike). Without the prior
  // this match slides 9 mm along x; from a prediction at the origin it slid to x = -0.25.
  std::mt19937 rng(5);
  auto corridor_points = [&rng](int per_surface) {
    std::normal_distribution<double> n(0.0, 0.01);
    std::uniform_real_distribution<double> along(-15.0, 15.0), across(-2.0, 2.0), up(-1.8, 1.0);
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < per_surface; ++i) {
      pts.emplace_back(along(rng), across(rng), -1.8 + n(rng));
      pts.emplace_back(along(rng), 2.0 + n(rng), up(rng));
      pts.emplace_back(along(rng), -2.0 + n(rng), up(rng));
    }
    return pts;
  };
  Pose6 truth;
  truth << 0.4, -0.1, 0.03, 0.005, -0.01, 0.02;
  auto scan_of = [&](const std::vector<Eigen::Vector3d>& world, double reach) {
    const Eigen::Isometry3d T = core::to_isometry(truth);
    std::vector<Eigen::Vector3d> scan;
    for (std::size_t i = 0; i < world.size(); i += 3) {
      const Eigen::Vector3d p = T.inverse() * world[i];
      if (p.head<2>().norm() < reach) scan.push_back(p);
    }
    return scan;
  };
  VoxelGrid tube({0.5, 200'000, 5, 0.001});
  for (const auto& p : corridor_points(12'000)) tube.add(p);
  tube.finalize();
  const std::vector<Eigen::Vector3d> tube_scan = scan_of(corridor_points(12'000), 10.0);
  PositionPrior prior;
  prior.center = truth;
  prior.center(0) = 0.25;  // predicted 0.15 m short along the axis
  const NewtonResult slid = newton_solve(tube, tube_scan, prior.center, NewtonOptions{});
  prior.relative_weight = 0.1;
  const NewtonResult held = newton_solve(tube, tube_scan, prior.center, NewtonOptions{}, nullptr,
                                         nullptr, nullptr, &prior);
  std::printf(
      "corridor (truth x 0.4, prediction 0.25): without the prior x %.4f; with it x %.4f, "
      "y %.4f (truth -0.1), z %.4f (0.03), rotation error %.5f rad\n",
      slid.pose(0), held.pose(0), held.pose(1), held.pose(2),
      (held.pose.tail<3>() - truth.tail<3>()).norm());
  EXPECT_NEAR(held.pose(0), 0.25, 0.002);
  EXPECT_NEAR(held.pose(1), truth(1), 0.005);
  EXPECT_NEAR(held.pose(2), truth(2), 0.005);
  EXPECT_LT((held.pose.tail<3>() - truth.tail<3>()).norm(), 0.01);

  // A scene that fixes every direction: a prediction 5 cm off moves the solution by little.
  const std::vector<Eigen::Vector3d> world = structured_world(3);
  VoxelGrid grid({0.5, 200'000, 5, 0.001});
  for (const auto& p : world) grid.add(p);
  grid.finalize();
  const std::vector<Eigen::Vector3d> scan = scan_of(world, 1e9);
  prior.center = truth;
  prior.center.head<3>() += Eigen::Vector3d(0.03, -0.03, 0.03);
  prior.relative_weight = 0.003;  // the odometry's default
  const NewtonResult free = newton_solve(grid, scan, Pose6::Zero(), NewtonOptions{});
  const NewtonResult pulled =
      newton_solve(grid, scan, Pose6::Zero(), NewtonOptions{}, nullptr, nullptr, nullptr, &prior);
  const double moved = (pulled.pose.head<3>() - free.pose.head<3>()).norm();
  std::printf("structured scene: the prior moved the solution by %.5f m\n", moved);
  EXPECT_TRUE(pulled.converged);
  EXPECT_LT(moved, 0.002);
  EXPECT_LT((pulled.pose.head<3>() - truth.head<3>()).norm(), 0.01);
  // The score and Hessian reported are S's alone: equal to a fresh scoring at the pose.
  const ScoreResult at = ndt_score(grid, scan, pulled.pose, true, nullptr, Neighbours::kSeven);
  EXPECT_NEAR(pulled.score, at.score, 1e-9 * std::abs(at.score));
  EXPECT_LT((pulled.hessian - at.hessian).norm(), 1e-9 * at.hessian.norm());
}

// The scan's motion solved with the pose: at the base the points are where they were given and
// the gradient is that of S with the points moving with the pose (finite differences).
TEST(ScanMotion, GradientEqualsFiniteDifferencesAtTheBase) {
  for (std::uint32_t seed : {2u, 5u, 8u}) {
    const Scene s = random_scene(seed);
    std::mt19937 rng(seed + 2000);
    std::uniform_real_distribution<double> u(-1.0, 1.0), frac(0.0, 1.0);
    Pose6 x;
    x << 0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng), 0.03 * u(rng), 0.03 * u(rng), 0.03 * u(rng);
    std::vector<Eigen::Vector3d> pts;
    const Eigen::Isometry3d T = core::to_isometry(x);
    for (const auto& p : s.test) pts.push_back(T.inverse() * p);
    std::vector<double> lever;
    for (std::size_t i = 0; i < pts.size(); ++i) lever.push_back(frac(rng));
    const ScanMotion motion{x, lever};
    const ScoreResult rigid = ndt_score(s.grid, pts, x, true, nullptr, Neighbours::kSeven);
    const ScoreResult r =
        ndt_score(s.grid, pts, x, true, nullptr, Neighbours::kSeven, nullptr, &motion);
    ASSERT_GT(r.matched, 300u);
    EXPECT_EQ(r.score, rigid.score);
    const double h = 1e-6;
    Vector6d g_fd;
    for (int k = 0; k < 6; ++k) {
      Pose6 a = x, b = x;
      a[k] += h;
      b[k] -= h;
      g_fd[k] =
          (ndt_score(s.grid, pts, a, false, nullptr, Neighbours::kSeven, nullptr, &motion).score -
           ndt_score(s.grid, pts, b, false, nullptr, Neighbours::kSeven, nullptr, &motion).score) /
          (2 * h);
    }
    const double g_err = (r.gradient - g_fd).norm() / g_fd.norm();
    const double rigid_err = (rigid.gradient - g_fd).norm() / g_fd.norm();
    std::printf("seed %u: gradient relative error %.2e (rigid gradient: %.2e)\n", seed, g_err,
                rigid_err);
    EXPECT_LT(g_err, 1e-4);
    EXPECT_GT(rigid_err, 0.05);  // the levers matter: the rigid gradient is another one
  }
}

// A scan undistorted for a wrong guess of its pose (and so of its motion): the points fired late
// in the revolution are off by more than the early ones. Solving for the motion with the pose
// recovers the pose; a rigid match settles on a compromise between early and late points.
TEST(ScanMotion, NewtonSolvesPoseAndUndistortionTogether) {
  const std::vector<Eigen::Vector3d> world = structured_world(4);
  VoxelGrid grid({0.5, 200'000, 5, 0.001});
  for (const auto& p : world) grid.add(p);
  grid.finalize();
  Pose6 truth, guess;
  truth << 0.3, -0.2, 0.05, 0.01, -0.015, 0.035;
  guess << 0.15, -0.12, 0.02, 0.01, -0.012, 0.02;  // 17 cm and 0.9 deg off
  const Eigen::Isometry3d T = core::to_isometry(truth);
  // The error of the guess in the sensor frame; a point with lever l was undistorted with l
  // times it missing.
  const Eigen::Isometry3d err = core::to_isometry(guess).inverse() * T;
  const Eigen::AngleAxisd aa(err.linear());
  std::vector<Eigen::Vector3d> scan;
  std::vector<double> lever;
  for (std::size_t i = 0; i < world.size(); i += 3) {
    const double l = static_cast<double>(i) / static_cast<double>(world.size());  // firing order
    Eigen::Isometry3d part = Eigen::Isometry3d::Identity();
    part.linear() = Eigen::AngleAxisd(l * aa.angle(), aa.axis()).toRotationMatrix();
    part.translation() = l * err.translation();
    scan.push_back(part.inverse() * (T.inverse() * world[i]));
    lever.push_back(l);
  }
  const ScanMotion motion{guess, lever};
  const NewtonOptions o;
  const NewtonResult solved = newton_solve(grid, scan, guess, o, nullptr, nullptr, &motion);
  const NewtonResult rigid = newton_solve(grid, scan, guess, o);
  auto errors = [&](const Pose6& x) {
    return std::pair((x.head<3>() - truth.head<3>()).norm(),
                     (x.tail<3>() - truth.tail<3>()).norm());
  };
  const auto [st, sr] = errors(solved.pose);
  const auto [rt, rr] = errors(rigid.pose);
  std::printf("with the scan motion: %.4f m %.5f rad (%d iterations); rigid: %.4f m %.5f rad\n", st,
              sr, solved.iterations, rt, rr);
  EXPECT_TRUE(solved.converged);
  EXPECT_LT(st, 0.01);
  EXPECT_LT(sr, 0.001);
  EXPECT_GT(rt, 3 * st);
}

TEST(ChiSquare, QuantilesMatchReferenceValues) {
  EXPECT_NEAR(chi2inv(0.999, 1), 10.828, 5e-4);
  EXPECT_NEAR(chi2inv(0.001, 10), 1.479, 5e-4);
  EXPECT_NEAR(chi2inv(0.999, 10), 29.588, 5e-4);
  EXPECT_NEAR(chi2inv(0.001, 1), 1.5708e-6, 1e-9);
  const ChiSquareTable t(200);
  EXPECT_DOUBLE_EQ(t.high(1), chi2inv(0.999, 1));
  EXPECT_DOUBLE_EQ(t.low(10), chi2inv(0.001, 10));
}

// Paper Figure 4: a reference voxel holding a plane patch, and test points that match it,
// are partly hidden by an occluder, come from another feature, or carry outliers.
struct Fig4 {
  VoxelGrid grid{{1.0, 10, 5, 0.001}};
  std::mt19937 rng{11};
  std::uniform_real_distribution<double> u{0.05, 0.95};
  std::normal_distribution<double> n{0.0, 0.01};
  Eigen::Vector3d plane_point() { return {u(rng), u(rng), 0.5 + n(rng)}; }
  Fig4() {
    for (int i = 0; i < 300; ++i) grid.add(plane_point());
    grid.finalize();
  }
  double cv(const std::vector<Eigen::Vector3d>& test) {
    VoxelResiduals res;
    res.reset(grid.size());
    accumulate_residuals(grid, test, Pose6::Zero(), res);
    const ChiSquareTable table(500);
    return voxel_consensus(res.rss[0], res.count[0], table);
  }
};

TEST(VoxelConsensus, Figure4CasesScoreBelowACleanMatch) {
  Fig4 f;
  std::vector<Eigen::Vector3d> clean, occluded, mismatch, outliers;
  for (int i = 0; i < 60; ++i) clean.push_back(f.plane_point());
  // Occlusion: a pole in front of the surface hides a third of it and returns instead.
  for (int i = 0; i < 60; ++i) {
    occluded.push_back(
        i < 40 ? f.plane_point()
               : Eigen::Vector3d(0.5 + f.n(f.rng), 0.2 + 0.6 * (i - 40) / 20.0, 0.25 + f.n(f.rng)));
  }
  // Feature mismatch: a plane through the same voxel at 60 degrees.
  for (int i = 0; i < 60; ++i) {
    const double a = f.u(f.rng) - 0.5, b = f.u(f.rng);
    mismatch.emplace_back(0.5 + a * std::cos(1.047), b, 0.5 + a * std::sin(1.047));
  }
  // Outliers: the clean points plus 15 % anywhere in the voxel.
  outliers = clean;
  for (int i = 0; i < 9; ++i) outliers.emplace_back(f.u(f.rng), f.u(f.rng), f.u(f.rng));
  const double cv_clean = f.cv(clean), cv_occl = f.cv(occluded), cv_mis = f.cv(mismatch),
               cv_out = f.cv(outliers);
  std::printf("Cv clean %.3f occlusion %.3f mismatch %.3f outliers %.3f\n", cv_clean, cv_occl,
              cv_mis, cv_out);
  EXPECT_GE(cv_clean, 0.9);
  EXPECT_LT(cv_occl, cv_clean);
  EXPECT_LT(cv_mis, cv_clean);
  EXPECT_LT(cv_out, cv_clean);
  // Too few test points: no Cv.
  EXPECT_TRUE(std::isnan(f.cv({clean.begin(), clean.begin() + 4})));
}

// Paper Figure 5: directions to voxels around the sensor; the same number of low-Cv voxels,
// clustered on one side or spread out.
TEST(LocalizationConsensus, ClusteredLowConsensusCostsMoreThanSpread) {
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < 48; ++i) {
    const double az = 2 * 3.14159265358979 * i / 48.0;
    const double el = (i % 3 - 1) * 0.3;
    dirs.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  }
  std::vector<double> all_good(48, 1.0), clustered(48, 1.0), spread(48, 1.0);
  for (int i = 0; i < 12; ++i) {
    clustered[static_cast<std::size_t>(i)] = 0.1;   // one quarter of the view
    spread[static_cast<std::size_t>(4 * i)] = 0.1;  // every fourth voxel
  }
  const double cm_all = localization_consensus(dirs, all_good);
  const double cm_clustered = localization_consensus(dirs, clustered);
  const double cm_spread = localization_consensus(dirs, spread);
  std::printf("Cm all good %.4f, spread %.4f, clustered %.4f\n", cm_all, cm_spread, cm_clustered);
  EXPECT_NEAR(cm_all, 1.0, 1e-12);
  EXPECT_LT(cm_spread, 1.0);
  EXPECT_LT(cm_clustered, cm_spread);
  EXPECT_GT(cm_clustered, 0.0);
}

TEST(LocalizationConsensus, DegenerateGeometryGivesZero) {
  std::vector<Eigen::Vector3d> line(10, Eigen::Vector3d::UnitX());
  std::vector<double> cv(10, 1.0);
  EXPECT_EQ(localization_consensus(line, cv), 0.0);
}

// Cm over a grid: measured when the voxels with a Cv span the three directions, whatever their
// Cv; not measured when too few have one (a sparse scan), though Cm is 0 either way.
TEST(LocalizationConsensus, TellsAnUnmeasuredCmFromALowOne) {
  VoxelGrid grid({0.5, 1'000, 5, 0.001});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.05, 0.45);
  const std::vector<Eigen::Vector3d> corners{{4, 0, 0}, {-4, 0, 0}, {0, 4, 0}, {0, -4, 0},
                                             {0, 0, 4}, {0, 0, -2}, {3, 3, 1}, {-3, 2, -1}};
  for (const auto& c : corners) {
    for (int i = 0; i < 20; ++i) grid.add(c + Eigen::Vector3d(u(rng), u(rng), u(rng)));
  }
  grid.finalize();
  ASSERT_EQ(grid.size(), corners.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Vector3d sensor = Eigen::Vector3d::Zero();
  std::vector<double> cv(grid.size(), 1.0);
  ConsensusMeasure m = measure_localization_consensus(grid, cv, sensor);
  EXPECT_TRUE(m.measured);
  EXPECT_NEAR(m.cm, 1.0, 1e-12);
  EXPECT_EQ(m.cm, localization_consensus(grid, cv, sensor));
  std::fill(cv.begin(), cv.end(), 0.0);  // every voxel disagrees
  m = measure_localization_consensus(grid, cv, sensor);
  EXPECT_TRUE(m.measured);
  EXPECT_EQ(m.cm, 0.0);
  std::fill(cv.begin(), cv.end(), nan);  // two voxels with a Cv: directions in a plane
  cv[0] = cv[2] = 1.0;
  m = measure_localization_consensus(grid, cv, sensor);
  EXPECT_FALSE(m.measured);
  EXPECT_EQ(m.cm, 0.0);
}

// The rings a sensor 1.9 m above a floor leaves on it from x = x0 (seven lasers, 1,800 points
// each), added to `out`.
void floor_rings(double x0, std::vector<Eigen::Vector3d>& out) {
  for (double elevation_deg = -15.0; elevation_deg <= -3.0; elevation_deg += 2.0) {
    const double r = 1.9 / std::tan(-elevation_deg * std::numbers::pi / 180.0);
    for (int k = 0; k < 1800; ++k) {
      const double a = 2.0 * std::numbers::pi * k / 1800.0;
      out.emplace_back(x0 + r * std::cos(a), r * std::sin(a), 0.0);
    }
  }
}

// A floor as a sensor 1.9 m above it samples it: points on rings of fixed radius, which move
// with the sensor. The reference holds ten such scans taken 1 m apart (a local map), the scan
// is taken 0.3 m past the newest. As plain voxel Gaussians the rings are thin arcs, and the
// scan scores far better with its rings moved back onto the newest scan's (as if the sensor
// had stood still) than at its true pose; as surface patches both score alike: the floor then
// holds height and tilt and nothing along it.
TEST(VoxelGrid, SurfacePatchesTakeTheRingsOutOfAFloor) {
  std::vector<Eigen::Vector3d> reference, scan;
  for (int i = 0; i < 10; ++i) floor_rings(-1.0 * i, reference);
  floor_rings(0.3, scan);  // in the reference's frame
  for (const bool patches : {false, true}) {
    VoxelGrid grid({0.5, 100'000, 5, 0.001, false, patches});
    for (const auto& p : reference) grid.add(p);
    grid.finalize();
    Pose6 truth = Pose6::Zero(), stood_still = Pose6::Zero();
    stood_still(0) = -0.3;  // the scan's rings moved back onto the newest scan's
    const double at_truth = ndt_score(grid, scan, truth, false, nullptr, Neighbours::kSeven).score;
    const double standing =
        ndt_score(grid, scan, stood_still, false, nullptr, Neighbours::kSeven).score;
    Pose6 up = truth;
    up(2) = 0.05;
    const double raised = ndt_score(grid, scan, up, false, nullptr, Neighbours::kSeven).score;
    std::printf("%s: score at the true pose %.1f, standing still %.1f, 5 cm up %.1f\n",
                patches ? "surface patches" : "voxel Gaussians", at_truth, standing, raised);
    if (patches) {
      EXPECT_NEAR(standing / at_truth, 1.0, 0.1);
      EXPECT_GT(raised, 0.5 * at_truth);  // the floor holds the height (scores are negative)
    } else {
      EXPECT_LT(standing, 1.5 * at_truth);  // the pull this guards against
    }
  }
}

// With patch_max_tilt_deg, only level planes become patches: the same rings on the floor lose
// their pull, and stood up as a wall (normal along y) they keep eq 4's Gaussians and the pull.
TEST(VoxelGrid, LevelPatchesLeaveSteepPlanesTheirGaussians) {
  std::vector<Eigen::Vector3d> reference, scan;
  for (int i = 0; i < 10; ++i) floor_rings(-1.0 * i, reference);
  floor_rings(0.3, scan);
  for (const bool wall : {false, true}) {
    const Eigen::Matrix3d turn =
        wall
            ? Eigen::AngleAxisd(std::numbers::pi / 2.0, Eigen::Vector3d::UnitX()).toRotationMatrix()
            : Eigen::Matrix3d::Identity();
    VoxelGrid grid({0.5, 100'000, 5, 0.001, false, true, 25.0});
    for (const auto& p : reference) grid.add(turn * p);
    grid.finalize();
    std::vector<Eigen::Vector3d> turned;
    for (const auto& p : scan) turned.push_back(turn * p);
    Pose6 stood_still = Pose6::Zero();
    stood_still(0) = -0.3;
    const double at_truth =
        ndt_score(grid, turned, Pose6::Zero(), false, nullptr, Neighbours::kSeven).score;
    const double standing =
        ndt_score(grid, turned, stood_still, false, nullptr, Neighbours::kSeven).score;
    std::printf("%s: score at the true pose %.1f, standing still %.1f\n", wall ? "wall" : "floor",
                at_truth, standing);
    if (wall) {
      EXPECT_LT(standing, 1.5 * at_truth);  // Gaussians: the rings still pull (negative scores)
    } else {
      EXPECT_NEAR(standing / at_truth, 1.0, 0.1);  // patches: no pull
    }
  }
}

// Surface patches turned on for a grid that already holds voxels derive those again (the
// odometry turns them on once its map holds a few scans), and off gives the voxel Gaussians back
// bit for bit.
TEST(VoxelGrid, SurfacePatchesSwitchedOnLaterApplyToTheVoxelsHeld) {
  std::vector<Eigen::Vector3d> floor;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) floor.emplace_back(0.05 * i, 0.05 * j, 0.002 * ((i * 7 + j) % 3));
  }
  VoxelGrid plain({0.5, 10'000, 5, 0.001, false, false});
  VoxelGrid patched({0.5, 10'000, 5, 0.001, false, true});
  VoxelGrid switched({0.5, 10'000, 5, 0.001, false, false});
  for (VoxelGrid* g : {&plain, &patched, &switched}) {
    for (const auto& p : floor) g->add(p);
    g->finalize();
  }
  const std::vector<Eigen::Vector3d> probe{{0.9, 0.9, 0.0}, {1.1, 0.6, 0.01}, {0.3, 1.4, -0.01}};
  auto score = [&](const VoxelGrid& g) {
    Pose6 shifted = Pose6::Zero();
    shifted(0) = 0.2;  // along the floor
    return ndt_score(g, probe, shifted, false, nullptr, Neighbours::kSeven).score;
  };
  ASSERT_NE(score(plain), score(patched));
  switched.set_surface_patches(true);
  switched.finalize();
  EXPECT_EQ(score(switched), score(patched));
  switched.set_surface_patches(false);
  switched.finalize();
  EXPECT_EQ(score(switched), score(plain));
}

// A grid made with surface patches keeps each voxel's neighbour list through additions,
// removals and compactions (which renumber the voxels); its Gaussians equal, bit for bit, those
// of a grid that finds the neighbours by lookups (made without patches, then switched on) and is
// never compacted.
TEST(VoxelGrid, NeighbourListsGiveTheGaussiansOfLookups) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 4.0), noise(-0.003, 0.003);
  std::vector<Eigen::Vector3d> points;
  double shift = 0.0;  // the points move on along x from round to round
  auto draw = [&] {    // a floor with a step, and a wall
    const double x = shift + u(rng), y = u(rng);
    if (points.size() % 4 == 3) return Eigen::Vector3d(x, 2.0 + noise(rng), 0.5 * y);
    return Eigen::Vector3d(x, y, (x - shift > 2.0 ? 0.3 : 0.0) + noise(rng));
  };
  for (int i = 0; i < 5000; ++i) {
    if (i == 2500) shift += 3.0;
    points.push_back(draw());
  }
  VoxelGrid listed({0.5, 10'000, 5, 0.001, false, true, 25.0});
  VoxelGrid looked_up({0.5, 10'000, 5, 0.001, false, false, 25.0});
  VoxelGrid plain({0.5, 10'000, 5, 0.001, false, false, 25.0});
  looked_up.set_surface_patches(true);
  std::size_t added = 0, removed = 0;
  for (int round = 0; round < 4; ++round) {
    // The new points come in and the oldest leave, emptying voxels that compact() then drops
    // from `listed` alone.
    for (VoxelGrid* g : {&listed, &looked_up, &plain}) {
      for (std::size_t i = added; i < points.size(); ++i) g->add(points[i]);
      for (std::size_t i = removed; i < removed + 2500; ++i) ASSERT_TRUE(g->remove(points[i]));
    }
    added = points.size();
    removed += 2500;
    ASSERT_GT(listed.empty_voxels(), 0u);
    listed.compact();
    looked_up.finalize();
    plain.finalize();
    ASSERT_LT(listed.size(), looked_up.size());
    int patches = 0;
    for (const Voxel& v : looked_up.voxels()) {
      const auto a = looked_up.index_of(v.key), b = listed.index_of(v.key);
      if (v.count == 0) {
        EXPECT_LT(b, 0);
        continue;
      }
      ASSERT_GE(b, 0);
      const Gaussian& ga = looked_up.gaussians()[static_cast<std::size_t>(a)];
      const Gaussian& gb = listed.gaussians()[static_cast<std::size_t>(b)];
      ASSERT_EQ(ga.valid, gb.valid);
      for (int k = 0; k < 3; ++k) EXPECT_EQ(ga.mean[k], gb.mean[k]);
      for (int k = 0; k < 6; ++k) EXPECT_EQ(ga.inv_cov[k], gb.inv_cov[k]);
      const Gaussian& gp = plain.gaussians()[static_cast<std::size_t>(plain.index_of(v.key))];
      if (ga.valid != 0 && ga.inv_cov[0] != gp.inv_cov[0]) ++patches;
    }
    EXPECT_GT(patches, 10) << "round " << round;  // the floor's voxels are patches
    shift += 3.0;
    for (int i = 0; i < 2500; ++i) points.push_back(draw());
  }
}

// finalize() derives again the voxels whose points changed and, with surface patches, their
// neighbours (whose neighbourhood changed); a neighbour neither a patch before nor now keeps
// its Gaussian. After every step of adding and removing, the Gaussians equal, bit for bit,
// those of a grid given the same additions and removals and finalized once at the end (on a
// runner that takes the chunks in reverse order), and some voxels whose own points never
// changed became patches and stopped being ones.
TEST(VoxelGrid, FinalizingAfterEachChangeEqualsFinalizingOnce) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 4.0), wide(0.0, 12.0), noise(-0.003, 0.003);
  std::vector<Eigen::Vector3d> floor, pile;
  for (int i = 0; i < 20000; ++i) floor.emplace_back(wide(rng), wide(rng), noise(rng));
  for (int i = 0; i < 300; ++i) {  // a heap on the floor: the planes around it are lost
    pile.emplace_back(1.6 + 0.8 * u(rng) / 4.0, 1.6 + 0.8 * u(rng) / 4.0, 0.05 + 0.1 * u(rng));
  }
  struct Step {
    const std::vector<Eigen::Vector3d>* points;
    bool add;
  };
  const std::vector<Step> steps{{&floor, true}, {&pile, true}, {&pile, false}, {&pile, true}};
  VoxelGrid stepwise({0.5, 10'000, 5, 0.001, false, true, 25.0});
  std::vector<bool> was_patch;
  int became = 0, stopped = 0;
  for (std::size_t n = 0; n < steps.size(); ++n) {
    std::vector<std::uint32_t> counts;
    for (const Voxel& v : stepwise.voxels()) counts.push_back(v.count);
    for (const auto& p : *steps[n].points) {
      if (steps[n].add) {
        ASSERT_TRUE(stepwise.add(p));
      } else {
        ASSERT_TRUE(stepwise.remove(p));
      }
    }
    stepwise.finalize();
    VoxelGrid once({0.5, 10'000, 5, 0.001, false, true, 25.0});
    for (std::size_t k = 0; k <= n; ++k) {
      for (const auto& p : *steps[k].points) steps[k].add ? once.add(p) : once.remove(p);
    }
    ReverseRunner runner;
    once.finalize(&runner);
    EXPECT_EQ(runner.tasks, kScoreChunks);  // enough voxels to share out
    ASSERT_EQ(once.size(), stepwise.size());
    for (std::size_t i = 0; i < once.size(); ++i) {
      const Gaussian& a = once.gaussians()[i];
      const Gaussian& b = stepwise.gaussians()[i];
      ASSERT_EQ(once.voxels()[i].key, stepwise.voxels()[i].key);
      ASSERT_EQ(a.valid, b.valid) << "step " << n << ", voxel " << i;
      for (int k = 0; k < 3; ++k) EXPECT_EQ(a.mean[k], b.mean[k]);
      for (int k = 0; k < 6; ++k) EXPECT_EQ(a.inv_cov[k], b.inv_cov[k]);
      const Voxel& v = stepwise.voxels()[i];
      if (i < counts.size() && v.count == counts[i] && v.patch != was_patch[i]) {
        ++(v.patch ? became : stopped);
      }
    }
    was_patch.clear();
    for (const Voxel& v : stepwise.voxels()) was_patch.push_back(v.patch);
  }
  EXPECT_GT(stopped, 0);  // the heap's neighbours, their own points untouched
  EXPECT_GT(became, 0);   // and the same when it went
}

}  // namespace
}  // namespace cndt::ndt
