#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cndt/cli/alloc_counter.hpp"
#include "cndt/cli/cloud_io.hpp"
#include "cndt/cli/commands.hpp"
#include "cndt/runtime/publisher.hpp"
#include "cndt/slam/map_file.hpp"
#include "cndt/slam/mapper.hpp"
#include "cndt/slam/odometry.hpp"

namespace cndt::cli {
namespace {

constexpr std::size_t kWarmupScans = 20;  // buffers reach their working size by then

struct ReplayContext {
  slam::ConsensusOdometry* odometry = nullptr;
  slam::Mapper* mapper = nullptr;  // null: odometry only
  runtime::PosePublisher* publisher = nullptr;
  std::ofstream trajectory, csv;
  std::ofstream odometry_tum, refined_tum, refined_csv;  // with the mapper
  std::vector<double> map_cm;                            // Cm against the map, per refined scan
  std::vector<double> mapper_ms;                         // per closed keyframe
  std::size_t max_scans = 0;
  std::size_t scans = 0;
  std::vector<double> ms;
  std::uint64_t iterations = 0;
  std::uint64_t allocations = 0;
  bool done = false;
};

void write_tum(std::ofstream& out, double t, const Eigen::Isometry3d& pose) {
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d p = pose.translation();
  const auto ns = static_cast<std::int64_t>(std::llround(t * 1e9));
  out << fmt::format("{}.{:09d} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f}\n",
                     ns / 1'000'000'000, ns % 1'000'000'000, p.x(), p.y(), p.z(), q.x(), q.y(),
                     q.z(), q.w());
}

// "x,y,z,roll,pitch,yaw" (metres, degrees) as a pose.
core::Result<Eigen::Isometry3d> parse_pose(const std::string& s) {
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
  constexpr double kDeg = M_PI / 180.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::rotation(v[3] * kDeg, v[4] * kDeg, v[5] * kDeg);
  T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return T;
}

void write_refined(ReplayContext& c) {
  for (const auto& p : c.mapper->refined()) {
    write_tum(c.refined_tum, p.stamp, p.pose);
    c.refined_csv << fmt::format("{:.9f},{},{:.6f}\n", p.stamp, c.mapper->stats().keyframes, p.cm);
    if (!std::isnan(p.cm)) c.map_cm.push_back(p.cm);
  }
}

void on_scan(const core::Scan& scan, void* user) {
  auto& c = *static_cast<ReplayContext*>(user);
  if (c.done) return;
  const bool counting = c.scans >= kWarmupScans;
  const std::uint64_t before = alloc_count();
  alloc_counting(counting);
  const auto t0 = std::chrono::steady_clock::now();
  const slam::OdometryResult r = c.odometry->process(scan);
  const auto t1 = std::chrono::steady_clock::now();
  alloc_counting(false);
  if (counting) c.allocations += alloc_count() - before;
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  c.ms.push_back(ms);
  c.iterations += static_cast<std::uint64_t>(r.coarse_iterations + r.fine_iterations);
  const std::int64_t ns = r.stamp.count();
  // A skipped scan has no pose; its line in the per-scan table says why.
  if ((r.flags & slam::kOdomSkipped) == 0) {
    Eigen::Isometry3d published = r.pose;
    if (c.mapper == nullptr) {
      write_tum(c.trajectory, static_cast<double>(ns) * 1e-9, r.pose);
    } else {
      if ((r.flags & slam::kOdomTooFewPoints) == 0) {
        const auto m0 = std::chrono::steady_clock::now();
        const bool closed =
            c.mapper->add(static_cast<double>(ns) * 1e-9, r.pose, c.odometry->scan_points());
        if (closed) {
          c.mapper_ms.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - m0)
                  .count());
          write_refined(c);
        }
      }
      write_tum(c.odometry_tum, static_cast<double>(ns) * 1e-9, r.pose);
      published = c.mapper->correction() * r.pose;
      write_tum(c.trajectory, static_cast<double>(ns) * 1e-9, published);
    }
    c.publisher->publish(runtime::make_pose_message(r, published, c.mapper != nullptr,
                                                    static_cast<std::uint32_t>(scan.sequence),
                                                    c.publisher->options()));
  }
  c.csv << fmt::format("{}.{:09d},{:.6f},{},{},{},{},{},{},{:.3f},{}\n", ns / 1'000'000'000,
                       ns % 1'000'000'000, r.cm, r.coarse_iterations, r.fine_iterations,
                       r.voxels_before, r.voxels_after, r.points, r.raw_points, ms, r.flags);
  ++c.scans;
  if (c.max_scans > 0 && c.scans >= c.max_scans) c.done = true;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::min<double>(
      static_cast<double>(v.size() - 1), std::ceil(p * static_cast<double>(v.size())) - 1));
  return v[i];
}

}  // namespace

