#include "cndt/vlp16/scan_assembler.hpp"

#include <algorithm>
#include <cmath>

namespace cndt::vlp16 {
namespace {
// The first scan of a stream counts as complete only if it starts within 1 deg after the cut.
constexpr int kStartTolerance = 100;
}  // namespace

ScanAssembler::ScanAssembler(const AssemblerOptions& options, double packet_period_us)
    : options_(options), period_ns_(packet_period_us * 1000.0), scan_(options.max_points) {}

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
                                                          std::uint32_t& lost) noexcept {
  const auto [first, last] = firing_span(packet);
  const std::chrono::nanoseconds first_time = packet_time + std::chrono::nanoseconds(first);
  const std::chrono::nanoseconds last_time = packet_time + std::chrono::nanoseconds(last);
  if (!have_last_) {
    have_last_ = true;
    last_packet_time_ = packet_time;
    last_point_time_ = last_time;
    return Continuity::kContinuous;
  }
  const std::chrono::nanoseconds dt = packet_time - last_packet_time_;
  if (dt < -options_.max_gap) {
    // The clock went far back (a sensor reset): start over from here.
    ++stats_.time_jumps;
    last_packet_time_ = packet_time;
    last_point_time_ = last_time;
    return Continuity::kJump;
  }
  if (first_time <= last_point_time_ && dt < options_.max_gap) {
    // A repeat of a packet, or one that overlaps the firings already taken.
    ++stats_.stale_packets;
    return Continuity::kStale;
  }
  last_packet_time_ = packet_time;
  last_point_time_ = last_time;
  if (dt > options_.max_gap) {
    ++stats_.gaps;
    stats_.lost_packets +=
        static_cast<std::uint64_t>(std::llround(static_cast<double>(dt.count()) / period_ns_) - 1);
    return Continuity::kGap;
  }
  if (static_cast<double>(dt.count()) > 1.5 * period_ns_) {
    lost =
        static_cast<std::uint32_t>(std::llround(static_cast<double>(dt.count()) / period_ns_) - 1);
    ++stats_.gaps;
    stats_.lost_packets += lost;
    return Continuity::kLoss;
  }
  return Continuity::kContinuous;
}

void ScanAssembler::attribute_loss(std::uint32_t lost, const DecodedPacket& packet) noexcept {
  std::uint32_t before_cut = lost;
  if (scan_open_ && packet.firing_count > 0) {
    const int rel = (packet.firings[0].azimuth - options_.cut_azimuth + 36000) % 36000;
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
                           std::chrono::nanoseconds packet_time) noexcept {
  if (first >= last) return;
  const Firing& head = packet.firings[static_cast<std::size_t>(first)];
  const Firing& tail = packet.firings[static_cast<std::size_t>(last - 1)];
  scan_.end = packet_time + std::chrono::nanoseconds(tail.offset_ns);
  auto& pts = scan_.points;
  const std::size_t room = pts.capacity() - pts.size();
  const std::size_t count = static_cast<std::size_t>(tail.first_point + tail.point_count) -
                            static_cast<std::size_t>(head.first_point);
  const std::size_t take = std::min(room, count);
  const auto from = packet.points.begin() + head.first_point;
  const std::size_t at = pts.size();
  pts.insert(pts.end(), from, from + static_cast<std::ptrdiff_t>(take));
  // Point times are offsets from the packet time; the scan started at or before this packet.
  const auto base = static_cast<std::uint32_t>((packet_time - scan_.stamp).count());
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
