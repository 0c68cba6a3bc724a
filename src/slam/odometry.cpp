#include "cndt/slam/odometry.hpp"

#include <cmath>

namespace cndt::slam {
namespace {

// A fraction `a` of a rigid motion (rotation about its axis, translation along the chord).
Eigen::Isometry3d scale_motion(const Eigen::Isometry3d& m, double a) {
  const Eigen::AngleAxisd aa(m.linear());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(aa.angle() * a, aa.axis()).toRotationMatrix();
  out.translation() = a * m.translation();
  return out;
}

bool finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

}  // namespace

ConsensusOdometry::ConsensusOdometry(const OdometryOptions& o)
    : options_(o),
      grid_({o.voxel_size, o.max_map_voxels, 5, 0.001, o.drop_ring_arcs}),
      chi2_(o.max_scan_points),
      scan_sampler_(o.scan_cell, o.max_scan_points),
      map_sampler_(o.map_cell, o.max_scan_points) {
  raw_.reserve(o.max_scan_points);
  test_.reserve(o.max_scan_points);
  map_points_.reserve(o.max_scan_points * (o.local_map_scans + 1));
  mask_.reserve(o.max_map_voxels);
  cv_.reserve(o.max_map_voxels);
  residuals_.count.reserve(o.max_map_voxels);
  residuals_.rss.reserve(o.max_map_voxels);
  for (double size : o.bootstrap_voxel_sizes) {
    bootstrap_grids_.emplace_back(
        ndt::VoxelGridOptions{size, o.max_map_voxels / 4, 5, 0.001, o.drop_ring_arcs});
  }
}

core::Pose6 ConsensusOdometry::bootstrap(const core::Pose6& x0) {
  core::Pose6 x = x0;
  for (ndt::VoxelGrid& g : bootstrap_grids_) {
    g.clear();
    for (const auto& scan_points : history_) {
      for (const auto& p : scan_points) g.add(p);
    }
    g.finalize();
    x = ndt::newton_solve(g, test_, x, options_.coarse).pose;
  }
  return x;
}

void ConsensusOdometry::deskew(const core::Scan& scan, const Eigen::Isometry3d& motion,
                               double scan_period_s) {
  raw_.clear();
  const double min2 = options_.min_range * options_.min_range;
  const double max2 = options_.max_range * options_.max_range;
  const bool undistort = options_.deskew && scan_period_s > 0.0;
  const Eigen::AngleAxisd aa(motion.linear());
  for (const core::Point& p : scan.points) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    const double r2 = v.squaredNorm();
    if (r2 < min2 || r2 > max2 || !v.allFinite()) continue;
    if (!undistort) {
      raw_.push_back(v);
      continue;
    }
    // Sensor pose at the point's firing time relative to the scan stamp: a fraction of the
    // predicted motion over one scan period.
    const double a = static_cast<double>(p.time_ns) * 1e-9 / scan_period_s;
    const Eigen::Matrix3d R = Eigen::AngleAxisd(aa.angle() * a, aa.axis()).toRotationMatrix();
    raw_.push_back(R * v + a * motion.translation());
  }
}

double ConsensusOdometry::consensus_at(const core::Pose6& x, std::vector<double>& cv) {
  residuals_.reset(grid_.size());
  ndt::accumulate_residuals(grid_, raw_, x, residuals_);
  ndt::voxel_consensus_all(residuals_, chi2_, {}, cv);
  return ndt::localization_consensus(grid_, cv, x.head<3>());
}

void ConsensusOdometry::update_reference(const Eigen::Isometry3d& pose) {
  const std::size_t keep = options_.reference == Reference::kPreviousScan
                               ? 1
                               : std::max<std::size_t>(1, options_.local_map_scans);
  if (history_.size() == keep) {
    // Reuse the oldest buffer for the newest scan.
    history_.push_back(std::move(history_.front()));
    history_.pop_front();
  } else {
    history_.emplace_back();
    history_.back().reserve(options_.max_scan_points);
  }
  std::vector<Eigen::Vector3d>& slot = history_.back();
  map_sampler_.run(raw_, slot);
  for (auto& p : slot) p = pose * p;
  grid_.clear();
  for (const auto& scan_points : history_) {
    for (const auto& p : scan_points) grid_.add(p);
  }
  grid_.finalize();
}

