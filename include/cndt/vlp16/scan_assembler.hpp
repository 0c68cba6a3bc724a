// Cuts the stream of decoded packets into revolutions. The cut is made per firing sequence where
// the rotor azimuth passes the cut angle, never on packet boundaries, so every scan covers exactly
// one turn. Packet loss is found from the sensor clock. A sensor set to a limited field of view
// is silent over the same sector every revolution: once two revolutions in a row show that
// silence, the cut moves into the middle of it and the silence no longer counts as loss.
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "cndt/core/scan.hpp"
#include "cndt/vlp16/decoder.hpp"

namespace cndt::vlp16 {

struct AssemblerOptions {
  std::uint16_t cut_azimuth = 0;                 ///< 0.01 deg, [0, 36000)
  std::size_t max_points = 150'000;              ///< point capacity of one scan, allocated once
  std::chrono::nanoseconds max_gap{50'000'000};  ///< a silence longer than this ends the scan
  bool cut_at_fov_gap = true;  ///< move the cut into a silent sector seen every revolution
};

/// A sector where the sensor sends nothing, every revolution (a limited field of view).
struct FovGap {
  std::uint16_t start = 0;       ///< azimuth of the last firing before the silence, 0.01 deg
  std::uint16_t length = 0;      ///< azimuth the silence spans, 0.01 deg; 0 = none found
  std::uint32_t packets = 0;     ///< packets the sensor would have sent over it
  std::int64_t duration_ns = 0;  ///< time from the last firing before to the first after
  /// Azimuth where the silence ends, 0.01 deg.
  [[nodiscard]] std::uint16_t end() const noexcept {
    return static_cast<std::uint16_t>((start + length) % 36000);
  }
};

struct AssemblerStats {
  std::uint64_t scans = 0;           ///< scans handed out
  std::uint64_t complete_scans = 0;  ///< scans with no flag set
  std::uint64_t lost_packets = 0;    ///< estimated from sensor-clock gaps
  std::uint64_t gaps = 0;            ///< places where packets were missing
  std::uint64_t time_jumps = 0;     ///< clock went back, or on while packets kept coming, > max_gap
  std::uint64_t stale_packets = 0;  ///< repeated or overlapping an earlier packet; dropped
  std::uint64_t points = 0;         ///< points in handed-out scans
  std::uint64_t points_dropped = 0;  ///< points refused for capacity
  std::uint64_t fov_silences = 0;    ///< silences over the field-of-view gap, not counted as loss
  std::uint64_t azimuth_jumps = 0;   ///< jumps inside a packet that the next packet's time refuted
  FovGap fov_gap;                    ///< the field-of-view gap, once found
  std::uint16_t cut_azimuth = 0;     ///< the cut in use, 0.01 deg (moved into the gap once found)
};

class ScanAssembler {
 public:
  ScanAssembler(const AssemblerOptions& options, double packet_period_us);

  /// Adds one decoded packet whose first firing happened at `packet_time` (absolute). Each scan
  /// that completes is passed to `sink(core::Scan&)`; the sink may swap the scan's contents for an
  /// empty scan of the same capacity. The assembler allocates nothing here. `received`, when
  /// known (not 0), is when the packet was received or captured: a sensor-clock step forward
  /// longer than max_gap while packets kept arriving is a clock jump, not lost data.
  template <class Sink>
  void add(const DecodedPacket& packet, std::chrono::nanoseconds packet_time, Sink&& sink,
           std::chrono::nanoseconds received = std::chrono::nanoseconds{0});

  /// Hands out the scan in progress (flagged kScanEndOfStream), if it has any firing.
  template <class Sink>
  void flush(Sink&& sink);

  /// Sets the packet period after the return mode became known (dual halves it).
  void set_packet_period_us(double us) noexcept { period_ns_ = us * 1000.0; }
  [[nodiscard]] const AssemblerStats& stats() const noexcept { return stats_; }

