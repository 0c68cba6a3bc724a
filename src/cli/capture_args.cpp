#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>

#include "cndt/cli/commands.hpp"

namespace cndt::cli {

int fail(const core::Error& error) {
  spdlog::error("{}", error.message);
  return error.code;
}

std::optional<core::Error> create_output_dir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!ec) return std::nullopt;
  return core::Error{core::kExitIoError,
                     fmt::format("cannot create output folder '{}': {}", dir, ec.message())};
}

void warn_if_cut_short(const CaptureReport& r) {
  if (r.pcap.truncated) {
    spdlog::warn("'{}' ends in the middle of record {} ({}); everything before it was read", r.path,
                 r.pcap.truncated->index, r.pcap.truncated->message);
  }
}

void add_odometry_input_options(CLI::App& cmd, OdometryInputArgs& a) {
  cmd.add_option("capture", a.capture,
                 "pcap or pcapng file, or a folder of clouds (KITTI .bin or PCD, in name "
                 "order; scan times from its times.txt if present, else --scan-period apart)")
      ->required();
  cmd.add_option("--scan-period", a.scan_period_s,
                 "Seconds between scans of a cloud folder without times.txt")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 10.0));
  cmd.add_option("--mode", a.mode,
                 "consensus (coarse match, Cv cut at eta, fine match) or naive (one match over "
                 "all voxels)")
      ->capture_default_str()
      ->check(CLI::IsMember({"consensus", "naive"}));
  cmd.add_option("--reference", a.reference,
                 "What each scan is matched against: local-map (recent scans merged) or "
                 "previous-scan (the paper's choice)")
      ->capture_default_str()
      ->check(CLI::IsMember({"local-map", "previous-scan"}));
  cmd.add_option("--config", a.config,
                 "Read the settings from this cndtd configuration file (config/cndtd.toml "
                 "documents every key); options given here override it");
  add_capture_options(cmd, a.capture_args);
}

core::Result<config::Config> odometry_config(const OdometryInputArgs& a, const CLI::App* command) {
  const CaptureArgs& ca = a.capture_args;
  config::Config c;
  if (!a.config.empty()) {
    auto loaded = config::load_config(a.config);
    if (!loaded) return loaded.error();
    c = std::move(loaded.value());
  }
  const auto given = [&](const char* option) {
    return command == nullptr || command->count(option) > 0;
  };
  if (given("--model")) c.sensor.model = ca.model;
  if (given("--sensor-ip")) c.sensor.sensor_ip = ca.sensor_ip;
  if (given("--data-port")) c.sensor.data_port = ca.data_port;
  if (given("--position-port")) c.sensor.position_port = ca.position_port;
  if (given("--cut-angle")) c.sensor.cut_angle_deg = ca.cut_angle_deg;
  if (given("--no-fov-cut")) c.sensor.cut_at_fov_gap = !ca.no_fov_cut;
  if (given("--min-range")) c.sensor.min_range_m = ca.min_range_m;
  if (given("--max-range")) c.sensor.max_range_m = ca.max_range_m;
  if (given("--no-vertical-offsets")) c.sensor.vertical_offsets = !ca.no_vertical_offsets;
  if (given("--max-points")) c.sensor.max_points = static_cast<std::int64_t>(ca.max_points);
  if (given("--mode")) c.odometry.mode = a.mode;
  if (given("--reference")) c.odometry.reference = a.reference;
  // The command line's capture checks (ranges, model names, addresses) on the result.
  CaptureArgs check = ca;
  check.model = c.sensor.model;
  check.sensor_ip = c.sensor.sensor_ip;
  check.min_range_m = c.sensor.min_range_m;
  check.max_range_m = c.sensor.max_range_m;
  check.cut_angle_deg = c.sensor.cut_angle_deg;
  check.max_points = static_cast<std::size_t>(c.sensor.max_points);
  if (auto ok = to_capture_options(check); !ok) return ok.error();
  return c;
}

