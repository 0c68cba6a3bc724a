// cndt map info | export: what a map file holds, and its voxels as a point cloud for viewers.
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cndt/cli/commands.hpp"
#include "cndt/slam/map_file.hpp"

namespace cndt::cli {
namespace {

// A map as large as the file says: the capacity is not the reader's concern here.
core::Result<slam::NdtMap> load_any(const std::string& path) {
  slam::MapOptions o;
  o.capacity = 1;
  {
    std::ifstream in(path, std::ios::binary);
    std::vector<std::uint8_t> head(slam::kMapHeaderBytes);
    if (in.read(reinterpret_cast<char*>(head.data()), static_cast<std::streamsize>(head.size()))) {
      auto h = slam::decode_map_header(head, path);
      if (h) o.capacity = std::max<std::uint64_t>(1, h.value().voxels);
    }
  }
  return slam::load_map_file(path, o);
}

// One exported vertex per voxel with a Gaussian.
struct VoxelPoint {
  float x, y, z;
  float size;  // 2 sqrt(largest covariance eigenvalue): the voxel's extent along its main axis
  float cv;    // mean consensus of the points it holds
  std::uint32_t count;
};

std::vector<VoxelPoint> voxel_points(const slam::NdtMap& map) {
  std::vector<VoxelPoint> out;
  out.reserve(map.gaussians());
  const auto& voxels = map.grid().voxels();
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const ndt::Voxel& v = voxels[i];
    if (!v.has_gaussian) continue;
    const Eigen::Vector3d mean = map.grid().gaussians()[i].mean_vector();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(v.covariance(), Eigen::EigenvaluesOnly);
    const double largest = std::max(es.eigenvalues().maxCoeff(), 0.0);
    out.push_back({static_cast<float>(mean.x()), static_cast<float>(mean.y()),
                   static_cast<float>(mean.z()), static_cast<float>(2.0 * std::sqrt(largest)),
                   v.consensus, v.count});
  }
  return out;
}

std::optional<core::Error> write_export(const std::string& path, const std::vector<VoxelPoint>& pts,
                                        bool ply) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    return core::Error{core::kExitIoError,
                       fmt::format("cannot create '{}': {}", path, std::strerror(errno))};
  }
  const std::size_t n = pts.size();
  if (ply) {
    out << "ply\nformat binary_little_endian 1.0\ncomment cndt map: NDT voxel means\n"
        << fmt::format("element vertex {}\n", n)
        << "property float x\nproperty float y\nproperty float z\nproperty float size\n"
        << "property float cv\nproperty uint count\nend_header\n";
  } else {
    out << "# .PCD v0.7 - cndt map: NDT voxel means\nVERSION 0.7\n"
        << "FIELDS x y z size cv count\nSIZE 4 4 4 4 4 4\nTYPE F F F F F U\nCOUNT 1 1 1 1 1 1\n"
        << fmt::format("WIDTH {}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\n", n, n)
        << "DATA binary\n";
  }
  std::vector<std::uint8_t> body(n * 24);
  const core::MutableByteSpan b(body);
  for (std::size_t i = 0; i < n; ++i) {
    const VoxelPoint& p = pts[i];
    const std::size_t o = i * 24;
    core::store_le_f32(b, o, p.x);
    core::store_le_f32(b, o + 4, p.y);
    core::store_le_f32(b, o + 8, p.z);
    core::store_le_f32(b, o + 12, p.size);
    core::store_le_f32(b, o + 16, p.cv);
    core::store_le32(b, o + 20, p.count);
  }
  out.write(reinterpret_cast<const char*>(body.data()), static_cast<std::streamsize>(body.size()));
  out.close();
  if (!out) {
    return core::Error{core::kExitIoError,
                       fmt::format("writing '{}' failed: {}", path, std::strerror(errno))};
  }
  return std::nullopt;
}

int run_info(const slam::NdtMap& map, const std::string& path) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  double cv_sum = 0.0;
  for (const ndt::Voxel& v : map.grid().voxels()) {
    const Eigen::Vector3d c = Eigen::Vector3d(v.key.x, v.key.y, v.key.z) * map.options().voxel_size;
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c + Eigen::Vector3d::Constant(map.options().voxel_size));
    cv_sum += static_cast<double>(v.consensus) * v.count;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  const auto& o = map.options();
  std::cout << fmt::format("file: {}\nformat: cndt map, version {}\nbytes: {}\n", path,
                           slam::kMapFileVersion, ec ? 0 : bytes)
            << fmt::format("voxel size: {} m\norigin: {} {} {}\n", o.voxel_size, o.origin.x(),
                           o.origin.y(), o.origin.z())
            << fmt::format("voxels: {}\nvoxels with a Gaussian: {}\npoints: {}\n", map.size(),
                           map.gaussians(), map.points());
  if (map.size() > 0) {
    std::cout << fmt::format(
        "extent: x {:.1f} .. {:.1f}, y {:.1f} .. {:.1f}, z {:.1f} .. {:.1f} m\n"
        "mean consensus: {:.3f}\n",
        lo.x(), hi.x(), lo.y(), hi.y(), lo.z(), hi.z(),
        cv_sum / static_cast<double>(std::max<std::uint64_t>(1, map.points())));
  }
  return core::kExitOk;
}

}  // namespace

void register_map(CLI::App& app, MapArgs& a) {
  auto* cmd = app.add_subcommand("map", "Inspect a map file, or export its voxels for a viewer");
  cmd->require_subcommand(1);
  auto* info = cmd->add_subcommand(
      "info", "Print what a map file holds: version, voxel size, origin, voxels, points, extent");
  info->add_option("FILE", a.file, "Map file (written by cndt replay --save-map or cndtd)")
      ->required();
  info->parse_complete_callback([&a] { a.action = MapArgs::Action::kInfo; });
  auto* exp = cmd->add_subcommand(
      "export",
      "Write the voxels that have a Gaussian as a point cloud for CloudCompare or PCL viewers: "
      "one vertex per voxel at its mean, with fields size (2 sqrt of the largest covariance "
      "eigenvalue, m), cv (mean voxel consensus) and count (points)");
  exp->add_option("FILE", a.file, "Map file")->required();
  auto* ply = exp->add_option("--ply", a.ply, "Write a binary little-endian PLY file here");
  auto* pcd = exp->add_option("--pcd", a.pcd, "Write a binary PCD (v0.7) file here");
  ply->excludes(pcd);
  exp->parse_complete_callback([&a] { a.action = MapArgs::Action::kExport; });
}

int run_map(const MapArgs& a) {
  if (a.action == MapArgs::Action::kExport && a.ply.empty() && a.pcd.empty()) {
    return fail({core::kExitUsage, "map export: give --ply OUT or --pcd OUT"});
  }
  auto map = load_any(a.file);
  if (!map) return fail(map.error());
  if (a.action == MapArgs::Action::kInfo) return run_info(map.value(), a.file);
  const bool ply = !a.ply.empty();
  const std::string& out = ply ? a.ply : a.pcd;
  const std::vector<VoxelPoint> pts = voxel_points(map.value());
  if (auto e = write_export(out, pts, ply)) return fail(*e);
  std::cout << fmt::format("{}: {} voxels\n", out, pts.size());
  return core::kExitOk;
}

}  // namespace cndt::cli
