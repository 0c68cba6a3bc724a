#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "cndt/cli/cloud_io.hpp"
#include "cndt/cli/commands.hpp"

namespace cndt::cli {
namespace {

struct DecodeContext {
  std::filesystem::path dir;
  CloudFormat format;
  bool complete_only;
  std::ofstream times;
  std::uint64_t written = 0;
  std::optional<core::Error> error;
};

std::string flag_names(std::uint32_t f) {
  if (f == 0) return "complete";
  std::string s;
  auto add = [&](std::uint32_t bit, const char* name) {
    if ((f & bit) != 0) s += s.empty() ? name : fmt::format("|{}", name);
  };
  add(core::kScanPartial, "partial");
  add(core::kScanPacketLoss, "packet_loss");
  add(core::kScanOverflow, "overflow");
  add(core::kScanTimeJump, "time_jump");
  add(core::kScanGapCut, "gap_cut");
  add(core::kScanEndOfStream, "end_of_stream");
  return s;
}

void write_scan(const core::Scan& scan, void* ctx) {
  auto& c = *static_cast<DecodeContext*>(ctx);
  if (c.error || (c.complete_only && !scan.complete())) return;
  const std::string name = fmt::format("{:06d}{}", c.written, cloud_extension(c.format));
  if (auto err = write_cloud((c.dir / name).string(), scan, c.format)) {
    c.error = err;
    return;
  }
  c.times << fmt::format("{} {:.9f} {:.9f} {} {} {} {}\n", name,
                         static_cast<double>(scan.stamp.count()) * 1e-9,
                         static_cast<double>(scan.end.count()) * 1e-9, scan.points.size(),
                         scan.packets, scan.lost_packets, flag_names(scan.flags));
  ++c.written;
}

}  // namespace

void register_decode(CLI::App& app, DecodeArgs& args) {
  auto* cmd = app.add_subcommand(
      "decode",
      "Write every scan of a capture as a point-cloud file, plus times.txt (file, "
      "stamp and end of the scan in seconds, points, packets, lost packets, flags)");
  cmd->add_option("capture", args.capture, "pcap or pcapng file")->required();
  cmd->add_option("--out", args.out_dir, "Output folder (created if missing)")->required();
  cmd->add_option("--format", args.format,
                  "bin (KITTI float32 x y z intensity), pcd or ply (binary, with per-point time "
                  "t in seconds after the scan stamp, ring and return type)")
      ->capture_default_str()
      ->check(CLI::IsMember({"bin", "pcd", "ply"}));
  cmd->add_flag("--complete-only", args.complete_only,
                "Skip scans flagged partial, lossy, cut by a gap or overflowing");
  add_capture_options(*cmd, args.capture_args);
}

int run_decode(const DecodeArgs& args) {
  auto options = to_capture_options(args.capture_args);
  if (!options) return fail(options.error());
  DecodeContext ctx;
  ctx.dir = args.out_dir;
  ctx.format = parse_cloud_format(args.format).value_or(CloudFormat::kBin);
  ctx.complete_only = args.complete_only;
  if (auto err = create_output_dir(args.out_dir)) return fail(*err);
  ctx.times.open(ctx.dir / "times.txt", std::ios::trunc);
  if (!ctx.times) {
    spdlog::error("cannot create '{}': {}", (ctx.dir / "times.txt").string(), std::strerror(errno));
    return core::kExitIoError;
  }
  ctx.times << "# file stamp_s end_s points packets lost_packets flags\n";
  auto report = read_capture(args.capture, options.value(), write_scan, &ctx);
  if (!report) return fail(report.error());
  ctx.times.close();
  if (ctx.error) return fail(*ctx.error);
  if (!ctx.times) {
    spdlog::error("writing '{}' failed", (ctx.dir / "times.txt").string());
    return core::kExitIoError;
  }
  const auto& r = report.value();
  if (r.pcap.truncated) {
    spdlog::warn("'{}' ends in the middle of record {}; everything before it was decoded", r.path,
                 r.pcap.truncated->index);
  }
  if (ctx.written == 0) {
    spdlog::error("no scan decoded from '{}' ({} data packets, {} rejected)", args.capture,
                  r.driver.data_packets, r.driver.rejected_total());
    return core::kExitDataError;
  }
  spdlog::info("wrote {} scans to '{}' ({} data packets, {} rejected, {} lost)", ctx.written,
               args.out_dir, r.driver.data_packets, r.driver.rejected_total(),
               r.assembler.lost_packets);
  return core::kExitOk;
}

}  // namespace cndt::cli
