// cndt replay: a capture (or a folder of clouds) through the runtime cndtd runs on (the same
// threads, rings and publishers), in replay mode: back-pressure instead of drops, so that the
// outputs are the same on every run.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "cndt/cli/commands.hpp"
#include "cndt/config/config.hpp"
#include "cndt/core/percentile.hpp"
#include "cndt/runtime/alloc_counter.hpp"
#include "cndt/runtime/pipeline.hpp"
#include "cndt/runtime/setup.hpp"
#include "cndt/slam/map_file.hpp"

namespace cndt::cli {
namespace {

void write_tum(std::ofstream& out, double t, const Eigen::Isometry3d& pose) {
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d p = pose.translation();
  const auto ns = static_cast<std::int64_t>(std::llround(t * 1e9));
  out << fmt::format("{}.{:09d} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f}\n",
                     ns / 1'000'000'000, ns % 1'000'000'000, p.x(), p.y(), p.z(), q.x(), q.y(),
                     q.z(), q.w());
}

// "x,y,z,roll,pitch,yaw" (metres, degrees) as six numbers.
core::Result<std::vector<double>> parse_pose(const std::string& s) {
  std::vector<double> v;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');) {
    try {
      std::size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size() || !std::isfinite(v.back())) v.clear();
    } catch (const std::exception&) {
      v.clear();
    }
    if (v.empty()) break;
  }
  if (v.size() != 6) {
    return core::Error{core::kExitUsage,
                       fmt::format("--initial-pose '{}': expected x,y,z,roll,pitch,yaw (metres, "
                                   "degrees), six numbers",
                                   s)};
  }
  return v;
}

// Whether an option was typed (always true when run_replay is called without a parser).
bool given(const ReplayArgs& a, const char* option) {
  return a.command == nullptr || a.command->count(option) > 0;
}

// The configuration the replay runs with: the file's (or the defaults), then every option
// given on the command line on top.
core::Result<config::Config> replay_config(const ReplayArgs& a) {
  auto loaded = odometry_config(a.input, a.command);
  if (!loaded) return loaded.error();
  config::Config c = std::move(loaded.value());
  if (given(a, "--jitter-seed")) c.odometry.guess_jitter_seed = a.jitter_seed;
  if (given(a, "--mapper")) c.mapper.enabled = c.mapper.enabled || a.mapper;
  if (given(a, "--map")) c.mapper.load = a.map;
  if (given(a, "--map-mode")) c.mapper.mode = a.map_mode;
  if (given(a, "--save-map")) c.mapper.save = a.save_map;
  if (given(a, "--map-window")) c.mapper.window_m = a.map_window_m;
  if (given(a, "--initial-pose") && !a.initial_pose.empty()) {
    auto pose = parse_pose(a.initial_pose);
    if (!pose) return pose.error();
    c.mapper.initial_pose = pose.value();
  }
  if (!a.udp_out.empty()) c.udp.destinations.push_back(a.udp_out);
  if (!a.udp_out.empty() && !runtime::split_endpoint(a.udp_out)) {
    return core::Error{core::kExitUsage,
                       fmt::format("--udp-out '{}': expected ADDRESS:PORT (e.g. 127.0.0.1:5600, "
                                   "[::1]:5600)",
                                   a.udp_out)};
  }
  return c;
}

// Per-keyframe outputs of the mapper, written on the mapper thread.
struct MapperOutputs {
  std::ofstream refined_tum, refined_csv;
  std::vector<double> map_cm, mapper_ms;
};

}  // namespace

