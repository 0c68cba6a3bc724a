// Plain UDP datagrams in and out, for the pose output: a non-blocking sender (a datagram the
// socket cannot take right now is dropped and counted, never waited for) and a receiver with a
// timeout (cndt listen, tests).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "cndt/core/bytes.hpp"
#include "cndt/core/result.hpp"

namespace cndt::net {

struct UdpSenderStats {
  std::uint64_t sent = 0;
  std::uint64_t dropped_would_block = 0;  ///< the socket buffer was full
  std::uint64_t errors = 0;               ///< e.g. no route, connection refused by ICMP
};

class UdpSender {
 public:
  /// `address` is a numeric IPv4/IPv6 address (unicast, broadcast or multicast).
  static core::Result<std::unique_ptr<UdpSender>> open(const std::string& address,
                                                       std::uint16_t port);
  ~UdpSender();
  UdpSender(const UdpSender&) = delete;
  UdpSender& operator=(const UdpSender&) = delete;
  /// Sends one datagram without blocking or allocating.
  bool send(core::ByteSpan datagram) noexcept;
  [[nodiscard]] UdpSenderStats stats() const noexcept;
  [[nodiscard]] std::string describe() const;

  struct Impl;

 private:
  explicit UdpSender(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

class UdpReceiver {
 public:
  /// Binds `address`:`port` (port 0 picks a free one; see port()).
  static core::Result<std::unique_ptr<UdpReceiver>> open(const std::string& address,
                                                         std::uint16_t port);
  ~UdpReceiver();
  UdpReceiver(const UdpReceiver&) = delete;
  UdpReceiver& operator=(const UdpReceiver&) = delete;
  /// Waits up to `timeout` for a datagram; its size (truncated to the buffer), or nothing. With
  /// `arrival`, also the time the kernel took the datagram in (wall clock, SO_TIMESTAMPNS; the
  /// time of this call's return where the kernel gives none): unlike the return of this call, it
  /// does not wait for the receiving thread to be scheduled.
  std::optional<std::size_t> receive(std::span<std::uint8_t> buffer,
                                     std::chrono::milliseconds timeout,
                                     std::chrono::system_clock::time_point* arrival = nullptr);
  [[nodiscard]] std::uint16_t port() const;

  struct Impl;

 private:
  explicit UdpReceiver(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace cndt::net
