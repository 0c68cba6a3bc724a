// cndt listen: decodes what cndt publishes (UDP datagrams, or CAN frames from a candump log) and
// checks CRCs, sequence numbers and rolling counters, for integrators and tests.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "cndt/can/can_bus.hpp"
#include "cndt/cli/commands.hpp"
#include "cndt/net/udp_datagram.hpp"
#include "cndt/output/can_codec.hpp"
#include "cndt/output/dbc.hpp"
#include "cndt/output/udp_codec.hpp"

namespace cndt::cli {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int /*sig*/) { g_stop = true; }

constexpr const char* kPoseHeader = "time,scan,x,y,z,qx,qy,qz,qw,cm,status,flags";

std::string pose_columns(const output::PoseMessage& m) {
  const Eigen::Quaterniond q = m.orientation.normalized();
  return fmt::format("{}.{:09d},{},{:.4f},{:.4f},{:.4f},{:.6f},{:.6f},{:.6f},{:.6f},{:.4f},{},{}",
                     m.stamp_ns / 1'000'000'000, m.stamp_ns % 1'000'000'000, m.scan_sequence,
                     m.position.x(), m.position.y(), m.position.z(), q.x(), q.y(), q.z(), q.w(),
                     m.cm, output::to_string(m.status), m.flags);
}

int listen_udp(const ListenArgs& a, std::ostream& out) {
  auto rx = net::UdpReceiver::open(a.bind_address, a.udp_port);
  if (!rx) return fail(rx.error());
  spdlog::info("listening for cndt pose datagrams on UDP {}:{}", a.bind_address,
               rx.value()->port());
  g_stop = false;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  out << "sequence," << kPoseHeader << "\n";
  std::array<std::uint8_t, 2048> buf{};
  std::uint64_t good = 0, bad = 0, gaps = 0, lost = 0;
  std::optional<std::uint32_t> last;
  auto idle_since = std::chrono::steady_clock::now();
  while (!g_stop && (a.count == 0 || good + bad < a.count)) {
    const auto n = rx.value()->receive(buf, std::chrono::milliseconds(200));
    if (!n) {
      if (a.timeout_s > 0 &&
          std::chrono::duration<double>(std::chrono::steady_clock::now() - idle_since).count() >=
              a.timeout_s) {
        spdlog::info("no datagram for {} s: stopping", a.timeout_s);
        break;
      }
      continue;
    }
    idle_since = std::chrono::steady_clock::now();
    const auto d = output::decode_pose_datagram(core::ByteSpan(buf).first(*n));
    if (d.error != output::DatagramError::kNone) {
      ++bad;
      spdlog::warn("datagram {} rejected: {} ({} bytes)", good + bad, output::to_string(d.error),
                   *n);
      continue;
    }
    ++good;
    if (last && d.sequence != *last + 1) {
      ++gaps;
      lost += static_cast<std::uint32_t>(d.sequence - *last - 1);
    }
    last = d.sequence;
    out << d.sequence << "," << pose_columns(d.pose) << "\n";
    out.flush();
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  spdlog::info("{} datagrams decoded, {} rejected, {} sequence gaps ({} datagrams missing)", good,
               bad, gaps, lost);
  return bad > 0 ? core::kExitDataError : core::kExitOk;
}

// One CAN frame decoded by the DBC: "time,MESSAGE,Signal=value unit,...".
std::string dbc_columns(const output::DbcMessage& m, const output::CanFrame& f) {
  std::string line = m.name;
  int mux = -1;
  for (const auto& s : m.signals) {
    if (s.is_multiplexer) mux = static_cast<int>(s.raw(f.data));
  }
  for (const auto& s : m.signals) {
    if (s.multiplexed_by >= 0 && s.multiplexed_by != mux) continue;
    const double v = s.physical(f.data);
    line += fmt::format(",{}={:.10g}", s.name, v);
    if (const auto it = s.values.find(s.raw(f.data)); it != s.values.end()) {
      line += fmt::format(" ({})", it->second);
    } else if (!s.unit.empty()) {
      line += " " + s.unit;
    }
  }
  return line;
}

int listen_candump(const ListenArgs& a, std::ostream& out) {
  std::ifstream in(a.candump);
  if (!in) {
    return fail({core::kExitNoInput, fmt::format("cannot open candump log '{}'", a.candump)});
  }
  std::optional<output::DbcDatabase> db;
  if (!a.dbc.empty()) {
    auto loaded = output::load_dbc(a.dbc);
    if (!loaded) return fail(loaded.error());
    db = std::move(loaded.value());
  }
  output::CanPoseDecoder decoder(a.base_id);
  out << (db ? "time,message,signals..." : kPoseHeader) << "\n";
  std::uint64_t frames = 0, malformed = 0, foreign = 0;
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n) {
    auto rec = can::parse_candump_line(line);
    if (!rec) {
      ++malformed;
      spdlog::warn("{}:{}: {}", a.candump, n, rec.error().message);
      continue;
    }
    if (!rec.value()) continue;
    const can::CandumpRecord& r = *rec.value();
    ++frames;
    const auto before = decoder.stats();
    const auto pose = decoder.feed(r.frame);
    const auto& after = decoder.stats();
    if (after.bad_crc > before.bad_crc || after.bad_length > before.bad_length) {
      spdlog::warn("{}:{}: frame {:03X} rejected: {}", a.candump, n, r.frame.id,
                   after.bad_crc > before.bad_crc ? "CRC mismatch" : "not 8 bytes");
      continue;
    }
    if (after.counter_gaps > before.counter_gaps) {
      spdlog::warn("{}:{}: frame {:03X}: rolling counter skipped (frames lost)", a.candump, n,
                   r.frame.id);
    }
    if (db) {
      const output::DbcMessage* m = db->message(r.frame.id, r.frame.extended);
      if (m == nullptr) {
        ++foreign;
        continue;
      }
      const long long ns = r.stamp.count();
      out << fmt::format("{}.{:06d},", ns / 1'000'000'000, (ns % 1'000'000'000) / 1000)
          << dbc_columns(*m, r.frame) << "\n";
    } else if (pose) {
      out << pose_columns(*pose) << "\n";
    } else if (r.frame.id < a.base_id || r.frame.id >= a.base_id + output::kCanFramesPerPose) {
      ++foreign;
    }
  }
  decoder.finish();
  const auto& s = decoder.stats();
  if (frames > 0 && s.frames == 0) {
    spdlog::warn("no frame has the pose ids {:#x}..{:#x}: is --base-id right?", a.base_id,
                 a.base_id + output::kCanFramesPerPose - 1);
  }
  spdlog::info(
      "{} frames ({} of other ids): {} poses; rejected: {} CRC, {} length, {} malformed lines; "
      "rolling counter: {} gaps, {} repeats; {} incomplete poses",
      frames, foreign, s.poses, s.bad_crc, s.bad_length, malformed, s.counter_gaps,
      s.counter_repeats, s.incomplete_poses);
  return s.bad_crc + s.bad_length + malformed > 0 ? core::kExitDataError : core::kExitOk;
}

}  // namespace

