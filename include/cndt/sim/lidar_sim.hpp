// A VLP-16 in a simulated scene: every laser fires at its own time from the sensor pose of that
// instant, rays are cast into the world, and returns are encoded in the sensor's exact packet
// format (ranges quantised to 2 mm, azimuths to 0.01 deg).
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cndt/core/result.hpp"
#include "cndt/core/scan.hpp"
#include "cndt/sim/scene.hpp"

namespace cndt::sim {

struct LidarSimOptions {
  int rpm = 600;           ///< 300..1200
  bool dual = false;       ///< dual return (last + strongest)
  double noise_m = 0.01;   ///< range noise, 1 sigma
  double drop_rate = 0.0;  ///< fraction of packets lost on the way
  /// Nothing arrives (data or position packets) for outage_s seconds from outage_start_s after
  /// the start: a cable pulled, a switch restarting.
  double outage_start_s = 0.0, outage_s = 0.0;
  /// From clock_step_at_s after the start the sensor's clock reads clock_step_s more (a time
  /// source taking over); the packets keep coming on time, and the ground truth and the capture
  /// times stay on the true clock.
  double clock_step_at_s = 0.0, clock_step_s = 0.0;
  double dropout = 0.002;  ///< fraction of returns the sensor misses
  double max_range_m = 100.0;
  std::int64_t start_time_ns = 1'767'225'600'000'000'000;  ///< 2026-01-01T00:00:00Z
  double duration_s = 10.0;
  std::uint64_t seed = 1;
  std::uint16_t cut_azimuth = 0;  ///< where ground-truth scans start, 0.01 deg
};

struct SimPacket {
  std::array<std::uint8_t, 1206> payload{};
  std::int64_t sensor_time_ns = 0;   ///< first firing of the packet, absolute
  std::int64_t capture_time_ns = 0;  ///< when a receiver would have stamped it
  std::int64_t clock_offset_ns = 0;  ///< the sensor clock's reading minus the true time
  std::uint64_t index = 0;
  bool dropped = false;  ///< lost on the way: not to be written
};

/// What the simulator put into a packet, for round-trip tests.
struct TruePoint {
  std::uint64_t packet = 0;
  int sequence = 0;  ///< firing sequence within the packet
  int laser = 0;
  core::ReturnType type = core::ReturnType::kSingle;
  Eigen::Vector3d sensor_point;  ///< before quantisation, sensor frame of the firing instant
  double range = 0.0;            ///< noisy range before quantisation
};

struct ScanStart {
  std::int64_t time_ns = 0;  ///< absolute time of the scan's first firing sequence
  Eigen::Isometry3d pose;    ///< T_world_sensor at that time
};

class LidarSimulator {
 public:
  LidarSimulator(const Scene& scene, const LidarSimOptions& options);

  /// Produces the next data packet; false once the duration is used up. When `truth` is given,
  /// the points encoded in this packet are appended to it.
  bool next(SimPacket& packet, std::vector<TruePoint>* truth = nullptr);
  /// A position packet ($GPRMC, PPS locked) for sensor time `time_ns`.
  std::array<std::uint8_t, 512> position_packet(std::int64_t time_ns) const;
  /// Scan starts seen so far (the first one is the first firing of the stream).
  [[nodiscard]] const std::vector<ScanStart>& scan_starts() const { return starts_; }
  [[nodiscard]] std::int64_t packet_period_ns() const { return period_ns_; }

 private:
  void fire_sequence(std::int64_t t_ns, int sequence, std::size_t record_off, std::size_t pair_off,
                     SimPacket& packet, std::vector<TruePoint>* truth);
  double rotor_deg(std::int64_t t_rel_ns) const;

  const Scene& scene_;
  LidarSimOptions options_;
  std::int64_t period_ns_;
  std::int64_t end_ns_;
  std::uint64_t next_index_ = 0;
  double rotor0_deg_;
  int last_rel_ = -1;
  std::vector<ScanStart> starts_;
  std::vector<Box> movers_;
  std::array<double, 16> cos_el_{}, sin_el_{}, z_off_{};
};

/// Runs a whole simulation into `dir`: capture.pcap (data on 2368 and position packets on 8308
/// from 192.168.1.201) and groundtruth.tum (time x y z qx qy qz qw at each scan start).
struct SimSummary {
  std::uint64_t packets = 0, dropped = 0, position_packets = 0, scans = 0;
  std::size_t objects = 0;
};
core::Result<SimSummary> write_simulation(const Scene& scene, const LidarSimOptions& options,
                                          const std::string& dir);

}  // namespace cndt::sim
