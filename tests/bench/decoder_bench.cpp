// Decoder + scan assembler throughput on simulated VLP-16 packets (street scene, 600 rpm).
// Run: build/release/tests/bench/decoder_bench --benchmark_repetitions=5
// The AVX2 kernel is used where the CPU has it; BM_Decode_* compare the two kernels.
#include <benchmark/benchmark.h>

#include <vector>

#include "cndt/sim/lidar_sim.hpp"
#include "cndt/vlp16/driver.hpp"

namespace {

std::vector<std::array<std::uint8_t, 1206>> make_packets(bool dual) {
  static const cndt::sim::Scene scene =
      cndt::sim::build_scene(cndt::sim::SceneKind::kStreet, 2.0, 4, 1);
  cndt::sim::LidarSimOptions o;
  o.duration_s = 2.0;
  o.dual = dual;
  cndt::sim::LidarSimulator sim(scene, o);
  std::vector<std::array<std::uint8_t, 1206>> out;
  cndt::sim::SimPacket p;
  while (sim.next(p)) out.push_back(p.payload);
  return out;
}

void run(benchmark::State& state, bool dual) {
  const auto packets = make_packets(dual);
  cndt::vlp16::Driver driver({});
  std::size_t scans = 0, points = 0;
  auto sink = [&](cndt::core::Scan& s) {
    ++scans;
    points += s.points.size();
  };
  std::int64_t t = 1'700'000'000'000'000'000;
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& p = packets[i];
    // The sensor clock runs on, so the assembler sees a continuous stream across iterations.
    driver.on_data(cndt::core::ByteSpan(p), std::chrono::nanoseconds(t), sink);
    t += dual ? 663'552 : 1'327'104;
    i = (i + 1) % packets.size();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
  state.counters["packets_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["points_per_packet"] =
      scans > 0 ? static_cast<double>(points) / static_cast<double>(state.iterations()) : 0.0;
}

void BM_DecodeAssemble_Strongest(benchmark::State& s) { run(s, false); }
void BM_DecodeAssemble_Dual(benchmark::State& s) { run(s, true); }
BENCHMARK(BM_DecodeAssemble_Strongest);
BENCHMARK(BM_DecodeAssemble_Dual);

}  // namespace

namespace {
// The decoder alone on the same packets, its portable and its AVX2 kernel side by side.
void decode_only(benchmark::State& state, bool simd) {
  const auto packets = make_packets(false);
  cndt::vlp16::DecoderOptions o;
  o.simd = simd;
  const cndt::vlp16::Decoder dec(cndt::vlp16::Model::kVlp16, o);
  cndt::vlp16::DecodedPacket out;
  std::size_t i = 0;
  for (auto _ : state) {
    const cndt::core::ByteSpan bytes(packets[i]);
    cndt::vlp16::PacketHeader h;
    if (cndt::vlp16::validate_data_packet(bytes, h) == cndt::vlp16::PacketError::kNone) {
      dec.decode(bytes, h, out);
    }
    benchmark::DoNotOptimize(out.point_count);
    i = (i + 1) % packets.size();
  }
  state.counters["packets_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
void BM_Decode_Portable(benchmark::State& s) { decode_only(s, false); }
void BM_Decode_Simd(benchmark::State& s) { decode_only(s, true); }
BENCHMARK(BM_Decode_Portable);
BENCHMARK(BM_Decode_Simd);
}  // namespace
