#include "cndt/cli/capture.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <optional>

#include "cndt/cli/cloud_io.hpp"

namespace cndt::cli {

core::Result<CaptureReport> read_capture(const std::string& path, const CaptureOptions& options,
                                         ScanVisitor visit, void* context) {
  auto opened = pcap::PcapSource::open(path, options.pcap);
  if (!opened) return opened.error();
  auto& source = *opened.value();
  CaptureReport report;
  report.path = path;
  report.pcapng = source.pcapng();
  report.link_type = source.link_type();
  std::error_code ec;
  report.file_bytes = std::filesystem::file_size(path, ec);

  vlp16::Driver driver(options.driver);
  auto sink = [&](core::Scan& scan) {
    report.scans.push_back(
        ScanSummary{scan.stamp, scan.end, scan.points.size(), scan.flags, scan.lost_packets});
    if (visit != nullptr) visit(scan, context);
  };
  io::SourcePacket packet;
  while (source.next(packet) == io::NextResult::kPacket) {
    if (packet.kind == io::PacketKind::kData) {
      driver.on_data(packet.payload, packet.time, sink);
    } else {
      driver.on_position(packet.payload);
    }
  }
  driver.finish(sink);
  report.pcap = source.stats();
  report.driver = driver.stats();
  report.assembler = driver.assembler_stats();
  report.model = driver.model();
  return report;
}

core::Error no_scan_error(const std::string& path, const vlp16::DriverStats& d) {
  const std::string why = d.rejected_total() > 0 ? ": " + d.rejects_text() : "";
  return {core::kExitDataError,
          fmt::format("no scan in '{}' ({} data packets, {} rejected{}; `cndt info` shows the "
                      "capture in detail)",
                      path, d.data_packets, d.rejected_total(), why)};
}

std::optional<core::Error> check_not_one_cloud(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return std::nullopt;
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (ext != ".bin" && ext != ".pcd" && ext != ".ply") return std::nullopt;
  const std::string folder = std::filesystem::path(path).parent_path().string();
  return core::Error{
      core::kExitUsage,
      fmt::format("'{}' is one cloud file: give a pcap or pcapng capture, or a folder of clouds "
                  "with one scan per file (KITTI .bin or PCD, in name order), such as '{}'",
                  path, folder.empty() ? "." : folder)};
}

core::Result<CaptureReport> read_scans(const std::string& path, const CaptureOptions& options,
                                       std::size_t max_points, double cloud_period_s,
                                       std::size_t max_scans, ScanVisitor visit, void* context) {
  struct Limit {
    std::size_t max, seen = 0;
    ScanVisitor visit;
    void* context;
  } limit{max_scans, 0, visit, context};
  const auto limited = [](const core::Scan& scan, void* ctx) {
    auto& l = *static_cast<Limit*>(ctx);
    if (l.max > 0 && l.seen >= l.max) return;
    ++l.seen;
    if (l.visit != nullptr) l.visit(scan, l.context);
  };
  if (auto err = check_not_one_cloud(path)) return *err;
  std::error_code ec;
  if (!std::filesystem::is_directory(path, ec)) return read_capture(path, options, limited, &limit);
  auto folder = list_cloud_folder(path, cloud_period_s);
  if (!folder) return folder.error();
  const CloudFolder& f = folder.value();
  CaptureReport report;
  report.path = path;
  core::Scan scan(max_points);
  for (std::size_t i = 0; i < f.files.size() && (max_scans == 0 || limit.seen < max_scans); ++i) {
    if (auto err = read_cloud(f.files[i], scan)) return *err;
    if (scan.points_dropped > 0) {
      spdlog::warn("'{}': {} points beyond the capacity of {} dropped", f.files[i],
                   scan.points_dropped, max_points);
    }
    scan.stamp = std::chrono::nanoseconds(std::llround(f.times_s[i] * 1e9));
    scan.sequence = i;
    report.scans.push_back(
        ScanSummary{scan.stamp, scan.end, scan.points.size(), scan.flags, scan.lost_packets});
    limited(scan, &limit);
  }
  return report;
}

}  // namespace cndt::cli
