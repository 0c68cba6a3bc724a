// Reading binary PCD files and comparing point clouds by nearest neighbour, for decoder tests.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

namespace cndt::test {

using Cloud = std::vector<Eigen::Vector3f>;

/// x, y, z of a PCD file with DATA binary (any other fields are skipped).
inline Cloud read_pcd_xyz(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::vector<std::string> fields;
  std::vector<int> sizes, counts;
  std::size_t points = 0;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "FIELDS") {
      for (std::string f; ls >> f;) fields.push_back(f);
    } else if (key == "SIZE") {
      for (int s; ls >> s;) sizes.push_back(s);
    } else if (key == "COUNT") {
      for (int c; ls >> c;) counts.push_back(c);
    } else if (key == "POINTS") {
      ls >> points;
    } else if (key == "DATA") {
      std::string kind;
      ls >> kind;
      if (kind != "binary") throw std::runtime_error(path + ": only DATA binary is read");
      break;
    }
  }
  if (counts.empty()) counts.assign(fields.size(), 1);
  std::size_t stride = 0;
  std::vector<std::size_t> offset;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    offset.push_back(stride);
    stride += static_cast<std::size_t>(sizes[i] * counts[i]);
  }
  auto at = [&](const char* name) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i] == name) return offset[i];
    }
    throw std::runtime_error(path + ": no field " + name);
  };
  const std::size_t ox = at("x"), oy = at("y"), oz = at("z");
  std::vector<char> data(points * stride);
  in.read(data.data(), static_cast<std::streamsize>(data.size()));
  Cloud c(points);
  for (std::size_t i = 0; i < points; ++i) {
    std::memcpy(&c[i].x(), data.data() + i * stride + ox, 4);
    std::memcpy(&c[i].y(), data.data() + i * stride + oy, 4);
    std::memcpy(&c[i].z(), data.data() + i * stride + oz, 4);
  }
  return c;
}

/// Fraction of `from`'s points that have a point of `to` within `tol` metres.
inline double fraction_within(const Cloud& from, const Cloud& to, float tol) {
  auto key = [tol](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    const auto ix = static_cast<std::int64_t>(std::floor(p.x() / tol)) + dx;
    const auto iy = static_cast<std::int64_t>(std::floor(p.y() / tol)) + dy;
    const auto iz = static_cast<std::int64_t>(std::floor(p.z() / tol)) + dz;
    return (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791);
  };
  std::unordered_multimap<std::int64_t, std::size_t> grid;
  for (std::size_t i = 0; i < to.size(); ++i) grid.emplace(key(to[i], 0, 0, 0), i);
  std::size_t hits = 0;
  for (const auto& p : from) {
    bool found = false;
    for (int dx = -1; dx <= 1 && !found; ++dx) {
      for (int dy = -1; dy <= 1 && !found; ++dy) {
        for (int dz = -1; dz <= 1 && !found; ++dz) {
          auto [b, e] = grid.equal_range(key(p, dx, dy, dz));
          for (auto it = b; it != e; ++it) {
            if ((to[it->second] - p).norm() <= tol) {
              found = true;
              break;
            }
          }
        }
      }
    }
    hits += found ? 1 : 0;
  }
  return from.empty() ? 0.0 : static_cast<double>(hits) / static_cast<double>(from.size());
}

}  // namespace cndt::test
