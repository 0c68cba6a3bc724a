#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "cndt/cli/commands.hpp"
#include "cndt/slam/trajectory_eval.hpp"

namespace cndt::cli {
namespace {

// TUM format: "time x y z qx qy qz qw" per line; '#' starts a comment.
core::Result<std::vector<slam::TimedPose>> read_tum(const std::string& path) {
  std::ifstream in(path);
  if (!in) return core::Error{core::kExitNoInput, fmt::format("cannot open '{}'", path)};
  std::vector<slam::TimedPose> out;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    double t, x, y, z, qx, qy, qz, qw;
    if (!(ls >> t >> x >> y >> z >> qx >> qy >> qz >> qw)) {
      return core::Error{core::kExitDataError,
                         fmt::format("{}:{}: expected 'time x y z qx qy qz qw'", path, n)};
    }
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      return core::Error{core::kExitDataError,
                         fmt::format("{}:{}: quaternion norm {:.4f} is not 1", path, n, q.norm())};
    }
    slam::TimedPose p;
    p.t = t;
    p.pose.linear() = q.normalized().toRotationMatrix();
    p.pose.translation() = Eigen::Vector3d(x, y, z);
    if (!out.empty() && t <= out.back().t) {
      return core::Error{core::kExitDataError,
                         fmt::format("{}:{}: time {} does not increase", path, n, t)};
    }
    out.push_back(p);
  }
  if (out.empty())
    return core::Error{core::kExitDataError, fmt::format("'{}' holds no pose", path)};
  return out;
}

}  // namespace

void register_eval(CLI::App& app, EvalArgs& a) {
  auto* cmd = app.add_subcommand(
      "eval",
      "Compare an estimated trajectory with ground truth (both TUM files) and print "
      "JSON: ATE RMSE after an SE(3) alignment, KITTI-style relative translational (%) "
      "and rotational (deg/m) errors over path segments of 10, 20, 40, ... m up to half the "
      "path (null below 20 m), per-frame RPE, and the errors of "
      "dead reckoning from the first pose (start_aligned: position and height error at the "
      "end, largest height error, roll and pitch error at the end), which the ATE's fit hides");
  cmd->add_option("--gt", a.gt, "Ground-truth TUM file")->required();
  cmd->add_option("--est", a.est, "Estimated TUM file")->required();
}

int run_eval(const EvalArgs& a) {
  auto gt = read_tum(a.gt);
  if (!gt) return fail(gt.error());
  auto est = read_tum(a.est);
  if (!est) return fail(est.error());
  const slam::EvalResult r = slam::evaluate(gt.value(), est.value());
  if (r.matched < 2) {
    return fail({core::kExitDataError,
                 fmt::format("only {} estimated poses fall inside the ground truth's time span",
                             r.matched)});
  }
  std::string lengths, frames;
  for (double l : r.segment_lengths)
    lengths += fmt::format("{}{:.0f}", lengths.empty() ? "" : ", ", l);
  for (const auto& f : r.frames) {
    frames += fmt::format("{}[{:.6f}, {:.5f}, {:.5f}]", frames.empty() ? "" : ", ", f.t,
                          f.translation, f.rotation_deg);
  }
  // No segment fits a path shorter than 20 m: the segment errors are not measured (null),
  // rather than reported as zero.
  auto number_or_null = [](double v, int digits) {
    return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : std::string("null");
  };
  if (r.segment_lengths.empty()) {
    spdlog::warn(
        "the ground truth's path is {:.1f} m, shorter than 20 m (twice the shortest segment): "
        "rte_percent and rre_deg_per_m are null; the ATE and the per-frame errors are measured",
        r.path_length);
  }
  std::cout << fmt::format(
      "{{\n  \"matched\": {},\n  \"path_length_m\": {:.3f},\n  \"ate_rmse_m\": {:.4f},\n  "
      "\"ate_max_m\": {:.4f},\n  \"rte_percent\": {},\n  \"rre_deg_per_m\": {},\n  "
      "\"rpe_translation_rmse_m\": {:.5f},\n  \"rpe_rotation_rmse_deg\": {:.5f},\n  "
      "\"start_aligned\": {{\"end_error_m\": {:.4f}, \"height_error_end_m\": {:.4f}, "
      "\"height_error_max_m\": {:.4f}, \"tilt_end_deg\": {:.4f}}},\n  "
      "\"segment_lengths_m\": [{}],\n  \"rpe_per_frame\": [{}]\n}}\n",
      r.matched, r.path_length, r.ate_rmse, r.ate_max, number_or_null(r.rte_percent, 4),
      number_or_null(r.rre_deg_per_m, 5), r.rpe_translation_rmse, r.rpe_rotation_rmse_deg,
      r.end_error, r.height_error_end, r.height_error_max, r.tilt_end_deg, lengths, frames);
  return core::kExitOk;
}

}  // namespace cndt::cli
