#include "cndt/net/udp_source.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <boost/lockfree/spsc_queue.hpp>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "asio.hpp"

namespace cndt::net {
namespace {

using boost::asio::ip::udp;
constexpr std::size_t kMaxDatagram = 1500;  // larger than any Velodyne payload

struct Slot {
  std::array<std::uint8_t, kMaxDatagram> data;
  std::uint16_t size;
  io::PacketKind kind;
  std::chrono::nanoseconds time;
  io::IpAddress source;
  std::uint16_t source_port, dest_port;
};

io::IpAddress to_ip(const boost::asio::ip::address& a) {
  io::IpAddress ip;
  if (a.is_v4()) {
    const auto b = a.to_v4().to_bytes();
    std::copy(b.begin(), b.end(), ip.bytes.begin());
  } else {
    ip.version = 6;
    const auto b = a.to_v6().to_bytes();
    std::copy(b.begin(), b.end(), ip.bytes.begin());
  }
  return ip;
}

}  // namespace

struct UdpSource::Impl {
  struct Listener {
    udp::socket socket;
    udp::endpoint sender;
    io::PacketKind kind;
    std::uint16_t port = 0;
    std::array<std::uint8_t, kMaxDatagram + 1> buffer{};
    explicit Listener(boost::asio::io_context& io, io::PacketKind k) : socket(io), kind(k) {}
  };

  UdpOptions options;
  boost::asio::io_context io;
  std::vector<std::unique_ptr<Listener>> listeners;
  boost::lockfree::spsc_queue<Slot> queue;
  std::thread thread;
  std::atomic<bool> stopped{false};
  // The consumer sleeps on `arrived` while the queue is empty; the receive thread takes `mutex`
  // after each push (and stop() after setting `stopped`) before it notifies, so a wake-up cannot
  // fall between the consumer's check and its wait.
  std::mutex mutex;
  std::condition_variable arrived;
  Slot current{};
  std::atomic<std::uint64_t> received{0}, accepted{0}, wrong_source{0}, oversize{0}, queue_full{0},
      errors{0};
  int granted_buffer = 0;

  explicit Impl(const UdpOptions& o) : options(o), queue(o.queue_capacity) {}

  void wake() {
    { const std::lock_guard<std::mutex> lock(mutex); }
    arrived.notify_one();
  }

  void arm(Listener& l) {
    l.socket.async_receive_from(boost::asio::buffer(l.buffer), l.sender,
                                [this, &l](const boost::system::error_code& ec, std::size_t n) {
                                  if (ec == boost::asio::error::operation_aborted) return;
                                  if (ec) {
                                    ++errors;
                                  } else {
                                    on_datagram(l, n);
                                  }
                                  arm(l);
                                });
  }

  void on_datagram(Listener& l, std::size_t n) {
    ++received;
    const io::IpAddress src = to_ip(l.sender.address());
    if (options.sensor_ip && src != *options.sensor_ip) {
      ++wrong_source;
      return;
    }
    if (n > kMaxDatagram) {
      ++oversize;
      return;
    }
    Slot s;
    std::copy_n(l.buffer.begin(), n, s.data.begin());
    s.size = static_cast<std::uint16_t>(n);
    s.kind = l.kind;
    s.time = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::system_clock::now().time_since_epoch());
    s.source = src;
    s.source_port = l.sender.port();
    s.dest_port = l.port;
    if (queue.push(s)) {
      ++accepted;
      wake();
    } else {
      ++queue_full;
    }
  }
};

core::Result<std::unique_ptr<UdpSource>> UdpSource::open(const UdpOptions& options) {
  auto impl = std::make_unique<Impl>(options);
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address(options.bind_address, ec);
  if (ec) {
    return core::Error{core::kExitConfigError,
                       fmt::format("bind address '{}' is not an IP address", options.bind_address)};
  }
  auto bind = [&](std::uint16_t port, io::PacketKind kind) -> std::optional<core::Error> {
    auto l = std::make_unique<Impl::Listener>(impl->io, kind);
    const udp::endpoint ep(address, port);
    l->socket.open(ep.protocol(), ec);
    if (!ec) l->socket.set_option(udp::socket::reuse_address(true), ec);
    if (!ec) l->socket.bind(ep, ec);
    if (ec) {
      return core::Error{core::kExitIoError, fmt::format("cannot listen on UDP {}:{}: {}",
                                                         options.bind_address, port, ec.message())};
    }
    l->socket.set_option(
        boost::asio::socket_base::receive_buffer_size(options.receive_buffer_bytes), ec);
    boost::asio::socket_base::receive_buffer_size granted;
    l->socket.get_option(granted, ec);
    impl->granted_buffer = granted.value();
    l->port = l->socket.local_endpoint().port();
    impl->listeners.push_back(std::move(l));
    return std::nullopt;
  };
  if (auto err = bind(options.data_port, io::PacketKind::kData)) return *err;
  if (options.position_port != 0) {
    if (auto err = bind(options.position_port, io::PacketKind::kPosition)) return *err;
  }
  // Linux reports twice the usable size; half of it is what was asked for when granted in full.
  if (impl->granted_buffer / 2 < options.receive_buffer_bytes) {
    spdlog::warn(
        "UDP receive buffer is {} bytes, less than the {} asked for; raise "
        "net.core.rmem_max to avoid losing packets in bursts",
        impl->granted_buffer / 2, options.receive_buffer_bytes);
  }
  for (auto& l : impl->listeners) impl->arm(*l);
  auto* raw = impl.get();
  impl->thread = std::thread([raw] { raw->io.run(); });
  return std::unique_ptr<UdpSource>(new UdpSource(std::move(impl)));
}

UdpSource::UdpSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

UdpSource::~UdpSource() { stop(); }

void UdpSource::stop() {
  if (impl_->stopped.exchange(true)) return;
  impl_->wake();
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

io::NextResult UdpSource::next(io::SourcePacket& packet, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!impl_->queue.pop(impl_->current)) {
    if (impl_->stopped.load()) return io::NextResult::kEnd;
    std::unique_lock<std::mutex> lock(impl_->mutex);
    const bool ready = impl_->arrived.wait_until(lock, deadline, [this] {
      return impl_->queue.read_available() > 0 || impl_->stopped.load();
    });
    if (!ready) return io::NextResult::kTimeout;
  }
  const Slot& s = impl_->current;
  packet.kind = s.kind;
  packet.time = s.time;
  packet.payload = core::ByteSpan(s.data.data(), s.size);
  packet.source = s.source;
  packet.source_port = s.source_port;
  packet.dest_port = s.dest_port;
  packet.index = impl_->accepted.load();
  return io::NextResult::kPacket;
}

UdpStats UdpSource::stats() const {
  UdpStats s;
  s.received = impl_->received.load();
  s.accepted = impl_->accepted.load();
  s.wrong_source = impl_->wrong_source.load();
  s.oversize = impl_->oversize.load();
  s.queue_full = impl_->queue_full.load();
  s.receive_errors = impl_->errors.load();
  s.receive_buffer_bytes = impl_->granted_buffer / 2;
  return s;
}

std::uint16_t UdpSource::data_port() const { return impl_->listeners.front()->port; }
std::uint16_t UdpSource::position_port() const {
  return impl_->listeners.size() > 1 ? impl_->listeners[1]->port : 0;
}

}  // namespace cndt::net
