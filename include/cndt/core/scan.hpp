// Point and Scan: one sensor revolution with a time for every point.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cndt/core/resident.hpp"

namespace cndt::core {

/// How a point's return was classified by the sensor.
enum class ReturnType : std::uint8_t {
  kSingle = 0,     ///< strongest or last return mode: one return per firing
  kStrongest = 1,  ///< dual mode, the strongest (or second strongest) return, distinct from last
  kLast = 2,       ///< dual mode, the last return, distinct from strongest
  kBoth = 3,       ///< dual mode, last and strongest were the same return; kept once
};

/// One return in the sensor frame (REP-103: x forward, y left, z up; metres).
struct Point {
  float x = 0.0F;
  float y = 0.0F;
  float z = 0.0F;
  float intensity = 0.0F;     ///< calibrated reflectivity, 0..255
  std::uint32_t time_ns = 0;  ///< firing time after the scan's stamp, non-negative, non-decreasing
  std::uint16_t ring = 0;     ///< 0 = lowest elevation
  ReturnType return_type = ReturnType::kSingle;
  std::uint8_t reserved = 0;
};

// The decoder writes a point as two blocks: 16 bytes of floats, then 8 bytes of time and tags.
static_assert(sizeof(Point) == 24 && offsetof(Point, time_ns) == 16 &&
                  offsetof(Point, ring) == 20 && offsetof(Point, return_type) == 22 &&
                  offsetof(Point, reserved) == 23,
              "Point layout changed: update Decoder::decode_sequence_n");

/// Bit flags describing how complete a scan is.
enum ScanFlags : std::uint32_t {
  kScanPartial = 1u << 0,      ///< did not start at the cut angle (first scan of a stream)
  kScanPacketLoss = 1u << 1,   ///< packets missing inside the revolution (see lost_packets)
  kScanOverflow = 1u << 2,     ///< more points than the configured capacity; extra points dropped
  kScanTimeJump = 1u << 3,     ///< the sensor clock went backwards or jumped inside the scan
  kScanGapCut = 1u << 4,       ///< ended early by a gap longer than the configured maximum
  kScanEndOfStream = 1u << 5,  ///< flushed at the end of the input, not at the cut angle
};

/// One revolution. The point buffer's capacity is fixed when the scan is created; push() refuses
/// points beyond it (counted in points_dropped) so a scan never allocates after construction.
struct Scan {
  explicit Scan(std::size_t capacity = 0) { reserve_resident(points, capacity); }

  std::chrono::nanoseconds stamp{0};  ///< absolute time (Unix epoch) of the scan's first firing
  std::chrono::nanoseconds end{0};    ///< absolute time of the scan's last firing
  std::uint64_t sequence = 0;         ///< 0, 1, 2 ... in the order scans were completed
  std::uint32_t flags = 0;            ///< ScanFlags
  std::uint32_t packets = 0;          ///< data packets that contributed firings
  std::uint32_t lost_packets = 0;     ///< packets missing inside this scan (timestamp gaps)
  std::uint32_t points_dropped = 0;   ///< points refused because the buffer was full
  std::vector<Point> points;

  /// From the cut angle round to it again: packets may be missing inside it.
  [[nodiscard]] bool whole_turn() const noexcept {
    return (flags &
            (kScanPartial | kScanOverflow | kScanTimeJump | kScanGapCut | kScanEndOfStream)) == 0;
  }
  [[nodiscard]] bool complete() const noexcept {
    return whole_turn() && (flags & kScanPacketLoss) == 0;
  }
  void reset() noexcept {
    stamp = end = std::chrono::nanoseconds{0};
    flags = packets = lost_packets = points_dropped = 0;
    points.clear();
  }
  bool push(const Point& p) noexcept {
    if (points.size() == points.capacity()) {
      ++points_dropped;
      flags |= kScanOverflow;
      return false;
    }
    points.push_back(p);
    return true;
  }
};

}  // namespace cndt::core
