// Runs a capture file through the driver: the common front half of info, decode, replay and sweep.
#pragma once

#include <optional>
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

/// The error for input that gave no scan at all: how many data packets it held and why they
/// were refused, by reason (an unsupported model, say), and where to look further.
core::Error no_scan_error(const std::string& path, const vlp16::DriverStats& driver);

/// A usage error naming the folder to pass when `path` is one cloud file (.bin, .pcd, .ply)
/// where a capture or a folder of clouds belongs; nothing otherwise.
std::optional<core::Error> check_not_one_cloud(const std::string& path);

/// What odometry programs read: a capture file (as read_capture) or a folder of clouds (KITTI
/// .bin or PCD, one scan per file in name order, stamped from the folder's times.txt or
/// `cloud_period_s` apart; no firing times, so no deskew). Scans hold at most `max_points`
/// points (a cloud's extra points are dropped, flagged and logged). `max_scans` > 0: only the
/// first max_scans scans are visited (a folder's later files are not read). Fails when the
/// input cannot be opened or a cloud cannot be read (the error names the file); the scans before
/// it have been visited. A folder's report holds its scans only.
core::Result<CaptureReport> read_scans(const std::string& path, const CaptureOptions& options,
                                       std::size_t max_points, double cloud_period_s,
                                       std::size_t max_scans, ScanVisitor visit, void* context);

}  // namespace cndt::cli
