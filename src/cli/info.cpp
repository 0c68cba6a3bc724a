#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <iostream>

#include "cndt/cli/commands.hpp"

namespace cndt::cli {
namespace {

struct PointStats {
  std::size_t min = 0, median = 0, max = 0;
};

PointStats points_per_scan(const CaptureReport& r, bool complete_only) {
  std::vector<std::size_t> n;
  for (const auto& s : r.scans) {
    if (!complete_only || (s.flags == 0)) n.push_back(s.points);
  }
  if (n.empty()) return {};
  std::sort(n.begin(), n.end());
  return {n.front(), n[n.size() / 2], n.back()};
}

std::string model_line(const CaptureReport& r) {
  const auto& d = r.driver;
  if (!d.product_id) {
    if (d.rejected[static_cast<std::size_t>(vlp16::PacketError::kUnsupportedModel)] > 0) {
      return "unsupported: packets use HDL-64E/VLS-128 block banks or an unknown product id; "
             "cndt decodes VLP-16, VLP-16 Hi-Res, HDL-32E and VLP-32C";
    }
    return "unknown (no valid data packet)";
  }
  std::string s = r.model ? std::string(vlp16::model_name(*r.model)) : "undecided";
  s += fmt::format(" (product byte 0x{:02X} = {}", *d.product_id,
                   vlp16::product_id_name(*d.product_id));
  if (d.model_mismatch) s += ", differs from the configured model";
  if (d.legacy_factory_packets > 0) s += ", firmware without factory bytes";
  return s + ")";
}

double span_s(const std::optional<std::chrono::nanoseconds>& a,
              const std::optional<std::chrono::nanoseconds>& b) {
  if (!a || !b) return 0.0;
  return static_cast<double>((*b - *a).count()) * 1e-9;
}

std::string json_escape(std::string_view s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      o += fmt::format("\\u{:04x}", static_cast<int>(c));
    } else {
      o += c;
    }
  }
  return o;
}

}  // namespace

std::string format_info_text(const CaptureReport& r) {
  const auto& p = r.pcap;
  const auto& d = r.driver;
  const auto& a = r.assembler;
  std::string o;
  o += fmt::format("capture        {} ({}, {}, {} bytes)\n", r.path, r.pcapng ? "pcapng" : "pcap",
                   pcap::link_type_name(r.link_type), r.file_bytes);
  o += fmt::format("records        {} read, {} UDP, span {:.3f} s\n", p.records, p.udp,
                   span_s(p.first_time, p.last_time));
  std::string ports;
  for (const auto& [port, n] : p.udp_by_dest_port) ports += fmt::format(" {}:{}", port, n);
  o += fmt::format("udp by port   {}\n", ports.empty() ? " none" : ports);
  for (const auto& [why, n] : p.skipped) {
    o += fmt::format("skipped        {} {}\n", n, pcap::frame_result_name(why));
  }
  if (p.wrong_source > 0) o += fmt::format("wrong source   {}\n", p.wrong_source);
  if (p.truncated) {
    const auto& t = *p.truncated;
    o += fmt::format(
        "cut short      record {} ({} of {} bytes present{}): {}\n", t.index, t.present, t.declared,
        t.dest_port ? fmt::format(", UDP port {}", *t.dest_port) : std::string(), t.message);
  }
  o += fmt::format("model          {}\n", model_line(r));
  o += fmt::format("return mode    {}\n",
                   d.return_mode ? vlp16::return_mode_name(*d.return_mode) : "unknown");
  o += fmt::format("rotation       {:.0f} rpm ({:.2f} Hz)\n", d.rpm(), d.rpm() / 60.0);
  o += fmt::format("data packets   {} offered, {} decoded, {} rejected\n", d.data_packets,
                   d.decoded_packets, d.rejected_total());
  for (std::size_t i = 1; i < d.rejected.size(); ++i) {
    if (d.rejected[i] > 0) {
      o += fmt::format("  rejected     {} {}\n", d.rejected[i],
                       vlp16::packet_error_name(static_cast<vlp16::PacketError>(i)));
    }
  }
  const PointStats all = points_per_scan(r, false);
  o += fmt::format("scans          {} ({} complete, {} flagged partial/lossy/cut)\n", a.scans,
                   a.complete_scans, a.scans - a.complete_scans);
  o += fmt::format("points/scan    min {} median {} max {} (all scans)\n", all.min, all.median,
                   all.max);
  o += fmt::format(
      "losses         {} packets lost in {} gaps, {} clock jumps, {} repeated or "
      "out-of-order packets dropped, {} points over capacity\n",
      a.lost_packets, a.gaps, a.time_jumps, a.stale_packets, a.points_dropped);
  if (a.azimuth_jumps > 0) {
    o += fmt::format(
        "bad azimuths   {} jumps inside a packet that the next packet's clock refuted (scans "
        "flagged time_jump)\n",
        a.azimuth_jumps);
  }
  if (a.fov_gap.length > 0) {
    o += fmt::format(
        "field of view  silent from {:.1f} to {:.1f} deg every turn ({} silences, not counted as "
        "loss); cut at {:.1f} deg\n",
        a.fov_gap.start / 100.0, a.fov_gap.end() / 100.0, a.fov_silences, a.cut_azimuth / 100.0);
  } else {
    o += fmt::format("field of view  full turn; cut at {:.1f} deg\n", a.cut_azimuth / 100.0);
  }
  o += fmt::format("time           {:.3f} s of sensor time, {} hour rollovers\n",
                   span_s(d.first_packet_time, d.last_packet_time), d.hour_rollovers);
  o += fmt::format("position       {} packets ({} rejected, {} with NMEA)", d.position_packets,
                   d.position_rejected, d.position_with_nmea);
  if (d.last_position) {
    const auto& pos = *d.last_position;
    o += fmt::format(", PPS {}", vlp16::pps_state_name(pos.pps));
    if (pos.has_nmea) {
      o += fmt::format(", fix {}, checksum {}\n               last NMEA: {}",
                       pos.fix_valid ? "valid" : "invalid", pos.nmea_checksum_ok ? "ok" : "BAD",
                       pos.sentence());
    }
  }
  o += "\n";
  return o;
}

