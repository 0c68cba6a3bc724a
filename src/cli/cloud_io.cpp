#include "cndt/cli/cloud_io.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
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

namespace cndt::cli {
namespace {

core::Error data_error(const std::string& path, const std::string& what) {
  return {core::kExitDataError, fmt::format("'{}': {}", path, what)};
}

bool is_number(const std::string& s) {
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0';
}

// One PCD field: its byte offset in a binary record, size, type letter and element count.
struct PcdField {
  std::string name;
  std::size_t size = 4, offset = 0, count = 1;
  char type = 'F';
};

double read_value(const char* p, const PcdField& f) {
  switch (f.type) {
    case 'F':
      if (f.size == 8) {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      } else {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
    case 'U': {
      std::uint64_t v = 0;
      std::memcpy(&v, p, f.size);  // little-endian host
      return static_cast<double>(v);
    }
    default: {
      std::int64_t v = 0;
      std::memcpy(&v, p, f.size);
      const int shift = static_cast<int>(64 - 8 * f.size);
      return static_cast<double>((v << shift) >> shift);  // sign-extend
    }
  }
}

core::Point make_point(double x, double y, double z, double intensity, double t, double ring) {
  core::Point p;
  p.x = static_cast<float>(x);
  p.y = static_cast<float>(y);
  p.z = static_cast<float>(z);
  p.intensity = static_cast<float>(intensity);
  p.time_ns = t > 0.0 && t < 1.0 ? static_cast<std::uint32_t>(t * 1e9) : 0;
  p.ring = static_cast<std::uint16_t>(std::clamp(ring, 0.0, 65535.0));
  return p;
}

std::optional<core::Error> read_pcd(const std::string& path, std::ifstream& in, core::Scan& scan) {
  std::vector<PcdField> fields;
  std::size_t points = 0;
  std::string data, line;
  int line_no = 0;
  while (data.empty() && std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    std::vector<std::string> v;
    for (std::string t; ls >> t;) v.push_back(t);
    auto bad = [&](const std::string& what) {
      return data_error(path, fmt::format("PCD header line {}: {}", line_no, what));
    };
    if (key == "FIELDS") {
      fields.clear();
      for (const auto& n : v) fields.push_back({n});
    } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
      if (v.size() != fields.size()) return bad(key + " does not list one value per field");
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (key == "TYPE") {
          if (v[i] != "F" && v[i] != "U" && v[i] != "I") return bad("unknown TYPE " + v[i]);
          fields[i].type = v[i][0];
        } else {
          const long n = std::strtol(v[i].c_str(), nullptr, 10);
          if (n <= 0 || (key == "SIZE" && n != 1 && n != 2 && n != 4 && n != 8)) {
            return bad(fmt::format("bad {} '{}'", key, v[i]));
          }
          (key == "SIZE" ? fields[i].size : fields[i].count) = static_cast<std::size_t>(n);
        }
      }
    } else if (key == "POINTS") {
      if (v.size() != 1 || !is_number(v[0])) return bad("bad POINTS");
      points = static_cast<std::size_t>(std::strtoull(v[0].c_str(), nullptr, 10));
    } else if (key == "DATA") {
      if (v.size() != 1) return bad("bad DATA");
      data = v[0];
    } else if (key != "VERSION" && key != "WIDTH" && key != "HEIGHT" && key != "VIEWPOINT") {
      return bad(fmt::format("unknown header key '{}'", key));
    }
  }
  if (data.empty()) return data_error(path, "not a PCD file (no DATA line)");
  if (data != "binary" && data != "ascii") {
    return data_error(path, fmt::format("PCD DATA {} is not supported (ascii or binary)", data));
  }
  std::size_t record = 0;
  int ix = -1, iy = -1, iz = -1, ii = -1, it = -1, ir = -1;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    fields[i].offset = record;
    record += fields[i].size * fields[i].count;
    const std::string& n = fields[i].name;
    const int idx = static_cast<int>(i);
    if (n == "x") ix = idx;
    if (n == "y") iy = idx;
    if (n == "z") iz = idx;
    if (n == "intensity" || n == "i") ii = idx;
    if (n == "t" || n == "time") it = idx;
    if (n == "ring") ir = idx;
  }
  if (ix < 0 || iy < 0 || iz < 0) return data_error(path, "PCD FIELDS lack x, y or z");
  auto get = [&](const std::vector<double>& vals, int i) {
    return i < 0 ? 0.0 : vals[static_cast<std::size_t>(i)];
  };
  std::vector<double> vals(fields.size());
  if (data == "binary") {
    std::vector<char> buf(record);
    for (std::size_t k = 0; k < points; ++k) {
      if (!in.read(buf.data(), static_cast<std::streamsize>(record))) {
        return data_error(path, fmt::format("PCD data ends at point {} of {}", k, points));
      }
      for (std::size_t i = 0; i < fields.size(); ++i) {
        vals[i] = read_value(buf.data() + fields[i].offset, fields[i]);
      }
      scan.push(make_point(get(vals, ix), get(vals, iy), get(vals, iz), get(vals, ii),
                           get(vals, it), get(vals, ir)));
    }
  } else {
    for (std::size_t k = 0; k < points; ++k) {
      if (!std::getline(in, line)) {
        return data_error(path, fmt::format("PCD data ends at point {} of {}", k, points));
      }
      ++line_no;
      std::istringstream ls(line);
      for (std::size_t i = 0; i < fields.size(); ++i) {
        for (std::size_t c = 0; c < fields[i].count; ++c) {
          double d = 0.0;
          if (!(ls >> d)) {
            return data_error(
                path, fmt::format("line {}: field {} is not a number", line_no, fields[i].name));
          }
          if (c == 0) vals[i] = d;
        }
      }
      scan.push(make_point(get(vals, ix), get(vals, iy), get(vals, iz), get(vals, ii),
                           get(vals, it), get(vals, ir)));
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<core::Error> read_cloud(const std::string& path, core::Scan& scan) {
  scan.reset();
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return core::Error{core::kExitNoInput,
                       fmt::format("cannot open '{}': {}", path, std::strerror(errno))};
  }
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".pcd") return read_pcd(path, in, scan);
  if (ext != ".bin") return data_error(path, "not a .bin or .pcd cloud");
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() % 16 != 0) {
    return data_error(path, fmt::format("{} bytes is not a whole number of KITTI points (16 "
                                        "bytes: float32 x y z intensity)",
                                        bytes.size()));
  }
  for (std::size_t o = 0; o < bytes.size(); o += 16) {
    float v[4];
    std::memcpy(v, bytes.data() + o, 16);
    scan.push(make_point(v[0], v[1], v[2], v[3], 0.0, 0.0));
  }
  return std::nullopt;
}

