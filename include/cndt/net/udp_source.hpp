// Live sensor input: receives data and position packets on their UDP ports with Boost.Asio on a
// thread of its own and hands them over through a lock-free queue. The consumer never blocks the
// receiver: when the queue is full the new packet is dropped and counted.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "cndt/core/result.hpp"
#include "cndt/io/packet_source.hpp"

namespace cndt::net {

struct UdpOptions {
  std::string bind_address = "0.0.0.0";
  std::uint16_t data_port = 2368;
  std::uint16_t position_port = 8308;      ///< 0 = do not listen for position packets
  std::optional<io::IpAddress> sensor_ip;  ///< accept only this source address
  int receive_buffer_bytes = 8 << 20;      ///< SO_RCVBUF asked for (the kernel may cap it)
  std::size_t queue_capacity = 4096;       ///< packets buffered between receiver and consumer
};

struct UdpStats {
  std::uint64_t received = 0;      ///< datagrams read from the sockets
  std::uint64_t accepted = 0;      ///< queued for the consumer
  std::uint64_t wrong_source = 0;  ///< not from the sensor address
  std::uint64_t oversize = 0;      ///< larger than any Velodyne packet (truncated, refused)
  std::uint64_t queue_full = 0;    ///< dropped because the consumer fell behind
  std::uint64_t receive_errors = 0;
  int receive_buffer_bytes = 0;  ///< SO_RCVBUF the kernel granted
};

class UdpSource final : public io::PacketSource {
 public:
  /// Binds the sockets and starts the receive thread. Errors name the address and port.
  static core::Result<std::unique_ptr<UdpSource>> open(const UdpOptions& options);
  ~UdpSource() override;
  UdpSource(const UdpSource&) = delete;
  UdpSource& operator=(const UdpSource&) = delete;

  /// Waits up to `timeout` for a packet; kEnd after stop().
  io::NextResult next(io::SourcePacket& packet, std::chrono::milliseconds timeout) override;
  /// Stops the receive thread; packets still queued are delivered, then next() returns kEnd.
  void stop();
  [[nodiscard]] UdpStats stats() const;
  [[nodiscard]] std::uint16_t data_port() const;  ///< the bound port (useful with port 0)
  [[nodiscard]] std::uint16_t position_port() const;

  struct Impl;

 private:
  explicit UdpSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace cndt::net
