// From a checked configuration to the options of every part: input, driver, pipeline (odometry,
// mapper, threads) and publisher. cndtd and `cndt replay --config` both go through here, so a
// file means the same thing to both.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>

#include "cndt/config/config.hpp"
#include "cndt/core/result.hpp"
#include "cndt/net/udp_source.hpp"
#include "cndt/pcap/pcap_source.hpp"
#include "cndt/runtime/pipeline.hpp"
#include "cndt/runtime/publisher.hpp"
#include "cndt/vlp16/driver.hpp"

namespace cndt::runtime {

struct Setup {
  pcap::PcapOptions pcap;
  net::UdpOptions udp;
  vlp16::DriverOptions driver;
  PipelineOptions pipeline;
  PublisherOptions publisher;
  std::size_t max_points = 150'000;
  Eigen::Isometry3d initial_pose = Eigen::Isometry3d::Identity();  ///< with a prior map
};

/// Options from a loaded config (errors only for values the loader cannot judge, such as an
/// unparsable sensor address).
core::Result<Setup> make_setup(const config::Config& config);

/// The publisher's outputs from the config: SocketCAN interface, candump log, UDP destinations.
core::Result<std::unique_ptr<PosePublisher>> make_publisher(const config::Config& config,
                                                            const PublisherOptions& options);

/// "ADDRESS:PORT" or "[IPv6]:PORT" split in two; nothing when malformed.
std::optional<std::pair<std::string, std::uint16_t>> split_endpoint(const std::string& text);

/// "x,y,z,roll,pitch,yaw" in metres and degrees as a pose.
Eigen::Isometry3d pose_from_xyz_rpy_deg(const std::vector<double>& v);

}  // namespace cndt::runtime
