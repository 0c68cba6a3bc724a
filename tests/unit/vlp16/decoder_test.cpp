#include "cndt/vlp16/decoder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <utility>

#include "packet_builder.hpp"

namespace cndt::vlp16 {
namespace {

using test::PacketBuilder;
constexpr double kDeg = std::numbers::pi / 180.0;

// Every test runs on the portable kernel and on the AVX2 kernel (where the CPU has it).
bool g_simd = false;

class DecoderKernel : public ::testing::TestWithParam<bool> {
 protected:
  void SetUp() override { g_simd = GetParam(); }
};

DecodedPacket decode_with(const PacketBuilder& b, Model model, const DecoderOptions& opt) {
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
  Decoder d(model, opt);
  DecodedPacket out;
  d.decode(b.span(), h, out);
  return out;
}

// With the kernel of the running test.
DecodedPacket decode(const PacketBuilder& b, Model model, DecoderOptions opt = {}) {
  opt.simd = g_simd;
  return decode_with(b, model, opt);
}

// Azimuth of a point in the sensor's clockwise convention, degrees in [0, 360).
double sensor_azimuth(const core::Point& p) {
  double a = std::atan2(-p.y, p.x) / kDeg;
  return a < 0 ? a + 360 : a;
}

TEST_P(DecoderKernel, Vlp16SingleReturnGeometryAndTiming) {
  PacketBuilder b;
  b.azimuths(9000, 40).all_records(5000, 77);  // 10 m everywhere
  const DecodedPacket out = decode(b, Model::kVlp16);
  ASSERT_EQ(out.firing_count, 24);
  ASSERT_EQ(out.point_count, 384);
  // Block 0, first sequence, laser 0: -15 deg elevation at exactly 90 deg azimuth.
  const core::Point& p0 = out.points[0];
  EXPECT_NEAR(p0.x, 0.0, 1e-4);
  EXPECT_NEAR(p0.y, -10.0 * std::cos(15 * kDeg), 1e-4);
  EXPECT_NEAR(p0.z, -10.0 * std::sin(15 * kDeg) + 0.0112, 1e-4);
  EXPECT_EQ(p0.ring, 0);
  EXPECT_EQ(p0.intensity, 77.0F);
  EXPECT_EQ(p0.time_ns, 0u);
  // Laser 15 (+15 deg, top ring) of the second sequence of block 3.
  const core::Point& p = out.points[static_cast<std::size_t>(3 * 32 + 16 + 15)];
  EXPECT_EQ(p.ring, 15);
  EXPECT_EQ(p.time_ns, 7u * 55296u + 15u * 2304u);
  // Azimuth interpolated inside the block: 90 + 0.4 * 3 + 0.4 * (55.296 + 15*2.304) / 110.592.
  const double expected = 90.0 + 1.2 + 0.4 * (55.296 + 15 * 2.304) / 110.592;
  EXPECT_NEAR(sensor_azimuth(p), expected, 1e-4);
  EXPECT_NEAR(std::hypot(p.x, p.y, p.z - (-0.0112)), 10.0, 1e-4);
  // The firing list gives the rotor azimuth at each sequence start.
  EXPECT_EQ(out.firings[1].azimuth, 9020);
  EXPECT_EQ(out.firings[23].azimuth, 9000 + 11 * 40 + 20);
  EXPECT_EQ(out.firings[23].offset_ns, 23u * 55296u);
}

TEST_P(DecoderKernel, InterpolatesAcrossTheAzimuthWrap) {
  PacketBuilder b;
  b.azimuths(35920, 40).all_records(5000, 10);
  b.azimuth(2, 36000);  // sent as 36000 by real units, read as 0 deg
  const DecodedPacket out = decode(b, Model::kVlp16);
  for (int f = 0; f + 1 < out.firing_count; ++f) {
    const int step = (out.firings[static_cast<std::size_t>(f + 1)].azimuth -
                      out.firings[static_cast<std::size_t>(f)].azimuth + 36000) %
                     36000;
    EXPECT_EQ(step, 20) << "firing " << f;
  }
  EXPECT_EQ(out.firings[4].azimuth, 0);
  EXPECT_EQ(out.firings[5].azimuth, 20);
}

TEST_P(DecoderKernel, LastBlockReusesThePreviousStep) {
  PacketBuilder b;
  b.azimuths(1000, 40).all_records(5000, 10);
  const DecodedPacket out = decode(b, Model::kVlp16);
  EXPECT_EQ(out.firings[23].azimuth - out.firings[22].azimuth, 20);
}

TEST_P(DecoderKernel, DualReturnKeepsIdenticalReturnsOnce) {
  PacketBuilder b(0x39, 0x22);
  for (int pair = 0; pair < 6; ++pair) {
    b.azimuth(2 * pair, static_cast<std::uint16_t>(1000 + 80 * pair));
    b.azimuth(2 * pair + 1, static_cast<std::uint16_t>(1000 + 80 * pair));
  }
  for (int r = 0; r < 32; ++r) {
    b.record(0, r, 5000, 50);                                // last
    b.record(1, r, r == 4 ? 2500 : 5000, r == 4 ? 90 : 50);  // strongest differs for record 4
  }
  const DecodedPacket out = decode(b, Model::kVlp16);
  ASSERT_EQ(out.firing_count, 12);
  // Pair 0 holds 32 firings' worth of records: 31 identical (kept once) + record 4 twice.
  const Firing& f0 = out.firings[0];
  ASSERT_EQ(f0.point_count, 17);
  int both = 0, last = 0, strongest = 0;
  for (int i = 0; i < f0.point_count; ++i) {
    switch (out.points[static_cast<std::size_t>(f0.first_point + i)].return_type) {
      case core::ReturnType::kBoth:
        ++both;
        break;
      case core::ReturnType::kLast:
        ++last;
        break;
      case core::ReturnType::kStrongest:
        ++strongest;
        break;
      default:
        break;
    }
  }
  EXPECT_EQ(both, 15);
  EXPECT_EQ(last, 1);
  EXPECT_EQ(strongest, 1);
  // Dual timing: pair p, sequence s fires at (2p + s) * 55.296 us.
  EXPECT_EQ(out.firings[3].offset_ns, 3u * 55296u);
  EXPECT_EQ(out.firings[2].azimuth, 1080);
}

TEST_P(DecoderKernel, AppliesRangeLimitsAndDropsNoReturn) {
  PacketBuilder b;
  b.azimuths(0, 40);
  b.record(0, 0, 0, 0);      // no return
  b.record(0, 1, 100, 5);    // 0.2 m, below the minimum
  b.record(0, 2, 60000, 5);  // 120 m
  b.record(0, 3, 1000, 5);   // 2 m
  DecoderOptions opt;
  opt.max_range_m = 100.0;
  const DecodedPacket out = decode(b, Model::kVlp16, opt);
  ASSERT_EQ(out.point_count, 1);
  EXPECT_EQ(out.points[0].ring, laser_table(Model::kVlp16).ring[3]);
}

TEST_P(DecoderKernel, VerticalOffsetsCanBeLeftOut) {
  PacketBuilder b;
  b.azimuths(0, 40).all_records(5000, 10);
  DecoderOptions opt;
  opt.vertical_offsets = false;
  const DecodedPacket out = decode(b, Model::kVlp16, opt);
  EXPECT_NEAR(out.points[0].z, -10.0 * std::sin(15 * kDeg), 1e-4);
}

TEST_P(DecoderKernel, Hdl32eUsesOneSequencePerBlock) {
  PacketBuilder b(0x37, 0x21);
  b.azimuths(0, 20).all_records(5000, 10);
  const DecodedPacket out = decode(b, Model::kHdl32e);
  ASSERT_EQ(out.firing_count, 12);
  ASSERT_EQ(out.point_count, 384);
  EXPECT_NEAR(std::asin(out.points[0].z / 10.0) / kDeg, -30.67, 1e-3);
  EXPECT_EQ(out.points[31].time_ns, 31u * 1152u);
  EXPECT_EQ(out.firings[5].offset_ns, 5u * 46080u);
  EXPECT_EQ(out.points[0].ring, 0);
  EXPECT_EQ(out.points[31].ring, 31);
}

TEST_P(DecoderKernel, Vlp32cAppliesAzimuthOffsetsAndFourMillimetreRange) {
  PacketBuilder b(0x37, 0x28);
  b.azimuths(0, 0).all_records(2500, 10);  // 10 m in 4 mm counts; rotor standing still
  const DecodedPacket out = decode(b, Model::kVlp32c);
  const core::Point& l0 = out.points[0];  // laser 0: -25 deg, +1.4 deg azimuth offset
  EXPECT_NEAR(std::hypot(l0.x, l0.y, l0.z), 10.0, 1e-3);
  EXPECT_NEAR(std::asin(l0.z / 10.0) / kDeg, -25.0, 1e-3);
  EXPECT_NEAR(sensor_azimuth(l0), 1.4, 1e-3);
  const core::Point& l1 = out.points[1];  // laser 1: -4.2 deg azimuth offset
  EXPECT_NEAR(sensor_azimuth(l1), 360.0 - 4.2, 1e-3);
  // Lasers fire in pairs: lasers 2 and 3 share a firing time.
  EXPECT_EQ(out.points[2].time_ns, out.points[3].time_ns);
  EXPECT_EQ(out.points[2].time_ns, 2304u);
}

// Packets of random records and azimuth steps: both kernels give the same points.
TEST(DecoderKernels, AgreeOnRandomPackets) {
  std::mt19937 rng(7);
  for (const auto& [model, product] :
       {std::pair{Model::kVlp16, 0x22}, {Model::kHdl32e, 0x21}, {Model::kVlp32c, 0x28}}) {
    for (const int mode : {0x37, 0x39}) {
      for (int n = 0; n < 50; ++n) {
        PacketBuilder b(static_cast<std::uint8_t>(mode), static_cast<std::uint8_t>(product));
        b.azimuths(static_cast<int>(rng() % 36000), static_cast<int>(rng() % 200));
        for (int blk = 0; blk < 12; ++blk) {
          for (int r = 0; r < 32; ++r) {
            // Some records equal to their pair's, as dual mode sends for a single return.
            const bool copy = (blk % 2 == 1) && rng() % 3 == 0;
            b.record(blk, r, static_cast<std::uint16_t>(rng() % 65536),
                     static_cast<std::uint8_t>(rng() % 256));
            if (copy) b.copy_record(blk - 1, r, blk, r);
          }
        }
        DecoderOptions portable, simd;
        portable.simd = false;
        simd.simd = true;
        const DecodedPacket a = decode_with(b, model, portable);
        const DecodedPacket c = decode_with(b, model, simd);
        ASSERT_EQ(a.point_count, c.point_count);
        ASSERT_EQ(a.firing_count, c.firing_count);
        for (int f = 0; f < a.firing_count; ++f) {
          const auto i = static_cast<std::size_t>(f);
          EXPECT_EQ(a.firings[i].first_point, c.firings[i].first_point);
          EXPECT_EQ(a.firings[i].point_count, c.firings[i].point_count);
          EXPECT_EQ(a.firings[i].azimuth, c.firings[i].azimuth);
        }
        for (int k = 0; k < a.point_count; ++k) {
          const auto& p = a.points[static_cast<std::size_t>(k)];
          const auto& q = c.points[static_cast<std::size_t>(k)];
          // Fused multiply-adds round differently: 1e-6 relative, 0.3 mm at 300 m.
          const double tol = 1e-6 * (1.0 + std::hypot(p.x, p.y, p.z));
          ASSERT_NEAR(p.x, q.x, tol);
          ASSERT_NEAR(p.y, q.y, tol);
          ASSERT_NEAR(p.z, q.z, tol);
          ASSERT_EQ(p.intensity, q.intensity);
          ASSERT_EQ(p.time_ns, q.time_ns);
          ASSERT_EQ(p.ring, q.ring);
          ASSERT_EQ(p.return_type, q.return_type);
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Kernels, DecoderKernel, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& i) {
                           return i.param ? "simd" : "portable";
                         });

}  // namespace
}  // namespace cndt::vlp16
