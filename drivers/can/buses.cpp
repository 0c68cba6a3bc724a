#include <fcntl.h>
#include <fmt/format.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

#include "cndt/can/can_bus.hpp"

namespace cndt::can {
namespace {

// Counted on the sending thread, read by the health reporter: relaxed atomics.
struct AtomicStats {
  std::atomic<std::uint64_t> sent{0}, dropped{0}, errors{0};
  CanBusStats snapshot() const noexcept {
    return {sent.load(std::memory_order_relaxed), dropped.load(std::memory_order_relaxed),
            errors.load(std::memory_order_relaxed)};
  }
};
void bump(std::atomic<std::uint64_t>& c) noexcept { c.fetch_add(1, std::memory_order_relaxed); }

class CandumpLogBus final : public CanBus {
 public:
  CandumpLogBus(int fd, std::string path, std::string iface)
      : fd_(fd), path_(std::move(path)), iface_(std::move(iface)) {}
  ~CandumpLogBus() override {
    flush();
    ::close(fd_);
  }
  CandumpLogBus(const CandumpLogBus&) = delete;
  CandumpLogBus& operator=(const CandumpLogBus&) = delete;

  bool send(const output::CanFrame& frame, std::chrono::nanoseconds stamp) noexcept override {
    if (kLineMax + iface_.size() > buffer_.size() - used_) flush();
    const std::size_t n =
        format_candump_line(frame, stamp, iface_, std::span<char>(buffer_).subspan(used_));
    if (n == 0) {
      bump(stats_.errors);
      return false;
    }
    used_ += n;
    bump(stats_.sent);
    return true;
  }

  void flush() noexcept override {
    std::size_t off = 0;
    while (off < used_) {
      const ssize_t w = ::write(fd_, buffer_.data() + off, used_ - off);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        bump(stats_.errors);  // the disk refused: the frames in hand are lost, counted
        break;
      }
      off += static_cast<std::size_t>(w);
    }
    used_ = 0;
  }

  [[nodiscard]] CanBusStats stats() const noexcept override { return stats_.snapshot(); }
  [[nodiscard]] std::string describe() const override {
    return fmt::format("candump log '{}' (interface {})", path_, iface_);
  }

 private:
  static constexpr std::size_t kLineMax = 64;
  int fd_;
  std::string path_, iface_;
  std::array<char, 16384> buffer_{};
  std::size_t used_ = 0;
  AtomicStats stats_;
};

class SocketCanBus final : public CanBus {
 public:
  SocketCanBus(int fd, std::string iface) : fd_(fd), iface_(std::move(iface)) {}
  ~SocketCanBus() override { ::close(fd_); }
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  bool send(const output::CanFrame& frame, std::chrono::nanoseconds /*stamp*/) noexcept override {
    can_frame cf{};
    cf.can_id =
        frame.extended ? ((frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (frame.id & CAN_SFF_MASK);
    cf.len = std::min<std::uint8_t>(frame.len, 8);
    std::memcpy(cf.data, frame.data.data(), cf.len);
    for (;;) {
      const ssize_t w = ::write(fd_, &cf, sizeof cf);
      if (w == static_cast<ssize_t>(sizeof cf)) {
        bump(stats_.sent);
        return true;
      }
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && (errno == ENOBUFS || errno == EAGAIN || errno == EWOULDBLOCK)) {
        bump(stats_.dropped);  // a stale pose is worth less than a blocked odometry
      } else {
        bump(stats_.errors);
      }
      return false;
    }
  }
  [[nodiscard]] CanBusStats stats() const noexcept override { return stats_.snapshot(); }
  [[nodiscard]] std::string describe() const override {
    return fmt::format("SocketCAN {}", iface_);
  }

 private:
  int fd_;
  std::string iface_;
  AtomicStats stats_;
};

}  // namespace

core::Result<std::unique_ptr<CanBus>> open_candump_log(const std::string& path,
                                                       const std::string& interface_name) {
  if (interface_name.empty() || interface_name.find_first_of(" \t\n()#") != std::string::npos) {
    return core::Error{
        core::kExitConfigError,
        fmt::format("CAN interface name '{}' cannot appear in a candump log", interface_name)};
  }
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return core::Error{core::kExitIoError,
                       fmt::format("cannot create CAN log '{}': {}", path, std::strerror(errno))};
  }
  return std::unique_ptr<CanBus>(std::make_unique<CandumpLogBus>(fd, path, interface_name));
}

core::Result<std::unique_ptr<CanBus>> open_socketcan(const std::string& interface_name) {
  if (interface_name.empty() || interface_name.size() >= IFNAMSIZ) {
    return core::Error{core::kExitConfigError,
                       fmt::format("CAN interface name '{}' is empty or longer than {} characters",
                                   interface_name, IFNAMSIZ - 1)};
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int e = errno;
    return core::Error{
        core::kExitIoError,
        e == EAFNOSUPPORT
            ? fmt::format("cannot open SocketCAN interface '{}': this kernel has no CAN support "
                          "(EAFNOSUPPORT; load the can and can_raw modules)",
                          interface_name)
            : fmt::format("cannot open a CAN socket for '{}': {}", interface_name,
                          std::strerror(e))};
  }
  // Transmit only: no receive filter, so nothing queues up unread.
  ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, nullptr, 0);
  const unsigned index = ::if_nametoindex(interface_name.c_str());
  if (index == 0) {
    ::close(fd);
    return core::Error{core::kExitIoError,
                       fmt::format("CAN interface '{}' does not exist (for a virtual bus: ip link "
                                   "add dev {} type vcan && ip link set up {})",
                                   interface_name, interface_name, interface_name)};
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int e = errno;
    ::close(fd);
    return core::Error{core::kExitIoError, fmt::format("cannot bind to CAN interface '{}': {}",
                                                       interface_name, std::strerror(e))};
  }
  return std::unique_ptr<CanBus>(std::make_unique<SocketCanBus>(fd, interface_name));
}

}  // namespace cndt::can
