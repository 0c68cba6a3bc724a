// Replays Velodyne payloads from a pcap or pcapng capture through libpcap, as fast as possible or
// paced by the capture's own clock. Every record is accounted for in PcapStats.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cndt/core/result.hpp"
#include "cndt/io/packet_source.hpp"
#include "cndt/pcap/frame.hpp"

namespace cndt::pcap {

struct PcapOptions {
  std::uint16_t data_port = 2368;
  std::uint16_t position_port = 8308;
  std::optional<IpAddress> sensor_ip;  ///< accept only packets from this source address
  double speed = 0.0;                  ///< 0: as fast as possible; 1: capture rate; 2: twice ...
};

/// A record the file ends in the middle of.
struct TruncatedRecord {
  std::uint64_t index = 0;                 ///< 1-based record number
  std::size_t declared = 0;                ///< bytes the record header declares
  std::size_t present = 0;                 ///< bytes actually in the file
  std::optional<std::uint16_t> dest_port;  ///< when enough of the frame survived to read it
  std::string message;                     ///< libpcap's description
};

struct PcapStats {
  std::uint64_t records = 0;  ///< complete records read
  std::uint64_t udp = 0;
  std::map<std::uint16_t, std::uint64_t> udp_by_dest_port;
  std::map<FrameResult, std::uint64_t> skipped;  ///< non-UDP records, by reason
  std::uint64_t wrong_source = 0;  ///< data/position port, but not from the sensor address
  std::uint64_t cut_payloads = 0;  ///< snap length shorter than the UDP payload
  std::uint64_t data = 0;          ///< delivered on the data port
  std::uint64_t position = 0;      ///< delivered on the position port
  std::optional<TruncatedRecord> truncated;
  std::optional<std::chrono::nanoseconds> first_time, last_time;
};

class PcapSource final : public io::PacketSource {
 public:
  /// Opens a capture. Errors name the file: missing or unreadable (exit 66), not a capture or an
  /// unsupported link type (65).
  static core::Result<std::unique_ptr<PcapSource>> open(const std::string& path,
                                                        const PcapOptions& options);
  ~PcapSource() override;
  PcapSource(const PcapSource&) = delete;
  PcapSource& operator=(const PcapSource&) = delete;

  io::NextResult next(io::SourcePacket& packet, std::chrono::milliseconds timeout) override;
  io::NextResult next(io::SourcePacket& packet) { return next(packet, {}); }

  [[nodiscard]] const PcapStats& stats() const noexcept { return stats_; }
  [[nodiscard]] int link_type() const noexcept { return link_type_; }
  [[nodiscard]] bool pcapng() const noexcept { return pcapng_; }
  [[nodiscard]] const std::string& path() const noexcept { return path_; }

 private:
  PcapSource(std::string path, const PcapOptions& options, void* handle, int link_type,
             bool pcapng);
  void inspect_truncated_record(long record_offset, const std::string& message);
  void pace(std::chrono::nanoseconds capture_time);

  std::string path_;
  PcapOptions options_;
  void* handle_;  // pcap_t*
  int link_type_;
  bool pcapng_;
  bool ended_ = false;
  PcapStats stats_;
  std::optional<std::chrono::nanoseconds> pace_capture_start_;
  std::chrono::steady_clock::time_point pace_wall_start_{};
};

}  // namespace cndt::pcap
