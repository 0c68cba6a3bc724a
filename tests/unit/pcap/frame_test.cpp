#include "cndt/pcap/frame.hpp"

#include <gtest/gtest.h>

#include "frames.hpp"

namespace cndt::pcap {
namespace {

const std::vector<std::uint8_t> kPayload(1206, 0x5A);

FrameResult parse(int dlt, const std::vector<std::uint8_t>& f, UdpDatagram& d) {
  return parse_frame(dlt, core::ByteSpan(f), d);
}

TEST(ParseFrame, EthernetIpv4) {
  UdpDatagram d;
  ASSERT_EQ(parse(1, test::ethernet(test::ipv4_udp(kPayload, 2368)), d), FrameResult::kUdp);
  EXPECT_EQ(d.dst_port, 2368);
  EXPECT_EQ(d.src_port, 2368);
  EXPECT_EQ(d.payload.size(), 1206u);
  EXPECT_EQ(d.src.to_string(), "192.168.1.201");
  EXPECT_FALSE(d.truncated());
}

TEST(ParseFrame, EthernetWithStackedVlanTags) {
  UdpDatagram d;
  ASSERT_EQ(parse(1, test::ethernet(test::ipv4_udp(kPayload, 8308), 0x0800, 2), d),
            FrameResult::kUdp);
  EXPECT_EQ(d.dst_port, 8308);
}

TEST(ParseFrame, EthernetPaddingIsNotPayload) {
  auto f = test::ethernet(test::ipv4_udp(std::vector<std::uint8_t>(4, 1), 2368));
  f.resize(60, 0);  // minimum Ethernet frame
  UdpDatagram d;
  ASSERT_EQ(parse(1, f, d), FrameResult::kUdp);
  EXPECT_EQ(d.payload.size(), 4u);
}

TEST(ParseFrame, LinuxCookedV1AndV2) {
  std::vector<std::uint8_t> sll(16, 0);
  sll[14] = 0x08;
  UdpDatagram d;
  ASSERT_EQ(parse(113, test::prepend(sll, test::ipv4_udp(kPayload, 2368)), d), FrameResult::kUdp);
  std::vector<std::uint8_t> sll2(20, 0);
  sll2[0] = 0x86;
  sll2[1] = 0xDD;
  ASSERT_EQ(parse(276, test::prepend(sll2, test::ipv6_udp(kPayload, 2368, false)), d),
            FrameResult::kUdp);
  EXPECT_EQ(d.src.version, 6);
  EXPECT_EQ(d.payload.size(), 1206u);
}

TEST(ParseFrame, RawIpAndIpv6ExtensionHeaders) {
  UdpDatagram d;
  ASSERT_EQ(parse(12, test::ipv4_udp(kPayload, 2368), d), FrameResult::kUdp);
  ASSERT_EQ(parse(229, test::ipv6_udp(kPayload, 2368, true), d), FrameResult::kUdp);
  EXPECT_EQ(d.payload.size(), 1206u);
  ASSERT_EQ(parse(12, test::ipv6_udp(kPayload, 2368, false), d), FrameResult::kUdp);
}

TEST(ParseFrame, BsdLoopbackInEitherByteOrder) {
  UdpDatagram d;
  ASSERT_EQ(parse(0, test::prepend({2, 0, 0, 0}, test::ipv4_udp(kPayload, 2368)), d),
            FrameResult::kUdp);
  ASSERT_EQ(parse(0, test::prepend({0, 0, 0, 2}, test::ipv4_udp(kPayload, 2368)), d),
            FrameResult::kUdp);
  ASSERT_EQ(parse(108, test::prepend({0, 0, 0, 30}, test::ipv6_udp(kPayload, 2368, false)), d),
            FrameResult::kUdp);
}

TEST(ParseFrame, ClassifiesWhatIsNotUdp) {
  UdpDatagram d;
  EXPECT_EQ(parse(1, test::ethernet(std::vector<std::uint8_t>(28, 0), 0x0806), d),
            FrameResult::kNotIp);  // ARP
  auto tcp = test::ipv4_udp(kPayload, 2368);
  tcp[9] = 6;
  EXPECT_EQ(parse(12, tcp, d), FrameResult::kNotUdp);
  EXPECT_EQ(parse(12, test::ipv4_udp(kPayload, 2368, 201, 0x2000), d), FrameResult::kFragment);
  EXPECT_EQ(parse(1, std::vector<std::uint8_t>(10, 0), d), FrameResult::kMalformed);
  EXPECT_EQ(parse(147, test::ipv4_udp(kPayload, 2368), d), FrameResult::kUnsupportedLink);
}

TEST(ParseFrame, CutPayloadIsReportedAsTruncated) {
  auto f = test::ethernet(test::ipv4_udp(kPayload, 2368));
  f.resize(600);
  UdpDatagram d;
  ASSERT_EQ(parse(1, f, d), FrameResult::kUdp);
  EXPECT_TRUE(d.truncated());
  EXPECT_EQ(d.payload_size, 1206u);
}

TEST(ParseFrame, InconsistentLengthsAreMalformed) {
  auto f = test::ipv4_udp(kPayload, 2368);
  core::store_be16(f, 24, 5000);  // UDP length beyond the IP datagram
  UdpDatagram d;
  EXPECT_EQ(parse(12, f, d), FrameResult::kMalformed);
  f = test::ipv4_udp(kPayload, 2368);
  f[0] = 0x43;  // IHL below 5
  EXPECT_EQ(parse(12, f, d), FrameResult::kMalformed);
}

}  // namespace
}  // namespace cndt::pcap