bool ConsensusOdometry::match(const core::Pose6& x0, OdometryResult& res) {
  core::Pose6 x = x0;
  bool converged = false;
  if (options_.mode == OdometryMode::kNaive) {
    const ndt::NewtonResult r = ndt::newton_solve(grid_, test_, x0, options_.naive);
    x = r.pose;
    converged = r.converged;
    res.fine_iterations += r.iterations;
    res.points = r.matched;
  } else {
    const ndt::NewtonResult coarse = ndt::newton_solve(grid_, test_, x0, options_.coarse);
    res.coarse_iterations += coarse.iterations;
    // Cv of every reference voxel at the coarse pose (eqs 8-9), then the cut at eta.
    consensus_at(coarse.pose, cv_);
    mask_.assign(grid_.size(), 1);
    res.voxels_before = res.voxels_after = 0;
    for (std::size_t i = 0; i < grid_.size(); ++i) {
      if (!std::isnan(cv_[i]) && cv_[i] < options_.eta) mask_[i] = 0;
      if (residuals_.count[i] > 0) {
        ++res.voxels_before;
        if (mask_[i] != 0) ++res.voxels_after;
      }
    }
    const ndt::NewtonResult fine =
        ndt::newton_solve(grid_, test_, coarse.pose, options_.fine, &mask_);
    x = fine.pose;
    converged = fine.converged;
    res.fine_iterations += fine.iterations;
    res.points = fine.matched;
  }
  res.pose = core::to_isometry(x);
  return converged;
}

OdometryResult ConsensusOdometry::process(const core::Scan& scan) {
  OdometryResult res;
  res.stamp = scan.stamp;
  if (!scan.complete()) res.flags |= kOdomScanIncomplete;
  // Constant-velocity prediction (rescaled to this scan's time step).
  const double dt =
      have_prev_ ? static_cast<double>((scan.stamp - prev_stamp_).count()) * 1e-9 : 0.1;
  const double period = have_prev2_ ? prev_period_s_ : 0.1;
  Eigen::Isometry3d motion =
      have_prev2_ ? scale_motion(prev_motion_, dt / period) : Eigen::Isometry3d::Identity();
  deskew(scan, scale_motion(motion, period / std::max(dt, 1e-3)), period);
  res.raw_points = raw_.size();
  scan_sampler_.run(raw_, test_);
  res.points = test_.size();
  if (!have_prev_) {
    res.flags |= kOdomFirstScan;
    res.pose = Eigen::Isometry3d::Identity();
    update_reference(res.pose);
    prev_pose_ = res.pose;
    prev_stamp_ = scan.stamp;
    have_prev_ = true;
    return res;
  }
  const Eigen::Isometry3d predicted = prev_pose_ * motion;
  if (test_.size() < options_.min_points) {
    res.flags |= kOdomTooFewPoints;
    res.pose = predicted;
  } else {
    core::Pose6 x0 = core::to_pose6(predicted);
    if (!have_motion_prior_) x0 = bootstrap(x0);
    Eigen::Isometry3d used_motion = motion;  // what the scan was deskewed with
    bool converged = false;
    for (int pass = 0; pass < 1 + options_.deskew_refinements; ++pass) {
      converged = match(x0, res);
      // Deskew again with the motion just estimated if it differs from the one used.
      const Eigen::Isometry3d estimated = prev_pose_.inverse() * res.pose;
      const Eigen::Isometry3d diff = used_motion.inverse() * estimated;
      const bool consistent =
          diff.translation().norm() < 0.02 && Eigen::AngleAxisd(diff.linear()).angle() < 0.002;
      if (!options_.deskew || consistent || pass == options_.deskew_refinements) break;
      used_motion = estimated;
      deskew(scan, scale_motion(estimated, period / std::max(dt, 1e-3)), period);
      scan_sampler_.run(raw_, test_);
      x0 = core::to_pose6(res.pose);
    }
    if (!converged) res.flags |= kOdomNotConverged;
    have_motion_prior_ = converged;
    if (!finite(res.pose)) {
      res.pose = predicted;
      res.flags |= kOdomNotConverged;
    }
    res.cm = consensus_at(core::to_pose6(res.pose), cv_);
    if (res.cm <= 0.0) res.flags |= kOdomDegenerate;
  }
  // Past the first scan (returned above), so the motion between the last two scans is known.
  prev_motion_ = prev_pose_.inverse() * res.pose;
  prev_period_s_ = std::max(dt, 1e-3);
  have_prev2_ = true;
  update_reference(res.pose);
  prev_pose_ = res.pose;
  prev_stamp_ = scan.stamp;
  return res;
}

}  // namespace cndt::slam
