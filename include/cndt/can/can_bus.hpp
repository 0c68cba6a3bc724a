// Where CAN frames go: a SocketCAN interface (can0, vcan0) or a candump-format log file. A bus
// never blocks its caller: a frame the bus cannot take right now is dropped and counted.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cndt/core/result.hpp"
#include "cndt/output/can_codec.hpp"

namespace cndt::can {

struct CanBusStats {
  std::uint64_t sent = 0;
  std::uint64_t dropped_queue_full = 0;  ///< ENOBUFS / EAGAIN: the transmit queue was full
  std::uint64_t errors = 0;              ///< other send failures
};

class CanBus {
 public:
  virtual ~CanBus() = default;
  /// Sends one frame stamped `stamp` (the log's timestamp; SocketCAN ignores it). Never blocks,
  /// never allocates. Returns false when the frame was not sent (counted in stats()).
  virtual bool send(const output::CanFrame& frame, std::chrono::nanoseconds stamp) noexcept = 0;
  /// Pushes buffered frames out (the log file); called after each pose.
  virtual void flush() noexcept {}
  [[nodiscard]] virtual CanBusStats stats() const noexcept = 0;
  [[nodiscard]] virtual std::string describe() const = 0;
};

/// Appends frames to a candump log ("(1767225600.100000) can0 300#1A2B..."), the format
/// can-utils' canplayer, log2asc and log2long read. The file is created or truncated.
core::Result<std::unique_ptr<CanBus>> open_candump_log(const std::string& path,
                                                       const std::string& interface_name);

/// A SocketCAN raw socket bound to `interface_name`, non-blocking. Fails with a message naming
/// the interface when the kernel has no CAN support or the interface does not exist.
core::Result<std::unique_ptr<CanBus>> open_socketcan(const std::string& interface_name);

/// One candump log line written into `out` (no allocation); returns its length.
std::size_t format_candump_line(const output::CanFrame& frame, std::chrono::nanoseconds stamp,
                                std::string_view interface_name, std::span<char> out) noexcept;

struct CandumpRecord {
  std::chrono::nanoseconds stamp{0};
  std::string interface_name;
  output::CanFrame frame;
};

/// Parses one candump log line. Classic frames only (standard or extended id, 0..8 data bytes,
/// '.' separators allowed, an optional " R"/" T" direction). Returns nothing for lines that
/// are not frames (comments, DROPCOUNT lines, blank); an error for a malformed frame line.
core::Result<std::optional<CandumpRecord>> parse_candump_line(std::string_view line);

}  // namespace cndt::can
