// The systemd notification protocol (sd_notify(3)): datagrams to $NOTIFY_SOCKET. Sent without
// blocking: a manager that does not read (a full socket queue) costs a counted message, never a
// stalled odometry thread (libsystemd's sd_notify blocks in that case). The socket is opened
// once; sending does not allocate.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string_view>

namespace cndt::runtime {

class Notifier {
 public:
  /// Reads NOTIFY_SOCKET (and the watchdog settings) from the environment.
  Notifier();
  ~Notifier();
  Notifier(const Notifier&) = delete;
  Notifier& operator=(const Notifier&) = delete;

  [[nodiscard]] bool enabled() const noexcept { return fd_ >= 0; }
  /// The interval systemd expects WATCHDOG=1 in (WATCHDOG_USEC for this process), or zero.
  [[nodiscard]] std::chrono::microseconds watchdog_interval() const noexcept { return watchdog_; }
  /// Sends one message ("READY=1", "STATUS=...", several lines allowed); false if not sent.
  bool send(std::string_view message) noexcept;
  /// WATCHDOG=1 when half the interval has passed since the last one (any thread, one at a
  /// time).
  void watchdog() noexcept;
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_.load(); }

 private:
  int fd_ = -1;
  unsigned address_length_ = 0;
  alignas(8) unsigned char address_[112] = {};  // sockaddr_un
  std::chrono::microseconds watchdog_{0};
  std::chrono::steady_clock::time_point last_ping_{};
  std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace cndt::runtime
