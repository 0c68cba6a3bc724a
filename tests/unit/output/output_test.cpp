// Pose encodings: CRCs, the CAN frames against config/cndt.dbc, the UDP datagram, candump lines.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "cndt/can/can_bus.hpp"
#include "cndt/output/can_codec.hpp"
#include "cndt/output/crc.hpp"
#include "cndt/output/dbc.hpp"
#include "cndt/output/udp_codec.hpp"

namespace cndt::output {
namespace {

core::ByteSpan ascii(const char* s) {
  return {reinterpret_cast<const std::uint8_t*>(s), std::char_traits<char>::length(s)};
}

TEST(Crc, CheckValues) {
  EXPECT_EQ(crc8_sae_j1850(ascii("123456789")), 0x4B);
  EXPECT_EQ(crc32_ieee(ascii("123456789")), 0xCBF43926u);
  EXPECT_EQ(crc8_sae_j1850({}), 0x00);  // init 0xFF xor-out 0xFF over nothing
}

PoseMessage random_pose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> pos(-5000.0, 5000.0), ang(-3.0, 3.0), pitch(-1.4, 1.4),
      u(0.0, 1.0);
  PoseMessage m;
  m.stamp_ns = 1'767'225'600'000'000'000 + static_cast<std::int64_t>(u(rng) * 1e12);
  m.stamp_ns -= m.stamp_ns % 1000;  // CAN carries microseconds
  m.scan_sequence = static_cast<std::uint32_t>(u(rng) * 60000);
  m.position = {pos(rng), pos(rng), pos(rng) * 0.01};
  m.orientation = Eigen::Quaterniond(from_roll_pitch_yaw(ang(rng), pitch(rng), ang(rng)));
  m.cm = u(rng);
  m.status = static_cast<PoseStatus>(static_cast<int>(u(rng) * 2.99));
  m.flags = u(rng) < 0.5 ? kPoseMapCorrected : 0;
  m.points = static_cast<std::uint32_t>(u(rng) * 60000);
  return m;
}

void expect_same_rotation(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double tol) {
  EXPECT_LT(a.angularDistance(b), tol);
}

// Each of roll, pitch and yaw within half a signal step (rounding), so the rotations differ by
// at most 1.5 steps (the three errors add up when the axes line up).
void expect_angles_within_half_step(const Eigen::Quaterniond& got, const Eigen::Quaterniond& want) {
  const Eigen::Vector3d a = roll_pitch_yaw(got.toRotationMatrix());
  const Eigen::Vector3d b = roll_pitch_yaw(want.toRotationMatrix());
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(std::remainder(a[i] - b[i], 2 * M_PI), 0.0, kCanAngleStep / 2 + 1e-9) << i;
  }
  expect_same_rotation(got, want, 1.5 * kCanAngleStep);
}

TEST(CanCodec, RoundTripWithinResolution) {
  std::mt19937_64 rng(7);
  CanPoseDecoder decoder;
  for (int i = 0; i < 500; ++i) {
    const PoseMessage m = random_pose(rng);
    const auto frames = encode_pose_frames(m, static_cast<std::uint8_t>(i));
    std::optional<PoseMessage> got;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      EXPECT_EQ(frames[k].id, kDefaultCanBaseId + k);
      EXPECT_EQ(frames[k].len, 8);
      EXPECT_EQ(frames[k].data[1] & 0x0F, i % 16);
      EXPECT_TRUE(can_crc_ok(frames[k]));
      got = decoder.feed(frames[k]);
      EXPECT_EQ(got.has_value(), k + 1 == frames.size());
    }
    ASSERT_TRUE(got);
    EXPECT_EQ(got->stamp_ns, m.stamp_ns);
    EXPECT_EQ(got->scan_sequence, m.scan_sequence & 0xFFFF);
    EXPECT_EQ(got->points, m.points);
    EXPECT_EQ(got->status, m.status);
    EXPECT_EQ(got->flags, m.flags);
    EXPECT_NEAR(got->cm, m.cm, kCanCmStep / 2 + 1e-12);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(got->position[a], m.position[a], kCanPositionStep / 2 + 1e-9);
    }
    expect_angles_within_half_step(got->orientation, m.orientation);
  }
  EXPECT_EQ(decoder.stats().poses, 500u);
  EXPECT_EQ(decoder.stats().bad_crc + decoder.stats().counter_gaps, 0u);
}

