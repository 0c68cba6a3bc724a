// Hands every odometry pose to the vehicle: five CAN frames (config/cndt.dbc) on each CAN bus and
// one UDP datagram (docs/protocol.md) to each UDP destination. Called on the odometry thread:
// never blocks, never allocates; what a bus cannot take is dropped and counted by the bus.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "cndt/can/can_bus.hpp"
#include "cndt/net/udp_datagram.hpp"
#include "cndt/output/pose_message.hpp"
#include "cndt/slam/odometry.hpp"

namespace cndt::runtime {

struct PublisherOptions {
  /// Below this Cm a matched pose is published as degraded (typical tracking on the simulated
  /// scenes gives a median Cm of 0.35-0.45 and a 1st percentile of 0.16-0.27).
  double degraded_below_cm = 0.15;
  std::uint32_t can_base_id = output::kDefaultCanBaseId;
  bool can_extended = false;
};

/// The message for one odometry result; `pose` is the published pose (odometry corrected by
/// the map when `map_corrected`).
output::PoseMessage make_pose_message(const slam::OdometryResult& result,
                                      const Eigen::Isometry3d& pose, bool map_corrected,
                                      std::uint32_t scan_sequence,
                                      const PublisherOptions& options) noexcept;

struct PublisherStats {
  std::uint64_t poses = 0;
  std::uint64_t valid = 0, degraded = 0, lost = 0;
};

class PosePublisher {
 public:
  explicit PosePublisher(const PublisherOptions& options) : options_(options) {}
  void add_can(std::unique_ptr<can::CanBus> bus) { can_.push_back(std::move(bus)); }
  void add_udp(std::unique_ptr<net::UdpSender> udp) { udp_.push_back(std::move(udp)); }

  /// Publishes one pose on every output.
  void publish(const output::PoseMessage& message) noexcept;
  void flush() noexcept;

  [[nodiscard]] const PublisherStats& stats() const { return stats_; }
  [[nodiscard]] const std::vector<std::unique_ptr<can::CanBus>>& can_buses() const { return can_; }
  [[nodiscard]] const std::vector<std::unique_ptr<net::UdpSender>>& udp_senders() const {
    return udp_;
  }
  [[nodiscard]] const PublisherOptions& options() const { return options_; }

 private:
  PublisherOptions options_;
  std::vector<std::unique_ptr<can::CanBus>> can_;
  std::vector<std::unique_ptr<net::UdpSender>> udp_;
  PublisherStats stats_;
  std::uint8_t counter_ = 0;
  std::uint32_t sequence_ = 0;
};

}  // namespace cndt::runtime
