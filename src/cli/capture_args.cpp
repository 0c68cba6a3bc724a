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
