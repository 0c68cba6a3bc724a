// The real cndtd binary as systemd runs it: a temporary config, VLP-16 packets over loopback UDP
// at the sensor's rate, a fake NOTIFY_SOCKET. READY=1 and WATCHDOG=1 arrive, every scan's pose
// arrives as a UDP datagram and in the candump log, and SIGTERM gives exit 0 and a map file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <regex>
#include <thread>

#include "cli_run.hpp"
#include "cndt/can/can_bus.hpp"
#include "cndt/net/udp_datagram.hpp"
#include "cndt/output/can_codec.hpp"
#include "cndt/output/udp_codec.hpp"
#include "cndt/sim/lidar_sim.hpp"
#include "cndt/slam/map_file.hpp"
#include "slurp.hpp"
#include "temp_dir.hpp"

extern char** environ;

namespace {

std::uint16_t free_udp_port() {
  auto probe = cndt::net::UdpReceiver::open("127.0.0.1", 0);
  return probe ? probe.value()->port() : 0;
}

// The notification socket systemd would listen on.
class NotifySocket {
 public:
  explicit NotifySocket(const std::string& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
    ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  ~NotifySocket() {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;
  // Everything received so far (non-blocking).
  void drain(std::vector<std::string>& out) const {
    char buf[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
      if (n <= 0) break;
      out.emplace_back(buf, static_cast<std::size_t>(n));
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
};

bool any_contains(const std::vector<std::string>& v, const std::string& s) {
  for (const auto& m : v) {
    if (m.find(s) != std::string::npos) return true;
  }
  return false;
}

TEST(Daemon, RunsAsSystemdServiceFedOverUdp) {
  cndt::test::TempDir dir;
  const std::uint16_t data_port = free_udp_port();
  auto rx = cndt::net::UdpReceiver::open("127.0.0.1", 0);
  ASSERT_TRUE(rx);
  const std::string map = dir.file("map.cndtmap"), can_log = dir.file("can.log");
  {
    std::ofstream cfg(dir.file("cndtd.toml"));
    cfg << "[sensor]\nsource = \"udp\"\nbind_address = \"127.0.0.1\"\ndata_port = " << data_port
        << "\nposition_port = 0\n[mapper]\nenabled = true\nsave = \"" << map
        << "\"\n[can]\nlog = \"" << can_log
        << "\"\n[udp]\ndestinations = [\"127.0.0.1:" << rx.value()->port()
        << "\"]\n[runtime]\nstatus_interval_s = 1.0\n"
        // The whole input fits in the scan ring: on a busy machine (tests run side by side) the
        // odometry may fall behind the sensor for a while without dropping scans.
        << "scan_ring = 64\n";
  }
  NotifySocket notify(dir.file("notify"));
  std::vector<std::string> env{"NOTIFY_SOCKET=" + dir.file("notify"), "WATCHDOG_USEC=1000000"};
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::strncmp(*e, "NOTIFY_SOCKET=", 14) != 0 && std::strncmp(*e, "WATCHDOG_", 9) != 0) {
      env.emplace_back(*e);
    }
  }
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  const std::string bin = CNDTD_BINARY, cfg_path = dir.file("cndtd.toml"),
                    log_path = dir.file("cndtd.log");
  std::vector<std::string> args{bin, "--config", cfg_path};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 2, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, bin.c_str(), &fa, nullptr, argv.data(), envp.data()), 0);
  posix_spawn_file_actions_destroy(&fa);

