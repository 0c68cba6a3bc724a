#include "cndt/slam/map_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <boost/crc.hpp>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace cndt::slam {
namespace {

constexpr std::uint8_t kMagic[8] = {'C', 'N', 'D', 'T', 'M', 'A', 'P', 0};
constexpr std::uint8_t kEndMagic[8] = {'C', 'N', 'D', 'T', 'E', 'N', 'D', 0};

// Header fields (byte offsets); docs/map_format.md has the table.
constexpr std::size_t kOffVersion = 8, kOffHeaderBytes = 12, kOffRecordBytes = 16, kOffFlags = 20,
                      kOffVoxelSize = 24, kOffOrigin = 32, kOffVoxels = 56, kOffPoints = 64,
                      kOffBodyCrc = 72, kOffHeaderCrc = 76;
// Record fields.
constexpr std::size_t kRecKey = 0, kRecCount = 12, kRecConsensus = 16, kRecReserved = 20,
                      kRecSum = 24, kRecSumOuter = 48;

std::uint32_t crc32(core::ByteSpan b) {
  boost::crc_32_type crc;
  crc.process_bytes(b.data(), b.size());
  return crc.checksum();
}

// Message text from parts (ostringstream: GCC 12 at -O3 warns falsely on chains of string +).
template <class... Parts>
std::string cat(const Parts&... parts) {
  std::ostringstream s;
  (s << ... << parts);
  return s.str();
}

std::string hex(std::uint32_t v) {
  std::ostringstream s;
  s << "0x" << std::hex << v;
  return s.str();
}

template <class... Parts>
core::Error corrupt(const std::string& name, const Parts&... what) {
  return {core::kExitDataError, cat(name, ": ", what...)};
}

std::string errno_text() { return std::strerror(errno); }

}  // namespace

std::vector<std::uint8_t> encode_map(const NdtMap& map) {
  const auto& voxels = map.grid().voxels();
  std::vector<std::uint8_t> out(kMapHeaderBytes + voxels.size() * kMapRecordBytes +
                                kMapTrailerBytes);
  const core::MutableByteSpan b(out);
  std::uint64_t points = 0;
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const ndt::Voxel& v = voxels[i];
    const std::size_t o = kMapHeaderBytes + i * kMapRecordBytes;
    core::store_le32(b, o + kRecKey, static_cast<std::uint32_t>(v.key.x));
    core::store_le32(b, o + kRecKey + 4, static_cast<std::uint32_t>(v.key.y));
    core::store_le32(b, o + kRecKey + 8, static_cast<std::uint32_t>(v.key.z));
    core::store_le32(b, o + kRecCount, v.count);
    core::store_le_f32(b, o + kRecConsensus, v.consensus);
    core::store_le32(b, o + kRecReserved, 0);
    for (int k = 0; k < 3; ++k) {
      core::store_le_f64(b, o + kRecSum + 8 * static_cast<std::size_t>(k), v.sum(k));
    }
    const double outer[6] = {v.sum_outer(0, 0), v.sum_outer(0, 1), v.sum_outer(0, 2),
                             v.sum_outer(1, 1), v.sum_outer(1, 2), v.sum_outer(2, 2)};
    for (std::size_t k = 0; k < 6; ++k) core::store_le_f64(b, o + kRecSumOuter + 8 * k, outer[k]);
    points += v.count;
  }
  std::copy(std::begin(kMagic), std::end(kMagic), out.begin());
  core::store_le32(b, kOffVersion, kMapFileVersion);
  core::store_le32(b, kOffHeaderBytes, static_cast<std::uint32_t>(kMapHeaderBytes));
  core::store_le32(b, kOffRecordBytes, static_cast<std::uint32_t>(kMapRecordBytes));
  core::store_le32(b, kOffFlags, 0);
  core::store_le_f64(b, kOffVoxelSize, map.options().voxel_size);
  for (int k = 0; k < 3; ++k) {
    core::store_le_f64(b, kOffOrigin + 8 * static_cast<std::size_t>(k), map.options().origin(k));
  }
  core::store_le64(b, kOffVoxels, voxels.size());
  core::store_le64(b, kOffPoints, points);
  core::store_le32(
      b, kOffBodyCrc,
      crc32(core::ByteSpan(out).subspan(kMapHeaderBytes, voxels.size() * kMapRecordBytes)));
  core::store_le32(b, kOffHeaderCrc, crc32(core::ByteSpan(out).first(kOffHeaderCrc)));
  std::copy(std::begin(kEndMagic), std::end(kEndMagic), out.end() - kMapTrailerBytes);
  return out;
}