TEST(CanCodec, EverySingleBitFlipIsRejected) {
  std::mt19937_64 rng(3);
  const auto frames = encode_pose_frames(random_pose(rng), 5);
  for (const CanFrame& f : frames) {
    for (int bit = 0; bit < 64; ++bit) {
      CanFrame bad = f;
      bad.data[static_cast<std::size_t>(bit / 8)] ^= static_cast<std::uint8_t>(1u << (bit % 8));
      EXPECT_FALSE(can_crc_ok(bad)) << "frame " << f.id << " bit " << bit;
    }
  }
  CanPoseDecoder d;
  CanFrame bad = frames[2];
  bad.data[4] ^= 0x10;
  for (std::size_t k = 0; k < frames.size(); ++k) EXPECT_FALSE(d.feed(k == 2 ? bad : frames[k]));
  d.finish();
  EXPECT_EQ(d.stats().bad_crc, 1u);
  EXPECT_EQ(d.stats().incomplete_poses, 1u);
  EXPECT_EQ(d.stats().poses, 0u);
}

TEST(CanCodec, CounterGapsRepeatsAndIncompletePoses) {
  std::mt19937_64 rng(11);
  CanPoseDecoder d;
  const auto feed_all = [&](std::uint8_t c, int skip_index = -1) {
    const auto frames = encode_pose_frames(random_pose(rng), c);
    int poses = 0;
    for (int k = 0; k < 5; ++k) {
      if (k != skip_index && d.feed(frames[static_cast<std::size_t>(k)])) ++poses;
    }
    return poses;
  };
  EXPECT_EQ(feed_all(14), 1);
  EXPECT_EQ(feed_all(15), 1);
  EXPECT_EQ(feed_all(0), 1);  // wraps
  EXPECT_EQ(d.stats().counter_gaps, 0u);
  EXPECT_EQ(feed_all(3), 1);              // 1 and 2 lost
  EXPECT_EQ(d.stats().counter_gaps, 5u);  // once per frame id
  EXPECT_EQ(feed_all(3), 0);              // stale repetition
  EXPECT_EQ(d.stats().counter_repeats, 5u);
  EXPECT_EQ(feed_all(4, 3), 0);  // the z frame is missing
  EXPECT_EQ(feed_all(5), 1);
  EXPECT_EQ(d.stats().incomplete_poses, 1u);
  EXPECT_EQ(d.stats().counter_gaps, 6u);  // the z frame's counter jumped 3 -> 5
}

TEST(CanCodec, OutOfRangeValuesAreClampedAndFlagged) {
  PoseMessage m;
  m.position = {40000.0, -1.0, 2.0};
  m.status = PoseStatus::kValid;
  CanPoseDecoder d;
  std::optional<PoseMessage> got;
  for (const auto& f : encode_pose_frames(m, 0)) got = d.feed(f);
  ASSERT_TRUE(got);
  EXPECT_NE(got->flags & kPoseOutOfRange, 0);
  EXPECT_NEAR(got->position.x(), 33554.431, 1e-6);
  EXPECT_NEAR(got->position.y(), -1.0, 1e-9);
  m.position.x() = 1.0;
  for (const auto& f : encode_pose_frames(m, 1)) got = d.feed(f);
  ASSERT_TRUE(got);
  EXPECT_EQ(got->flags & kPoseOutOfRange, 0);
}

