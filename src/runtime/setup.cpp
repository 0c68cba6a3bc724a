#include "cndt/runtime/setup.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "cndt/core/pose.hpp"

namespace cndt::runtime {

Eigen::Isometry3d pose_from_xyz_rpy_deg(const std::vector<double>& v) {
  constexpr double kDeg = M_PI / 180.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (v.size() != 6) return T;
  T.linear() = core::rotation(v[3] * kDeg, v[4] * kDeg, v[5] * kDeg);
  T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return T;
}

std::optional<std::pair<std::string, std::uint16_t>> split_endpoint(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) return std::nullopt;
  std::string host = text.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  const std::string p = text.substr(colon + 1);
  unsigned long port = 0;
  try {
    std::size_t used = 0;
    port = std::stoul(p, &used);
    if (used != p.size()) return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (host.empty() || port == 0 || port > 65535) return std::nullopt;
  return std::pair<std::string, std::uint16_t>{host, static_cast<std::uint16_t>(port)};
}

core::Result<Setup> make_setup(const config::Config& c) {
  Setup s;
  const auto& in = c.sensor;
  std::optional<io::IpAddress> sensor_ip;
  if (!in.sensor_ip.empty()) {
    sensor_ip = io::IpAddress::parse(in.sensor_ip);
    if (!sensor_ip) {
      return core::Error{
          core::kExitConfigError,
          fmt::format("sensor.sensor_ip: '{}' is not an IPv4 or IPv6 address", in.sensor_ip)};
    }
  }
  s.pcap.data_port = static_cast<std::uint16_t>(in.data_port);
  s.pcap.position_port = static_cast<std::uint16_t>(in.position_port);
  s.pcap.sensor_ip = sensor_ip;
  s.pcap.speed = in.pcap_realtime ? 1.0 : 0.0;
  s.udp.bind_address = in.bind_address;
  s.udp.data_port = static_cast<std::uint16_t>(in.data_port);
  s.udp.position_port = static_cast<std::uint16_t>(in.position_port);
  s.udp.sensor_ip = sensor_ip;
  s.udp.receive_buffer_bytes = static_cast<int>(in.receive_buffer_bytes);
  s.udp.queue_capacity = static_cast<std::size_t>(in.packet_queue);
  if (in.model == "auto") {
    s.driver.model = std::nullopt;
  } else {
    s.driver.model = vlp16::parse_model(in.model);
  }
  s.driver.decoder.min_range_m = in.min_range_m;
  s.driver.decoder.max_range_m = in.max_range_m;
  s.driver.decoder.vertical_offsets = in.vertical_offsets;
  s.driver.assembler.cut_azimuth =
      static_cast<std::uint16_t>(std::lround(in.cut_angle_deg * 100.0) % 36000);
  s.driver.assembler.cut_at_fov_gap = in.cut_at_fov_gap;
  s.max_points = static_cast<std::size_t>(in.max_points);
  s.driver.assembler.max_points = s.max_points;

  auto& o = s.pipeline.odometry;
  const auto& od = c.odometry;
  o.mode = od.mode == "naive" ? slam::OdometryMode::kNaive : slam::OdometryMode::kConsensus;
  o.reference =
      od.reference == "previous-scan" ? slam::Reference::kPreviousScan : slam::Reference::kLocalMap;
  o.voxel_size = od.voxel_size_m;
  o.eta = od.eta;
  o.fine_reach = od.fine_reach_m;
  o.pyramid_while_near = od.pyramid_while_near;
  o.near_shortfall_fraction = od.near_shortfall_fraction;
  o.near_shortfall = od.near_shortfall_m;
  o.scan_cell = od.scan_cell_m;
  o.map_cell = od.map_cell_m;
  o.min_range = od.min_range_m;
  o.max_range = od.max_range_m;
  o.deskew = od.deskew;
  o.level_frame = od.level_frame;
  o.deskew_refinements = static_cast<int>(od.deskew_refinements);
  o.local_map_scans = static_cast<std::size_t>(od.local_map_scans);
  o.local_map_points = static_cast<std::size_t>(od.local_map_points);
  o.map_min_translation = od.map_min_translation_m;
  o.map_admit_distance = od.map_admit_distance_m;
  o.max_map_voxels = static_cast<std::size_t>(od.max_map_voxels);
  o.min_points = static_cast<std::size_t>(od.min_points);
  o.max_acceleration = od.max_acceleration_mps2;
  o.max_angular_acceleration = od.max_angular_acceleration_degps2 * std::numbers::pi / 180.0;
  o.bound_degenerate_slide = od.bound_degenerate_slide;
  o.max_speed = od.max_speed_mps;
  o.start_search_radius = od.start_search_radius_m;
  o.gap_acceleration = od.gap_acceleration_mps2;
  o.gap_search_radius = od.gap_search_radius_m;
  o.gap_turn_hypothesis_rad = od.gap_turn_hypothesis_deg * std::numbers::pi / 180.0;
  o.prior_weight = od.prior_weight;
  o.prior_acceleration_threshold = od.prior_acceleration_threshold_mps2;
  o.surface_patches = od.surface_patches;
  o.patches_after_scans = static_cast<std::size_t>(od.patches_after_scans);
  o.patch_max_tilt_deg = od.patch_max_tilt_deg;
  o.patches_clean_scans = static_cast<std::size_t>(od.patches_clean_scans);
  o.deskew_to_mid_scan = od.deskew_to_mid_scan;
  o.mid_scan_after_clean = static_cast<std::size_t>(od.mid_scan_after_clean);
  o.deskew_acceleration = od.deskew_acceleration;
  o.guess_jitter_seed = static_cast<std::uint64_t>(od.guess_jitter_seed);
  o.max_scan_points = s.max_points;

  const auto& mp = c.mapper;
  s.pipeline.mapper = mp.enabled || !mp.load.empty() || !mp.save.empty();
  auto& mo = s.pipeline.mapper_options;
  mo.max_scan_points = s.max_points;
  mo.eta = o.eta;
  mo.point_cell = o.map_cell;
  mo.keyframe_similarity = mp.keyframe_similarity;
  mo.keyframe_scans = static_cast<std::size_t>(mp.keyframe_scans);
  mo.map.voxel_size = o.voxel_size;
  mo.map.capacity = static_cast<std::size_t>(mp.capacity_voxels);
  mo.map.window_radius = mp.window_m;
  mo.update_map = mp.load.empty() || mp.mode == "update";
  s.pipeline.correction_time_constant = mp.correction_time_constant_s;
  s.initial_pose = pose_from_xyz_rpy_deg(mp.initial_pose);

  const auto& rt = c.runtime;
  s.pipeline.scan_ring = static_cast<std::size_t>(rt.scan_ring);
  s.pipeline.keyframe_ring = static_cast<std::size_t>(rt.keyframe_ring);
  s.pipeline.keyframe_ring_points = static_cast<std::size_t>(rt.keyframe_ring_points);
  if (rt.realtime)
    s.pipeline.odometry_thread.fifo_priority = static_cast<int>(rt.odometry_priority);
  s.pipeline.odometry_thread.cpu = static_cast<int>(rt.odometry_cpu);
  s.pipeline.mapper_thread.nice = static_cast<int>(rt.mapper_nice);
  s.pipeline.mapper_thread.cpu = static_cast<int>(rt.mapper_cpu);
  s.pipeline.scoring_threads = static_cast<std::size_t>(rt.scoring_threads);

  s.publisher.degraded_below_cm = c.output.degraded_below_cm;
  s.publisher.can_base_id = static_cast<std::uint32_t>(c.can.base_id);
  s.publisher.can_extended = c.can.extended;
  if (!c.can.extended && c.can.base_id + 4 > 0x7FF) {
    return core::Error{core::kExitConfigError,
                       fmt::format("can.base_id: {:#x} + 4 exceeds the 11-bit range; lower it or "
                                   "set can.extended = true",
                                   c.can.base_id)};
  }
  return s;
}

core::Result<std::unique_ptr<PosePublisher>> make_publisher(const config::Config& c,
                                                            const PublisherOptions& options) {
  auto pub = std::make_unique<PosePublisher>(options);
  if (!c.can.interface.empty()) {
    auto bus = can::open_socketcan(c.can.interface);
    if (!bus) return bus.error();
    pub->add_can(std::move(bus.value()));
  }
  if (!c.can.log.empty()) {
    auto log = can::open_candump_log(c.can.log, c.can.log_interface);
    if (!log) return log.error();
    pub->add_can(std::move(log.value()));
  }
  for (const std::string& d : c.udp.destinations) {
    const auto ep = split_endpoint(d);
    if (!ep) {
      return core::Error{core::kExitConfigError,
                         fmt::format("udp.destinations: '{}' is not ADDRESS:PORT", d)};
    }
    auto udp = net::UdpSender::open(ep->first, ep->second);
    if (!udp) return udp.error();
    pub->add_udp(std::move(udp.value()));
  }
  return pub;
}

}  // namespace cndt::runtime
