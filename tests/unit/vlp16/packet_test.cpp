#include "cndt/vlp16/packet.hpp"

#include <gtest/gtest.h>

#include "packet_builder.hpp"

namespace cndt::vlp16 {
namespace {

using test::PacketBuilder;

TEST(ValidateDataPacket, AcceptsWellFormedPacket) {
  PacketBuilder b;
  b.azimuths(100, 40).toh(123456);
  PacketHeader h;
  ASSERT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
  EXPECT_EQ(h.toh_us, 123456u);
  EXPECT_EQ(h.mode, ReturnMode::kStrongest);
  EXPECT_EQ(h.product_id, 0x22);
}

TEST(ValidateDataPacket, RefusesWrongSize) {
  PacketBuilder b;
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span().first(1205), h), PacketError::kWrongSize);
  EXPECT_EQ(validate_data_packet(core::ByteSpan{}, h), PacketError::kWrongSize);
}

TEST(ValidateDataPacket, RefusesBadBlockFlag) {
  PacketBuilder b;
  core::store_le16(b.bytes, 700, 0x1234);
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kBadBlockFlag);
}

TEST(ValidateDataPacket, AzimuthAtExactlyOneTurnIsTheWrapNotAnError) {
  PacketBuilder b;
  b.azimuth(5, 36000);
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
  b.azimuth(5, 36001);
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kBadAzimuth);
}

TEST(ValidateDataPacket, RefusesUnknownReturnMode) {
  PacketBuilder b(0x40, 0x22);
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kBadFactoryBytes);
}

TEST(ValidateDataPacket, RecognisesButRefusesHdl64AndUnknownModels) {
  PacketBuilder b;
  core::store_le16(b.bytes, 100, 0xDDFF);  // HDL-64E lower bank
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kUnsupportedModel);
  PacketBuilder vls(0x37, kProductVls128);
  EXPECT_EQ(validate_data_packet(vls.span(), h), PacketError::kUnsupportedModel);
}

TEST(ValidateDataPacket, LegacyFirmwareWithoutFactoryBytesIsStrongest) {
  PacketBuilder b(0, 0);
  PacketHeader h;
  ASSERT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
  EXPECT_TRUE(h.legacy_factory_bytes);
  EXPECT_EQ(h.mode, ReturnMode::kStrongest);
}

TEST(ValidateDataPacket, RefusesClockFarBeyondTheHour) {
  PacketBuilder b;
  b.toh(3'600'000'500u);  // just past the hour is seen on real units
  PacketHeader h;
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kNone);
  b.toh(4'000'000'000u);
  EXPECT_EQ(validate_data_packet(b.span(), h), PacketError::kBadTimestamp);
}

}  // namespace
}  // namespace cndt::vlp16
