#include "cndt/cli/cloud_io.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

namespace cndt::cli {
namespace {

template <class T>
void put(std::vector<char>& out, T v) {
  const auto* p = reinterpret_cast<const char*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

std::vector<char> body(const core::Scan& scan, bool extended) {
  std::vector<char> out;
  out.reserve(scan.points.size() * (extended ? 23 : 16));
  for (const auto& p : scan.points) {
    put(out, p.x);
    put(out, p.y);
    put(out, p.z);
    put(out, p.intensity);
    if (extended) {
      put(out, static_cast<float>(p.time_ns) * 1e-9F);
      put(out, p.ring);
      put(out, static_cast<std::uint8_t>(p.return_type));
    }
  }
  return out;
}

}  // namespace

std::optional<CloudFormat> parse_cloud_format(std::string_view s) {
  if (s == "bin") return CloudFormat::kBin;
  if (s == "pcd") return CloudFormat::kPcd;
  if (s == "ply") return CloudFormat::kPly;
  return std::nullopt;
}

std::string_view cloud_extension(CloudFormat f) {
  switch (f) {
    case CloudFormat::kBin:
      return ".bin";
    case CloudFormat::kPcd:
      return ".pcd";
    case CloudFormat::kPly:
      return ".ply";
  }
  return ".bin";
}

std::optional<core::Error> write_cloud(const std::string& path, const core::Scan& scan,
                                       CloudFormat format) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    return core::Error{core::kExitIoError,
                       fmt::format("cannot create '{}': {}", path, std::strerror(errno))};
  }
  const std::size_t n = scan.points.size();
  if (format == CloudFormat::kPcd) {
    out << "# .PCD v0.7 - written by cndt\nVERSION 0.7\n"
        << "FIELDS x y z intensity t ring return_type\nSIZE 4 4 4 4 4 2 1\n"
        << "TYPE F F F F F U U\nCOUNT 1 1 1 1 1 1 1\n"
        << fmt::format("WIDTH {}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\n", n, n)
        << "DATA binary\n";
  } else if (format == CloudFormat::kPly) {
    out << "ply\nformat binary_little_endian 1.0\ncomment written by cndt\n"
        << fmt::format("element vertex {}\n", n)
        << "property float x\nproperty float y\nproperty float z\nproperty float intensity\n"
        << "property float t\nproperty ushort ring\nproperty uchar return_type\nend_header\n";
  }
  const std::vector<char> data = body(scan, format != CloudFormat::kBin);
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) {
    return core::Error{core::kExitIoError,
                       fmt::format("writing '{}' failed: {}", path, std::strerror(errno))};
  }
  return std::nullopt;
}

}  // namespace cndt::cli
