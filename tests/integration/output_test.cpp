// What cndt publishes, end to end: the candump log of a replay decodes with config/cndt.dbc alone
// to the poses of trajectory.tum, CRCs and counters verify, corrupted frames and datagrams are
// rejected by `cndt listen`, and every pose arrives as a UDP datagram (with the time the kernel
// took it in).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "cli_run.hpp"
#include "cndt/can/can_bus.hpp"
#include "cndt/net/udp_datagram.hpp"
#include "cndt/output/crc.hpp"
#include "cndt/output/dbc.hpp"
#include "cndt/output/udp_codec.hpp"
#include "slurp.hpp"
#include "temp_dir.hpp"

namespace {

using cndt::test::run;
using cndt::test::slurp;

struct TumPose {
  double t = 0;
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
};

std::vector<TumPose> read_tum(const std::string& path) {
  std::vector<TumPose> out;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream ls(line);
    TumPose p;
    double qx, qy, qz, qw;
    if (ls >> p.t >> p.p.x() >> p.p.y() >> p.p.z() >> qx >> qy >> qz >> qw) {
      p.q = Eigen::Quaterniond(qw, qx, qy, qz).normalized();
      out.push_back(p);
    }
  }
  return out;
}

// A short simulated street replayed once for all tests here.
class PoseOutput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new cndt::test::TempDir();
    const auto r = run("sim --scene street --duration 3 --out " + dir_->file("sim"));
    ASSERT_EQ(r.code, 0) << r.output;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static cndt::test::TempDir* dir_;
};
cndt::test::TempDir* PoseOutput::dir_ = nullptr;