void register_replay(CLI::App& app, ReplayArgs& a) {
  auto* cmd = a.command = app.add_subcommand(
      "replay",
      "Run consensus-NDT odometry over a capture and write trajectory.tum (time x y z "
      "qx qy qz qw: the sensor pose at each scan start), scans.csv (per scan: time, "
      "Cm, iterations, voxels before/after the Cv cut, points, milliseconds, flags) "
      "summary.json and can.log (every CAN frame cndtd would send, candump format; "
      "config/cndt.dbc describes them)");
  add_odometry_input_options(*cmd, a.input);
  cmd->add_option("--out", a.out_dir, "Output folder (created if missing)")->required();
  cmd->add_option("--jitter-seed", a.jitter_seed,
                  "Evaluation only: move every match's initial guess by at most 0.5e-9 m / rad "
                  "per coordinate, drawn from this seed (0: off). Replays under a few seeds show "
                  "how far a result depends on chance at the level of rounding "
                  "(docs/accuracy.md)")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{1'000'000'000}));
  cmd->add_flag("--realtime", a.realtime,
                "Deliver the capture's packets at their recorded pace (default: as fast as the "
                "odometry takes them)");
  cmd->add_option("--max-scans", a.max_scans, "Stop after this many scans (0: all)")
      ->capture_default_str();
  cmd->add_flag("--mapper", a.mapper,
                "Run the mapper (keyframes, eq-7 refinement, map): trajectory.tum is then the "
                "odometry corrected by the map as it stood at each scan (each new correction "
                "blended in over mapper.correction_time_constant_s), odometry.tum the odometry "
                "alone, refined.tum every scan pose after its keyframe's refinement and "
                "refined.csv its Cm against the map. Off by default (it takes a second core; on "
                "simulated drives it brings the ATE to 0.1-0.3 x the odometry's, "
                "docs/mapper.md). --map and --save-map imply it");
  auto* map = cmd->add_option("--map", a.map,
                              "Localize in this prior map (a cndt map file) instead of building "
                              "one from scratch");
  cmd->add_option("--map-mode", a.map_mode,
                  "With --map: frozen (the prior map is not changed) or update (refined scans "
                  "are added to it)")
      ->capture_default_str()
      ->check(CLI::IsMember({"frozen", "update"}))
      ->needs(map);
  cmd->add_option("--initial-pose", a.initial_pose,
                  "With --map: the first scan's pose in the map frame, x,y,z,roll,pitch,yaw "
                  "(metres, degrees; default 0,0,0,0,0,0)")
      ->needs(map);
  cmd->add_option("--save-map", a.save_map,
                  "Write the map here at the end (atomically; see docs/map_format.md)");
  cmd->add_option("--map-window", a.map_window_m,
                  "With the mapper: keep only map voxels within this many metres (horizontally) "
                  "of the vehicle, so that memory stays bounded on long runs; 0 keeps the whole "
                  "map")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e5));
  cmd->add_option("--udp-out", a.udp_out,
                  "Also send every pose as a UDP datagram (docs/protocol.md) to ADDRESS:PORT, "
                  "e.g. 127.0.0.1:5600 (see cndt listen --udp)");
}

