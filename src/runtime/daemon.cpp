#include "cndt/runtime/daemon.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <csignal>
#include <mutex>
#include <thread>

#include "cndt/core/percentile.hpp"
#include "cndt/net/udp_source.hpp"
#include "cndt/pcap/pcap_source.hpp"
#include "cndt/runtime/alloc_counter.hpp"
#include "cndt/runtime/notify.hpp"
#include "cndt/runtime/pipeline.hpp"
#include "cndt/runtime/setup.hpp"
#include "cndt/slam/map_file.hpp"

namespace cndt::runtime {
namespace {

using Clock = std::chrono::steady_clock;

// Input counters copied out of the driver now and then, for the health line.
struct InputCounters {
  std::mutex mutex;
  vlp16::DriverStats driver;
  std::uint64_t lost_packets = 0;
  std::uint64_t udp_queue_full = 0;
};

}  // namespace

int run_daemon(const config::Config& c) {
  auto setup_r = make_setup(c);
  if (!setup_r) {
    spdlog::error("{}", setup_r.error().message);
    return setup_r.error().code;
  }
  Setup& setup = setup_r.value();
  const bool live = c.sensor.source == "udp";
  setup.pipeline.live = live;

  // Signals are taken by the main thread only (sigtimedwait), never by the workers.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  if (c.runtime.realtime) {
    if (auto problem = lock_memory()) {
      spdlog::warn("{}; running on without it", *problem);
    } else {
      spdlog::info("memory locked (mlockall)");
    }
  }
  auto publisher = make_publisher(c, setup.publisher);
  if (!publisher) {
    spdlog::error("{}", publisher.error().message);
    return publisher.error().code;
  }
  for (const auto& bus : publisher.value()->can_buses()) {
    spdlog::info("publishing CAN frames on {}", bus->describe());
  }
  for (const auto& udp : publisher.value()->udp_senders()) {
    spdlog::info("publishing pose datagrams to {}", udp->describe());
  }

  Pipeline pipeline(setup.pipeline, setup.max_points, *publisher.value());
  if (!c.mapper.load.empty()) {
    auto prior = slam::load_map_file(c.mapper.load, setup.pipeline.mapper_options.map);
    if (!prior) {
      spdlog::error("{}", prior.error().message);
      return prior.error().code;
    }
    spdlog::info("localizing in '{}' ({} map): {} voxels", c.mapper.load, c.mapper.mode,
                 prior.value().size());
    pipeline.start_from(std::move(prior.value()), setup.initial_pose);
  }
  // WATCHDOG=1 from the odometry loop: a stalled odometry gets the service restarted.
  Notifier notifier;
  if (notifier.watchdog_interval().count() > 0) {
    spdlog::info("systemd watchdog every {:.1f} s: pinged from the odometry loop",
                 static_cast<double>(notifier.watchdog_interval().count()) * 1e-6);
  }
  pipeline.on_scan_done([](void* n) { static_cast<Notifier*>(n)->watchdog(); }, &notifier);

  // Input.
  std::unique_ptr<io::PacketSource> source;
  net::UdpSource* udp_source = nullptr;
  if (live) {
    auto udp = net::UdpSource::open(setup.udp);
    if (!udp) {
      spdlog::error("{}", udp.error().message);
      return udp.error().code;
    }
    udp_source = udp.value().get();
    spdlog::info("receiving VLP-16 packets on UDP {}:{} (position {})", c.sensor.bind_address,
                 udp_source->data_port(), udp_source->position_port());
    source = std::move(udp.value());
  } else {
    auto pcap = pcap::PcapSource::open(c.sensor.pcap, setup.pcap);
    if (!pcap) {
      spdlog::error("{}", pcap.error().message);
      return pcap.error().code;
    }
    spdlog::info("reading packets from '{}' ({})", c.sensor.pcap,
                 c.sensor.pcap_realtime ? "at the recorded pace" : "as fast as possible");
    source = std::move(pcap.value());
  }

  pipeline.start();
  InputCounters counters;
  std::atomic<bool> stop_input{false}, input_ended{false};
  std::thread input([&] {
    vlp16::Driver driver(setup.driver);
    auto sink = [&](core::Scan& scan) { pipeline.push(scan, Clock::now()); };
    io::SourcePacket packet;
    auto last_copy = Clock::now();
    const auto copy_counters = [&] {
      std::lock_guard<std::mutex> lock(counters.mutex);
      counters.driver = driver.stats();
      counters.lost_packets = driver.assembler_stats().lost_packets;
      if (udp_source != nullptr) counters.udp_queue_full = udp_source->stats().queue_full;
    };
    while (!stop_input.load()) {
      const io::NextResult r = source->next(packet, std::chrono::milliseconds(100));
      if (r == io::NextResult::kEnd) break;
      if (live) pipeline.service_input();
      if (r == io::NextResult::kPacket) {
        if (packet.kind == io::PacketKind::kData) {
          driver.on_data(packet.payload, packet.time, sink);
        } else {
          driver.on_position(packet.payload);
        }
      }
      if (Clock::now() - last_copy > std::chrono::milliseconds(500)) {
        copy_counters();
        last_copy = Clock::now();
      }
    }
    if (!stop_input.load()) driver.finish(sink);  // the end of a capture: its last scan too
    copy_counters();
    input_ended.store(true);
  });