core::Result<MapFileHeader> decode_map_header(core::ByteSpan b, const std::string& name) {
  if (b.size() < sizeof kMagic || !std::equal(std::begin(kMagic), std::end(kMagic), b.begin())) {
    return corrupt(name, "not a cndt map file (it does not start with \"CNDTMAP\")");
  }
  if (b.size() < kMapHeaderBytes) {
    return corrupt(name, "truncated in the header: ", b.size(), " bytes, the header alone is ",
                   kMapHeaderBytes);
  }
  const std::uint32_t stored = core::load_le32(b, kOffHeaderCrc);
  const std::uint32_t computed = crc32(b.first(kOffHeaderCrc));
  if (stored != computed) {
    return corrupt(name, "header checksum mismatch (bytes 0-", kOffHeaderCrc - 1, ": stored ",
                   hex(stored), ", computed ", hex(computed), "): the header is corrupted");
  }
  MapFileHeader h;
  h.version = core::load_le32(b, kOffVersion);
  if (h.version != kMapFileVersion) {
    return corrupt(name, "map file version ", h.version, "; this build reads version ",
                   kMapFileVersion);
  }
  const std::uint32_t header_bytes = core::load_le32(b, kOffHeaderBytes);
  const std::uint32_t record_bytes = core::load_le32(b, kOffRecordBytes);
  if (header_bytes != kMapHeaderBytes || record_bytes != kMapRecordBytes) {
    return corrupt(name, "header says ", header_bytes, "-byte header and ", record_bytes,
                   "-byte records; version 1 has ", kMapHeaderBytes, " and ", kMapRecordBytes);
  }
  h.voxel_size = core::load_le_f64(b, kOffVoxelSize);
  if (!std::isfinite(h.voxel_size) || h.voxel_size <= 0.0) {
    return corrupt(name, "voxel size ", h.voxel_size, " (byte ", kOffVoxelSize,
                   ") is not a positive length");
  }
  for (int k = 0; k < 3; ++k) {
    h.origin(k) = core::load_le_f64(b, kOffOrigin + 8 * static_cast<std::size_t>(k));
  }
  if (!h.origin.allFinite()) return corrupt(name, "origin (byte 32) is not finite");
  h.voxels = core::load_le64(b, kOffVoxels);
  h.points = core::load_le64(b, kOffPoints);
  return h;
}