int run_replay(const ReplayArgs& a) {
  auto cfg = replay_config(a);
  if (!cfg) return fail(cfg.error());
  const config::Config& c = cfg.value();
  if (auto err = check_not_one_cloud(a.input.capture)) return fail(*err);
  auto setup_r = runtime::make_setup(c);
  if (!setup_r) return fail(setup_r.error());
  runtime::Setup& setup = setup_r.value();
  setup.pcap.speed = a.realtime ? 1.0 : 0.0;
  setup.pipeline.live = false;
  if (!c.can.interface.empty()) {
    spdlog::info("replay does not send on CAN interface '{}': the frames are in can.log",
                 c.can.interface);
  }
  if (auto err = create_output_dir(a.out_dir)) return fail(*err);
  const std::filesystem::path dir(a.out_dir);

  config::Config outputs = c;
  outputs.can.interface.clear();
  outputs.can.log = (dir / "can.log").string();
  auto publisher = runtime::make_publisher(outputs, setup.publisher);
  if (!publisher) return fail(publisher.error());

  std::optional<slam::NdtMap> prior;
  if (!c.mapper.load.empty()) {
    auto loaded = slam::load_map_file(c.mapper.load, setup.pipeline.mapper_options.map);
    if (!loaded) return fail(loaded.error());
    spdlog::info("localizing in '{}' ({} map): {} voxels", c.mapper.load, c.mapper.mode,
                 loaded.value().size());
    prior = std::move(loaded.value());
  }
  const bool with_mapper = setup.pipeline.mapper;
  std::ofstream trajectory(dir / "trajectory.tum", std::ios::trunc);
  std::ofstream csv(dir / "scans.csv", std::ios::trunc);
  std::ofstream odometry_tum;
  MapperOutputs mo;
  if (with_mapper) {
    odometry_tum.open(dir / "odometry.tum", std::ios::trunc);
    mo.refined_tum.open(dir / "refined.tum", std::ios::trunc);
    mo.refined_csv.open(dir / "refined.csv", std::ios::trunc);
    mo.refined_csv << "time,keyframe,cm_map\n";
  }
  if (!trajectory || !csv ||
      (with_mapper && (!odometry_tum || !mo.refined_tum || !mo.refined_csv))) {
    return fail({core::kExitIoError,
                 fmt::format("cannot write in '{}': {}", a.out_dir, std::strerror(errno))});
  }
  csv << "time,cm,coarse_iterations,fine_iterations,voxels_before,voxels_after,points,"
         "raw_points,odometry_ms,flags\n";

  runtime::Pipeline pipeline(setup.pipeline, setup.max_points, *publisher.value());
  if (prior) pipeline.start_from(std::move(*prior), setup.initial_pose);
  if (with_mapper) {
    pipeline.on_keyframe([&mo](const slam::Mapper& m, double ms) {
      mo.mapper_ms.push_back(ms);
      for (const auto& p : m.refined()) {
        write_tum(mo.refined_tum, p.stamp, p.pose);
        mo.refined_csv << fmt::format("{:.9f},{},{:.6f}\n", p.stamp, m.stats().keyframes, p.cm);
        if (!std::isnan(p.cm)) mo.map_cm.push_back(p.cm);
      }
    });
  }
  const auto wall0 = std::chrono::steady_clock::now();
  pipeline.start();

  // The input thread: packets through the driver, scans into the pipeline.
  std::optional<core::Error> input_error;
  CaptureReport report;
  std::thread input([&] {
    // After stop() (a failed runtime) the pipeline takes no more scans.
    const auto push = [](const core::Scan& scan, void* ctx) {
      static_cast<runtime::Pipeline*>(ctx)->push(scan, std::chrono::steady_clock::now());
    };
    CaptureOptions co;
    co.pcap = setup.pcap;
    co.driver = setup.driver;
    auto r = read_scans(a.input.capture, co, setup.max_points, a.input.scan_period_s, a.max_scans,
                        push, &pipeline);
    if (!r) {
      input_error = r.error();
    } else {
      report = std::move(r.value());
    }
    pipeline.close_input(true);
  });

  std::vector<double> ms;
  std::uint64_t iterations = 0, scans = 0;
  const auto consume = [&](const runtime::ScanResult& res) {
    const slam::OdometryResult& r = res.odometry;
    const std::int64_t ns = r.stamp.count();
    const double t = static_cast<double>(ns) * 1e-9;
    ms.push_back(res.odometry_ms);
    iterations += static_cast<std::uint64_t>(r.coarse_iterations + r.fine_iterations);
    ++scans;
    // A skipped scan has no pose; its line in the per-scan table says why.
    if (res.published_pose) {
      write_tum(trajectory, t, res.published);
      if (with_mapper) write_tum(odometry_tum, t, r.pose);
    }
    csv << fmt::format("{}.{:09d},{:.6f},{},{},{},{},{},{},{:.3f},{}\n", ns / 1'000'000'000,
                       ns % 1'000'000'000, r.cm, r.coarse_iterations, r.fine_iterations,
                       r.voxels_before, r.voxels_after, r.points, r.raw_points, res.odometry_ms,
                       r.flags);
  };
  runtime::ScanResult res;
  while (!pipeline.done()) {
    bool any = false;
    while (pipeline.pop(res)) {
      consume(res);
      any = true;
    }
    if (!any) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  input.join();
  pipeline.join();
  while (pipeline.pop(res)) consume(res);
  if (input_error) return fail(*input_error);
  if (!report.path.empty()) warn_if_cut_short(report);

  const runtime::PipelineStats ps = pipeline.stats();
  slam::Mapper* mapper = pipeline.mapper();
  if (with_mapper) {
    odometry_tum.close();
    mo.refined_tum.close();
    mo.refined_csv.close();
    if (!c.mapper.save.empty()) {
      if (auto err = slam::save_map_file(mapper->map(), c.mapper.save)) return fail(*err);
      spdlog::info("map saved to '{}': {} voxels", c.mapper.save, mapper->map().size());
    }
  }
  for (const auto& bus : publisher.value()->can_buses()) {
    if (bus->stats().errors > 0) {
      return fail({core::kExitIoError, fmt::format("{}: {} frames could not be written",
                                                   bus->describe(), bus->stats().errors)});
    }
  }
  for (const auto& udp : publisher.value()->udp_senders()) {
    const auto st = udp->stats();
    if (st.dropped_would_block + st.errors > 0) {
      spdlog::warn("{}: {} datagrams sent, {} dropped (socket full), {} failed", udp->describe(),
                   st.sent, st.dropped_would_block, st.errors);
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  trajectory.close();
  csv.close();
  if (!trajectory || !csv) {
    return fail({core::kExitIoError, fmt::format("writing in '{}' failed", a.out_dir)});
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::ofstream summary(dir / "summary.json", std::ios::trunc);
  summary << fmt::format(
      "{{\n  \"scans\": {},\n  \"packets_ok\": {},\n  \"packets_bad\": {},\n  \"scans_dropped\": "
      "{},\n  \"lost_packets\": {},\n  \"odometry_ms_p50\": {:.3f},\n  \"odometry_ms_p99\": "
      "{:.3f},\n  \"iterations_mean\": {:.3f},\n  \"heap_allocations_in_odometry\": {},\n  "
      "\"heap_allocations_counted_after_scan\": {},\n  \"heap_allocations_include_malloc\": "
      "{},\n  \"page_faults_in_odometry\": {},\n  \"peak_rss_mb\": {:.1f},\n  \"wall_s\": "
      "{:.3f},\n "
      " \"mode\": \"{}\",\n  \"reference\": \"{}\",\n  \"mapper\": {},\n  \"keyframes\": {},\n  "
      "\"mapper_ms_p50\": {:.3f},\n  \"mapper_ms_p99\": {:.3f},\n  \"map_voxels\": {},\n  "
      "\"map_cm_median\": {:.4f}\n}}\n",
      scans, report.driver.decoded_packets, report.driver.rejected_total(), ps.scans_dropped,
      report.assembler.lost_packets, core::percentile(ms, 0.5), core::percentile(ms, 0.99),
      scans > 1 ? static_cast<double>(iterations) / static_cast<double>(scans - 1) : 0.0,
      ps.heap_allocations_in_odometry, setup.pipeline.warmup_scans, runtime::alloc_counts_malloc(),
      ps.page_faults_in_odometry, static_cast<double>(ru.ru_maxrss) / 1024.0, wall, c.odometry.mode,
      c.odometry.reference, with_mapper, mapper ? mapper->stats().keyframes : 0,
      core::percentile(mo.mapper_ms, 0.5), core::percentile(mo.mapper_ms, 0.99),
      mapper ? mapper->map().size() : 0, core::percentile(mo.map_cm, 0.5));
  summary.close();
  if (scans == 0) return fail(no_scan_error(a.input.capture, report.driver));
  spdlog::info("{} scans in {:.1f} s; odometry {:.1f} ms median, {:.1f} ms p99; results in '{}'",
               scans, wall, core::percentile(ms, 0.5), core::percentile(ms, 0.99), a.out_dir);
  return core::kExitOk;
}

}  // namespace cndt::cli