 private:
  enum class Continuity { kContinuous, kLoss, kGap, kJump, kStale, kFovFound };
  // Compares the packet's time with the previous packet's: loss, long silence or clock jump.
  Continuity check_continuity(const DecodedPacket& packet, std::chrono::nanoseconds packet_time,
                              std::chrono::nanoseconds received, std::uint32_t& lost);
  // A silence of `missing` packet periods ended at this packet: takes out what the field-of-view
  // gap explains (learning the gap from two revolutions in a row) and says what remains.
  Continuity classify_silence(const DecodedPacket& packet, std::chrono::nanoseconds packet_time,
                              std::chrono::nanoseconds dt, std::uint32_t missing,
                              std::uint32_t& lost);
  // Takes a silence over `length` (0.01 deg) from azimuth `from`, ended at `end`, as one turn of a
  // field-of-view gap when the silence before covered the same sector one turn earlier; then
  // records the gap and sets pending_cut_. A silence wide enough for a field of view becomes the
  // silence before; a shorter one is left out.
  bool learn_fov_gap(int from, int length, std::chrono::nanoseconds end, std::uint32_t missing,
                     std::chrono::nanoseconds duration);
  // Where, inside a packet, the azimuth jumps over a sector: a sensor with a limited field of view
  // fills the packet's last blocks from the start of the next pass, fired that much later.
  struct Skip {
    int at = 0;                 // first firing after the jump; firing_count = none
    int from = 0, length = 0;   // the sector jumped over, 0.01 deg
    std::int64_t extra_ns = 0;  // how much later than the packet's timing those firings fired
    int new_cut = -1;           // the cut moves here at the skip (a gap just found); -1 = stays
  };
  [[nodiscard]] Skip find_skip(const DecodedPacket& packet) const noexcept;
  // Finds a skip in the packet and takes it as a field-of-view silence: learns the gap from it,
  // and moves the stream's time on past it until the next packet confirms or refutes the delay.
  Skip take_skip(const DecodedPacket& packet, std::chrono::nanoseconds packet_time);
  // The packet after a skip: arrived as late as the skip said (the delay is corrected from its
  // clock), or on the packet's own timing (the skip was a bad azimuth, not a silence: the
  // stream's time goes back and skip_refuted_ asks add() to end the scan in progress).
  void check_skip_delay(const DecodedPacket& packet, std::chrono::nanoseconds packet_time) noexcept;
  // Moves the open scan's firings after the last skip (`tail`) by `fix` ns (the skip's delay as
  // the next packet's clock gives it); false when that would put them before the firings ahead.
  struct ShiftedTail;
  bool retime_after_skip(const ShiftedTail& tail, std::int64_t fix) noexcept;
  // Azimuth the rotor turns in one packet period, 0.01 deg (0 before the speed is known).
  [[nodiscard]] double packet_arc() const noexcept { return azimuth_per_ns_ * period_ns_; }
  // How far (0.01 deg) two azimuths of the same sector may differ: 1.5 packets of rotation.
  [[nodiscard]] int azimuth_tolerance() const noexcept;
  // Notes the rotor's speed and the last azimuth of a packet that was taken.
  void note_azimuths(const DecodedPacket& packet, const Skip& skip) noexcept;
  template <class Sink>
  void finish(Sink&& sink, std::uint32_t extra_flags);
  void start_scan(std::chrono::nanoseconds stamp, int relative_azimuth) noexcept;
  // Copies the points of firings [first, last) into the scan (up to its capacity), their times
  // rebased from the packet onto the scan stamp (plus `extra_ns` past a skip), and moves the
  // scan's end to the last firing.
  void append(const DecodedPacket& packet, int first, int last,
              std::chrono::nanoseconds packet_time, std::int64_t extra_ns) noexcept;
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
  // Receive times of the last two packets, newest first; 0 = unknown.
  std::array<std::chrono::nanoseconds, 2> received_before_{};
  std::chrono::nanoseconds last_point_time_{0};  // latest firing accepted so far
  int last_rel_ = 0;
  // Field-of-view gap detection.
  bool have_last_azimuth_ = false;
  int last_azimuth_ = 0;         // of the last firing taken
  double azimuth_per_ns_ = 0.0;  // rotor speed from the latest packet, 0.01 deg per ns
  struct Silence {
    int from = 0, length = 0;         // 0.01 deg
    std::chrono::nanoseconds end{0};  // time of the firing that ended it
    bool valid = false;
  } last_silence_;
  std::uint16_t pending_cut_ = 0;          // the cut a newly found gap asks for
  std::int64_t unconfirmed_shift_ns_ = 0;  // a skip's delay, until the next packet shows it
  bool skip_refuted_ = false;  // the scan in progress holds firings given a delay they did not have
  // Where the open scan's firings after the last skip begin, for retime_after_skip: its points
  // from `from` on, or the whole scan (`whole`) when it began after the skip.
  struct ShiftedTail {
    std::size_t from = static_cast<std::size_t>(-1);
    bool whole = false;
  } shifted_;
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
                        Sink&& sink, std::chrono::nanoseconds received) {
  std::uint32_t lost = 0;
  const Continuity continuity = check_continuity(packet, packet_time, received, lost);
  if (skip_refuted_) {
    // This packet's firings would come before the ones already given the refuted delay: the
    // scan ends there, so that its point times never decrease.
    skip_refuted_ = false;
    finish(sink, core::kScanTimeJump);
    next_partial_ = true;
  }
  switch (continuity) {
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
    case Continuity::kFovFound:
      // The cut moved into the silence just ended: the scan in progress ends here.
      finish(sink, core::kScanGapCut);
      next_partial_ = false;
      break;
  }
  // A skip inside the packet is a silence too (the packet's timing does not show it).
  const Skip skip = take_skip(packet, packet_time);
  // Firings go to the open scan in runs: a run ends where the azimuth passes the cut, and at a
  // skip.
  int run = 0;  // first firing of the run not yet copied
  bool started_after_skip = false;
  for (int i = 0; i < packet.firing_count; ++i) {
    const Firing& f = packet.firings[static_cast<std::size_t>(i)];
    const std::int64_t extra = i >= skip.at ? skip.extra_ns : 0;
    if (i == skip.at) {
      append(packet, run, i, packet_time, 0);
      run = i;
      if (skip.new_cut >= 0) {
        // The cut moved into the sector just skipped: the scan in progress ends here.
        stats_.cut_azimuth = static_cast<std::uint16_t>(skip.new_cut);
        finish(sink, core::kScanGapCut);
        next_partial_ = false;
      }
    }
    const int rel = (f.azimuth - stats_.cut_azimuth + 36000) % 36000;
    if (scan_open_ && rel < last_rel_) {
      append(packet, run, i, packet_time, extra);
      run = i;
      finish(sink, 0);
      next_partial_ = false;
    }
    if (!scan_open_) {
      started_after_skip = i >= skip.at;
      start_scan(packet_time + std::chrono::nanoseconds(f.offset_ns + extra), rel);
      ++scan_.packets;
    } else if (i == 0) {
      ++scan_.packets;
    }
    last_rel_ = rel;
  }
  const std::size_t tail_from = scan_.points.size();
  append(packet, run, packet.firing_count, packet_time, run >= skip.at ? skip.extra_ns : 0);
  if (skip.at < packet.firing_count)
    shifted_ = {started_after_skip ? 0 : tail_from, started_after_skip};
  note_azimuths(packet, skip);
}

}  // namespace cndt::vlp16