core::Result<CloudFolder> list_cloud_folder(const std::string& dir, double period_s) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return core::Error{core::kExitNoInput, fmt::format("'{}' is not a folder", dir)};
  }
  CloudFolder f;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".bin" || ext == ".pcd")) f.files.push_back(e.path());
  }
  if (ec)
    return core::Error{core::kExitIoError, fmt::format("cannot list '{}': {}", dir, ec.message())};
  std::sort(f.files.begin(), f.files.end());
  if (f.files.empty()) return data_error(dir, "no .bin or .pcd cloud in this folder");
  for (std::size_t i = 0; i < f.files.size(); ++i)
    f.times_s.push_back(period_s * static_cast<double>(i));
  std::ifstream times(fs::path(dir) / "times.txt");
  if (!times) return f;
  // `cndt decode` writes "file stamp_s ..." per line; KITTI writes one time per line.
  std::string line;
  std::size_t index = 0;
  int line_no = 0;
  const std::string times_path = (fs::path(dir) / "times.txt").string();
  while (std::getline(times, line)) {
    ++line_no;
    std::istringstream ls(line);
    std::string first, second;
    if (!(ls >> first) || first[0] == '#') continue;
    if (is_number(first)) {
      if (index < f.times_s.size()) f.times_s[index] = std::strtod(first.c_str(), nullptr);
      ++index;
      continue;
    }
    if (!(ls >> second) || !is_number(second)) {
      return data_error(times_path, fmt::format("line {}: no time after '{}'", line_no, first));
    }
    const auto it = std::find_if(f.files.begin(), f.files.end(), [&](const std::string& p) {
      return fs::path(p).filename() == first;
    });
    if (it != f.files.end()) {
      f.times_s[static_cast<std::size_t>(it - f.files.begin())] =
          std::strtod(second.c_str(), nullptr);
    }
  }
  return f;
}

}  // namespace cndt::cli
