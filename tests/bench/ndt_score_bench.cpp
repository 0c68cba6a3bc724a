// The NDT scoring kernel alone: one ndt_score call on a street scan's matched points (the
// odometry's scan cells) against the odometry's local map after 40 scans, at the odometry's own
// pose for it. Per call: with and without derivatives, 7 voxels per point and 1, with the lookup
// cache warm (Newton iterations after the first) and without it (the first scoring of a scan), on
// one thread and with the chunks shared with a helper thread (runtime::ScoreThreads, as cndtd runs
// with [runtime] scoring_threads = 2; wall time). Then Cv's residual sums over the scan's
// map_cell points at the same pose: accumulate_residuals against ndt::ResidualAccumulator on one
// thread and two. Then the odometry's two downsamplings of the scan's returns, and last the
// local map's update when a scan enters and leaves it.
// Run: build/release/tests/bench/ndt_score_bench
#include <benchmark/benchmark.h>

#include <vector>

#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/ndt_score.hpp"
#include "cndt/runtime/score_threads.hpp"
#include "cndt/slam/odometry.hpp"
#include "sim_scans.hpp"

namespace {

struct Fixture {
  cndt::slam::ConsensusOdometry odometry{cndt::slam::OdometryOptions{}};
  std::vector<Eigen::Vector3d> points;      // sensor frame, the odometry's scan cells
  std::vector<cndt::slam::TimedPoint> raw;  // the last scan's returns in range
  cndt::core::Pose6 pose;

