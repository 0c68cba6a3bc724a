// Cuts the stream of decoded packets into revolutions. The cut is made per firing sequence where
// the rotor azimuth passes the cut angle, never on packet boundaries, so every scan covers exactly
// one turn. Packet loss is found from the sensor clock.
#pragma once

#include <chrono>
#include <cstdint>

#include "cndt/core/scan.hpp"
#include "cndt/vlp16/decoder.hpp"

namespace cndt::vlp16 {

struct AssemblerOptions {
  std::uint16_t cut_azimuth = 0;                 ///< 0.01 deg, [0, 36000)
  std::size_t max_points = 150'000;              ///< point capacity of one scan, allocated once
  std::chrono::nanoseconds max_gap{50'000'000};  ///< a silence longer than this ends the scan
};

struct AssemblerStats {
  std::uint64_t scans = 0;           ///< scans handed out
  std::uint64_t complete_scans = 0;  ///< scans with no flag set
  std::uint64_t lost_packets = 0;    ///< estimated from sensor-clock gaps
  std::uint64_t gaps = 0;            ///< places where packets were missing
  std::uint64_t time_jumps = 0;      ///< sensor clock went backwards by more than max_gap
  std::uint64_t stale_packets = 0;   ///< repeated or overlapping an earlier packet; dropped
  std::uint64_t points = 0;          ///< points in handed-out scans
  std::uint64_t points_dropped = 0;  ///< points refused for capacity
};

class ScanAssembler {
 public:
  ScanAssembler(const AssemblerOptions& options, double packet_period_us);

  /// Adds one decoded packet whose first firing happened at `packet_time` (absolute). Each scan
  /// that completes is passed to `sink(core::Scan&)`; the sink may swap the scan's contents for an
  /// empty scan of the same capacity. The assembler allocates nothing here.
  template <class Sink>
  void add(const DecodedPacket& packet, std::chrono::nanoseconds packet_time, Sink&& sink);

  /// Hands out the scan in progress (flagged kScanEndOfStream), if it has any firing.
  template <class Sink>
  void flush(Sink&& sink);

  /// Sets the packet period after the return mode became known (dual halves it).
  void set_packet_period_us(double us) noexcept { period_ns_ = us * 1000.0; }
  [[nodiscard]] const AssemblerStats& stats() const noexcept { return stats_; }

 private:
  enum class Continuity { kContinuous, kLoss, kGap, kJump, kStale };
  // Compares the packet's time with the previous packet's: loss, long silence or clock jump.
  Continuity check_continuity(const DecodedPacket& packet, std::chrono::nanoseconds packet_time,
                              std::uint32_t& lost) noexcept;
  template <class Sink>
  void finish(Sink&& sink, std::uint32_t extra_flags);
  void start_scan(std::chrono::nanoseconds stamp, int relative_azimuth) noexcept;
  // Copies the points of firings [first, last) into the scan (up to its capacity), their times
  // rebased from the packet onto the scan stamp, and moves the scan's end to the last firing.
  void append(const DecodedPacket& packet, int first, int last,
              std::chrono::nanoseconds packet_time) noexcept;
  // Charges `lost` packets to the scan they belonged to: when the cut fell among them, those
  // before it to the scan in progress and the rest to the next one.
  void attribute_loss(std::uint32_t lost, const DecodedPacket& packet) noexcept;

  AssemblerOptions options_;
  double period_ns_;
  core::Scan scan_;
  bool scan_open_ = false;
  bool next_partial_ = true;      // the next scan does not start at the cut angle
  std::uint32_t next_flags_ = 0;  // flags carried into the next scan (loss before it opened)
  std::uint32_t next_lost_ = 0;
  bool have_last_ = false;
  std::chrono::nanoseconds last_packet_time_{0};
  std::chrono::nanoseconds last_point_time_{0};  // latest firing accepted so far
  int last_rel_ = 0;
  AssemblerStats stats_;
};

// ---- implementation of the templates ----

template <class Sink>
void ScanAssembler::finish(Sink&& sink, std::uint32_t extra_flags) {
  if (!scan_open_) return;
  scan_.flags |= extra_flags;
  ++stats_.scans;
  if (scan_.complete()) ++stats_.complete_scans;
  stats_.points += scan_.points.size();
  stats_.points_dropped += scan_.points_dropped;
  sink(scan_);
  ++scan_.sequence;
  scan_.reset();
  scan_open_ = false;
}

template <class Sink>
void ScanAssembler::flush(Sink&& sink) {
  finish(sink, core::kScanEndOfStream);
}

template <class Sink>
void ScanAssembler::add(const DecodedPacket& packet, std::chrono::nanoseconds packet_time,
                        Sink&& sink) {
  std::uint32_t lost = 0;
  switch (check_continuity(packet, packet_time, lost)) {
    case Continuity::kContinuous:
      break;
    case Continuity::kLoss:
      attribute_loss(lost, packet);
      break;
    case Continuity::kGap:
      finish(sink, core::kScanGapCut);
      next_partial_ = true;
      break;
    case Continuity::kJump:
      finish(sink, core::kScanTimeJump);
      next_partial_ = true;
      next_flags_ |= core::kScanTimeJump;
      break;
    case Continuity::kStale:
      return;  // a duplicate or a packet from the past: its firings would run time backwards
  }
  // Firings go to the open scan in runs: a run ends where the azimuth passes the cut.
  int run = 0;  // first firing of the run not yet copied
  for (int i = 0; i < packet.firing_count; ++i) {
    const Firing& f = packet.firings[static_cast<std::size_t>(i)];
    const int rel = (f.azimuth - options_.cut_azimuth + 36000) % 36000;
    if (scan_open_ && rel < last_rel_) {
      append(packet, run, i, packet_time);
      run = i;
      finish(sink, 0);
      next_partial_ = false;
    }
    if (!scan_open_) {
      start_scan(packet_time + std::chrono::nanoseconds(f.offset_ns), rel);
      ++scan_.packets;
    } else if (i == 0) {
      ++scan_.packets;
    }
    last_rel_ = rel;
  }
  append(packet, run, packet.firing_count, packet_time);
}

}  // namespace cndt::vlp16