  // Main thread: results, health, signals.
  std::vector<double> latency, odo_ms, cm;
  std::uint64_t results = 0, valid = 0, degraded = 0, lost = 0, last_scans = 0;
  bool ready = false;
  auto last_status = Clock::now();
  const auto interval = std::chrono::duration<double>(c.runtime.status_interval_s);
  const auto status = [&](bool final_line) {
    const PipelineStats ps = pipeline.stats();
    InputCounters snap;
    {
      std::lock_guard<std::mutex> lock(counters.mutex);
      snap.driver = counters.driver;
      snap.lost_packets = counters.lost_packets;
      snap.udp_queue_full = counters.udp_queue_full;
    }
    std::string can_text, udp_text;
    for (const auto& bus : publisher.value()->can_buses()) {
      const auto s = bus->stats();
      can_text += fmt::format("; CAN {} sent, {} dropped, {} errors", s.sent, s.dropped_queue_full,
                              s.errors);
    }
    for (const auto& u : publisher.value()->udp_senders()) {
      const auto s = u->stats();
      udp_text += fmt::format("; UDP {} sent, {} dropped, {} errors", s.sent, s.dropped_would_block,
                              s.errors);
    }
    const std::string window =
        final_line ? std::string()
                   : fmt::format(
                         "; odometry {:.1f}/{:.1f} ms, latency {:.1f}/{:.1f} ms (p50/p99 "
                         "over the last {} scans); Cm median {:.2f}",
                         core::percentile(odo_ms, 0.5), core::percentile(odo_ms, 0.99),
                         core::percentile(latency, 0.5), core::percentile(latency, 0.99),
                         odo_ms.size(), core::percentile(cm, 0.5));
    const std::string line = fmt::format(
        "{} scans (+{}), {} dropped; packets {} ok, rejected: {}, {} lost, {} queue-full{}; "
        "poses {} valid, {} degraded, {} lost; keyframes {}; heap allocations in odometry "
        "{}{}{}",
        ps.scans_done, ps.scans_done - last_scans, ps.scans_dropped, snap.driver.decoded_packets,
        snap.driver.rejects_text(), snap.lost_packets, snap.udp_queue_full, window, valid, degraded,
        lost, ps.keyframes,
        ps.allocations_counted ? fmt::format("{}, page faults {}", ps.heap_allocations_in_odometry,
                                             ps.page_faults_in_odometry)
                               : std::string("(warming up)"),
        can_text, udp_text);
    spdlog::info("{}{}", final_line ? "final: " : "", line);
    notifier.send(fmt::format("STATUS={} scans, {} dropped, Cm {:.2f}, latency p99 {:.1f} ms",
                              ps.scans_done, ps.scans_dropped, core::percentile(cm, 0.5),
                              core::percentile(latency, 0.99)));
    last_scans = ps.scans_done;
    latency.clear();
    odo_ms.clear();
    cm.clear();
  };
  ScanResult res;
  bool stopping = false;
  while (!pipeline.done()) {
    while (pipeline.pop(res)) {
      ++results;
      odo_ms.push_back(res.odometry_ms);
      if (!res.published_pose) continue;
      latency.push_back(res.latency_ms);
      cm.push_back(res.odometry.cm);
      const auto m =
          make_pose_message(res.odometry, res.published, res.map_corrected, 0, setup.publisher);
      valid += m.status == output::PoseStatus::kValid;
      degraded += m.status == output::PoseStatus::kDegraded;
      lost += m.status == output::PoseStatus::kLost;
      if (!ready) {
        ready = true;
        notifier.send("READY=1\nSTATUS=scans flowing");
        spdlog::info("first pose published: ready");
      }
    }
    if (!stopping && input_ended.load()) {
      spdlog::info("input ended: finishing the queued scans");
      pipeline.close_input(true);
      stopping = true;
    }
    timespec wait{0, 100'000'000};
    const int sig = sigtimedwait(&stop_signals, nullptr, &wait);
    if (sig > 0 && !stopping) {
      spdlog::info("{}: finishing the scan in hand, then saving and exiting",
                   sig == SIGTERM ? "SIGTERM" : "SIGINT");
      notifier.send("STOPPING=1");
      stop_input.store(true);
      if (udp_source != nullptr) udp_source->stop();
      pipeline.close_input(false);
      stopping = true;
    }
    if (Clock::now() - last_status >= interval) {
      status(false);
      last_status = Clock::now();
    }
  }
  stop_input.store(true);
  if (udp_source != nullptr) udp_source->stop();
  input.join();
  pipeline.join();
  while (pipeline.pop(res)) ++results;
  status(true);
  int rc = 0;
  slam::Mapper* mapper = pipeline.mapper();
  if (mapper != nullptr && !c.mapper.save.empty() && mapper->map().size() == 0) {
    // A daemon stopped before any scan (no sensor) must not replace a good map by nothing.
    spdlog::warn("the map is empty: '{}' is left as it was", c.mapper.save);
  } else if (mapper != nullptr && !c.mapper.save.empty()) {
    if (auto err = slam::save_map_file(mapper->map(), c.mapper.save)) {
      spdlog::error("{}", err->message);
      rc = err->code;
    } else {
      spdlog::info("map saved to '{}': {} voxels", c.mapper.save, mapper->map().size());
    }
  }
  return rc;
}

}  // namespace cndt::runtime
