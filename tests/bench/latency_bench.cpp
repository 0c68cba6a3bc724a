// End-to-end latency of cndtd at the sensor's rate: a simulated VLP-16 street drive is sent over
// loopback UDP at 10 Hz (one packet every 1327.104 us) to the real daemon, which publishes every
// pose as a UDP datagram (and CAN frames to a candump log). For each scan: the time from sending
// the last packet of its revolution to the arrival of its datagram, as the kernel stamps it
// (SO_TIMESTAMPNS, wall clock; the send times are taken on the same clock). Beside it, the time
// to when the benchmark's receiving thread read the datagram: that adds the wake-up of a thread
// that shares the two cores with the daemon, which a controller on its own computer would not
// see. Prints p50/p90/p99/max of both, the scans the daemon dropped, and the daemon's own final
// health line.
//
//   latency_bench CNDTD [SECONDS=60] [mapper] [realtime] [scoring=N] [csv=FILE]
//
// With `realtime` the daemon runs as configured for a vehicle computer ([runtime] realtime =
// true: memory locked, the odometry thread SCHED_FIFO and pinned to the last CPU, the mapper to
// the first); it needs the privilege (root or CAP_SYS_NICE), else the daemon warns and runs on.
// scoring=N sets [runtime] scoring_threads (default: the configuration's default). csv=FILE
// writes each scan's latencies (scan index, stamp, milliseconds to the kernel's arrival and to the
// read) to FILE.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "cndt/core/percentile.hpp"
#include "cndt/net/udp_datagram.hpp"
#include "cndt/output/udp_codec.hpp"
#include "cndt/sim/lidar_sim.hpp"

extern char** environ;