// config/cndt.dbc alone decodes the frames: every signal by name, scaled as the DBC says.
TEST(Dbc, ProjectDbcDecodesTheFrames) {
  auto db = load_dbc(std::string(CNDT_SOURCE_DIR) + "/config/cndt.dbc");
  ASSERT_TRUE(db) << db.error().message;
  ASSERT_EQ(db.value().messages.size(), kCanFramesPerPose);
  for (const auto& msg : db.value().messages) {
    EXPECT_EQ(msg.length, 8u);
    ASSERT_NE(msg.signal("CRC"), nullptr) << msg.name;
    ASSERT_NE(msg.signal("Counter"), nullptr) << msg.name;
    // No two signals share a bit.
    std::uint64_t used = 0;
    for (const auto& s : msg.signals) {
      ASSERT_TRUE(s.little_endian);
      const std::uint64_t bits = (s.length == 64 ? ~0ull : ((1ull << s.length) - 1)) << s.start;
      EXPECT_EQ(used & bits, 0u) << msg.name << "." << s.name;
      used |= bits;
    }
  }
  const DbcMessage* status = db.value().message(kDefaultCanBaseId, false);
  ASSERT_NE(status, nullptr);
  EXPECT_EQ(status->name, "CNDT_Status");
  ASSERT_NE(status->signal("Status"), nullptr);
  EXPECT_EQ(status->signal("Status")->values.at(1), "degraded");
  EXPECT_FALSE(db.value().messages[0].comment.empty());

  std::mt19937_64 rng(5);
  for (int i = 0; i < 200; ++i) {
    const PoseMessage m = random_pose(rng);
    const auto frames = encode_pose_frames(m, static_cast<std::uint8_t>(i));
    const auto value = [&](std::string_view msg, std::string_view sig) {
      const DbcMessage* dm = db.value().message(msg);
      EXPECT_NE(dm, nullptr);
      const CanFrame& f = frames[dm->id - kDefaultCanBaseId];
      return dm->signal(sig)->physical(f.data);
    };
    EXPECT_NEAR(value("CNDT_PositionXY", "X"), m.position.x(), 0.0005 + 1e-9);
    EXPECT_NEAR(value("CNDT_PositionXY", "Y"), m.position.y(), 0.0005 + 1e-9);
    EXPECT_NEAR(value("CNDT_PositionZ", "Z"), m.position.z(), 0.0005 + 1e-9);
    const Eigen::Matrix3d R =
        from_roll_pitch_yaw(value("CNDT_Orientation", "Roll"), value("CNDT_Orientation", "Pitch"),
                            value("CNDT_Orientation", "Yaw"));
    expect_angles_within_half_step(Eigen::Quaterniond(R), m.orientation);
    EXPECT_NEAR(value("CNDT_Status", "Cm"), m.cm, 0.5e-4 + 1e-12);
    EXPECT_EQ(value("CNDT_Status", "Status"), static_cast<double>(m.status));
    const double t = value("CNDT_Time", "TimeS") + value("CNDT_Time", "TimeUs") * 1e-6;
    EXPECT_NEAR(t, static_cast<double>(m.stamp_ns) * 1e-9, 1e-6);
    for (const auto& f : frames) {
      const DbcMessage* dm = db.value().message(f.id, false);
      EXPECT_EQ(dm->signal("Counter")->raw(f.data), i % 16);
      EXPECT_EQ(dm->signal("CRC")->raw(f.data), f.data[0]);
    }
  }
}

TEST(Dbc, MotorolaSignedAndMultiplexedSignals) {
  auto db = parse_dbc(
      "VERSION \"\"\n"
      "BO_ 2147483905 Ext: 8 Node\n"  // 0x101 | extended flag
      " SG_ Mux M : 0|4@1+ (1,0) [0|15] \"\" X\n"
      " SG_ A m1 : 7|12@0- (0.5,-1) [-1000|1000] \"m\" X\n"
      " SG_ B m2 : 23|8@0+ (1,0) [0|255] \"\" X\n"
      "CM_ SG_ 2147483905 A \"multi\n line\";\n",
      "t.dbc");
  ASSERT_TRUE(db) << db.error().message;
  const DbcMessage* m = db.value().message(0x101, true);
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(m->signal("Mux")->is_multiplexer);
  EXPECT_EQ(m->signal("A")->multiplexed_by, 1);
  EXPECT_EQ(m->signal("A")->comment, "multi\n line");
  // A: Motorola, MSB at bit 7 of byte 0, 12 bits: byte 0 then the high nibble of byte 1.
  const std::array<std::uint8_t, 8> data{0xFF, 0xE0, 0xAB, 0, 0, 0, 0, 0};
  EXPECT_EQ(m->signal("A")->raw(data), -2);  // 0xFFE as 12-bit two's complement
  EXPECT_DOUBLE_EQ(m->signal("A")->physical(data), -2.0);
  EXPECT_EQ(m->signal("B")->raw(data), 0xAB);
}

TEST(Dbc, ErrorsNameTheLine) {
  const auto expect_error = [](const char* text, const char* needle) {
    auto db = parse_dbc(text, "bad.dbc");
    ASSERT_FALSE(db) << text;
    EXPECT_NE(db.error().message.find(needle), std::string::npos) << db.error().message;
  };
  expect_error("VERSION \"\"\nBO_ 100 M: 8 N\n SG_ S : 60|8@1+ (1,0) [0|1] \"\" X\n",
               "bad.dbc:3: signal 'S' (60|8@1) does not fit");
  expect_error("VERSION \"\"\nBO_ 100 M 8 N\n", "bad.dbc:2: malformed message");
  expect_error("VERSION \"\"\nBO_ 100 M: 8 N\n SG_ S : 0|8@2+ (1,0) [0|1] \"\" X\n",
               "bad.dbc:3: malformed signal");
  expect_error("VERSION \"\"\nBO_ 100 M: 8 N\n SG_ S : 0|8@1+ (x,0) [0|1] \"\" X\n",
               "bad.dbc:3: signal 'S': factor");
  expect_error("VERSION \"\"\nBO_ 4000 M: 8 N\n", "bad.dbc:2: standard id 0xfa0");
  expect_error("VERSION \"\"\nCM_ \"never closed;\n", "bad.dbc:2: unterminated string");
  expect_error("VERSION \"\"\nBO_ 100 M: 8 N\nVAL_ 100 Q 0 \"a\" ;\n",
               "bad.dbc:3: value table for unknown signal 'Q'");
  expect_error("hello\n", "not a DBC file");
  auto missing = load_dbc("/nonexistent/x.dbc");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, core::kExitNoInput);
}