void add_capture_options(CLI::App& cmd, CaptureArgs& a) {
  cmd.add_option("--model", a.model,
                 "Sensor model: auto (product byte; packet period separates HDL-32E from early "
                 "VLP-16 firmware), vlp16, vlp16-hires, hdl32e, vlp32c")
      ->capture_default_str();
  cmd.add_option("--sensor-ip", a.sensor_ip,
                 "Accept packets only from this source address (default: any)");
  cmd.add_option("--data-port", a.data_port, "UDP destination port of data packets")
      ->capture_default_str();
  cmd.add_option("--position-port", a.position_port,
                 "UDP destination port of position (GPS/PPS) packets")
      ->capture_default_str();
  cmd.add_option("--cut-angle", a.cut_angle_deg,
                 "Azimuth in degrees [0, 360) where one revolution ends and the next begins")
      ->capture_default_str();
  cmd.add_flag("--no-fov-cut", a.no_fov_cut,
               "Keep the cut angle and count every silence as packet loss, also when the sensor "
               "is silent over the same sector every turn (by default such a field-of-view gap "
               "is found after two turns and the cut moves into it)");
  cmd.add_option("--min-range", a.min_range_m, "Drop returns nearer than this, metres")
      ->capture_default_str();
  cmd.add_option("--max-range", a.max_range_m, "Drop returns farther than this, metres")
      ->capture_default_str();
  cmd.add_flag("--no-vertical-offsets", a.no_vertical_offsets,
               "Do not add the per-laser vertical offsets of the VLP-16 manual (other drivers "
               "such as nebula and the ROS1 driver leave them out)");
  cmd.add_option("--max-points", a.max_points, "Point capacity of one scan")->capture_default_str();
}

core::Result<CaptureOptions> to_capture_options(const CaptureArgs& a) {
  CaptureOptions o;
  if (a.model != "auto") {
    const auto m = vlp16::parse_model(a.model);
    if (!m) {
      return core::Error{core::kExitUsage,
                         fmt::format("--model: '{}' is not one of auto, vlp16, vlp16-hires, "
                                     "hdl32e, vlp32c",
                                     a.model)};
    }
    o.driver.model = *m;
  } else {
    o.driver.model = std::nullopt;
  }
  if (!a.sensor_ip.empty()) {
    o.pcap.sensor_ip = io::IpAddress::parse(a.sensor_ip);
    if (!o.pcap.sensor_ip) {
      return core::Error{
          core::kExitUsage,
          fmt::format("--sensor-ip: '{}' is not an IPv4 or IPv6 address", a.sensor_ip)};
    }
  }
  if (!(a.cut_angle_deg >= 0.0 && a.cut_angle_deg < 360.0)) {
    return core::Error{core::kExitUsage,
                       fmt::format("--cut-angle: {} is outside [0, 360)", a.cut_angle_deg)};
  }
  if (!(a.min_range_m >= 0.0 && a.max_range_m > a.min_range_m)) {
    return core::Error{core::kExitUsage,
                       fmt::format("--min-range {} / --max-range {}: need 0 <= min < max",
                                   a.min_range_m, a.max_range_m)};
  }
  if (a.max_points < 1000 || a.max_points > 10'000'000) {
    return core::Error{core::kExitUsage,
                       fmt::format("--max-points: {} is outside [1000, 10000000]", a.max_points)};
  }
  o.pcap.data_port = a.data_port;
  o.pcap.position_port = a.position_port;
  o.driver.decoder.min_range_m = a.min_range_m;
  o.driver.decoder.max_range_m = a.max_range_m;
  o.driver.decoder.vertical_offsets = !a.no_vertical_offsets;
  o.driver.assembler.cut_azimuth =
      static_cast<std::uint16_t>(std::lround(a.cut_angle_deg * 100.0) % 36000);
  o.driver.assembler.cut_at_fov_gap = !a.no_fov_cut;
  o.driver.assembler.max_points = a.max_points;
  return o;
}

}  // namespace cndt::cli
