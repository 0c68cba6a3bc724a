#include "cndt/runtime/notify.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

namespace cndt::runtime {

Notifier::Notifier() {
  static_assert(sizeof(sockaddr_un) <= sizeof(address_));
  const char* path = std::getenv("NOTIFY_SOCKET");
  if (path != nullptr && (path[0] == '/' || path[0] == '@')) {
    const std::size_t n = std::strlen(path);
    sockaddr_un a{};
    if (n < sizeof a.sun_path) {
      a.sun_family = AF_UNIX;
      std::memcpy(a.sun_path, path, n);
      if (path[0] == '@') a.sun_path[0] = '\0';  // the abstract namespace
      address_length_ =
          static_cast<unsigned>(offsetof(sockaddr_un, sun_path) + n + (path[0] == '@' ? 0 : 1));
      std::memcpy(address_, &a, sizeof a);
      fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    }
  }
  std::uint64_t usec = 0;
  // libsystemd reads WATCHDOG_USEC and checks WATCHDOG_PID against this process.
  if (sd_watchdog_enabled(0, &usec) > 0) watchdog_ = std::chrono::microseconds(usec);
}

Notifier::~Notifier() {
  if (fd_ >= 0) ::close(fd_);
}

bool Notifier::send(std::string_view message) noexcept {
  if (fd_ < 0) return false;
  const ssize_t n = ::sendto(fd_, message.data(), message.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(address_), address_length_);
  if (n != static_cast<ssize_t>(message.size())) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  return true;
}

void Notifier::watchdog() noexcept {
  if (watchdog_.count() == 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ping_ >= watchdog_ / 2) {
    send("WATCHDOG=1");
    last_ping_ = now;
  }
}

}  // namespace cndt::runtime