TEST(UdpCodec, RoundTripAndRejections) {
  std::mt19937_64 rng(9);
  const PoseMessage m = random_pose(rng);
  const PoseDatagram d = encode_pose_datagram(m, 42);
  ASSERT_EQ(d.size(), 96u);
  EXPECT_EQ(d[0], 'C');
  const DecodedDatagram got = decode_pose_datagram(d);
  ASSERT_EQ(got.error, DatagramError::kNone);
  EXPECT_EQ(got.sequence, 42u);
  EXPECT_EQ(got.pose.stamp_ns, m.stamp_ns);
  EXPECT_EQ(got.pose.scan_sequence, m.scan_sequence);
  EXPECT_EQ(got.pose.position, m.position);  // f64: exact
  expect_same_rotation(got.pose.orientation, m.orientation, 1e-12);
  EXPECT_NEAR(got.pose.cm, m.cm, 1e-7);
  EXPECT_EQ(got.pose.status, m.status);
  EXPECT_EQ(got.pose.flags, m.flags);
  EXPECT_EQ(got.pose.points, m.points);

  for (std::size_t byte = 0; byte < d.size(); ++byte) {
    PoseDatagram bad = d;
    bad[byte] ^= 0x04;
    EXPECT_NE(decode_pose_datagram(bad).error, DatagramError::kNone) << "byte " << byte;
  }
  EXPECT_EQ(decode_pose_datagram(core::ByteSpan(d).first(95)).error, DatagramError::kSize);
  PoseDatagram magic = d;
  magic[0] = 'X';
  EXPECT_EQ(decode_pose_datagram(magic).error, DatagramError::kMagic);
  PoseDatagram version = d;
  version[4] = 9;
  EXPECT_EQ(decode_pose_datagram(version).error, DatagramError::kVersion);
  PoseDatagram crc = d;
  crc[30] ^= 1;
  EXPECT_EQ(decode_pose_datagram(crc).error, DatagramError::kCrc);
}

TEST(Candump, FormatAndParseRoundTrip) {
  std::mt19937_64 rng(1);
  const auto frames = encode_pose_frames(random_pose(rng), 9);
  std::array<char, 128> buf{};
  const auto stamp = std::chrono::nanoseconds(1'767'225'600'123'456'789);
  const std::size_t n = can::format_candump_line(frames[2], stamp, "can0", buf);
  const std::string line(buf.data(), n);
  EXPECT_EQ(line.substr(0, 26), "(1767225600.123456) can0 3");
  EXPECT_EQ(line.size(), 26u + 2 + 1 + 16 + 1);
  auto rec = can::parse_candump_line(line);
  ASSERT_TRUE(rec) << rec.error().message;
  ASSERT_TRUE(rec.value().has_value());
  EXPECT_EQ(rec.value()->frame.id, frames[2].id);
  EXPECT_EQ(rec.value()->frame.data, frames[2].data);
  EXPECT_EQ(rec.value()->frame.len, 8);
  EXPECT_EQ(rec.value()->interface_name, "can0");
  EXPECT_EQ(rec.value()->stamp.count(), 1'767'225'600'123'456'000);

  for (const char* ok : {"(0000000001.5) vcan0 12345678#01.02.03 R", "(1.000000001) c 7FF#",
                         "  (1.0) can1 123#DEADBEEF  "}) {
    auto r = can::parse_candump_line(ok);
    ASSERT_TRUE(r) << ok << ": " << r.error().message;
    EXPECT_TRUE(r.value().has_value()) << ok;
  }
  auto ext = can::parse_candump_line("(1.0) can0 12345678#0102");
  EXPECT_TRUE(ext.value()->frame.extended);
  EXPECT_EQ(ext.value()->frame.len, 2);
  for (const char* skip : {"", "# comment", "DROPCOUNT: 3", "(1.0) can0 123#R"}) {
    auto r = can::parse_candump_line(skip);
    ASSERT_TRUE(r) << skip;
    EXPECT_FALSE(r.value().has_value()) << skip;
  }
  for (const char* bad : {"(1.0 can0 123#00", "(1.0) can0 12#00", "(1.0) can0 123#0",
                          "(1.0) can0 123#0102030405060708AA", "(1.0) can0 123##100",
                          "(x.0) can0 123#00", "(1.0) can0 123#GG", "(1.0) can0"}) {
    auto r = can::parse_candump_line(bad);
    EXPECT_FALSE(r) << bad;
  }
}

}  // namespace
}  // namespace cndt::output
