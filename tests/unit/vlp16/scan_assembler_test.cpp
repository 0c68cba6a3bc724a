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

// Feeds `packets` VLP-16 packets at 600 rpm (40 cdeg per block) from azimuth `start`, skipping
// the packet indices in `skip`.
std::vector<Collected> run(int packets, int start, AssemblerOptions opt = {},
                           std::vector<int> skip = {}, std::int64_t extra_gap_at = -1,
                           std::int64_t extra_gap_ns = 0) {
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
    as.add(dp, nanoseconds(t), sink);
    t += kPeriodNs;
  }
  as.flush(sink);
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

}  // namespace
}  // namespace cndt::vlp16
