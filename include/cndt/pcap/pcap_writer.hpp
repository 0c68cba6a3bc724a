// Writes UDP payloads into a classic pcap file (Ethernet, IPv4, UDP), the format every capture
// tool reads. Used by `cndt record` and the simulator.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cndt/core/bytes.hpp"
#include "cndt/core/result.hpp"
#include "cndt/io/ip_address.hpp"

namespace cndt::pcap {

struct UdpEndpoints {
  io::IpAddress source = io::IpAddress::v4(192, 168, 1, 201);
  io::IpAddress destination = io::IpAddress::v4(255, 255, 255, 255);
  std::uint16_t source_port = 2368;
  std::uint16_t dest_port = 2368;
};

class PcapWriter {
 public:
  /// Creates (truncates) `path`. Nanosecond timestamps when `nanosecond` is set.
  static core::Result<std::unique_ptr<PcapWriter>> create(const std::string& path,
                                                          bool nanosecond = false);
  ~PcapWriter();
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;

  /// Appends one IPv4/UDP datagram (IPv6 endpoints are written as IPv6) framed in Ethernet.
  void write_udp(std::chrono::nanoseconds time, const UdpEndpoints& endpoints,
                 core::ByteSpan payload);
  /// Flushes and closes; returns an error naming the file if any write failed.
  std::optional<core::Error> close();
  [[nodiscard]] std::uint64_t packets() const noexcept { return packets_; }

 private:
  PcapWriter(std::string path, void* dead, void* dumper, bool nanosecond);
  std::string path_;
  void* dead_;    // pcap_t*
  void* dumper_;  // pcap_dumper_t*
  bool nanosecond_;
  std::uint64_t packets_ = 0;
  std::uint16_t ip_id_ = 0;
  std::vector<std::uint8_t> frame_;
};

}  // namespace cndt::pcap