void register_replay(CLI::App& app, ReplayArgs& a) {
  auto* cmd = app.add_subcommand(
      "replay",
      "Run consensus-NDT odometry over a capture and write trajectory.tum (time x y z "
      "qx qy qz qw: the sensor pose at each scan start), scans.csv (per scan: time, "
      "Cm, iterations, voxels before/after the Cv cut, points, milliseconds, flags) "
      "summary.json and can.log (every CAN frame cndtd would send, candump format; "
      "config/cndt.dbc describes them)");
  cmd->add_option("capture", a.capture,
                  "pcap or pcapng file, or a folder of clouds (KITTI .bin or PCD, in name "
                  "order; scan times from its times.txt if present, else --scan-period apart)")
      ->required();
  cmd->add_option("--scan-period", a.scan_period_s,
                  "Seconds between scans of a cloud folder without times.txt")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 10.0));
  cmd->add_option("--out", a.out_dir, "Output folder (created if missing)")->required();
  cmd->add_option("--mode", a.mode,
                  "consensus (coarse match, Cv cut at eta, fine match) or naive (one match over "
                  "all voxels)")
      ->capture_default_str()
      ->check(CLI::IsMember({"consensus", "naive"}));
  cmd->add_option("--reference", a.reference,
                  "What each scan is matched against: local-map (recent scans merged) or "
                  "previous-scan (the paper's choice)")
      ->capture_default_str()
      ->check(CLI::IsMember({"local-map", "previous-scan"}));
  cmd->add_option("--max-scans", a.max_scans, "Stop after this many scans (0: all)")
      ->capture_default_str();
  cmd->add_flag("--mapper", a.mapper,
                "Run the mapper (keyframes, eq-7 refinement, map): trajectory.tum is then the "
                "odometry corrected by the map as it stood at each scan, odometry.tum the "
                "odometry alone, refined.tum every scan pose after its keyframe's refinement and "
                "refined.csv its Cm against the map. Off by default: on the simulated loop it "
                "does not yet beat the odometry (docs/mapper.md). --map and --save-map imply it");
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
  add_capture_options(*cmd, a.capture_args);
}

core::Result<std::pair<std::string, std::uint16_t>> parse_endpoint(const std::string& text,
                                                                   const std::string& what) {
  const auto colon = text.rfind(':');
  std::string host = colon == std::string::npos ? "" : text.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  unsigned long port = 0;
  try {
    std::size_t used = 0;
    const std::string p = colon == std::string::npos ? "" : text.substr(colon + 1);
    port = std::stoul(p, &used);
    if (used != p.size()) port = 0;
  } catch (const std::exception&) {
    port = 0;
  }
  if (host.empty() || port == 0 || port > 65535) {
    return core::Error{core::kExitUsage,
                       fmt::format("{} '{}': expected ADDRESS:PORT (e.g. 127.0.0.1:5600, "
                                   "[::1]:5600)",
                                   what, text)};
  }
  return std::pair<std::string, std::uint16_t>{host, static_cast<std::uint16_t>(port)};
}

