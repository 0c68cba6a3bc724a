#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>

#include "cndt/cli/commands.hpp"
#include "cndt/net/udp_source.hpp"
#include "cndt/pcap/pcap_writer.hpp"

namespace cndt::cli {
namespace {
std::atomic<bool> g_stop{false};
extern "C" void on_signal(int /*sig*/) { g_stop.store(true); }
}  // namespace

void register_record(CLI::App& app, RecordArgs& a) {
  auto* cmd = app.add_subcommand(
      "record",
      "Capture what the live UDP receiver gets (data and position packets) into a "
      "pcap file, with the real source addresses and receive times. Stops on Ctrl-C, "
      "after --duration seconds or after --packets packets.");
  cmd->add_option("--out", a.out, "pcap file to write")->required();
  cmd->add_option("--bind", a.bind_address, "Local address to listen on")->capture_default_str();
  cmd->add_option("--data-port", a.data_port, "UDP port of data packets")->capture_default_str();
  cmd->add_option("--position-port", a.position_port,
                  "UDP port of position packets (0: do not listen)")
      ->capture_default_str();
  cmd->add_option("--sensor-ip", a.sensor_ip, "Record only packets from this address");
  cmd->add_option("--duration", a.duration_s, "Stop after this many seconds (0: no limit)")
      ->capture_default_str();
  cmd->add_option("--packets", a.max_packets, "Stop after this many packets (0: no limit)")
      ->capture_default_str();
}

int run_record(const RecordArgs& a) {
  net::UdpOptions o;
  o.bind_address = a.bind_address;
  o.data_port = a.data_port;
  o.position_port = a.position_port;
  if (!a.sensor_ip.empty()) {
    o.sensor_ip = io::IpAddress::parse(a.sensor_ip);
    if (!o.sensor_ip) {
      spdlog::error("--sensor-ip: '{}' is not an IPv4 or IPv6 address", a.sensor_ip);
      return core::kExitUsage;
    }
  }
  auto writer = pcap::PcapWriter::create(a.out, true);
  if (!writer) return fail(writer.error());
  auto source = net::UdpSource::open(o);
  if (!source) return fail(source.error());
  g_stop.store(false);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  spdlog::info("recording UDP {}:{} (position {}) into '{}'", a.bind_address,
               source.value()->data_port(), source.value()->position_port(), a.out);
  const auto start = std::chrono::steady_clock::now();
  io::SourcePacket p;
  std::uint64_t written = 0;
  while (!g_stop.load()) {
    if (a.duration_s > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >=
            a.duration_s) {
      break;
    }
    if (a.max_packets > 0 && written >= a.max_packets) break;
    if (source.value()->next(p, std::chrono::milliseconds(100)) != io::NextResult::kPacket) {
      continue;
    }
    pcap::UdpEndpoints ep;
    ep.source = p.source;
    ep.destination = p.source.version == 6 ? *io::IpAddress::parse("ff02::1")
                                           : io::IpAddress::v4(255, 255, 255, 255);
    ep.source_port = p.source_port;
    ep.dest_port = p.dest_port;
    writer.value()->write_udp(p.time, ep, p.payload);
    ++written;
  }
  source.value()->stop();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const auto err = writer.value()->close();
  const net::UdpStats s = source.value()->stats();
  spdlog::info(
      "wrote {} packets to '{}' (received {}, wrong source {}, oversize {}, dropped "
      "for a full queue {}, receive errors {})",
      written, a.out, s.received, s.wrong_source, s.oversize, s.queue_full, s.receive_errors);
  if (err) {
    spdlog::error("{}", err->message);
    return err->code;
  }
  return core::kExitOk;
}

}  // namespace cndt::cli