void register_listen(CLI::App& app, ListenArgs& a) {
  auto* cmd = app.add_subcommand(
      "listen",
      "Decode what cndt publishes: pose datagrams on a UDP port, or CAN frames in a candump "
      "log. Prints one CSV line per pose (with --dbc: per frame, every signal as the DBC "
      "describes it). CRCs, datagram sequence numbers and CAN rolling counters are checked; "
      "rejected input is reported on stderr and makes the exit code 65");
  auto* udp = cmd->add_option("--udp", a.udp_port, "UDP port to receive pose datagrams on");
  auto* candump = cmd->add_option("--candump", a.candump, "candump log file to decode");
  udp->excludes(candump);
  cmd->add_option("--bind", a.bind_address, "With --udp: local address to bind")
      ->capture_default_str()
      ->needs(udp);
  cmd->add_option("--count", a.count, "With --udp: stop after this many datagrams (0: no limit)")
      ->needs(udp);
  cmd->add_option("--timeout", a.timeout_s,
                  "With --udp: stop after this many seconds without a datagram (0: never; "
                  "Ctrl-C stops too)")
      ->check(CLI::Range(0.0, 1e6))
      ->needs(udp);
  cmd->add_option("--dbc", a.dbc,
                  "With --candump: decode the frames with this DBC file (e.g. config/cndt.dbc) "
                  "instead of the built-in layout")
      ->needs(candump);
  cmd->add_option("--base-id", a.base_id,
                  "With --candump: CAN id of the first of the five pose frames (default 0x300)")
      ->needs(candump);
  cmd->add_option("--out", a.out, "Write the decoded lines to this file instead of stdout");
}

int run_listen(const ListenArgs& a) {
  if (a.udp_port == 0 && a.candump.empty()) {
    return fail({core::kExitUsage, "listen: give --udp PORT or --candump FILE"});
  }
  std::ofstream file;
  if (!a.out.empty()) {
    file.open(a.out, std::ios::trunc);
    if (!file) return fail({core::kExitIoError, fmt::format("cannot write '{}'", a.out)});
  }
  std::ostream& out = a.out.empty() ? std::cout : file;
  return a.candump.empty() ? listen_udp(a, out) : listen_candump(a, out);
}

}  // namespace cndt::cli
