// Scans of a simulated VLP-16 drive, decoded by the driver as a live run would decode them: for
// benchmarks and tests that need realistic scans without a capture file.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "cndt/core/scan.hpp"
#include "cndt/sim/lidar_sim.hpp"
#include "cndt/vlp16/driver.hpp"

namespace cndt::test {

/// Simulates driving through `scene` with the sensor settings `o` and hands every scan the
/// driver assembles to `sink`, the last partial one included. Returns the simulator's scan
/// starts (ground truth).
template <class Sink>
std::vector<sim::ScanStart> simulate_scene(const sim::Scene& scene, const sim::LidarSimOptions& o,
                                           Sink&& sink) {
  sim::LidarSimulator simulator(scene, o);
  vlp16::Driver driver({});
  sim::SimPacket p;
  while (simulator.next(p)) {
    if (p.dropped) continue;  // lost on the way
    driver.on_data(core::ByteSpan(p.payload), std::chrono::nanoseconds(p.capture_time_ns), sink);
  }
  driver.finish(sink);
  return simulator.scan_starts();
}

/// The first `seconds` of it with the default sensor (`seed` for the sensor's noise).
template <class Sink>
std::vector<sim::ScanStart> simulate_scene(const sim::Scene& scene, double seconds,
                                           std::uint64_t seed, Sink&& sink) {
  sim::LidarSimOptions o;
  o.duration_s = seconds;
  o.seed = seed;
  return simulate_scene(scene, o, sink);
}

/// The same for `seconds` of a `kind` drive with `movers` (`seed` for world, traffic and noise).
template <class Sink>
std::vector<sim::ScanStart> simulate_scans(sim::SceneKind kind, double seconds, int movers,
                                           std::uint64_t seed, Sink&& sink) {
  return simulate_scene(sim::build_scene(kind, seconds, movers, seed), seconds, seed, sink);
}

/// The scans of such a drive with 4 movers, collected.
inline std::vector<core::Scan> simulate_scans(sim::SceneKind kind, double seconds,
                                              std::uint64_t seed) {
  std::vector<core::Scan> out;
  simulate_scans(kind, seconds, 4, seed, [&](core::Scan& s) { out.push_back(s); });
  return out;
}

}  // namespace cndt::test
