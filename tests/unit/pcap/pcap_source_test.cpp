#include "cndt/pcap/pcap_source.hpp"

#include <gtest/gtest.h>
#include <pcap/pcap.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "cndt/pcap/pcap_writer.hpp"
#include "frames.hpp"
#include "temp_dir.hpp"

namespace cndt::pcap {
namespace {

using std::chrono::nanoseconds;
constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;

std::vector<std::uint8_t> payload(std::size_t n, std::uint8_t v) {
  return std::vector<std::uint8_t>(n, v);
}

// 6 data packets, 2 position packets, 1 packet on another port; 10 ms apart.
void write_sample(const std::string& path) {
  auto w = PcapWriter::create(path, true);
  ASSERT_TRUE(w) << w.error().message;
  UdpEndpoints data, pos, other;
  pos.source_port = pos.dest_port = 8308;
  other.dest_port = 9999;
  for (int i = 0; i < 9; ++i) {
    const auto t = nanoseconds(kT0 + i * 10'000'000LL);
    if (i == 3 || i == 6) {
      w.value()->write_udp(t, pos, payload(512, static_cast<std::uint8_t>(i)));
    } else if (i == 8) {
      w.value()->write_udp(t, other, payload(100, 1));
    } else {
      w.value()->write_udp(t, data, payload(1206, static_cast<std::uint8_t>(i)));
    }
  }
  ASSERT_FALSE(w.value()->close().has_value());
}

TEST(PcapSource, ReadsBackWhatTheWriterWrote) {
  test::TempDir dir;
  const std::string path = dir.file("a.pcap");
  write_sample(path);
  auto src = PcapSource::open(path, {});
  ASSERT_TRUE(src) << src.error().message;
  io::SourcePacket p;
  int data = 0, position = 0;
  while (src.value()->next(p) == io::NextResult::kPacket) {
    if (p.kind == io::PacketKind::kData) {
      ++data;
      EXPECT_EQ(p.payload.size(), 1206u);
    } else {
      ++position;
      EXPECT_EQ(p.payload.size(), 512u);
    }
    EXPECT_EQ(p.time.count(), kT0 + static_cast<std::int64_t>(p.index - 1) * 10'000'000LL);
    EXPECT_EQ(p.payload[0], static_cast<std::uint8_t>(p.index - 1));
    EXPECT_EQ(p.source.to_string(), "192.168.1.201");
  }
  EXPECT_EQ(data, 6);
  EXPECT_EQ(position, 2);
  const PcapStats& s = src.value()->stats();
  EXPECT_EQ(s.records, 9u);
  EXPECT_EQ(s.udp_by_dest_port.at(2368), 6u);
  EXPECT_EQ(s.udp_by_dest_port.at(8308), 2u);
  EXPECT_EQ(s.udp_by_dest_port.at(9999), 1u);
  EXPECT_FALSE(s.truncated.has_value());
}

TEST(PcapSource, FiltersBySensorAddress) {
  test::TempDir dir;
  const std::string path = dir.file("a.pcap");
  write_sample(path);
  PcapOptions o;
  o.sensor_ip = io::IpAddress::parse("192.168.1.77");
  auto src = PcapSource::open(path, o);
  ASSERT_TRUE(src);
  io::SourcePacket p;
  EXPECT_EQ(src.value()->next(p), io::NextResult::kEnd);
  EXPECT_EQ(src.value()->stats().wrong_source, 8u);
}

TEST(PcapSource, FileCutInsideARecordEndsCleanlyAndSaysWhere) {
  test::TempDir dir;
  const std::string path = dir.file("cut.pcap");
  write_sample(path);
  const auto size = std::filesystem::file_size(path);
  // The last record is 100 bytes of payload + 42 of headers + 16 of record header: cut inside
  // the record before it instead (a data packet: 1206 + 42 + 16).
  std::filesystem::resize_file(path, size - (100 + 42 + 16) - 1000);
  auto src = PcapSource::open(path, {});
  ASSERT_TRUE(src);
  io::SourcePacket p;
  int n = 0;
  while (src.value()->next(p) == io::NextResult::kPacket) ++n;
  EXPECT_EQ(n, 7);  // records 1..7 complete (5 data + 2 position)
  const auto& t = src.value()->stats().truncated;
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->index, 8u);
  EXPECT_EQ(t->declared, 1248u);
  EXPECT_EQ(t->present, 248u);
  ASSERT_TRUE(t->dest_port.has_value());
  EXPECT_EQ(*t->dest_port, 2368);
  EXPECT_FALSE(t->message.empty());
}

TEST(PcapSource, ReadsPcapng) {
  test::TempDir dir;
  const std::string path = dir.file("a.pcapng");
  std::vector<std::uint8_t> f;
  auto u32 = [&f](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) f.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  };
  auto u16 = [&f](std::uint16_t v) {
    f.push_back(static_cast<std::uint8_t>(v & 0xFF));
    f.push_back(static_cast<std::uint8_t>(v >> 8));
  };
  // Section header block.
  u32(0x0A0D0D0A);
  u32(28);
  u32(0x1A2B3C4D);
  u16(1);
  u16(0);
  u32(0xFFFFFFFF);
  u32(0xFFFFFFFF);
  u32(28);
  // Interface description block: Ethernet, snaplen 65535.
  u32(1);
  u32(20);
  u16(1);
  u16(0);
  u32(65535);
  u32(20);
  for (int i = 0; i < 2; ++i) {
    const auto frame = test::ethernet(test::ipv4_udp(payload(1206, 7), 2368));
    const auto padded = (frame.size() + 3) / 4 * 4;
    const auto len = static_cast<std::uint32_t>(32 + padded);
    const std::uint64_t ts_us = 1'700'000'000'000'000ULL + static_cast<std::uint64_t>(i) * 1000;
    u32(6);
    u32(len);
    u32(0);
    u32(static_cast<std::uint32_t>(ts_us >> 32));
    u32(static_cast<std::uint32_t>(ts_us & 0xFFFFFFFF));
    u32(static_cast<std::uint32_t>(frame.size()));
    u32(static_cast<std::uint32_t>(frame.size()));
    f.insert(f.end(), frame.begin(), frame.end());
    f.resize(f.size() + (padded - frame.size()), 0);
    u32(len);
  }
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(f.data()), static_cast<std::streamsize>(f.size()));
  auto src = PcapSource::open(path, {});
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_TRUE(src.value()->pcapng());
  io::SourcePacket p;
  ASSERT_EQ(src.value()->next(p), io::NextResult::kPacket);
  EXPECT_EQ(p.time.count(), 1'700'000'000'000'000'000LL);
  ASSERT_EQ(src.value()->next(p), io::NextResult::kPacket);
  EXPECT_EQ(p.time.count(), 1'700'000'000'001'000'000LL);
  EXPECT_EQ(src.value()->next(p), io::NextResult::kEnd);
}

