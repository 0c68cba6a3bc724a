// Runs a capture file through the driver: the common front half of info, decode and replay.
#pragma once

#include <string>
#include <vector>

#include "cndt/core/result.hpp"
#include "cndt/core/scan.hpp"
#include "cndt/pcap/pcap_source.hpp"
#include "cndt/vlp16/driver.hpp"

namespace cndt::cli {

struct CaptureOptions {
  pcap::PcapOptions pcap;
  vlp16::DriverOptions driver;
};

struct ScanSummary {
  std::chrono::nanoseconds stamp{0}, end{0};
  std::size_t points = 0;
  std::uint32_t flags = 0;
  std::uint32_t lost_packets = 0;
};

struct CaptureReport {
  std::string path;
  bool pcapng = false;
  int link_type = 0;
  std::uintmax_t file_bytes = 0;
  pcap::PcapStats pcap;
  vlp16::DriverStats driver;
  vlp16::AssemblerStats assembler;
  std::optional<vlp16::Model> model;
  std::vector<ScanSummary> scans;
};

/// Callback type for scans; called on the reading thread, the scan is valid during the call.
using ScanVisitor = void (*)(const core::Scan& scan, void* context);

/// Reads the whole capture. Fails only when the file cannot be opened or is not a capture; bad
/// packets and a cut-short end are reported in the CaptureReport.
core::Result<CaptureReport> read_capture(const std::string& path, const CaptureOptions& options,
                                         ScanVisitor visit = nullptr, void* context = nullptr);

}  // namespace cndt::cli
