#include "cndt/cli/capture.hpp"

#include <filesystem>

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

}  // namespace cndt::cli