std::string format_info_json(const CaptureReport& r) {
  const auto& p = r.pcap;
  const auto& d = r.driver;
  const auto& a = r.assembler;
  std::string o = "{\n";
  auto kv = [&o](std::string_view k, const std::string& v, bool last = false) {
    o += fmt::format("  \"{}\": {}{}\n", k, v, last ? "" : ",");
  };
  auto str = [](std::string_view s) { return fmt::format("\"{}\"", json_escape(s)); };
  kv("path", str(r.path));
  kv("format", str(r.pcapng ? "pcapng" : "pcap"));
  kv("link_type", str(pcap::link_type_name(r.link_type)));
  kv("records", std::to_string(p.records));
  kv("udp", std::to_string(p.udp));
  std::string ports = "{";
  for (const auto& [port, n] : p.udp_by_dest_port) {
    ports += fmt::format("{}\"{}\": {}", ports.size() > 1 ? ", " : "", port, n);
  }
  kv("udp_by_dest_port", ports + "}");
  std::string skipped = "{";
  for (const auto& [why, n] : p.skipped) {
    skipped += fmt::format("{}\"{}\": {}", skipped.size() > 1 ? ", " : "",
                           pcap::frame_result_name(why), n);
  }
  kv("skipped_records", skipped + "}");
  kv("wrong_source", std::to_string(p.wrong_source));
  if (p.truncated) {
    kv("truncated_record",
       fmt::format("{{\"index\": {}, \"declared\": {}, \"present\": {}, \"dest_port\": {}}}",
                   p.truncated->index, p.truncated->declared, p.truncated->present,
                   p.truncated->dest_port ? std::to_string(*p.truncated->dest_port) : "null"));
  } else {
    kv("truncated_record", "null");
  }
  kv("model", r.model ? str(vlp16::model_name(*r.model)) : "null");
  kv("product_id", d.product_id ? std::to_string(*d.product_id) : "null");
  kv("return_mode", d.return_mode ? str(vlp16::return_mode_name(*d.return_mode)) : "null");
  kv("rpm", fmt::format("{:.1f}", d.rpm()));
  kv("data_packets", std::to_string(d.data_packets));
  kv("decoded_packets", std::to_string(d.decoded_packets));
  std::string rej = "{";
  for (std::size_t i = 1; i < d.rejected.size(); ++i) {
    rej += fmt::format("{}\"{}\": {}", i > 1 ? ", " : "",
                       vlp16::packet_error_name(static_cast<vlp16::PacketError>(i)), d.rejected[i]);
  }
  kv("rejected", rej + "}");
  kv("scans", std::to_string(a.scans));
  kv("complete_scans", std::to_string(a.complete_scans));
  const PointStats all = points_per_scan(r, false);
  kv("points_per_scan",
     fmt::format("{{\"min\": {}, \"median\": {}, \"max\": {}}}", all.min, all.median, all.max));
  kv("lost_packets", std::to_string(a.lost_packets));
  kv("gaps", std::to_string(a.gaps));
  kv("time_jumps", std::to_string(a.time_jumps));
  kv("stale_packets", std::to_string(a.stale_packets));
  if (a.fov_gap.length > 0) {
    kv("fov_gap", fmt::format("{{\"from_deg\": {:.2f}, \"to_deg\": {:.2f}, \"silences\": {}}}",
                              a.fov_gap.start / 100.0, a.fov_gap.end() / 100.0, a.fov_silences));
  } else {
    kv("fov_gap", "null");
  }
  kv("cut_deg", fmt::format("{:.2f}", a.cut_azimuth / 100.0));
  kv("azimuth_jumps", std::to_string(a.azimuth_jumps));
  kv("hour_rollovers", std::to_string(d.hour_rollovers));
  kv("duration_s", fmt::format("{:.6f}", span_s(d.first_packet_time, d.last_packet_time)));
  kv("position_packets", std::to_string(d.position_packets));
  kv("position_rejected", std::to_string(d.position_rejected));
  kv("pps", d.last_position ? str(vlp16::pps_state_name(d.last_position->pps)) : "null");
  kv("nmea",
     d.last_position && d.last_position->has_nmea ? str(d.last_position->sentence()) : "null",
     true);
  return o + "}\n";
}

void register_info(CLI::App& app, InfoArgs& args) {
  auto* cmd = app.add_subcommand(
      "info",
      "Tell what is in a capture: model, return mode, rpm, packets by port and by "
      "rejection reason, scans, points per scan, losses, duration, position/PPS state");
  cmd->add_option("capture", args.capture, "pcap or pcapng file")->required();
  cmd->add_flag("--json", args.json, "Print JSON instead of text");
  add_capture_options(*cmd, args.capture_args);
}

int run_info(const InfoArgs& args) {
  auto options = to_capture_options(args.capture_args);
  if (!options) return fail(options.error());
  auto report = read_capture(args.capture, options.value());
  if (!report) return fail(report.error());
  const CaptureReport& r = report.value();
  warn_if_cut_short(r);
  std::cout << (args.json ? format_info_json(r) : format_info_text(r));
  if (r.driver.data_packets == 0) {
    spdlog::error("'{}' holds no Velodyne data packets (UDP port {})", r.path,
                  args.capture_args.data_port);
    return core::kExitDataError;
  }
  return core::kExitOk;
}

}  // namespace cndt::cli
