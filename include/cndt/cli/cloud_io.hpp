// Writes one scan as a KITTI .bin, a binary PCD or a binary PLY file.
#pragma once

#include <optional>
#include <string>

#include "cndt/core/exit_codes.hpp"
#include "cndt/core/scan.hpp"

namespace cndt::cli {

enum class CloudFormat { kBin, kPcd, kPly };
std::optional<CloudFormat> parse_cloud_format(std::string_view s);
std::string_view cloud_extension(CloudFormat f);

/// bin: float32 x y z intensity (KITTI). pcd/ply: x y z intensity (float32), t (float32 seconds
/// after the scan stamp), ring (uint16), return_type (uint8). Returns an error naming the file.
std::optional<core::Error> write_cloud(const std::string& path, const core::Scan& scan,
                                       CloudFormat format);

}  // namespace cndt::cli