core::Result<NdtMap> decode_map(core::ByteSpan b, const std::string& name, const MapOptions& base) {
  auto header = decode_map_header(b, name);
  if (!header) return header.error();
  const MapFileHeader& h = header.value();
  constexpr std::uint64_t kMaxVoxels =
      (std::numeric_limits<std::uint64_t>::max() - kMapHeaderBytes - kMapTrailerBytes) /
      kMapRecordBytes;
  if (h.voxels > kMaxVoxels) {
    return corrupt(name, "header claims ", h.voxels, " voxels");
  }
  const std::uint64_t expected = kMapHeaderBytes + h.voxels * kMapRecordBytes + kMapTrailerBytes;
  if (b.size() != expected) {
    return corrupt(name, (b.size() < expected ? "truncated" : "trailing bytes"), ": the file is ",
                   b.size(), " bytes, the header's ", h.voxels, " voxels make ", expected);
  }
  if (!std::equal(std::begin(kEndMagic), std::end(kEndMagic), b.end() - kMapTrailerBytes)) {
    return corrupt(name, "the trailer (byte ", expected - kMapTrailerBytes,
                   ") is not \"CNDTEND\": the file is damaged at its end");
  }
  const core::ByteSpan body = b.subspan(kMapHeaderBytes, h.voxels * kMapRecordBytes);
  const std::uint32_t stored = core::load_le32(b, kOffBodyCrc);
  const std::uint32_t computed = crc32(body);
  if (stored != computed) {
    return corrupt(name, "voxel records checksum mismatch (bytes ", kMapHeaderBytes, "-",
                   kMapHeaderBytes + body.size() - 1, ": stored ", hex(stored), ", computed ",
                   hex(computed), "): the records are corrupted");
  }
  if (h.voxels > base.capacity) {
    return core::Error{core::kExitConfigError,
                       cat(name, ": the map holds ", h.voxels,
                           " voxels, more than the configured capacity of ", base.capacity)};
  }
  MapOptions o = base;
  o.voxel_size = h.voxel_size;
  o.origin = h.origin;
  NdtMap map(o);
  std::uint64_t points = 0;
  for (std::uint64_t i = 0; i < h.voxels; ++i) {
    const core::ByteSpan r = body.subspan(i * kMapRecordBytes, kMapRecordBytes);
    const std::string where =
        cat("voxel record ", i, " (byte ", kMapHeaderBytes + i * kMapRecordBytes, ")");
    const ndt::VoxelKey key{static_cast<std::int32_t>(core::load_le32(r, kRecKey)),
                            static_cast<std::int32_t>(core::load_le32(r, kRecKey + 4)),
                            static_cast<std::int32_t>(core::load_le32(r, kRecKey + 8))};
    const std::uint32_t count = core::load_le32(r, kRecCount);
    const float consensus = core::load_le_f32(r, kRecConsensus);
    Eigen::Vector3d sum;
    for (int k = 0; k < 3; ++k) {
      sum(k) = core::load_le_f64(r, kRecSum + 8 * static_cast<std::size_t>(k));
    }
    double outer[6];
    for (std::size_t k = 0; k < 6; ++k) outer[k] = core::load_le_f64(r, kRecSumOuter + 8 * k);
    Eigen::Matrix3d sum_outer;
    sum_outer << outer[0], outer[1], outer[2], outer[1], outer[3], outer[4], outer[2], outer[4],
        outer[5];
    if (count == 0) return corrupt(name, where, " holds no points");
    if (!sum.allFinite() || !sum_outer.allFinite() || !std::isfinite(consensus)) {
      return corrupt(name, where, " holds a value that is not finite");
    }
    if (!map.grid().restore(key, count, sum, sum_outer, consensus)) {
      return corrupt(name, where, ": voxel (", key.x, ", ", key.y, ", ", key.z, ") appears twice");
    }
    points += count;
  }
  if (points != h.points) {
    return corrupt(name, "the records hold ", points, " points, the header says ", h.points);
  }
  map.finalize();
  return map;
}

std::optional<core::Error> save_map_file(const NdtMap& map, const std::string& path) {
  const std::vector<std::uint8_t> bytes = encode_map(map);
  const std::string tmp = path + ".tmp";
  auto io_error = [&](const std::string& what, const std::string& file) {
    return core::Error{core::kExitIoError, cat(file, ": ", what, ": ", errno_text())};
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return io_error("cannot create", tmp);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const auto e = io_error("write failed", tmp);
      ::close(fd);
      ::unlink(tmp.c_str());
      return e;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const auto e = io_error("fsync failed", tmp);
    ::close(fd);
    ::unlink(tmp.c_str());
    return e;
  }
  if (::close(fd) != 0) {
    const auto e = io_error("close failed", tmp);
    ::unlink(tmp.c_str());
    return e;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const auto e = io_error(cat("cannot rename ", tmp, " to it"), path);
    ::unlink(tmp.c_str());
    return e;
  }
  // The rename is durable once the folder's entry is on disk.
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::absolute(path, ec).parent_path();
  const int dfd = ec ? -1 : ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return std::nullopt;
}

core::Result<NdtMap> load_map_file(const std::string& path, const MapOptions& base) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return core::Error{core::kExitNoInput, path + ": no such map file"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return core::Error{core::kExitNoInput, path + ": cannot open: " + errno_text()};
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) return core::Error{core::kExitIoError, path + ": read failed"};
  return decode_map(bytes, path, base);
}

}  // namespace cndt::slam
