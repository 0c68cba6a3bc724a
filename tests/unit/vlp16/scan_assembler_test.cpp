#include "cndt/vlp16/scan_assembler.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "packet_builder.hpp"

namespace cndt::vlp16 {
namespace {

using std::chrono::nanoseconds;
constexpr std::int64_t kPeriodNs = 1'327'104;

struct Collected {
  core::Scan scan;
  std::vector<std::uint32_t> times;
  std::size_t capacity = 0;  // of the assembler's buffer when the scan was handed out
};

// When the packets were received, as the assembler is told.
enum class Received {
  kUnknown,    // not given
  kWithClock,  // in step with the sensor clock, gaps included (an outage)
  kSteady,     // one packet period apart whatever the sensor clock does (a clock jump)
  kBurst,      // 10 us apart: read from a queue all at once
};

// Feeds `packets` VLP-16 packets at 600 rpm (40 cdeg per block) from azimuth `start`, skipping
// the packet indices in `skip`; the sensor clock moves on by `extra_gap_ns` more at packet
// `extra_gap_at`.
std::vector<Collected> run(int packets, int start, AssemblerOptions opt = {},
                           std::vector<int> skip = {}, std::int64_t extra_gap_at = -1,
                           std::int64_t extra_gap_ns = 0, Received received = Received::kUnknown,
                           AssemblerStats* stats = nullptr) {
  Decoder dec(Model::kVlp16, {});
  ScanAssembler as(opt, 1327.104);
  std::vector<Collected> out;
  auto sink = [&](core::Scan& s) {
    Collected c{s, {}, s.points.capacity()};
    for (const auto& p : s.points) c.times.push_back(p.time_ns);
    out.push_back(std::move(c));
  };
  DecodedPacket dp;
  std::int64_t t = 1'000'000'000'000;
  for (int k = 0; k < packets; ++k) {
    if (k == extra_gap_at) t += extra_gap_ns;
    const int az = (start + k * 480) % 36000;
    if (std::find(skip.begin(), skip.end(), k) != skip.end()) {
      t += kPeriodNs;
      continue;
    }
    test::PacketBuilder b;
    b.azimuths(az, 40).all_records(5000, 10);
    PacketHeader h;
    EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
    dec.decode(b.span(), h, dp);
    std::int64_t rx = t + 500'000;
    if (received == Received::kUnknown) rx = 0;
    if (received == Received::kSteady) rx = 2'000'000'000'000 + k * kPeriodNs;
    if (received == Received::kBurst) rx = 2'000'000'000'000 + k * 10'000;
    as.add(dp, nanoseconds(t), sink, nanoseconds(rx));
    t += kPeriodNs;
  }
  as.flush(sink);
  if (stats != nullptr) *stats = as.stats();
  return out;
}

TEST(ScanAssembler, CutsOneScanPerRevolutionAtTheCutAngle) {
  const auto scans = run(400, 18000);  // ~5.3 turns starting at 180 deg
  ASSERT_GE(scans.size(), 6u);
  EXPECT_TRUE(scans[0].scan.flags & core::kScanPartial);
  for (std::size_t i = 1; i + 1 < scans.size(); ++i) {
    const auto& s = scans[i].scan;
    EXPECT_TRUE(s.complete()) << "scan " << i << " flags " << s.flags;
    // The synthetic rotor turns 0.4 deg per block: one turn is 75 packets, 1800 firing
    // sequences of 16 points, 75 x 1.327104 ms; the last sequence starts one sequence earlier.
    const double duration_ms = static_cast<double>((s.end - s.stamp).count()) * 1e-6;
    EXPECT_NEAR(duration_ms, 75 * 1.327104 - 0.055296, 1e-6);
    EXPECT_EQ(s.points.size(), 1800u * 16u);
    EXPECT_EQ(s.packets, 76u);  // the cut falls inside a packet: 74 whole + 2 shared
    // Point times: non-negative, non-decreasing, within the turn.
    const auto& t = scans[i].times;
    EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
    EXPECT_LT(t.back(), 100'100'000u);
  }
  EXPECT_TRUE(scans.back().scan.flags & core::kScanEndOfStream);
  // Consecutive scan stamps are one turn apart.
  for (std::size_t i = 2; i + 1 < scans.size(); ++i) {
    EXPECT_EQ((scans[i].scan.stamp - scans[i - 1].scan.stamp).count(), 75 * kPeriodNs);
  }
}

TEST(ScanAssembler, HonoursACutAngle) {
  AssemblerOptions opt;
  opt.cut_azimuth = 9000;
  const auto scans = run(300, 0, opt);
  ASSERT_GE(scans.size(), 3u);
  // The first point of every later scan was fired at or just after 90 degrees.
  for (std::size_t i = 1; i < scans.size(); ++i) {
    const auto& p = scans[i].scan.points.front();
    double az = std::atan2(-p.y, p.x) * 180.0 / 3.141592653589793;
    if (az < 0) az += 360;
    EXPECT_NEAR(az, 90.0, 0.25) << "scan " << i;
  }
}

TEST(ScanAssembler, FlagsAndCountsLostPackets) {
  const auto scans = run(300, 0, {}, {100, 101, 150});
  std::uint32_t lost = 0;
  int lossy = 0;
  for (const auto& c : scans) {
    lost += c.scan.lost_packets;
    if (c.scan.flags & core::kScanPacketLoss) ++lossy;
  }
  EXPECT_EQ(lost, 3u);
  // Packets 100-101 lie inside the second turn; packet 150 starts the third turn (the cut is at
  // its first block), so the third scan, not the second, is missing it.
  EXPECT_EQ(lossy, 2);
  EXPECT_EQ(scans[1].scan.lost_packets, 2u);
  EXPECT_EQ(scans[2].scan.lost_packets, 1u);
}

TEST(ScanAssembler, ALongSilenceEndsTheScan) {
  const auto scans = run(300, 0, {}, {}, 120, 200'000'000);  // 0.2 s without packets
  int gap_cut = 0;
  for (const auto& c : scans) gap_cut += (c.scan.flags & core::kScanGapCut) ? 1 : 0;
  EXPECT_EQ(gap_cut, 1);
}

// The sensor clock steps 5 s on at packet 120. Received in step with it, that is an outage: a
// gap that ends the scan, packets counted lost. Received one period apart as always, it is a
// clock jump: nothing lost, the scan ends there flagged, and the next one starts flagged too.
// Received in a burst (a reader catching up on its queue), the receive times say nothing: loss.
TEST(ScanAssembler, AClockSteppingOnWhilePacketsKeepComingIsAJumpNotLoss) {
  AssemblerStats outage, jump, unknown, burst;
  run(300, 0, {}, {}, 120, 5'000'000'000, Received::kBurst, &burst);
  EXPECT_EQ(burst.gaps, 1u);
  EXPECT_EQ(burst.time_jumps, 0u);
  const auto a = run(300, 0, {}, {}, 120, 5'000'000'000, Received::kWithClock, &outage);
  const auto b = run(300, 0, {}, {}, 120, 5'000'000'000, Received::kSteady, &jump);
  run(300, 0, {}, {}, 120, 5'000'000'000, Received::kUnknown, &unknown);
  EXPECT_EQ(outage.gaps, 1u);
  EXPECT_NEAR(static_cast<double>(outage.lost_packets), 5e9 / kPeriodNs, 1.0);
  EXPECT_EQ(outage.time_jumps, 0u);
  EXPECT_EQ(unknown.gaps, 1u);  // without receive times the two cannot be told apart
  EXPECT_EQ(jump.gaps, 0u);
  EXPECT_EQ(jump.lost_packets, 0u);
  EXPECT_EQ(jump.time_jumps, 1u);
  int cut = 0, jumped = 0;
  for (const auto& c : a) cut += (c.scan.flags & core::kScanGapCut) ? 1 : 0;
  for (const auto& c : b) {
    jumped += (c.scan.flags & core::kScanTimeJump) ? 1 : 0;
    EXPECT_EQ(c.scan.flags & core::kScanGapCut, 0u);
    EXPECT_EQ(c.scan.lost_packets, 0u);
  }
  EXPECT_EQ(cut, 1);
  EXPECT_EQ(jumped, 2);  // the scan the jump ended and the one it began
}

TEST(ScanAssembler, ClockGoingBackwardsIsFlagged) {
  const auto scans = run(300, 0, {}, {}, 120, -80'000'000);
  int jumps = 0;
  for (const auto& c : scans) {
    jumps += (c.scan.flags & core::kScanTimeJump) ? 1 : 0;
    EXPECT_TRUE(std::is_sorted(c.times.begin(), c.times.end()));
  }
  EXPECT_GE(jumps, 1);
}

TEST(ScanAssembler, RepeatedOrOverlappingPacketsAreDropped) {
  Decoder dec(Model::kVlp16, {});
  ScanAssembler as({}, 1327.104);
  std::vector<std::uint32_t> times;
  std::size_t points = 0;
  auto sink = [&](core::Scan& s) {
    points += s.points.size();
    for (std::size_t i = 1; i < s.points.size(); ++i) {
      ASSERT_LE(s.points[i - 1].time_ns, s.points[i].time_ns);
    }
  };
  DecodedPacket dp;
  std::int64_t t = 1'000'000'000'000;
  for (int k = 0; k < 200; ++k) {
    test::PacketBuilder b;
    b.azimuths((k * 480) % 36000, 40).all_records(5000, 10);
    PacketHeader h;
    ASSERT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
    dec.decode(b.span(), h, dp);
    as.add(dp, nanoseconds(t), sink);
    if (k % 50 == 10) as.add(dp, nanoseconds(t), sink);            // a duplicate
    if (k % 50 == 20) as.add(dp, nanoseconds(t - 400'000), sink);  // from the recent past
    t += kPeriodNs;
  }
  as.flush(sink);
  EXPECT_EQ(as.stats().stale_packets, 8u);
  EXPECT_EQ(as.stats().time_jumps, 0u);
  EXPECT_EQ(points, 200u * 384u);
}

TEST(ScanAssembler, NeverGrowsPastItsCapacity) {
  AssemblerOptions opt;
  opt.max_points = 5000;
  const auto scans = run(200, 0, opt);
  bool overflowed = false;
  for (const auto& c : scans) {
    EXPECT_LE(c.scan.points.size(), 5000u);
    EXPECT_EQ(c.capacity, 5000u);
    if (c.scan.flags & core::kScanOverflow) {
      overflowed = true;
      EXPECT_GT(c.scan.points_dropped, 0u);
    }
  }
  EXPECT_TRUE(overflowed);
}

// A sensor set to a limited field of view: the rotor turns at 600 rpm (0.4 deg per block) but
// blocks are fired only while the azimuth lies in [fov_start, fov_start + fov_length). Packets are
// filled with 12 fired blocks in a row, so the packet that ends a pass carries the first blocks of
// the next pass, fired almost a turn's silence later than the packet's timing says. The packet
// time is the time of its first block. `lose` drops packets by index; `bad_azimuth` overwrites one
// block's azimuth (packet index, block) with a value 90 deg off; `silence_error_ns` makes every
// silence that much longer (or shorter) than the rotor's speed before it predicts.
struct FovRun {
  std::vector<Collected> scans;
  AssemblerStats stats;
};
FovRun run_fov(int turns, AssemblerOptions opt = {}, std::vector<int> lose = {},
               std::pair<int, int> bad_azimuth = {-1, -1}, std::int64_t silence_error_ns = 0) {
  constexpr int kFovStart = 27000, kFovLength = 18000, kBlockStep = 40;
  constexpr std::int64_t kBlockNs = kPeriodNs / 12;
  Decoder dec(Model::kVlp16, {});
  ScanAssembler as(opt, 1327.104);
  FovRun out;
  auto sink = [&](core::Scan& s) {
    Collected c{s, {}, s.points.capacity()};
    for (const auto& p : s.points) c.times.push_back(p.time_ns);
    out.scans.push_back(std::move(c));
  };
  const std::int64_t t0 = 1'000'000'000'000;
  const int blocks = turns * 36000 / kBlockStep;
  std::vector<std::pair<int, std::int64_t>> fired;  // azimuth, time
  std::int64_t skew = 0;  // each silence lasts silence_error_ns longer than the rotor's pace says
  bool in_fov = true;
  for (int b = 0; b < blocks; ++b) {
    const int az = (kFovStart + 2000 + b * kBlockStep) % 36000;
    const bool fires = (az - kFovStart + 36000) % 36000 < kFovLength;
    if (fires && !in_fov) skew += silence_error_ns;
    in_fov = fires;
    if (fires) fired.emplace_back(az, t0 + b * kBlockNs + skew);
  }
  DecodedPacket dp;
  for (std::size_t k = 0; (k + 1) * 12 <= fired.size(); ++k) {
    if (std::find(lose.begin(), lose.end(), static_cast<int>(k)) != lose.end()) continue;
    test::PacketBuilder pb;
    for (std::size_t i = 0; i < 12; ++i) {
      int az = fired[k * 12 + i].first;
      if (static_cast<int>(k) == bad_azimuth.first && static_cast<int>(i) == bad_azimuth.second) {
        az = (az + 9000) % 36000;
      }
      pb.azimuth(static_cast<int>(i), static_cast<std::uint16_t>(az));
    }
    pb.all_records(5000, 10);
    PacketHeader h;
    EXPECT_EQ(validate_data_packet(pb.span(), h), PacketError::kNone);
    dec.decode(pb.span(), h, dp);
    as.add(dp, nanoseconds(fired[k * 12].second), sink);
  }
  as.flush(sink);
  out.stats = as.stats();
  return out;
}

TEST(ScanAssembler, LimitedFieldOfViewMovesTheCutIntoTheSilence) {
  const FovRun r = run_fov(8);
  // The silence runs from the last firing sequence before 90 deg (89.8) to 270 deg, and is
  // learned on its second turn: the cut moves to its middle.
  EXPECT_EQ(r.stats.fov_gap.start, 8980);
  EXPECT_EQ(r.stats.fov_gap.length, 18020);
  EXPECT_NEAR(r.stats.cut_azimuth, 17990, 40);
  // The rotor starts at 290 deg: 8 turns pass the silent sector 8 times, none of it loss.
  EXPECT_EQ(r.stats.fov_silences, 8u);
  EXPECT_EQ(r.stats.lost_packets, 0u);
  EXPECT_EQ(r.stats.gaps, 0u);
  EXPECT_EQ(r.stats.azimuth_jumps, 0u);
  const auto azimuth_of = [](const core::Point& p) {
    return std::fmod(std::atan2(-p.y, p.x) * 18000.0 / 3.141592653589793 + 36000.0, 36000.0);
  };
  int whole = 0, in_gap_cut = 0;
  std::int64_t last_stamp = 0;
  for (std::size_t i = 0; i < r.scans.size(); ++i) {
    const core::Scan& s = r.scans[i].scan;
    if (!s.complete()) continue;
    ++whole;
    // One pass: 450 blocks of 2 sequences of 16 points.
    EXPECT_EQ(s.points.size(), 450u * 32u) << "scan " << i;
    const auto& t = r.scans[i].times;
    EXPECT_TRUE(std::is_sorted(t.begin(), t.end())) << "scan " << i;
    // Each point was fired when the rotor stood at its azimuth, silence or not: 0.4 deg per
    // 110.592 us from the scan's first point.
    const auto& p = s.points;
    const double first = azimuth_of(p.front());
    for (std::size_t j = 0; j < p.size(); j += 997) {
      const double swept = std::fmod(azimuth_of(p[j]) - first + 36000.0, 36000.0);
      EXPECT_NEAR(swept, p[j].time_ns * (40.0 / 110'592.0), 30.0) << "scan " << i << " pt " << j;
    }
    if (std::abs(first - 27000.0) > 30.0) continue;  // cut at 0 deg, before the gap was learned
    // Cut in the gap: the pass alone, 449 blocks and a sequence, and a turn after the one before.
    ++in_gap_cut;
    const double duration_ms = static_cast<double>((s.end - s.stamp).count()) * 1e-6;
    EXPECT_NEAR(duration_ms, 449 * 0.110592 + 0.055296, 0.01) << "scan " << i;
    if (last_stamp != 0) {
      EXPECT_EQ(s.stamp.count() - last_stamp, 900 * (kPeriodNs / 12)) << "scan " << i;
    }
    last_stamp = s.stamp.count();
  }
  EXPECT_GE(whole, 6);
  EXPECT_GE(in_gap_cut, 5);
}

TEST(ScanAssembler, AConfiguredCutInsideTheSilenceStays) {
  AssemblerOptions opt;
  opt.cut_azimuth = 12000;  // 120 deg: inside the silent sector from 89.8 to 270 deg
  const FovRun r = run_fov(6, opt);
  EXPECT_EQ(r.stats.fov_gap.length, 18020);
  EXPECT_EQ(r.stats.cut_azimuth, 12000);
  EXPECT_EQ(r.stats.lost_packets, 0u);
  // The cut never moved, so no scan was ended early: the first is partial, the rest whole.
  int whole = 0;
  for (std::size_t i = 1; i + 1 < r.scans.size(); ++i) {
    EXPECT_TRUE(r.scans[i].scan.complete()) << "scan " << i;
    EXPECT_EQ(r.scans[i].scan.points.size(), 450u * 32u) << "scan " << i;
    ++whole;
  }
  EXPECT_GE(whole, 4);
}

TEST(ScanAssembler, TheNextPacketsClockCorrectsTheDelayAfterASkip) {
  // The rotor crosses the silent sector 3 ms faster or slower than its speed before said: the
  // firings after each skip take the time the next packet's clock gives, both ways.
  for (const std::int64_t error : {-3'000'000, 3'000'000}) {
    const FovRun r = run_fov(6, {}, {}, {-1, -1}, error);
    EXPECT_GT(r.stats.fov_gap.length, 0u) << error;
    EXPECT_EQ(r.stats.lost_packets, 0u) << error;
    EXPECT_EQ(r.stats.azimuth_jumps, 0u) << error;
    EXPECT_EQ(r.stats.stale_packets, 0u) << error;
    int whole = 0;
    for (std::size_t i = 0; i < r.scans.size(); ++i) {
      const auto& t = r.scans[i].times;
      EXPECT_TRUE(std::is_sorted(t.begin(), t.end())) << error << " scan " << i;
      if (!r.scans[i].scan.complete()) continue;
      ++whole;
      // A scan cut in the silence is one pass, fired at the rotor's pace.
      const double duration_ms =
          static_cast<double>((r.scans[i].scan.end - r.scans[i].scan.stamp).count()) * 1e-6;
      if (duration_ms < 60.0) {
        EXPECT_NEAR(duration_ms, 449 * 0.110592 + 0.055296, 0.01) << error << " scan " << i;
      }
    }
    EXPECT_GE(whole, 4) << error;
  }
}

TEST(ScanAssembler, LimitedFieldOfViewCanBeTakenAsLoss) {
  AssemblerOptions opt;
  opt.cut_at_fov_gap = false;
  const FovRun r = run_fov(4, opt);
  EXPECT_EQ(r.stats.fov_gap.length, 0u);
  EXPECT_EQ(r.stats.fov_silences, 0u);
  EXPECT_GT(r.stats.lost_packets, 100u);
  for (const auto& c : r.scans) EXPECT_FALSE(c.scan.complete());
}

TEST(ScanAssembler, LossInsideALimitedFieldOfViewIsStillCounted) {
  // Packets 200 and 201 lie in the fifth pass, well after the gap was learned.
  const FovRun r = run_fov(8, {}, {200, 201});
  EXPECT_EQ(r.stats.lost_packets, 2u);
  EXPECT_EQ(r.stats.gaps, 1u);
  EXPECT_GT(r.stats.fov_gap.length, 0u);
  std::uint32_t lossy = 0;
  for (const auto& c : r.scans) lossy += (c.scan.flags & core::kScanPacketLoss) ? 1u : 0u;
  EXPECT_EQ(lossy, 1u);
}

TEST(ScanAssembler, AJumpInsideAPacketThatTheClockDoesNotShowIsABadAzimuth) {
  // One block 90 deg off in the middle of a pass: the next packet comes on time, so the firings
  // after the jump were not fired later, and no packet after it may be lost or dropped.
  const FovRun r = run_fov(6, {}, {}, {160, 5});
  EXPECT_EQ(r.stats.azimuth_jumps, 1u);
  EXPECT_EQ(r.stats.stale_packets, 0u);
  EXPECT_EQ(r.stats.lost_packets, 0u);
  EXPECT_GT(r.stats.fov_gap.length, 0u);
  // The scan holding those firings ends before the next packet's: point times never decrease.
  int jumped = 0;
  for (const auto& c : r.scans) {
    jumped += (c.scan.flags & core::kScanTimeJump) ? 1 : 0;
    EXPECT_TRUE(std::is_sorted(c.times.begin(), c.times.end()));
    EXPECT_GE(c.scan.end, c.scan.stamp);
  }
  EXPECT_EQ(jumped, 1);
}

}  // namespace
}  // namespace cndt::vlp16