TEST_F(PoseOutput, CandumpLogDecodesWithTheDbcAloneToTheTrajectory) {
  const std::string out = dir_->file("rep");
  auto r = run("replay " + dir_->file("sim/capture.pcap") + " --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto traj = read_tum(out + "/trajectory.tum");
  ASSERT_GE(traj.size(), 25u);

  auto db = cndt::output::load_dbc(std::string(CNDT_SOURCE_DIR) + "/config/cndt.dbc");
  ASSERT_TRUE(db) << db.error().message;
  // Signals by message name, per pose; a pose is complete when every message has arrived.
  std::vector<std::map<std::string, double>> poses;
  std::map<std::string, double> current;
  std::map<std::string, long> last_counter;
  std::ifstream in(out + "/can.log");
  std::size_t frames = 0, signals_per_pose = 0;
  for (const auto& m : db.value().messages) signals_per_pose += m.signals.size();
  for (std::string line; std::getline(in, line);) {
    auto rec = cndt::can::parse_candump_line(line);
    ASSERT_TRUE(rec) << rec.error().message;
    ASSERT_TRUE(rec.value().has_value()) << line;
    const auto& f = rec.value()->frame;
    const auto* m = db.value().message(f.id, f.extended);
    ASSERT_NE(m, nullptr) << line;
    ASSERT_EQ(f.len, m->length) << line;
    ++frames;
    // CRC-8 SAE J1850 over bytes 1..7, as the DBC's comment says.
    EXPECT_EQ(m->signal("CRC")->raw(f.data),
              cndt::output::crc8_sae_j1850(cndt::core::ByteSpan(f.data).subspan(1)))
        << line;
    const long counter = static_cast<long>(m->signal("Counter")->raw(f.data));
    if (last_counter.count(m->name) != 0) {
      EXPECT_EQ(counter, (last_counter[m->name] + 1) % 16) << line;
    }
    last_counter[m->name] = counter;
    for (const auto& s : m->signals) current[m->name + "." + s.name] = s.physical(f.data);
    if (current.size() == signals_per_pose) {
      poses.push_back(current);
      current.clear();
    }
  }
  EXPECT_TRUE(current.empty());
  ASSERT_EQ(poses.size(), traj.size());
  EXPECT_EQ(frames, 5 * traj.size());
  double worst_pos = 0, worst_ang = 0;
  for (std::size_t i = 0; i < traj.size(); ++i) {
    auto& s = poses[i];
    // Microseconds (truncated) against the TUM file's nanoseconds, compared apart from the whole
    // seconds so that the epoch's size costs no precision.
    const double whole = std::floor(traj[i].t);
    EXPECT_EQ(s["CNDT_Time.TimeS"], whole) << i;
    EXPECT_NEAR(s["CNDT_Time.TimeUs"] * 1e-6, traj[i].t - whole, 1.0e-6 + 3e-7) << i;
    const Eigen::Vector3d p(s["CNDT_PositionXY.X"], s["CNDT_PositionXY.Y"], s["CNDT_PositionZ.Z"]);
    // DBC resolution 1 mm (rounding: half of it), TUM's 6 decimals add at most 0.5 um.
    worst_pos = std::max(worst_pos, (p - traj[i].p).cwiseAbs().maxCoeff());
    const Eigen::Vector3d want = cndt::output::roll_pitch_yaw(traj[i].q.toRotationMatrix());
    const Eigen::Vector3d got(s["CNDT_Orientation.Roll"], s["CNDT_Orientation.Pitch"],
                              s["CNDT_Orientation.Yaw"]);
    for (int a = 0; a < 3; ++a) {
      worst_ang = std::max(worst_ang, std::abs(std::remainder(got[a] - want[a], 2 * M_PI)));
    }
    EXPECT_GE(s["CNDT_Status.Cm"], 0.0);
    EXPECT_LE(s["CNDT_Status.Cm"], 1.0);
    EXPECT_LE(s["CNDT_Status.Status"], 2.0);
  }
  EXPECT_LE(worst_pos, 0.0005 + 1e-6);
  EXPECT_LE(worst_ang, 0.5e-4 + 1e-8);
  RecordProperty("worst_position_error_m", std::to_string(worst_pos));
  RecordProperty("worst_angle_error_rad", std::to_string(worst_ang));

  // cndt listen reads the same log cleanly, and refuses a corrupted copy naming the line.
  r = run("listen --candump " + out + "/can.log --out " + dir_->file("decoded.csv"));
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find(std::to_string(traj.size()) + " poses"), std::string::npos) << r.output;
  r = run("listen --candump " + out + "/can.log --dbc " + CNDT_SOURCE_DIR +
          "/config/cndt.dbc --out " + dir_->file("decoded_dbc.csv"));
  EXPECT_EQ(r.code, 0) << r.output;
  std::ifstream log(out + "/can.log");
  std::ofstream bad(dir_->file("bad.log"));
  int n = 0;
  for (std::string line; std::getline(log, line);) {
    if (++n == 13) line[line.size() - 3] = line[line.size() - 3] == '0' ? '1' : '0';
    bad << line << "\n";
  }
  bad.close();
  r = run("listen --candump " + dir_->file("bad.log"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("bad.log:13: frame 302 rejected: CRC mismatch"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("1 incomplete poses"), std::string::npos) << r.output;
}

TEST_F(PoseOutput, EveryPoseArrivesAsAUdpDatagram) {
  auto rx = cndt::net::UdpReceiver::open("127.0.0.1", 0);
  ASSERT_TRUE(rx) << rx.error().message;
  const std::string out = dir_->file("rep_udp");
  const auto r = run("replay " + dir_->file("sim/capture.pcap") + " --out " + out +
                     " --udp-out 127.0.0.1:" + std::to_string(rx.value()->port()));
  ASSERT_EQ(r.code, 0) << r.output;
  const auto traj = read_tum(out + "/trajectory.tum");
  std::array<std::uint8_t, 256> buf{};
  std::size_t i = 0;
  while (auto n = rx.value()->receive(buf, std::chrono::milliseconds(500))) {
    const auto d = cndt::output::decode_pose_datagram(cndt::core::ByteSpan(buf).first(*n));
    ASSERT_EQ(d.error, cndt::output::DatagramError::kNone);
    EXPECT_EQ(d.sequence, i);
    ASSERT_LT(i, traj.size());
    EXPECT_NEAR(static_cast<double>(d.pose.stamp_ns) * 1e-9, traj[i].t, 1e-6);
    EXPECT_LT((d.pose.position - traj[i].p).norm(), 2e-6);
    EXPECT_LT(d.pose.orientation.angularDistance(traj[i].q), 1e-6);
    ++i;
  }
  EXPECT_EQ(i, traj.size());
}

// The arrival time is the kernel's, taken when the datagram came in, not when the receiving
// thread got to it: a datagram read 200 ms after it was sent still carries its sending time.
// A datagram longer than the buffer comes truncated to it.
TEST(UdpReceiver, GivesTheTimeTheKernelTookTheDatagramIn) {
  auto rx = cndt::net::UdpReceiver::open("127.0.0.1", 0);
  ASSERT_TRUE(rx) << rx.error().message;
  auto tx = cndt::net::UdpSender::open("127.0.0.1", rx.value()->port());
  ASSERT_TRUE(tx) << tx.error().message;
  const std::array<std::uint8_t, 5> payload{1, 2, 3, 4, 5};
  // The kernel turns its receive stamping on a moment after the first socket asks for it (a
  // deferred switch); until then a datagram is stamped when it is read. So the datagram is sent
  // again, up to three times, until one is stamped on arrival, 200 ms before it is read.
  bool on_arrival = false;
  for (int attempt = 0; attempt < 3 && !on_arrival; ++attempt) {
    const auto before = std::chrono::system_clock::now();
    ASSERT_TRUE(tx.value()->send(cndt::core::ByteSpan(payload)));
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    std::array<std::uint8_t, 16> buf{};
    std::chrono::system_clock::time_point arrival{};
    const auto n = rx.value()->receive(buf, std::chrono::milliseconds(1000), &arrival);
    const auto after = std::chrono::system_clock::now();
    ASSERT_TRUE(n);
    EXPECT_EQ(*n, payload.size());
    EXPECT_TRUE(std::equal(payload.begin(), payload.end(), buf.begin()));
    EXPECT_GE(arrival, before - std::chrono::milliseconds(5));  // the clock's own resolution
    EXPECT_LE(arrival, after);
    on_arrival = arrival < before + std::chrono::milliseconds(100) &&
                 after - arrival >= std::chrono::milliseconds(150);
  }
  EXPECT_TRUE(on_arrival);

  ASSERT_TRUE(tx.value()->send(cndt::core::ByteSpan(payload)));
  std::array<std::uint8_t, 3> small{};
  const auto m = rx.value()->receive(small, std::chrono::milliseconds(1000));
  ASSERT_TRUE(m);
  EXPECT_EQ(*m, small.size());
  EXPECT_EQ(small[2], 3);
  EXPECT_FALSE(rx.value()->receive(small, std::chrono::milliseconds(20)));  // nothing left
}

TEST_F(PoseOutput, ListenRejectsCorruptDatagramsAndCountsGaps) {
  std::uint16_t port = 0;
  {
    auto probe = cndt::net::UdpReceiver::open("127.0.0.1", 0);
    ASSERT_TRUE(probe);
    port = probe.value()->port();
  }
  cndt::test::CliRun listened;
  std::thread listener([&] {
    listened = run("listen --udp " + std::to_string(port) +
                   " --bind 127.0.0.1 --count 4 --timeout 10 --out " + dir_->file("udp.csv"));
  });
  auto tx = cndt::net::UdpSender::open("127.0.0.1", port);
  ASSERT_TRUE(tx);
  cndt::output::PoseMessage m;
  m.status = cndt::output::PoseStatus::kValid;
  m.stamp_ns = 1'767'225'600'000'000'000;
  // Resend until the listener is up (it binds after start-up), then the sequence 1, 2, 5 and
  // a corrupted datagram.
  for (int attempt = 0; attempt < 50; ++attempt) {
    std::ifstream probe(dir_->file("udp.csv"));
    if (probe.good()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  for (std::uint32_t seq : {1u, 2u, 5u}) {
    m.position.x() = seq;
    const auto d = cndt::output::encode_pose_datagram(m, seq);
    tx.value()->send(d);
  }
  auto bad = cndt::output::encode_pose_datagram(m, 6);
  bad[30] ^= 0x01;
  tx.value()->send(bad);
  listener.join();
  EXPECT_EQ(listened.code, 65) << listened.output;
  EXPECT_NE(listened.output.find("CRC mismatch"), std::string::npos) << listened.output;
  EXPECT_NE(listened.output.find("3 datagrams decoded, 1 rejected, 1 sequence gaps (2 datagrams "
                                 "missing)"),
            std::string::npos)
      << listened.output;
  std::ifstream csv(dir_->file("udp.csv"));
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 4);  // header + 3 poses
}

}  // namespace

namespace {

// Two replays through the threaded runtime, with the mapper: the same bytes.
TEST_F(PoseOutput, ReplaysAreByteIdentical) {
  for (const char* name : {"det1", "det2"}) {
    const auto r =
        run("replay " + dir_->file("sim/capture.pcap") + " --mapper --out " + dir_->file(name));
    ASSERT_EQ(r.code, 0) << r.output;
  }
  for (const char* f : {"trajectory.tum", "odometry.tum", "refined.tum", "can.log"}) {
    const std::string a = slurp(dir_->file(std::string("det1/") + f));
    EXPECT_FALSE(a.empty()) << f;
    EXPECT_EQ(a, slurp(dir_->file(std::string("det2/") + f))) << f;
  }
}

}  // namespace
