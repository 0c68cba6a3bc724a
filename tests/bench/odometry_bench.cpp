// Consensus-NDT odometry per VLP-16 scan (600 rpm, ~28.8k returns) on a simulated street drive,
// and consensus against naive mode side by side on the same scans in one run; then consensus with
// its scorings shared with a helper thread as cndtd runs it ([runtime] scoring_threads = 2).
// Run: build/release/tests/bench/odometry_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <vector>

#include "cndt/runtime/score_threads.hpp"
#include "cndt/slam/odometry.hpp"
#include "sim_scans.hpp"

namespace {

constexpr double kSeconds = 10.0;

const std::vector<cndt::core::Scan>& street_scans() {
  static const std::vector<cndt::core::Scan> scans =
      cndt::test::simulate_scans(cndt::sim::SceneKind::kStreet, kSeconds, 1);
  return scans;
}

struct Run {
  std::vector<double> ms;         // the whole step per scan
  std::vector<double> commit_ms;  // of which the reference update, after the pose is known
  std::vector<double> update_ms;  // commit_ms of the scans that changed the reference grid
  double total_ms = 0.0;
  double iterations = 0.0;  // per matched scan
};

Run run_sequence(cndt::slam::OdometryMode mode, cndt::ndt::TaskRunner* runner = nullptr) {
  cndt::slam::OdometryOptions o;
  o.mode = mode;
  cndt::slam::ConsensusOdometry odometry(o);
  odometry.set_score_runner(runner);
  Run r;
  long iterations = 0;
  for (const auto& scan : street_scans()) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto res = odometry.estimate(scan);
    const auto t1 = std::chrono::steady_clock::now();
    const std::uint64_t version = odometry.reference_grid().version();
    odometry.commit();
    const auto t2 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(res.pose);
    r.ms.push_back(std::chrono::duration<double, std::milli>(t2 - t0).count());
    r.commit_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    // Scans enter the local map 1 m apart: about every other scan at this drive's speed.
    if (odometry.reference_grid().version() != version) r.update_ms.push_back(r.commit_ms.back());
    iterations += res.coarse_iterations + res.fine_iterations;
  }
  for (double m : r.ms) r.total_ms += m;
  r.iterations = static_cast<double>(iterations) / static_cast<double>(r.ms.size() - 1);
  return r;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

// One iteration = the whole drive in consensus mode, then in naive mode, each with a fresh
// odometry. Counters: per-scan milliseconds (median, p99) and iterations per scan of both modes,
// the ratio of their total times, and the time of consensus's reference update (commit), which a
// real-time caller runs after publishing the pose: its mean per scan, and its median over the
// scans that changed the reference (the others' commit does next to nothing).
void ConsensusVersusNaive(benchmark::State& state) {
  street_scans();  // simulated outside the timing
  Run c, n;
  for (auto _ : state) {
    c = run_sequence(cndt::slam::OdometryMode::kConsensus);
    n = run_sequence(cndt::slam::OdometryMode::kNaive);
  }
  state.counters["scans"] = static_cast<double>(c.ms.size());
  state.counters["consensus_ms_p50"] = percentile(c.ms, 0.5);
  state.counters["consensus_ms_p99"] = percentile(c.ms, 0.99);
  state.counters["consensus_iterations"] = c.iterations;
  double commit_total = 0.0;
  for (double m : c.commit_ms) commit_total += m;
  state.counters["consensus_commit_ms_mean"] = commit_total / static_cast<double>(c.ms.size());
  state.counters["consensus_update_ms_p50"] =
      c.update_ms.empty() ? 0.0 : percentile(c.update_ms, 0.5);
  state.counters["consensus_updates"] = static_cast<double>(c.update_ms.size());
  state.counters["naive_ms_p50"] = percentile(n.ms, 0.5);
  state.counters["naive_ms_p99"] = percentile(n.ms, 0.99);
  state.counters["naive_iterations"] = n.iterations;
  state.counters["time_ratio"] = c.total_ms / n.total_ms;
}
BENCHMARK(ConsensusVersusNaive)->Iterations(1)->Unit(benchmark::kSecond);

// Consensus on one thread and with a helper, side by side (the poses are the same); with the
// reference update's median over the scans that changed the reference, as above.
void ConsensusOneVersusTwoThreads(benchmark::State& state) {
  street_scans();
  cndt::runtime::ScoreThreads helper(1, {});
  Run one, two;
  for (auto _ : state) {
    one = run_sequence(cndt::slam::OdometryMode::kConsensus);
    two = run_sequence(cndt::slam::OdometryMode::kConsensus, &helper);
  }
  state.counters["one_thread_ms_p50"] = percentile(one.ms, 0.5);
  state.counters["one_thread_ms_p99"] = percentile(one.ms, 0.99);
  state.counters["two_threads_ms_p50"] = percentile(two.ms, 0.5);
  state.counters["two_threads_ms_p99"] = percentile(two.ms, 0.99);
  state.counters["one_thread_update_ms_p50"] = percentile(one.update_ms, 0.5);
  state.counters["two_threads_update_ms_p50"] = percentile(two.update_ms, 0.5);
  state.counters["time_ratio"] = two.total_ms / one.total_ms;
}
BENCHMARK(ConsensusOneVersusTwoThreads)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
