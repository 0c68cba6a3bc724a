// Writes one scan as a KITTI .bin, a binary PCD or a binary PLY file; reads scan folders back
// (KITTI .bin, PCD) for replay.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cndt/core/exit_codes.hpp"
#include "cndt/core/result.hpp"
#include "cndt/core/scan.hpp"

namespace cndt::cli {

enum class CloudFormat { kBin, kPcd, kPly };
std::optional<CloudFormat> parse_cloud_format(std::string_view s);
std::string_view cloud_extension(CloudFormat f);

/// bin: float32 x y z intensity (KITTI). pcd/ply: x y z intensity (float32), t (float32 seconds
/// after the scan stamp), ring (uint16), return_type (uint8). Returns an error naming the file.
std::optional<core::Error> write_cloud(const std::string& path, const core::Scan& scan,
                                       CloudFormat format);

/// Reads one cloud into `scan` (cleared first; points beyond its capacity are dropped and
/// flagged): a KITTI .bin (float32 x y z intensity) or a PCD (v0.5-0.7, DATA ascii or binary,
/// fields x y z required; intensity, t (seconds after the stamp) and ring used when present;
/// other fields skipped). Errors name the file and what was wrong.
std::optional<core::Error> read_cloud(const std::string& path, core::Scan& scan);

/// A folder of clouds in name order (.bin and .pcd files), with each scan's start time from the
/// folder's times.txt when there is one (one line per file, seconds, as `cndt decode` writes it),
/// otherwise file index x `period_s`.
struct CloudFolder {
  std::vector<std::string> files;
  std::vector<double> times_s;
};
core::Result<CloudFolder> list_cloud_folder(const std::string& dir, double period_s);

}  // namespace cndt::cli