int run_replay(const ReplayArgs& a) {
  auto options = to_capture_options(a.capture_args);
  if (!options) return fail(options.error());
  if (auto err = create_output_dir(a.out_dir)) return fail(*err);
  slam::OdometryOptions oo;
  oo.mode = a.mode == "naive" ? slam::OdometryMode::kNaive : slam::OdometryMode::kConsensus;
  oo.reference =
      a.reference == "previous-scan" ? slam::Reference::kPreviousScan : slam::Reference::kLocalMap;
  oo.max_scan_points = options.value().driver.assembler.max_points;
  slam::ConsensusOdometry odometry(oo);
  ReplayContext ctx;
  ctx.odometry = &odometry;
  slam::MapperOptions mo;
  mo.max_scan_points = oo.max_scan_points;
  mo.eta = oo.eta;
  mo.point_cell = oo.map_cell;
  mo.map.window_radius = a.map_window_m;
  mo.update_map = a.map.empty() || a.map_mode == "update";
  std::optional<slam::Mapper> mapper;
  if (a.mapper || !a.map.empty() || !a.save_map.empty()) {
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
    if (!a.initial_pose.empty()) {
      auto pose = parse_pose(a.initial_pose);
      if (!pose) return fail(pose.error());
      start = pose.value();
    }
    mapper.emplace(mo);
    if (!a.map.empty()) {
      auto prior = slam::load_map_file(a.map, mo.map);
      if (!prior) return fail(prior.error());
      spdlog::info("localizing in '{}' ({} map): {} voxels", a.map, a.map_mode,
                   prior.value().size());
      mapper->start_from(std::move(prior.value()), start);
    }
    ctx.mapper = &*mapper;
  }
  ctx.max_scans = a.max_scans;
  const std::filesystem::path dir(a.out_dir);
  runtime::PosePublisher publisher{runtime::PublisherOptions{}};
  {
    auto log = can::open_candump_log((dir / "can.log").string(), "can0");
    if (!log) return fail(log.error());
    publisher.add_can(std::move(log.value()));
  }
  if (!a.udp_out.empty()) {
    auto ep = parse_endpoint(a.udp_out, "--udp-out");
    if (!ep) return fail(ep.error());
    auto udp = net::UdpSender::open(ep.value().first, ep.value().second);
    if (!udp) return fail(udp.error());
    publisher.add_udp(std::move(udp.value()));
  }
  ctx.publisher = &publisher;
  ctx.trajectory.open(dir / "trajectory.tum", std::ios::trunc);
  ctx.csv.open(dir / "scans.csv", std::ios::trunc);
  if (ctx.mapper != nullptr) {
    ctx.odometry_tum.open(dir / "odometry.tum", std::ios::trunc);
    ctx.refined_tum.open(dir / "refined.tum", std::ios::trunc);
    ctx.refined_csv.open(dir / "refined.csv", std::ios::trunc);
    ctx.refined_csv << "time,keyframe,cm_map\n";
  }
  if (!ctx.trajectory || !ctx.csv ||
      (ctx.mapper != nullptr && (!ctx.odometry_tum || !ctx.refined_tum || !ctx.refined_csv))) {
    return fail({core::kExitIoError,
                 fmt::format("cannot write in '{}': {}", a.out_dir, std::strerror(errno))});
  }
  ctx.csv << "time,cm,coarse_iterations,fine_iterations,voxels_before,voxels_after,points,"
             "raw_points,odometry_ms,flags\n";
  const auto wall0 = std::chrono::steady_clock::now();
  CaptureReport r;
  std::error_code ec;
  if (std::filesystem::is_directory(a.capture, ec)) {
    // A folder of clouds (KITTI .bin or PCD): one scan per file, no firing times (no deskew).
    auto folder = list_cloud_folder(a.capture, a.scan_period_s);
    if (!folder) return fail(folder.error());
    core::Scan scan(oo.max_scan_points);
    const CloudFolder& f = folder.value();
    for (std::size_t i = 0; i < f.files.size() && !ctx.done; ++i) {
      if (auto err = read_cloud(f.files[i], scan)) return fail(*err);
      if (scan.points_dropped > 0) {
        spdlog::warn("'{}': {} points beyond the capacity of {} dropped", f.files[i],
                     scan.points_dropped, oo.max_scan_points);
      }
      scan.stamp = std::chrono::nanoseconds(std::llround(f.times_s[i] * 1e9));
      scan.sequence = i;
      on_scan(scan, &ctx);
    }
  } else {
    auto report = read_capture(a.capture, options.value(), on_scan, &ctx);
    if (!report) return fail(report.error());
    r = report.value();
    warn_if_cut_short(r);
  }
  if (ctx.mapper != nullptr) {
    const auto m0 = std::chrono::steady_clock::now();
    ctx.mapper->flush();
    if (!ctx.mapper->refined().empty()) {
      ctx.mapper_ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - m0).count());
    }
    write_refined(ctx);
    ctx.odometry_tum.close();
    ctx.refined_tum.close();
    ctx.refined_csv.close();
    if (!a.save_map.empty()) {
      if (auto err = slam::save_map_file(ctx.mapper->map(), a.save_map)) return fail(*err);
      spdlog::info("map saved to '{}': {} voxels", a.save_map, ctx.mapper->map().size());
    }
  }
  publisher.flush();
  for (const auto& bus : publisher.can_buses()) {
    if (bus->stats().errors > 0) {
      return fail({core::kExitIoError, fmt::format("{}: {} frames could not be written",
                                                   bus->describe(), bus->stats().errors)});
    }
  }
  for (const auto& udp : publisher.udp_senders()) {
    const auto st = udp->stats();
    if (st.dropped_would_block + st.errors > 0) {
      spdlog::warn("{}: {} datagrams sent, {} dropped (socket full), {} failed", udp->describe(),
                   st.sent, st.dropped_would_block, st.errors);
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  ctx.trajectory.close();
  ctx.csv.close();
  if (!ctx.trajectory || !ctx.csv) {
    return fail({core::kExitIoError, fmt::format("writing in '{}' failed", a.out_dir)});
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::ofstream summary(dir / "summary.json", std::ios::trunc);
  summary << fmt::format(
      "{{\n  \"scans\": {},\n  \"packets_ok\": {},\n  \"packets_bad\": {},\n  \"scans_dropped\": "
      "0,\n  \"lost_packets\": {},\n  \"odometry_ms_p50\": {:.3f},\n  \"odometry_ms_p99\": "
      "{:.3f},\n  \"iterations_mean\": {:.3f},\n  \"heap_allocations_in_odometry\": {},\n  "
      "\"heap_allocations_counted_after_scan\": {},\n  \"peak_rss_mb\": {:.1f},\n  \"wall_s\": "
      "{:.3f},\n "
      " \"mode\": \"{}\",\n  \"reference\": \"{}\",\n  \"mapper\": {},\n  \"keyframes\": {},\n  "
      "\"mapper_ms_p50\": {:.3f},\n  \"mapper_ms_p99\": {:.3f},\n  \"map_voxels\": {},\n  "
      "\"map_cm_median\": {:.4f}\n}}\n",
      ctx.scans, r.driver.decoded_packets, r.driver.rejected_total(), r.assembler.lost_packets,
      percentile(ctx.ms, 0.5), percentile(ctx.ms, 0.99),
      ctx.scans > 1 ? static_cast<double>(ctx.iterations) / static_cast<double>(ctx.scans - 1)
                    : 0.0,
      ctx.allocations, kWarmupScans, static_cast<double>(ru.ru_maxrss) / 1024.0, wall, a.mode,
      a.reference, ctx.mapper != nullptr, ctx.mapper ? ctx.mapper->stats().keyframes : 0,
      percentile(ctx.mapper_ms, 0.5), percentile(ctx.mapper_ms, 0.99),
      ctx.mapper ? ctx.mapper->map().size() : 0, percentile(ctx.map_cm, 0.5));
  summary.close();
  if (ctx.scans == 0) {
    return fail({core::kExitDataError,
                 fmt::format("no scan in '{}' ({} data packets, {} rejected)", a.capture,
                             r.driver.data_packets, r.driver.rejected_total())});
  }
  spdlog::info("{} scans in {:.1f} s; odometry {:.1f} ms median, {:.1f} ms p99; results in '{}'",
               ctx.scans, wall, percentile(ctx.ms, 0.5), percentile(ctx.ms, 0.99), a.out_dir);
  return core::kExitOk;
}

}  // namespace cndt::cli