  // A simulated street, sent at the sensor's rate (one packet every 1327 us) once the daemon
  // listens. It says so in its log right after binding the socket (what arrives before its
  // receiver thread runs waits in the socket buffer). A fixed wait is not enough: on a busy
  // machine start-up took longer than 1.5 s, and the first 6 scans went to a closed port.
  const auto scene = cndt::sim::build_scene(cndt::sim::SceneKind::kStreet, 6.0, 4, 1);
  cndt::sim::LidarSimOptions so;
  so.duration_s = 6.0;
  cndt::sim::LidarSimulator simulator(scene, so);
  std::vector<std::array<std::uint8_t, 1206>> packets;
  cndt::sim::SimPacket p;
  while (simulator.next(p)) packets.push_back(p.payload);
  const auto listening = [&] {
    return cndt::test::slurp(log_path).find("receiving VLP-16 packets on UDP") != std::string::npos;
  };
  const auto spawned = std::chrono::steady_clock::now();
  while (!listening() && std::chrono::steady_clock::now() - spawned < std::chrono::seconds(60)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (!listening()) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    FAIL() << "cndtd did not listen on UDP within 60 s";
  }
  auto tx = cndt::net::UdpSender::open("127.0.0.1", data_port);
  ASSERT_TRUE(tx);
  std::vector<std::string> messages;  // read as systemd would, while the daemon runs
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < packets.size(); ++k) {
    std::this_thread::sleep_until(start + std::chrono::nanoseconds(1'327'104 * k));
    tx.value()->send(packets[k]);
    if (k % 64 == 0) notify.drain(messages);
  }
  // Poses as they arrive, until none has come for 2 s (the scans in the ring are through).
  std::array<std::uint8_t, 256> buf{};
  std::size_t datagrams = 0;
  const auto take = [&](std::chrono::milliseconds wait) {
    while (auto n = rx.value()->receive(buf, wait)) {
      const auto d = cndt::output::decode_pose_datagram(cndt::core::ByteSpan(buf).first(*n));
      EXPECT_EQ(d.error, cndt::output::DatagramError::kNone);
      EXPECT_EQ(d.sequence, datagrams);
      ++datagrams;
    }
  };
  const auto sent = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - sent < std::chrono::seconds(60)) {
    take(std::chrono::milliseconds(2000));
    if (datagrams >= 57) break;
  }
  ASSERT_EQ(::kill(pid, SIGTERM), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  const std::string log = cndt::test::slurp(log_path);
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 0) << log;

  notify.drain(messages);
  EXPECT_TRUE(any_contains(messages, "READY=1")) << log;
  EXPECT_TRUE(any_contains(messages, "WATCHDOG=1")) << log;
  EXPECT_TRUE(any_contains(messages, "STATUS=")) << log;

  // The daemon's own count of published poses, from its final health line.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      log, m,
      std::regex(
          R"(final: (\d+) scans \(\+\d+\), (\d+) dropped.*poses (\d+) valid, (\d+) degraded, (\d+) lost)")))
      << log;
  const std::size_t scans = std::stoul(m[1]), dropped = std::stoul(m[2]);
  const std::size_t published = std::stoul(m[3]) + std::stoul(m[4]) + std::stoul(m[5]);
  EXPECT_EQ(dropped, 0u) << log;
  RecordProperty("poses_published", std::to_string(published));
  // 6 s at 10 Hz: 60 revolutions; the first (partial) is skipped, the last is still open.
  EXPECT_GE(published, 57u) << log;
  EXPECT_EQ(scans, published + 1) << log;
  EXPECT_NE(log.find("heap allocations in odometry 0"), std::string::npos) << log;

  take(std::chrono::milliseconds(200));
  EXPECT_EQ(datagrams, published);

  cndt::output::CanPoseDecoder decoder;
  std::ifstream can_in(can_log);
  for (std::string line; std::getline(can_in, line);) {
    auto rec = cndt::can::parse_candump_line(line);
    ASSERT_TRUE(rec && rec.value()) << line;
    decoder.feed(rec.value()->frame);
  }
  EXPECT_EQ(decoder.stats().poses, published);
  EXPECT_EQ(decoder.stats().bad_crc + decoder.stats().counter_gaps, 0u);

  auto loaded = cndt::slam::load_map_file(map, cndt::slam::MapOptions{});
  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_GT(loaded.value().size(), 1000u);
}

TEST(Daemon, CheckReportsEveryConfigProblemWithItsLine) {
  cndt::test::TempDir dir;
  std::ofstream(dir.file("bad.toml")) << "[sensor]\n"
                                         "data_port = 2368\n"
                                         "colour = \"red\"\n"
                                         "[odometry]\n"
                                         "eta = \"0.7\"\n"
                                         "voxel_size_m = -1.0\n";
  const auto r = cndt::test::run_command(std::string(CNDTD_BINARY) + " --check --config " +
                                         dir.file("bad.toml"));
  EXPECT_EQ(r.code, 78) << r.output;
  EXPECT_NE(r.output.find("bad.toml:3:1: sensor.colour: unknown key"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("bad.toml:5:7: odometry.eta: expected a number, got a string"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("bad.toml:6:16: odometry.voxel_size_m: -1 is out of range"),
            std::string::npos)
      << r.output;
  std::ofstream(dir.file("good.toml")) << "[odometry]\neta = 0.75\n";
  const auto ok = cndt::test::run_command(std::string(CNDTD_BINARY) + " --check --config " +
                                          dir.file("good.toml"));
  EXPECT_EQ(ok.code, 0) << ok.output;
  const auto shipped = cndt::test::run_command(std::string(CNDTD_BINARY) + " --check --config " +
                                               CNDT_SOURCE_DIR + "/config/cndtd.toml");
  EXPECT_EQ(shipped.code, 0) << shipped.output;
}

}  // namespace

namespace {

TEST(Daemon, ServiceUnitExposureIsAtMostTwo) {
  if (std::system("command -v systemd-analyze >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "systemd-analyze is not installed: the unit's exposure is not measured here";
  }
  const auto r = cndt::test::run_command("systemd-analyze security --offline=true " +
                                         std::string(CNDT_SOURCE_DIR) + "/systemd/cndtd.service");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.output, m, std::regex(R"(Overall exposure level for cndtd\.service: ([0-9.]+))")))
      << r.output;
  const double exposure = std::stod(m[1]);
  RecordProperty("exposure", m[1].str());
  EXPECT_LE(exposure, 2.0) << r.output;
  // What the unit promises beyond the score.
  const std::string text =
      cndt::test::slurp(std::string(CNDT_SOURCE_DIR) + "/systemd/cndtd.service");
  for (const char* line :
       {"Type=notify", "WatchdogSec=", "Restart=on-failure", "DynamicUser=yes",
        "StateDirectory=cndtd", "ProtectSystem=strict",
        "RestrictAddressFamilies=AF_INET AF_INET6 AF_CAN AF_UNIX", "LimitMEMLOCK="}) {
    EXPECT_NE(text.find(line), std::string::npos) << line;
  }
}

}  // namespace