namespace {

using Clock = std::chrono::steady_clock;
using Wall = std::chrono::system_clock;

void print_percentiles(const char* what, const std::vector<double>& ms) {
  std::printf("%s over %zu scans: p50 %.1f ms, p90 %.1f ms, p99 %.1f ms, max %.1f ms\n", what,
              ms.size(), cndt::core::percentile(ms, 0.5), cndt::core::percentile(ms, 0.9),
              cndt::core::percentile(ms, 0.99), cndt::core::percentile(ms, 1.0));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: latency_bench CNDTD [SECONDS=60] [mapper] [realtime] [scoring=N] "
                 "[csv=FILE]\n";
    return 2;
  }
  const std::string cndtd = argv[1];
  const double seconds = argc > 2 ? std::stod(argv[2]) : 60.0;
  bool mapper = false, realtime = false;
  std::string scoring;   // [runtime] scoring_threads, empty: the default
  std::string csv_path;  // per-scan latencies, empty: none
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "mapper") {
      mapper = true;
    } else if (a == "realtime") {
      realtime = true;
    } else if (a.starts_with("scoring=") && a.size() > 8 &&
               a.find_first_not_of("0123456789", 8) == std::string::npos) {
      scoring = a.substr(8);
    } else if (a.starts_with("csv=") && a.size() > 4) {
      csv_path = a.substr(4);
    } else {
      std::cerr << "latency_bench: unknown argument '" << a
                << "' (mapper, realtime, scoring=N, csv=FILE)\n";
      return 2;
    }
  }
  const unsigned cpus = std::max(1u, std::thread::hardware_concurrency());

  const auto dir =
      std::filesystem::temp_directory_path() / ("cndt-latency-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::uint16_t data_port = 0;
  {
    auto probe = cndt::net::UdpReceiver::open("127.0.0.1", 0);
    data_port = probe.value()->port();
  }
  auto rx = cndt::net::UdpReceiver::open("127.0.0.1", 0);
  if (!rx) {
    std::cerr << rx.error().message << "\n";
    return 1;
  }
  {
    std::ofstream cfg(dir / "cndtd.toml");
    cfg << "[sensor]\nbind_address = \"127.0.0.1\"\ndata_port = " << data_port
        << "\nposition_port = 0\n[mapper]\nenabled = " << (mapper ? "true" : "false")
        << "\n[can]\nlog = \"" << (dir / "can.log").string()
        << "\"\n[udp]\ndestinations = [\"127.0.0.1:" << rx.value()->port() << "\"]\n";
    cfg << "[runtime]\n";
    if (realtime) {
      cfg << "realtime = true\nodometry_cpu = " << cpus - 1 << "\nmapper_cpu = 0\n";
    }
    if (!scoring.empty()) cfg << "scoring_threads = " << scoring << "\n";
  }
  std::fprintf(stderr, "simulating %.0f s of a street drive...\n", seconds);
  const auto scene = cndt::sim::build_scene(cndt::sim::SceneKind::kStreet, seconds, 4, 1);
  cndt::sim::LidarSimOptions so;
  so.duration_s = seconds;
  cndt::sim::LidarSimulator simulator(scene, so);
  std::vector<cndt::sim::SimPacket> packets;
  cndt::sim::SimPacket p;
  while (simulator.next(p)) packets.push_back(p);

  const std::string cfg_path = (dir / "cndtd.toml").string(),
                    log_path = (dir / "cndtd.log").string();
  std::vector<std::string> args{cndtd, "--config", cfg_path};
  std::vector<char*> argv_c;
  for (auto& a : args) argv_c.push_back(a.data());
  argv_c.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 2, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  if (posix_spawn(&pid, cndtd.c_str(), &fa, nullptr, argv_c.data(), environ) != 0) {
    std::cerr << "cannot start " << cndtd << "\n";
    return 1;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));

  // Receive on a thread of its own: by scan start time, when each datagram arrived (the
  // kernel's stamp) and when this thread read it.
  struct Arrival {
    Wall::time_point kernel, read;
  };
  std::map<std::int64_t, Arrival> arrived;
  std::atomic<bool> stop{false};
  std::thread receiver([&] {
    std::array<std::uint8_t, 256> buf{};
    while (!stop.load()) {
      Wall::time_point kernel{};
      const auto n = rx.value()->receive(buf, std::chrono::milliseconds(100), &kernel);
      const auto now = Wall::now();
      if (!n) continue;
      const auto d = cndt::output::decode_pose_datagram(cndt::core::ByteSpan(buf).first(*n));
      if (d.error == cndt::output::DatagramError::kNone) arrived[d.pose.stamp_ns] = {kernel, now};
    }
  });
  auto tx = cndt::net::UdpSender::open("127.0.0.1", data_port);
  std::vector<Wall::time_point> sent(packets.size());
  const auto start = Clock::now();
  for (std::size_t k = 0; k < packets.size(); ++k) {
    std::this_thread::sleep_until(start + std::chrono::nanoseconds(1'327'104 * k));
    tx.value()->send(packets[k].payload);
    sent[k] = Wall::now();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));
  stop.store(true);
  receiver.join();
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);

  // Scan k ends where scan k+1 starts: its last packet is the last one whose first firing is
  // before the next scan's stamp (that packet completes the revolution in the driver). The
  // daemon dates the sensor's top-of-hour clock by its own clock, so times are compared within
  // the hour.
  constexpr std::int64_t kHour = 3'600'000'000'000;
  const auto in_hour = [](std::int64_t t) { return ((t % kHour) + kHour) % kHour; };
  std::vector<std::int64_t> stamps;
  for (const auto& [s, t] : arrived) stamps.push_back(s);
  std::vector<double> latency_ms, read_ms;
  std::vector<std::pair<std::size_t, std::int64_t>> latency_scan;  // scan index and stamp
  std::size_t j = 0;
  for (std::size_t k = 0; k + 1 < stamps.size(); ++k) {
    const std::int64_t next = stamps[k + 1];
    if (next - stamps[k] > 150'000'000) continue;  // a scan between them is missing
    while (j + 1 < packets.size() && in_hour(packets[j + 1].sensor_time_ns) < in_hour(next)) ++j;
    const Arrival& a = arrived[stamps[k]];
    latency_ms.push_back(std::chrono::duration<double, std::milli>(a.kernel - sent[j]).count());
    read_ms.push_back(std::chrono::duration<double, std::milli>(a.read - sent[j]).count());
    latency_scan.emplace_back(k, stamps[k]);
  }
  if (!csv_path.empty()) {
    std::ofstream csv(csv_path);
    csv << "scan,stamp_ns,latency_ms,read_latency_ms\n";
    for (std::size_t i = 0; i < latency_ms.size(); ++i) {
      csv << latency_scan[i].first << ',' << latency_scan[i].second << ',' << latency_ms[i] << ','
          << read_ms[i] << '\n';
    }
    if (!csv) std::cerr << "latency_bench: cannot write " << csv_path << "\n";
  }
  std::ifstream log_in(log_path);
  std::string line, final_line;
  while (std::getline(log_in, line)) {
    if (line.find("final:") != std::string::npos) final_line = line;
    // Anything the daemon warned about (or a sanitizer reported) is shown.
    if (line.find("warn") != std::string::npos || line.find("error") != std::string::npos ||
        line.find("WARNING") != std::string::npos) {
      std::fprintf(stderr, "daemon: %s\n", line.c_str());
    }
  }
  std::printf(
      "cndtd at 10 Hz over loopback, %.0f s street drive%s%s%s%s: %zu packets, %zu poses "
      "received\n",
      seconds, mapper ? " with the mapper" : "",
      realtime ? ", odometry thread SCHED_FIFO on its own CPU" : "",
      scoring.empty() ? "" : ", scoring_threads = ", scoring.c_str(), packets.size(),
      arrived.size());
  print_percentiles("latency last packet -> pose datagram (its arrival, kernel stamp)", latency_ms);
  print_percentiles("  to its read by the benchmark's receiving thread", read_ms);
  std::printf("daemon exit status %d; %s\n", WIFEXITED(status) ? WEXITSTATUS(status) : -1,
              final_line.c_str());
  if (std::getenv("CNDT_KEEP_LOG") != nullptr) {
    std::filesystem::copy_file(log_path, std::getenv("CNDT_KEEP_LOG"),
                               std::filesystem::copy_options::overwrite_existing);
  }
  std::filesystem::remove_all(dir);
  return 0;
}
