// The map file: a versioned little-endian binary format holding a map's voxels with their
// running sums, so that a map read back keeps growing exactly as if it had never been saved.
// docs/map_format.md describes it byte by byte. Files are written atomically (a temporary file,
// fsync, rename, fsync of the folder): a crash or a kill mid-save leaves the previous file.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cndt/core/bytes.hpp"
#include "cndt/core/exit_codes.hpp"
#include "cndt/core/result.hpp"
#include "cndt/slam/ndt_map.hpp"

namespace cndt::slam {

inline constexpr std::uint32_t kMapFileVersion = 1;
inline constexpr std::size_t kMapHeaderBytes = 80;
inline constexpr std::size_t kMapRecordBytes = 96;
inline constexpr std::size_t kMapTrailerBytes = 8;

/// What the header of a map file says.
struct MapFileHeader {
  std::uint32_t version = kMapFileVersion;
  double voxel_size = 0.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::uint64_t voxels = 0;
  std::uint64_t points = 0;
};

/// The whole file for `map` (header, one record per voxel in index order, trailer).
std::vector<std::uint8_t> encode_map(const NdtMap& map);

/// Checks and reads a header; `name` (the file) and the offending field go into the error.
core::Result<MapFileHeader> decode_map_header(core::ByteSpan bytes, const std::string& name);

/// Reads a whole file's bytes into a new map. Voxel size and origin come from the file, the
/// capacity and the Gaussian settings from `base`. Every check (size, checksums, version, each
/// record) fails with a message that names the file, the section and the byte offset.
core::Result<NdtMap> decode_map(core::ByteSpan bytes, const std::string& name,
                                const MapOptions& base);

/// Writes `map` to `path` atomically: `path`.tmp is written and fsynced, then renamed over
/// `path`, then the folder is fsynced.
std::optional<core::Error> save_map_file(const NdtMap& map, const std::string& path);

core::Result<NdtMap> load_map_file(const std::string& path, const MapOptions& base);

}  // namespace cndt::slam