TEST(PcapSource, ReadsLinuxCookedCaptures) {
  test::TempDir dir;
  const std::string path = dir.file("sll.pcap");
  pcap_t* dead = pcap_open_dead(DLT_LINUX_SLL, 65535);
  pcap_dumper_t* d = pcap_dump_open(dead, path.c_str());
  ASSERT_NE(d, nullptr);
  std::vector<std::uint8_t> sll(16, 0);
  sll[14] = 0x08;
  const auto frame = test::prepend(sll, test::ipv4_udp(payload(1206, 3), 2368));
  pcap_pkthdr h{};
  h.caplen = h.len = static_cast<bpf_u_int32>(frame.size());
  pcap_dump(reinterpret_cast<u_char*>(d), &h, frame.data());
  pcap_dump_close(d);
  pcap_close(dead);
  auto src = PcapSource::open(path, {});
  ASSERT_TRUE(src) << src.error().message;
  io::SourcePacket p;
  ASSERT_EQ(src.value()->next(p), io::NextResult::kPacket);
  EXPECT_EQ(p.payload.size(), 1206u);
}

TEST(PcapSource, PacesByCaptureTime) {
  test::TempDir dir;
  const std::string path = dir.file("a.pcap");
  write_sample(path);  // spans 80 ms
  PcapOptions o;
  o.speed = 2.0;  // 40 ms of replay
  auto src = PcapSource::open(path, o);
  ASSERT_TRUE(src);
  io::SourcePacket p;
  const auto start = std::chrono::steady_clock::now();
  while (src.value()->next(p) == io::NextResult::kPacket) {
  }
  // Pacing only ever waits, so the replay cannot finish sooner than capture time / speed.
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(30));
}

TEST(PcapSourceErrors, NameTheFileAndTheProblem) {
  test::TempDir dir;
  auto missing = PcapSource::open(dir.file("nope.pcap"), {});
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, core::kExitNoInput);
  EXPECT_NE(missing.error().message.find("nope.pcap"), std::string::npos);

  auto directory = PcapSource::open(dir.path().string(), {});
  ASSERT_FALSE(directory);
  EXPECT_EQ(directory.error().code, core::kExitNoInput);

  std::ofstream(dir.file("empty.pcap")).close();
  auto empty = PcapSource::open(dir.file("empty.pcap"), {});
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().code, core::kExitDataError);
  EXPECT_NE(empty.error().message.find("empty"), std::string::npos);

  std::ofstream(dir.file("notes.txt")) << "this is not a capture\n";
  auto text = PcapSource::open(dir.file("notes.txt"), {});
  ASSERT_FALSE(text);
  EXPECT_EQ(text.error().code, core::kExitDataError);
  EXPECT_NE(text.error().message.find("not a pcap"), std::string::npos);

  pcap_t* dead = pcap_open_dead(147, 65535);  // a user-defined link type
  pcap_dumper_t* d = pcap_dump_open(dead, dir.file("user.pcap").c_str());
  pcap_dump_close(d);
  pcap_close(dead);
  auto user = PcapSource::open(dir.file("user.pcap"), {});
  ASSERT_FALSE(user);
  EXPECT_EQ(user.error().code, core::kExitDataError);
  EXPECT_NE(user.error().message.find("link type"), std::string::npos);
}

}  // namespace
}  // namespace cndt::pcap
