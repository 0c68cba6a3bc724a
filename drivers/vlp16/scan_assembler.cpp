#include "cndt/vlp16/scan_assembler.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <utility>

namespace cndt::vlp16 {
namespace {
// The first scan of a stream counts as complete only if it starts within 1 deg after the cut.
constexpr int kStartTolerance = 100;
// A silent sector shorter than this (0.01 deg) is packet loss, never a field-of-view gap.
constexpr int kMinFovGap = 1000;
// The slowest rotor (300 rpm) turns once in 0.2 s: a skip said to take longer is not a silence.
constexpr std::int64_t kMaxSkipNs = 400'000'000;

// How far the rotor turns from azimuth b to azimuth a (0.01 deg), in [0, 36000).
int azimuth_ahead(int a, int b) { return (a - b + 36000) % 36000; }

// Signed difference a - b of two azimuths (0.01 deg), in (-18000, 18000].
int azimuth_diff(int a, int b) {
  const int d = azimuth_ahead(a, b);
  return d > 18000 ? d - 36000 : d;
}
}  // namespace

ScanAssembler::ScanAssembler(const AssemblerOptions& options, double packet_period_us)
    : options_(options), period_ns_(packet_period_us * 1000.0), scan_(options.max_points) {
  stats_.cut_azimuth = options.cut_azimuth;
}

namespace {
// Earliest and latest firing time in a packet, as offsets from the packet time.
std::pair<std::uint32_t, std::uint32_t> firing_span(const DecodedPacket& p) {
  if (p.point_count > 0) {
    return {p.points[0].time_ns, p.points[static_cast<std::size_t>(p.point_count - 1)].time_ns};
  }
  if (p.firing_count > 0) {
    return {p.firings[0].offset_ns,
            p.firings[static_cast<std::size_t>(p.firing_count - 1)].offset_ns};
  }
  return {0, 0};
}
}  // namespace

ScanAssembler::Continuity ScanAssembler::check_continuity(const DecodedPacket& packet,
                                                          std::chrono::nanoseconds packet_time,
                                                          std::chrono::nanoseconds received,
                                                          std::uint32_t& lost) {
  const auto [first, last] = firing_span(packet);
  const std::chrono::nanoseconds first_time = packet_time + std::chrono::nanoseconds(first);
  const std::chrono::nanoseconds last_time = packet_time + std::chrono::nanoseconds(last);
  check_skip_delay(packet, packet_time);
  // The receive clock's step over the last two packets, when all three times are known and it
  // moved on. Two: a packet is sent after its last firing, so a silence that begins inside a
  // packet shows in the receive times one packet before it shows in the sensor clock.
  const std::chrono::nanoseconds received_dt = received - received_before_[1];
  const bool receive_steady = received.count() != 0 && received_before_[0].count() != 0 &&
                              received_before_[1].count() != 0 && received_dt.count() > 0;
  received_before_ = {received, received_before_[0]};
  if (!have_last_) {
    have_last_ = true;
    last_packet_time_ = packet_time;
    last_point_time_ = last_time;
    return Continuity::kContinuous;
  }
  const std::chrono::nanoseconds dt = packet_time - last_packet_time_;
  // The sensor clock stepped forward while the packets kept coming at their pace (a time source
  // taking over): nothing was lost. (Two packets received less than a period apart were read
  // from a queue in a burst, as after the reader stalled and the socket dropped packets: their
  // receive times say nothing about a silence between them.)
  const bool stepped_on = dt > options_.max_gap && receive_steady &&
                          received_dt < options_.max_gap && received_dt < dt / 4 &&
                          static_cast<double>(received_dt.count()) >= period_ns_;
  if (dt < -options_.max_gap || stepped_on) {
    // The clock went far back (a sensor reset) or stepped on: the times before and after the
    // step do not compare; start over from here.
    ++stats_.time_jumps;
    last_packet_time_ = packet_time;
    last_point_time_ = last_time;
    last_silence_.valid = false;
    return Continuity::kJump;
  }
  if (first_time <= last_point_time_ && dt < options_.max_gap) {
    // A repeat of a packet, or one that overlaps the firings already taken.
    ++stats_.stale_packets;
    return Continuity::kStale;
  }
  last_packet_time_ = packet_time;
  last_point_time_ = last_time;
  if (dt > options_.max_gap || static_cast<double>(dt.count()) > 1.5 * period_ns_) {
    const auto missing =
        static_cast<std::uint32_t>(std::llround(static_cast<double>(dt.count()) / period_ns_) - 1);
    return classify_silence(packet, packet_time, dt, missing, lost);
  }
  return Continuity::kContinuous;
}

ScanAssembler::Continuity ScanAssembler::classify_silence(const DecodedPacket& packet,
                                                          std::chrono::nanoseconds packet_time,
                                                          std::chrono::nanoseconds dt,
                                                          std::uint32_t missing,
                                                          std::uint32_t& lost) {
  const auto as_loss = [&](std::uint32_t n, std::chrono::nanoseconds span) {
    ++stats_.gaps;
    stats_.lost_packets += n;
    if (span > options_.max_gap) return Continuity::kGap;
    lost = n;
    return Continuity::kLoss;
  };
  if (!options_.cut_at_fov_gap || !have_last_azimuth_ || packet.firing_count == 0 ||
      azimuth_per_ns_ <= 0.0) {
    return as_loss(missing, dt);
  }
  // The silence runs from the last firing taken to this packet's first, in the turning direction.
  const int from = last_azimuth_;
  const int length = azimuth_ahead(packet.firings[0].azimuth, from);
  const int tol = azimuth_tolerance();
  const double packets_per_turn = 36000.0 / packet_arc();
  // Longer than a turn, the azimuths no longer say which sector was silent.
  const bool within_turn = static_cast<double>(missing) < packets_per_turn - 1.0;
  FovGap& gap = stats_.fov_gap;
  if (gap.length > 0 && within_turn) {
    // How far before the gap's start the silence began (slightly negative: just after it).
    int before = azimuth_ahead(gap.start, from);
    if (before > 36000 - tol) before -= 36000;
    if (before >= -tol && before + gap.length <= length + tol) {
      // The whole gap was silent, as every turn; what the silence held beyond it was lost.
      ++stats_.fov_silences;
      const std::uint32_t excess = missing > gap.packets ? missing - gap.packets : 0;
      if (excess <= 1) return Continuity::kContinuous;  // a packet's jitter of where it falls
      return as_loss(excess, dt - std::chrono::nanoseconds(gap.duration_ns));
    }
  }
  if (learn_fov_gap(from, length, packet_time, missing, dt)) {
    ++stats_.fov_silences;
    const bool moved = pending_cut_ != stats_.cut_azimuth;
    stats_.cut_azimuth = pending_cut_;
    return moved ? Continuity::kFovFound : Continuity::kContinuous;
  }
  return as_loss(missing, dt);
}

bool ScanAssembler::learn_fov_gap(int from, int length, std::chrono::nanoseconds end,
                                  std::uint32_t missing, std::chrono::nanoseconds duration) {
  if (azimuth_per_ns_ <= 0.0) return false;
  const int tol = azimuth_tolerance();
  // The same sector, one turn after the silence before.
  const double turn_ns = 36000.0 / azimuth_per_ns_;
  const double apart = static_cast<double>((end - last_silence_.end).count());
  const bool repeats = last_silence_.valid && std::abs(apart - turn_ns) < 0.2 * turn_ns &&
                       std::abs(azimuth_diff(from, last_silence_.from)) <= tol &&
                       std::abs(length - last_silence_.length) <= 2 * tol;
  const bool wide = length >= kMinFovGap && static_cast<double>(length) >= 3.0 * packet_arc() &&
                    static_cast<double>(duration.count()) < 0.95 * turn_ns;
  if (!wide) return false;  // too short to be a field of view: loss, and no candidate
  last_silence_ = {from, length, end, true};
  if (!repeats) return false;
  FovGap& gap = stats_.fov_gap;
  gap.start = static_cast<std::uint16_t>(from);
  gap.length = static_cast<std::uint16_t>(length);
  gap.packets = missing;
  gap.duration_ns = duration.count();
  // A configured cut already inside the gap (clear of its edges) stays; otherwise the middle.
  const int configured = azimuth_ahead(options_.cut_azimuth, from);
  const bool keep = configured > tol && configured < length - tol;
  pending_cut_ =
      keep ? options_.cut_azimuth : static_cast<std::uint16_t>((from + length / 2) % 36000);
  spdlog::info(
      "the sensor is silent from {:.1f} to {:.1f} deg every turn (a limited field of view): "
      "revolutions are cut at {:.1f} deg ({}) and this silence is not counted as packet loss",
      from / 100.0, gap.end() / 100.0, pending_cut_ / 100.0,
      keep ? "the configured cut" : "the middle of the silence");
  return true;
}

ScanAssembler::Skip ScanAssembler::find_skip(const DecodedPacket& packet) const noexcept {
  Skip skip;
  skip.at = packet.firing_count;
  for (int i = 1; i < packet.firing_count; ++i) {
    const Firing& a = packet.firings[static_cast<std::size_t>(i - 1)];
    const Firing& b = packet.firings[static_cast<std::size_t>(i)];
    const int step = azimuth_ahead(b.azimuth, a.azimuth);
    if (step < kMinFovGap || step >= 36000 - kMinFovGap) continue;
    skip.at = i;
    skip.from = a.azimuth;
    skip.length = step;
    // The rotor's speed: from earlier packets, else from this packet's firings before the skip.
    double rate = azimuth_per_ns_;
    const Firing& head = packet.firings[0];
    if (rate <= 0.0 && i >= 2 && a.offset_ns > head.offset_ns) {
      rate = azimuth_ahead(a.azimuth, head.azimuth) /
             static_cast<double>(a.offset_ns - head.offset_ns);
    }
    if (rate > 0.0) {
      const double crossing_ns = step / rate;
      const double interval_ns = static_cast<double>(b.offset_ns - a.offset_ns);
      skip.extra_ns = std::max<std::int64_t>(0, std::llround(crossing_ns - interval_ns));
    }
    break;
  }
  return skip;
}

bool ScanAssembler::retime_after_skip(const ShiftedTail& tail, std::int64_t fix) noexcept {
  if (!scan_open_ || fix == 0) return true;
  auto& pts = scan_.points;
  if (tail.whole) {
    // The scan began after the skip: its stamp moves and its point offsets stay.
    scan_.stamp += std::chrono::nanoseconds(fix);
    scan_.end += std::chrono::nanoseconds(fix);
    return true;
  }
  if (tail.from >= pts.size()) return true;  // none of the open scan's points came after it
  const std::int64_t before = tail.from > 0 ? pts[tail.from - 1].time_ns : 0;
  if (static_cast<std::int64_t>(pts[tail.from].time_ns) + fix < before) return false;
  for (std::size_t i = tail.from; i < pts.size(); ++i) {
    pts[i].time_ns = static_cast<std::uint32_t>(static_cast<std::int64_t>(pts[i].time_ns) + fix);
  }
  scan_.end += std::chrono::nanoseconds(fix);
  return true;
}

int ScanAssembler::azimuth_tolerance() const noexcept {
  return static_cast<int>(std::ceil(1.5 * packet_arc()));
}

ScanAssembler::Skip ScanAssembler::take_skip(const DecodedPacket& packet,
                                             std::chrono::nanoseconds packet_time) {
  Skip none;
  none.at = packet.firing_count;
  if (!options_.cut_at_fov_gap) return none;
  Skip skip = find_skip(packet);
  if (skip.at >= packet.firing_count || skip.extra_ns <= 0 || skip.extra_ns > kMaxSkipNs) {
    return none;
  }
  const Firing& f = packet.firings[static_cast<std::size_t>(skip.at)];
  const std::chrono::nanoseconds end =
      packet_time + std::chrono::nanoseconds(f.offset_ns + skip.extra_ns);
  const auto missing =
      static_cast<std::uint32_t>(std::llround(static_cast<double>(skip.extra_ns) / period_ns_));
  const FovGap& gap = stats_.fov_gap;
  const int tol = azimuth_tolerance();
  const bool known = gap.length > 0 && std::abs(azimuth_diff(skip.from, gap.start)) <= tol &&
                     std::abs(skip.length - gap.length) <= 2 * tol;
  // A packet is sent whole or not at all, so a jump inside one is never packet loss.
  ++stats_.fov_silences;
  if (!known &&
      learn_fov_gap(skip.from, skip.length, end, missing,
                    std::chrono::nanoseconds(skip.extra_ns)) &&
      pending_cut_ != stats_.cut_azimuth) {
    skip.new_cut = pending_cut_;
  }
  // The next packet follows the firings after the skip.
  last_packet_time_ += std::chrono::nanoseconds(skip.extra_ns);
  last_point_time_ += std::chrono::nanoseconds(skip.extra_ns);
  unconfirmed_shift_ns_ = skip.extra_ns;
  return skip;
}

void ScanAssembler::check_skip_delay(const DecodedPacket& packet,
                                     std::chrono::nanoseconds packet_time) noexcept {
  const std::int64_t shift = std::exchange(unconfirmed_shift_ns_, 0);
  const ShiftedTail tail = std::exchange(shifted_, {});
  if (shift <= 0) return;
  // Packets lost between the skip's packet and this one, by the azimuth the rotor moved.
  double lost = 0.0;
  if (packet.firing_count > 0 && have_last_azimuth_ && packet_arc() > 0.0) {
    const int arc = azimuth_ahead(packet.firings[0].azimuth, last_azimuth_);
    if (arc < 18000) lost = std::round(arc / packet_arc());
  }
  // How much later than the skip said this packet came, beyond those lost packets.
  const double late =
      static_cast<double>((packet_time - last_packet_time_).count()) - (1.0 + lost) * period_ns_;
  // The delay was reckoned from the rotor's speed over a few packets: allow a tenth of it.
  const double slack = 0.1 * static_cast<double>(shift) + period_ns_;
  if (std::abs(late) <= slack) {
    // As late as the skip said: a silence over a sector. The packet's clock gives the delay, and
    // the firings after the skip move with it (unless that would put them before the firings
    // ahead of the skip: then the clock does not agree with the skip after all).
    const std::int64_t fix = std::llround(late);
    if (retime_after_skip(tail, fix)) {
      last_packet_time_ += std::chrono::nanoseconds(fix);
      last_point_time_ += std::chrono::nanoseconds(fix);
      return;
    }
  } else if (late > 0.0) {
    return;  // later still: the silence check that follows counts it
  }
  // On the packet's own timing: the jump was a bad azimuth, and the firings after it were given
  // times that they did not have.
  ++stats_.azimuth_jumps;
  --stats_.fov_silences;
  last_packet_time_ -= std::chrono::nanoseconds(shift);
  last_point_time_ -= std::chrono::nanoseconds(shift);
  skip_refuted_ = true;
}

void ScanAssembler::note_azimuths(const DecodedPacket& packet, const Skip& skip) noexcept {
  if (packet.firing_count <= 0) return;
  // The speed from the firings on one side of a skip: the longer run.
  const bool tail_longer = skip.at < packet.firing_count && 2 * skip.at < packet.firing_count;
  const int head = tail_longer ? skip.at : 0;
  const int tail =
      tail_longer || skip.at >= packet.firing_count ? packet.firing_count - 1 : skip.at - 1;
  const Firing& first = packet.firings[static_cast<std::size_t>(head)];
  const Firing& last = packet.firings[static_cast<std::size_t>(tail)];
  // Azimuths are whole 0.01 deg: a span of a few firings gives the speed only to a few percent,
  // so short spans are not used (but for the first estimate) and the estimate is smoothed.
  if (last.offset_ns > first.offset_ns && (tail - head >= 5 || azimuth_per_ns_ <= 0.0)) {
    const int arc = azimuth_ahead(last.azimuth, first.azimuth);
    if (arc > 0 && arc < 18000) {
      const double sample = arc / static_cast<double>(last.offset_ns - first.offset_ns);
      azimuth_per_ns_ = azimuth_per_ns_ <= 0.0 ? sample : 0.9 * azimuth_per_ns_ + 0.1 * sample;
    }
  }
  last_azimuth_ = packet.firings[static_cast<std::size_t>(packet.firing_count - 1)].azimuth;
  have_last_azimuth_ = true;
}

void ScanAssembler::attribute_loss(std::uint32_t lost, const DecodedPacket& packet) noexcept {
  std::uint32_t before_cut = lost;
  if (scan_open_ && packet.firing_count > 0) {
    const int rel = azimuth_ahead(packet.firings[0].azimuth, stats_.cut_azimuth);
    if (rel < last_rel_) {
      // The missing packets spanned the cut: spread them evenly over the azimuth they covered.
      const double span = rel + 36000 - last_rel_;
      before_cut = 0;
      for (std::uint32_t k = 1; k <= lost; ++k) {
        const double at = last_rel_ + span * k / (lost + 1);
        before_cut += at < 36000.0 ? 1 : 0;
      }
    }
  }
  const std::uint32_t after_cut = lost - before_cut;
  if (!scan_open_) {
    next_lost_ += lost;
    next_flags_ |= core::kScanPacketLoss;
    return;
  }
  if (before_cut > 0) {
    scan_.lost_packets += before_cut;
    scan_.flags |= core::kScanPacketLoss;
  }
  if (after_cut > 0) {
    next_lost_ += after_cut;
    next_flags_ |= core::kScanPacketLoss;
  }
}

void ScanAssembler::append(const DecodedPacket& packet, int first, int last,
                           std::chrono::nanoseconds packet_time, std::int64_t extra_ns) noexcept {
  if (first >= last) return;
  const Firing& head = packet.firings[static_cast<std::size_t>(first)];
  const Firing& tail = packet.firings[static_cast<std::size_t>(last - 1)];
  scan_.end = packet_time + std::chrono::nanoseconds(tail.offset_ns + extra_ns);
  auto& pts = scan_.points;
  const std::size_t room = pts.capacity() - pts.size();
  const std::size_t count = static_cast<std::size_t>(tail.first_point + tail.point_count) -
                            static_cast<std::size_t>(head.first_point);
  const std::size_t take = std::min(room, count);
  const auto from = packet.points.begin() + head.first_point;
  const std::size_t at = pts.size();
  pts.insert(pts.end(), from, from + static_cast<std::ptrdiff_t>(take));
  // Point times are offsets from the packet time; the scan started at or before this packet.
  const auto base = static_cast<std::uint32_t>((packet_time - scan_.stamp).count() + extra_ns);
  for (std::size_t i = at; i < pts.size(); ++i) pts[i].time_ns += base;
  if (take < count) {
    scan_.points_dropped += static_cast<std::uint32_t>(count - take);
    scan_.flags |= core::kScanOverflow;
  }
}

void ScanAssembler::start_scan(std::chrono::nanoseconds stamp, int relative_azimuth) noexcept {
  scan_.stamp = stamp;
  scan_.end = stamp;
  scan_.flags = next_flags_;
  scan_.lost_packets = next_lost_;
  if (next_partial_ && relative_azimuth > kStartTolerance) scan_.flags |= core::kScanPartial;
  next_flags_ = 0;
  next_lost_ = 0;
  scan_open_ = true;
}

}  // namespace cndt::vlp16
