#include "cndt/vlp16/position_packet.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstring>

namespace cndt::vlp16 {
namespace {

std::array<std::uint8_t, 512> make(const char* nmea, std::uint8_t pps) {
  std::array<std::uint8_t, 512> p{};
  core::store_le32(p, 0xC6, 1'234'567u);
  p[0xCA] = pps;
  std::memcpy(p.data() + 0xCE, nmea, std::strlen(nmea));
  return p;
}

TEST(PositionPacket, ParsesGprmcWithChecksum) {
  const auto p = make(
      "$GPRMC,081802.00,A,3649.7478558,N,00224.4542928,W,0.034,212.5,210116,0.0,E,A*2E\r\n", 2);
  PositionPacket out;
  ASSERT_EQ(parse_position_packet(p, out), PositionError::kNone);
  EXPECT_EQ(out.toh_us, 1'234'567u);
  EXPECT_EQ(out.pps, PpsState::kLocked);
  EXPECT_TRUE(out.has_nmea);
  EXPECT_TRUE(out.nmea_checksum_ok);
  EXPECT_TRUE(out.fix_valid);
  EXPECT_EQ(out.utc_seconds_of_day, 8 * 3600 + 18 * 60 + 2);
  EXPECT_EQ(out.sentence().substr(0, 6), "$GPRMC");
}

TEST(PositionPacket, FlagsABadChecksumAndAVoidFix) {
  const auto p = make("$GPRMC,081802.00,V,,,,,,,210116,,,N*00\r\n", 0);
  PositionPacket out;
  ASSERT_EQ(parse_position_packet(p, out), PositionError::kNone);
  EXPECT_FALSE(out.nmea_checksum_ok);
  EXPECT_FALSE(out.fix_valid);
  EXPECT_EQ(out.pps, PpsState::kAbsent);
}

TEST(PositionPacket, NoGpsAttachedMeansNoSentence) {
  std::array<std::uint8_t, 512> p{};
  PositionPacket out;
  ASSERT_EQ(parse_position_packet(p, out), PositionError::kNone);
  EXPECT_FALSE(out.has_nmea);
}

TEST(PositionPacket, RefusesWrongSizeAndBadPps) {
  std::array<std::uint8_t, 512> p{};
  PositionPacket out;
  EXPECT_EQ(parse_position_packet(core::ByteSpan(p).first(200), out), PositionError::kWrongSize);
  p[0xCA] = 7;
  EXPECT_EQ(parse_position_packet(p, out), PositionError::kBadPps);
}

}  // namespace
}  // namespace cndt::vlp16
