#include "cndt/net/udp_datagram.hpp"

#include <fmt/format.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>

#include "asio.hpp"

namespace cndt::net {

using boost::asio::ip::udp;

struct UdpSender::Impl {
  boost::asio::io_context io;
  udp::socket socket{io};
  udp::endpoint destination;
  // Counted on the sending thread, read by the health reporter.
  std::atomic<std::uint64_t> sent{0}, dropped{0}, errors{0};
};

core::Result<std::unique_ptr<UdpSender>> UdpSender::open(const std::string& address,
                                                         std::uint16_t port) {
  boost::system::error_code ec;
  const auto ip = boost::asio::ip::make_address(address, ec);
  if (ec) {
    return core::Error{
        core::kExitConfigError,
        fmt::format("UDP output address '{}' is not a numeric IPv4/IPv6 address", address)};
  }
  if (port == 0) {
    return core::Error{
        core::kExitConfigError,
        fmt::format("UDP output port 0 for '{}': give the receiver's port", address)};
  }
  auto impl = std::make_unique<Impl>();
  impl->destination = udp::endpoint(ip, port);
  impl->socket.open(impl->destination.protocol(), ec);
  if (!ec && ip.is_v4() && ip.to_v4() == boost::asio::ip::address_v4::broadcast()) {
    impl->socket.set_option(boost::asio::socket_base::broadcast(true), ec);
  }
  if (!ec) impl->socket.non_blocking(true, ec);
  if (ec) {
    return core::Error{core::kExitIoError, fmt::format("cannot open a UDP socket to {}:{}: {}",
                                                       address, port, ec.message())};
  }
  return std::unique_ptr<UdpSender>(new UdpSender(std::move(impl)));
}

UdpSender::UdpSender(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
UdpSender::~UdpSender() = default;

bool UdpSender::send(core::ByteSpan datagram) noexcept {
  boost::system::error_code ec;
  impl_->socket.send_to(boost::asio::buffer(datagram.data(), datagram.size()), impl_->destination,
                        0, ec);
  if (!ec) {
    impl_->sent.fetch_add(1, std::memory_order_relaxed);
    return true;
  }
  if (ec == boost::asio::error::would_block || ec == boost::asio::error::no_buffer_space) {
    impl_->dropped.fetch_add(1, std::memory_order_relaxed);
  } else {
    impl_->errors.fetch_add(1, std::memory_order_relaxed);
  }
  return false;
}

UdpSenderStats UdpSender::stats() const noexcept {
  return {impl_->sent.load(std::memory_order_relaxed),
          impl_->dropped.load(std::memory_order_relaxed),
          impl_->errors.load(std::memory_order_relaxed)};
}

std::string UdpSender::describe() const {
  return fmt::format("UDP {}:{}", impl_->destination.address().to_string(),
                     impl_->destination.port());
}

struct UdpReceiver::Impl {
  boost::asio::io_context io;
  udp::socket socket{io};
};

core::Result<std::unique_ptr<UdpReceiver>> UdpReceiver::open(const std::string& address,
                                                             std::uint16_t port) {
  boost::system::error_code ec;
  const auto ip = boost::asio::ip::make_address(address, ec);
  if (ec) {
    return core::Error{core::kExitUsage,
                       fmt::format("'{}' is not a numeric IPv4/IPv6 address", address)};
  }
  auto impl = std::make_unique<Impl>();
  const udp::endpoint ep(ip, port);
  impl->socket.open(ep.protocol(), ec);
  if (!ec) impl->socket.set_option(boost::asio::socket_base::reuse_address(true), ec);
  if (!ec) impl->socket.bind(ep, ec);
  if (!ec) impl->socket.non_blocking(true, ec);
  // Each datagram comes with the time the kernel received it (see receive()).
  const int on = 1;
  if (!ec &&
      ::setsockopt(impl->socket.native_handle(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    ec = boost::system::error_code(errno, boost::system::system_category());
  }
  if (ec) {
    return core::Error{core::kExitIoError,
                       fmt::format("cannot listen on UDP {}:{}: {}", address, port, ec.message())};
  }
  return std::unique_ptr<UdpReceiver>(new UdpReceiver(std::move(impl)));
}

UdpReceiver::UdpReceiver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
UdpReceiver::~UdpReceiver() = default;

std::optional<std::size_t> UdpReceiver::receive(std::span<std::uint8_t> buffer,
                                                std::chrono::milliseconds timeout,
                                                std::chrono::system_clock::time_point* arrival) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const int fd = impl_->socket.native_handle();
  for (;;) {
    iovec iov{buffer.data(), buffer.size()};
    alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec))> control{};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.data();
    msg.msg_controllen = control.size();
    const ssize_t n = ::recvmsg(fd, &msg, 0);
    if (n >= 0) {
      if (arrival != nullptr) {
        *arrival = std::chrono::system_clock::now();
        for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
          if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
            timespec ts{};
            std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
            *arrival = std::chrono::system_clock::time_point(
                std::chrono::duration_cast<std::chrono::system_clock::duration>(
                    std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec)));
          }
        }
      }
      // A datagram longer than the buffer arrives truncated to it.
      return (msg.msg_flags & MSG_TRUNC) != 0 ? buffer.size() : static_cast<std::size_t>(n);
    }
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return std::nullopt;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return std::nullopt;
    pollfd p{fd, POLLIN, 0};
    ::poll(&p, 1, static_cast<int>(std::min<long long>(left.count(), 1000)));
  }
}

std::uint16_t UdpReceiver::port() const { return impl_->socket.local_endpoint().port(); }

}  // namespace cndt::net
