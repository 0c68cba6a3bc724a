// The mapper's keyframe close: the eq-7 joint refinement of a 10-scan keyframe against the map
// and among its scans, then the Cm and map update, on a simulated street drive (VLP-16 at
// 600 rpm, 8 m/s). At 10 Hz a 10-scan keyframe arrives every second: the margin is 1 s over
// the time per keyframe, on the second core.
// Run: build/release/tests/bench/mapper_bench
#include <benchmark/benchmark.h>

#include <vector>

#include "cndt/slam/mapper.hpp"
#include "cndt/slam/odometry.hpp"
#include "sim_scans.hpp"

namespace {

struct OdometryScan {
  double t;
  Eigen::Isometry3d pose;
  std::vector<Eigen::Vector3d> points;
};

// 3.2 s of street: the odometry's poses and deskewed points of about 30 scans.
const std::vector<OdometryScan>& scans() {
  static const std::vector<OdometryScan> out = [] {
    cndt::slam::ConsensusOdometry odometry({});
    std::vector<OdometryScan> v;
    cndt::test::simulate_scans(cndt::sim::SceneKind::kStreet, 3.2, 4, 1, [&](cndt::core::Scan& s) {
      const auto r = odometry.process(s);
      if ((r.flags & cndt::slam::kOdomSkipped) != 0) return;
      const auto pts = odometry.scan_points();
      v.push_back({static_cast<double>(s.stamp.count()) * 1e-9, r.pose, {pts.begin(), pts.end()}});
    });
    return v;
  }();
  return out;
}

// One iteration: the third keyframe (scans 20-29) closes against the map of the first two.
void KeyframeClose10Scans(benchmark::State& state) {
  cndt::slam::MapperOptions o;
  o.keyframe_similarity = 0.0;  // keyframes of exactly keyframe_scans = 10 scans
  cndt::slam::Mapper base(o);
  const auto& s = scans();
  for (std::size_t i = 0; i < 20; ++i) base.add(s[i].t, s[i].pose, s[i].points);
  base.flush();
  std::size_t map_voxels = 0;
  int iterations = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cndt::slam::Mapper m = base;
    for (std::size_t i = 20; i < 30; ++i) m.add(s[i].t, s[i].pose, s[i].points);
    state.ResumeTiming();
    m.flush();
    benchmark::DoNotOptimize(m.correction());
    map_voxels = m.map().size();
    iterations = m.stats().last_iterations;
  }
  state.counters["map_voxels"] = static_cast<double>(map_voxels);
  state.counters["lm_iterations"] = iterations;
}
BENCHMARK(KeyframeClose10Scans)->Unit(benchmark::kMillisecond)->MinTime(3.0);

}  // namespace
