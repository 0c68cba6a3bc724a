#include "cndt/slam/trajectory_eval.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace cndt::slam {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

double angle_deg(const Eigen::Matrix3d& R) {
  const double c = std::clamp((R.trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * kRadToDeg;
}

// Ground truth at time t, interpolated (translation linear, rotation slerp).
bool interpolate(const std::vector<TimedPose>& gt, double t, Eigen::Isometry3d& out) {
  if (gt.empty() || t < gt.front().t - 1e-6 || t > gt.back().t + 1e-6) return false;
  auto it = std::lower_bound(gt.begin(), gt.end(), t,
                             [](const TimedPose& p, double v) { return p.t < v; });
  if (it == gt.end()) it = gt.end() - 1;
  if (it == gt.begin() || std::abs(it->t - t) < 1e-6) {
    out = it->pose;
    return true;
  }
  const TimedPose& b = *it;
  const TimedPose& a = *(it - 1);
  const double f = (t - a.t) / (b.t - a.t);
  const Eigen::Quaterniond qa(a.pose.linear()), qb(b.pose.linear());
  out = Eigen::Isometry3d::Identity();
  out.linear() = qa.slerp(f, qb).toRotationMatrix();
  out.translation() = (1 - f) * a.pose.translation() + f * b.pose.translation();
  return true;
}

}  // namespace

EvalResult evaluate(const std::vector<TimedPose>& ground_truth,
                    const std::vector<TimedPose>& estimate) {
  EvalResult r;
  std::vector<Eigen::Isometry3d> gt, est;
  std::vector<double> times;
  for (const auto& e : estimate) {
    Eigen::Isometry3d g;
    if (!interpolate(ground_truth, e.t, g)) continue;
    gt.push_back(g);
    est.push_back(e.pose);
    times.push_back(e.t);
  }
  r.matched = gt.size();
  if (gt.size() < 2) return r;
  // ATE: best rigid alignment of the estimated positions onto the true ones (Umeyama).
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(gt.size())), dst(3, src.cols());
  for (std::size_t i = 0; i < gt.size(); ++i) {
    src.col(static_cast<Eigen::Index>(i)) = est[i].translation();
    dst.col(static_cast<Eigen::Index>(i)) = gt[i].translation();
  }
  const Eigen::Matrix4d A = Eigen::umeyama(src, dst, false);
  double sum2 = 0.0;
  for (Eigen::Index i = 0; i < src.cols(); ++i) {
    const Eigen::Vector3d p = A.topLeftCorner<3, 3>() * src.col(i) + A.topRightCorner<3, 1>();
    const double e = (p - dst.col(i)).norm();
    sum2 += e * e;
    r.ate_max = std::max(r.ate_max, e);
  }
  r.ate_rmse = std::sqrt(sum2 / static_cast<double>(src.cols()));
  // From the first pose on, with nothing fitted afterwards.
  const Eigen::Isometry3d start = gt.front() * est.front().inverse();
  for (std::size_t i = 0; i < gt.size(); ++i) {
    const double dz = (start * est[i]).translation().z() - gt[i].translation().z();
    r.height_error_max = std::max(r.height_error_max, std::abs(dz));
  }
  const Eigen::Isometry3d last = start * est.back();
  r.end_error = (last.translation() - gt.back().translation()).norm();
  r.height_error_end = last.translation().z() - gt.back().translation().z();
  // The world's up as each sees it from the sensor (the rotations' third rows): a turn about
  // the vertical leaves it, so this is roll and pitch alone, whatever the sensor's mounting.
  const double up_cos = std::clamp(last.linear().row(2).dot(gt.back().linear().row(2)), -1.0, 1.0);
  r.tilt_end_deg = std::acos(up_cos) * kRadToDeg;
  // Per-frame relative pose error.
  double st = 0.0, sr = 0.0;
  std::vector<double> dist(gt.size(), 0.0);
  for (std::size_t i = 0; i + 1 < gt.size(); ++i) {
    const Eigen::Isometry3d dg = gt[i].inverse() * gt[i + 1];
    const Eigen::Isometry3d de = est[i].inverse() * est[i + 1];
    const Eigen::Isometry3d E = dg.inverse() * de;
    const FrameError fe{times[i], E.translation().norm(), angle_deg(E.linear())};
    r.frames.push_back(fe);
    st += fe.translation * fe.translation;
    sr += fe.rotation_deg * fe.rotation_deg;
    dist[i + 1] = dist[i] + dg.translation().norm();
  }
  r.rpe_translation_rmse = std::sqrt(st / static_cast<double>(r.frames.size()));
  r.rpe_rotation_rmse_deg = std::sqrt(sr / static_cast<double>(r.frames.size()));
  r.path_length = dist.back();
  // Segment errors, KITTI style: from every 10th frame, over each length.
  for (double len = 10.0; len <= r.path_length / 2.0; len *= 2.0) r.segment_lengths.push_back(len);
  double terr = 0.0, rerr = 0.0;
  std::size_t n = 0;
  for (double len : r.segment_lengths) {
    for (std::size_t i = 0; i < gt.size(); i += 10) {
      const auto it = std::lower_bound(dist.begin() + static_cast<std::ptrdiff_t>(i), dist.end(),
                                       dist[i] + len);
      if (it == dist.end()) break;
      const auto j = static_cast<std::size_t>(it - dist.begin());
      const Eigen::Isometry3d E = (gt[i].inverse() * gt[j]).inverse() * (est[i].inverse() * est[j]);
      terr += E.translation().norm() / len;
      rerr += angle_deg(E.linear()) / len;
      ++n;
    }
  }
  if (n > 0) {
    r.rte_percent = 100.0 * terr / static_cast<double>(n);
    r.rre_deg_per_m = rerr / static_cast<double>(n);
  }
  return r;
}

}  // namespace cndt::slam