  Fixture() {
    const std::vector<cndt::core::Scan> scans =
        cndt::test::simulate_scans(cndt::sim::SceneKind::kStreet, 4.2, 1);
    // The last whole scan (the capture ends mid-revolution) is matched against the map of those
    // before it: score it the same way.
    for (std::size_t i = 0; i + 2 < scans.size(); ++i) odometry.process(scans[i]);
    const cndt::slam::OdometryResult last = odometry.process(scans[scans.size() - 2]);
    pose = cndt::core::to_pose6(last.pose);
    const cndt::slam::OdometryOptions& o = odometry.options();
    for (const cndt::core::Point& q : scans[scans.size() - 2].points) {
      const Eigen::Vector3d v(q.x, q.y, q.z);
      const double r = v.norm();
      if (r >= o.min_range && r <= o.max_range) raw.push_back({v, q.time_ns * 1e-9});
    }
    cndt::slam::Downsampler cells(odometry.options().scan_cell, odometry.options().max_scan_points);
    cells.run(odometry.scan_points(), points);
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void Score(benchmark::State& state) {
  const Fixture& f = fixture();
  const bool derivatives = state.range(0) != 0;
  const auto neighbours = static_cast<cndt::ndt::Neighbours>(state.range(1));
  const bool warm = state.range(2) != 0;
  const auto threads = static_cast<std::size_t>(state.range(3));
  const cndt::ndt::VoxelGrid& grid = f.odometry.reference_grid();
  cndt::runtime::ScoreThreads helpers(threads - 1, {});
  cndt::ndt::LookupCache cache(f.points.size());
  cndt::ndt::LookupCache cold(f.points.size());  // reset before every call
  cache.set_runner(&helpers);
  cold.set_runner(&helpers);
  std::size_t terms = 0;
  for (auto _ : state) {
    if (!warm) {
      state.PauseTiming();
      cold = cndt::ndt::LookupCache(f.points.size());
      cold.set_runner(&helpers);
      state.ResumeTiming();
    }
    cndt::ndt::LookupCache* c = warm ? &cache : &cold;
    const cndt::ndt::ScoreResult r =
        cndt::ndt::ndt_score(grid, f.points, f.pose, derivatives, nullptr, neighbours, c);
    terms = r.terms;
    benchmark::DoNotOptimize(r.hessian);
  }
  state.counters["points"] = static_cast<double>(f.points.size());
  state.counters["terms"] = static_cast<double>(terms);
  state.counters["voxels"] = static_cast<double>(grid.size());
  state.counters["ns_per_term"] =
      benchmark::Counter(static_cast<double>(terms) * static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
// Arguments: derivatives, voxels per point, cache warm, threads.
BENCHMARK(Score)
    ->ArgNames({"derivatives", "voxels", "warm", "threads"})
    ->Args({1, 7, 1, 1})
    ->Args({1, 7, 1, 2})
    ->Args({0, 7, 1, 1})
    ->Args({1, 7, 0, 1})
    ->Args({1, 7, 0, 2})
    ->Args({1, 1, 1, 1})
    ->Args({1, 1, 1, 2})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// Cv's residual sums (the odometry's Cv at the coarse pose and Cm at the final one) over the
// scan's map_cell points: threads 0 = accumulate_residuals, else ResidualAccumulator with that
// many threads.
void CvResiduals(benchmark::State& state) {
  const Fixture& f = fixture();
  const auto threads = static_cast<std::size_t>(state.range(0));
  const cndt::ndt::VoxelGrid& grid = f.odometry.reference_grid();
  const std::span<const Eigen::Vector3d> points = f.odometry.scan_points();
  cndt::runtime::ScoreThreads helpers(threads > 1 ? threads - 1 : 0, {});
  cndt::ndt::ResidualAccumulator accumulator(points.size());
  cndt::ndt::VoxelResiduals residuals;
  residuals.reset(grid.size());
  for (auto _ : state) {
    state.PauseTiming();
    residuals.reset(grid.size());
    state.ResumeTiming();
    if (threads == 0) {
      cndt::ndt::accumulate_residuals(grid, points, f.pose, residuals);
    } else {
      accumulator.run(grid, points, f.pose, residuals, &helpers);
    }
    benchmark::DoNotOptimize(residuals.rss.data());
  }
  state.counters["points"] = static_cast<double>(points.size());
}
BENCHMARK(CvResiduals)
    ->ArgNames({"threads"})
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// The odometry's two downsamplings of a scan: its returns in range into map_cell centroids (with
// their mean firing times), then those into scan_cell centroids.
void Downsample(benchmark::State& state) {
  const Fixture& f = fixture();
  const cndt::slam::OdometryOptions& o = f.odometry.options();
  cndt::slam::Downsampler map_cells(o.map_cell, o.max_scan_points);
  cndt::slam::Downsampler scan_cells(o.scan_cell, o.max_scan_points);
  std::vector<cndt::slam::TimedPoint> map_points, scan_points;
  map_points.reserve(o.max_scan_points);
  scan_points.reserve(o.max_scan_points);
  for (auto _ : state) {
    map_cells.run(f.raw, map_points);
    scan_cells.run(map_points, scan_points);
    benchmark::DoNotOptimize(scan_points.data());
  }
  state.counters["raw_points"] = static_cast<double>(f.raw.size());
  state.counters["map_cells"] = static_cast<double>(map_points.size());
  state.counters["scan_cells"] = static_cast<double>(scan_points.size());
}
BENCHMARK(Downsample)->UseRealTime()->Unit(benchmark::kMicrosecond);

// The local map's update when a scan enters it: a street scan's map_cell points added to a copy
// of the odometry's reference grid (surface patches on, as the odometry has them by then) and
// the Gaussians derived again (finalize), then the same points removed and derived again (as
// when the scan leaves). The points are those of the fixture's last scan, 1 m further along
// the street (where the next scan to enter would lie at this speed), so they touch the voxels
// a new scan does; after the first iteration the voxels they create are there, emptied.
void GridUpdate(benchmark::State& state) {
  const Fixture& f = fixture();
  cndt::ndt::VoxelGrid grid = f.odometry.reference_grid();
  Eigen::Isometry3d at = cndt::core::to_isometry(f.pose);
  at.translation() += at.linear() * Eigen::Vector3d(1.0, 0.0, 0.0);
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& p : f.odometry.scan_points()) {
    points.push_back(f.odometry.level_rotation() * (at * p));
  }
  for (auto _ : state) {
    for (const Eigen::Vector3d& p : points) grid.add(p);
    grid.finalize();
    for (const Eigen::Vector3d& p : points) grid.remove(p);
    grid.finalize();
    benchmark::DoNotOptimize(grid.gaussians().data());
  }
  state.counters["points"] = static_cast<double>(points.size());
  state.counters["voxels"] = static_cast<double>(grid.size());
  state.counters["patches"] = grid.options().surface_patches ? 1.0 : 0.0;
}
BENCHMARK(GridUpdate)->Unit(benchmark::kMillisecond);

}  // namespace
