#include "cndt/slam/mapper.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "cndt/core/pose.hpp"

namespace cndt::slam {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// T exp(delta) for a step delta = (v, w) in the sensor frame (w as a rotation vector).
Eigen::Isometry3d retract(const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 1>& d) {
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d w = d.tail<3>();
  const double angle = w.norm();
  if (angle > 0.0) step.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  step.translation() = d.head<3>();
  return T * step;
}

// Degrees of freedom the chi-square table needs: test points of up to `scans` scans, each
// downsampled to `cell`, in one voxel of edge L.
std::size_t dof_capacity(double voxel, double cell, std::size_t scans) {
  return max_centroids_per_voxel(voxel, cell, 1'000'000) * std::max<std::size_t>(1, scans);
}

}  // namespace

Mapper::KeyframeScan::KeyframeScan(const MapperOptions& o)
    : grid({o.map.voxel_size, o.scan_voxels, o.map.min_points, o.map.eigen_floor, true, false}) {
  points.reserve(o.max_scan_points);
  test.reserve(o.max_scan_points);
  mask.reserve(o.scan_voxels);
}

Mapper::Mapper(const MapperOptions& o)
    : options_(o),
      map_(o.map),
      first_occupancy_({o.similarity_voxel, o.scan_voxels, 1, 0.001, false, false}),
      occupancy_({o.similarity_voxel, o.scan_voxels, 1, 0.001, false, false}),
      chi2_(dof_capacity(o.map.voxel_size, std::min(o.test_cell, o.point_cell), o.keyframe_scans)),
      test_sampler_(o.test_cell, o.max_scan_points) {
  scans_.reserve(std::max<std::size_t>(1, o.keyframe_scans));
  for (std::size_t i = 0; i < std::max<std::size_t>(1, o.keyframe_scans); ++i) {
    scans_.emplace_back(o);
  }
  map_mask_.reserve(o.map.capacity);
  cv_.reserve(std::max(o.map.capacity, o.scan_voxels));
  residuals_.count.reserve(std::max(o.map.capacity, o.scan_voxels));
  residuals_.rss.reserve(std::max(o.map.capacity, o.scan_voxels));
  refined_.reserve(scans_.size());
}

void Mapper::start_from(NdtMap&& map, const Eigen::Isometry3d& T_map_odom) {
  map_ = std::move(map);
  T_map_odom_ = T_map_odom;
  open_ = 0;
}

double Mapper::similarity(const Eigen::Isometry3d& T, std::span<const Eigen::Vector3d> points) {
  occupancy_.clear();
  for (const auto& p : points) occupancy_.add(T * p);
  std::size_t common = 0;
  for (const ndt::Voxel& v : occupancy_.voxels()) common += first_occupancy_.index_of(v.key) >= 0;
  const std::size_t all = first_occupancy_.size() + occupancy_.size() - common;
  return all == 0 ? 0.0 : static_cast<double>(common) / static_cast<double>(all);
}

bool Mapper::add(double stamp, const Eigen::Isometry3d& T_odom_sensor,
                 std::span<const Eigen::Vector3d> points) {
  refined_.clear();
  bool closed = false;
  if (open_ > 0 && (open_ == scans_.size() ||
                    similarity(T_odom_sensor, points) < options_.keyframe_similarity)) {
    close_keyframe();
    closed = true;
  }
  KeyframeScan& k = scans_[open_++];
  k.stamp = stamp;
  k.odom = T_odom_sensor;
  k.pose = T_map_odom_ * T_odom_sensor;
  k.points.assign(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(std::min(
                                                       points.size(), options_.max_scan_points)));
  test_sampler_.run(k.points, k.test);
  if (open_ == 1) {
    first_occupancy_.clear();
    for (const auto& p : k.points) first_occupancy_.add(T_odom_sensor * p);
  }
  return closed;
}

void Mapper::flush() {
  refined_.clear();
  if (open_ > 0) close_keyframe();
}

void Mapper::compute_masks() {
  // Eqs 8-9 for every reference voxel eq 7 scores against: the map's, from all the keyframe's
  // test points, and each scan's own NDT, from the other scans' points.
  const std::size_t k = open_;
  const bool use_map = map_.gaussians() > 0;
  stats_.voxels_masked = 0;
  if (use_map) {
    residuals_.reset(map_.size());
    for (std::size_t l = 0; l < k; ++l) {
      ndt::accumulate_residuals(map_.grid(), scans_[l].test, core::to_pose6(scans_[l].pose),
                                residuals_);
    }
    ndt::voxel_consensus_all(residuals_, chi2_, {}, cv_);
    map_mask_.assign(map_.size(), 1);
    for (std::size_t i = 0; i < map_.size(); ++i) {
      if (!std::isnan(cv_[i]) && cv_[i] < options_.eta) {
        map_mask_[i] = 0;
        ++stats_.voxels_masked;
      }
    }
  }
  for (std::size_t l = 0; l < k; ++l) {
    KeyframeScan& s = scans_[l];
    residuals_.reset(s.grid.size());
    for (std::size_t m = 0; m < k; ++m) {
      if (m == l) continue;
      ndt::accumulate_residuals(s.grid, scans_[m].test,
                                core::to_pose6(s.pose.inverse() * scans_[m].pose), residuals_);
    }
    ndt::voxel_consensus_all(residuals_, chi2_, {}, cv_);
    s.mask.assign(s.grid.size(), 1);
    for (std::size_t i = 0; i < s.grid.size(); ++i) {
      if (!std::isnan(cv_[i]) && cv_[i] < options_.eta) {
        s.mask[i] = 0;
        ++stats_.voxels_masked;
      }
    }
  }
}

// Eq 7: every scan against the map, and every scan against every other scan of the keyframe.
double Mapper::total_score(const std::vector<Eigen::Isometry3d>& poses) const {
  const std::size_t k = open_;
  const bool use_map = map_.gaussians() > 0;
  double s = 0.0;
  for (std::size_t l = 0; l < k; ++l) {
    if (use_map) {
      for (const auto& p : scans_[l].test) {
        s += ndt::point_terms(map_.grid(), poses[l] * p, options_.map_neighbours, &map_mask_);
      }
    }
    for (std::size_t m = 0; m < k && options_.pair_terms; ++m) {
      if (m == l) continue;
      const Eigen::Isometry3d T_lm = poses[l].inverse() * poses[m];
      for (const auto& p : scans_[m].test) {
        s += ndt::point_terms(scans_[l].grid, T_lm * p, options_.pair_neighbours, &scans_[l].mask);
      }
    }
  }
  return s;
}

void Mapper::linearize(const std::vector<Eigen::Isometry3d>& poses, std::size_t first_free,
                       Eigen::MatrixXd& H, Eigen::VectorXd& g) const {
  // Right-multiplied steps T exp(d), d = (v, w): for a map term q = T_l p,
  // dq/dd_l = R_l [I | -[p]x]; for a pair term q = T_l^-1 T_m p (scan m against scan l's NDT),
  // dq/dd_m = R_lm [I | -[p]x] and dq/dd_l = [-I | [q]x]. With b = dS/dq and M = d2S/dq2 of the
  // point, a term adds J^T b to the gradient and J^T M J to the Hessian blocks of its scans.
  const std::size_t k = open_;
  const bool use_map = map_.gaussians() > 0;
  H.setZero();
  g.setZero();
  auto block = [&](std::size_t l) { return static_cast<Eigen::Index>(6 * (l - first_free)); };
  Eigen::Vector3d b;
  Eigen::Matrix3d M;
  Eigen::Matrix<double, 3, 6> Jl, Jm;
  for (std::size_t l = 0; l < k; ++l) {
    const bool l_free = l >= first_free;
    const Eigen::Matrix3d& Rl = poses[l].linear();
    if (use_map && l_free) {
      for (const auto& p : scans_[l].test) {
        if (ndt::point_terms(map_.grid(), poses[l] * p, options_.map_neighbours, &map_mask_, &b,
                             &M) == 0.0) {
          continue;
        }
        Jl << Rl, -Rl * skew(p);
        H.block<6, 6>(block(l), block(l)).noalias() += Jl.transpose() * M * Jl;
        g.segment<6>(block(l)).noalias() += Jl.transpose() * b;
      }
    }
    for (std::size_t m = 0; m < k && options_.pair_terms; ++m) {
      if (m == l) continue;
      const bool m_free = m >= first_free;
      if (!l_free && !m_free) continue;
      const Eigen::Isometry3d T_lm = poses[l].inverse() * poses[m];
      const Eigen::Matrix3d& R_lm = T_lm.linear();
      for (const auto& p : scans_[m].test) {
        const Eigen::Vector3d q = T_lm * p;
        if (ndt::point_terms(scans_[l].grid, q, options_.pair_neighbours, &scans_[l].mask, &b,
                             &M) == 0.0) {
          continue;
        }
        // q = exp(-d_l) T_l^-1 T_m exp(d_m) p: dq/dd_m = R_lm [I | -[p]x], dq/dd_l = [-I | [q]x].
        Jm << R_lm, -R_lm * skew(p);
        Jl << -Eigen::Matrix3d::Identity(), skew(q);
        if (m_free) {
          H.block<6, 6>(block(m), block(m)).noalias() += Jm.transpose() * M * Jm;
          g.segment<6>(block(m)).noalias() += Jm.transpose() * b;
        }
        if (l_free) {
          H.block<6, 6>(block(l), block(l)).noalias() += Jl.transpose() * M * Jl;
          g.segment<6>(block(l)).noalias() += Jl.transpose() * b;
        }
        if (l_free && m_free) {
          const Eigen::Matrix<double, 6, 6> Hlm = Jl.transpose() * M * Jm;
          H.block<6, 6>(block(l), block(m)) += Hlm;
          H.block<6, 6>(block(m), block(l)) += Hlm.transpose();
        }
      }
    }
  }
}

int Mapper::refine() {
  // Levenberg-Marquardt over the stacked 6k vector of right-multiplied pose steps. The Hessian
  // has a 6x6 block per scan and per pair of scans; each point adds to at most two blocks.
  const std::size_t k = open_;
  const bool use_map = map_.gaussians() > 0;
  // Without a map, the first scan holds the gauge (the problem is invariant to moving them all).
  const std::size_t first_free = use_map ? 0 : 1;
  if (k <= first_free) return 0;
  const auto n = static_cast<Eigen::Index>(6 * (k - first_free));
  std::vector<Eigen::Isometry3d> poses(k), trial(k);
  for (std::size_t l = 0; l < k; ++l) poses[l] = scans_[l].pose;
  double S = total_score(poses);
  stats_.last_score_before = S;
  Eigen::MatrixXd H(n, n);
  Eigen::VectorXd g(n);
  double lambda = 1e-4;
  int it = 0;
  for (; it < options_.max_iterations; ++it) {
    linearize(poses, first_free, H, g);
    auto block = [&](std::size_t l) { return static_cast<Eigen::Index>(6 * (l - first_free)); };
    // As in the odometry's Newton solver: eigenvalues made positive (a saddle still gives a
    // descent direction) and floored, then Levenberg-Marquardt damping on top.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (H + H.transpose()));
    Eigen::VectorXd ev = es.eigenvalues().cwiseAbs();
    const double largest = std::max(ev.maxCoeff(), 1e-9);
    ev = ev.cwiseMax(largest * 1e-6);
    const Eigen::VectorXd vg = es.eigenvectors().transpose() * g;
    bool accepted = false;
    Eigen::VectorXd step;
    for (int tries = 0; tries < 10 && !accepted; ++tries) {
      step = -(es.eigenvectors() * (vg.array() / (ev.array() + lambda * largest)).matrix());
      for (std::size_t l = 0; l < k; ++l) {
        trial[l] = l < first_free ? poses[l] : retract(poses[l], step.segment<6>(block(l)));
      }
      const double S_trial = total_score(trial);
      if (S_trial < S) {
        accepted = true;
        poses.swap(trial);
        S = S_trial;
        lambda = std::max(lambda / 3.0, 1e-7);
      } else {
        lambda *= 4.0;
      }
    }
    if (!accepted) break;
    double largest_t = 0.0, largest_r = 0.0;
    for (std::size_t l = first_free; l < k; ++l) {
      largest_t = std::max(largest_t, step.segment<3>(block(l)).norm());
      largest_r = std::max(largest_r, step.segment<3>(block(l) + 3).norm());
    }
    if (largest_t < 1e-3 && largest_r < 2e-4) {
      ++it;
      break;
    }
  }
  for (std::size_t l = 0; l < k; ++l) scans_[l].pose = poses[l];
  stats_.last_score_after = S;
  stats_.last_iterations = it;
  return it;
}

void Mapper::score_and_update_map() {
  // Cm of every scan against the map as it stands (eqs 8-13). Then only points in voxels the map
  // agrees with (Cv >= eta) enter; where the map cannot test a voxel (new ground, fewer test
  // points than a Cv needs) nothing speaks against the point and it enters with Cv 1.
  for (std::size_t l = 0; l < open_; ++l) {
    const KeyframeScan& s = scans_[l];
    const bool test = map_.gaussians() > 0;
    refined_.push_back({s.stamp, s.pose, std::numeric_limits<double>::quiet_NaN()});
    if (test) {
      residuals_.reset(map_.size());
      ndt::accumulate_residuals(map_.grid(), s.points, core::to_pose6(s.pose), residuals_);
      ndt::voxel_consensus_all(residuals_, chi2_, {}, cv_);
      refined_.back().cm = ndt::localization_consensus(map_.grid(), cv_, s.pose.translation());
    }
    if (!options_.update_map) continue;
    for (const auto& p : s.points) {
      const Eigen::Vector3d q = s.pose * p;
      double c = std::numeric_limits<double>::quiet_NaN();
      if (test) {
        // A voxel that this scan's own points created has no Cv: the map could not test it.
        const std::int64_t idx = map_.grid().index_of(map_.grid().key_of(q));
        if (idx >= 0 && static_cast<std::size_t>(idx) < cv_.size()) {
          c = cv_[static_cast<std::size_t>(idx)];
        }
      }
      if (!std::isnan(c) && c < options_.eta) continue;
      map_.add(q, std::isnan(c) ? 1.0 : c);
    }
    map_.finalize();
  }
  if (!options_.update_map) return;
  const Eigen::Vector3d at = scans_[open_ - 1].pose.translation();
  if ((at - last_evict_).head<2>().norm() >= options_.evict_every) {
    map_.evict_outside(at);
    last_evict_ = at;
  }
}

void Mapper::prepare_keyframe() {
  for (std::size_t l = 0; l < open_; ++l) {
    KeyframeScan& s = scans_[l];
    s.grid.clear();
    for (const auto& p : s.points) s.grid.add(p);
    s.grid.finalize();
  }
  compute_masks();
}

double Mapper::eq7(const std::vector<Eigen::Isometry3d>& poses, Eigen::VectorXd* g,
                   Eigen::MatrixXd* H) {
  prepare_keyframe();
  const auto n = static_cast<Eigen::Index>(6 * open_);
  if (g != nullptr && H != nullptr) {
    g->resize(n);
    H->resize(n, n);
    linearize(poses, 0, *H, *g);
  }
  return total_score(poses);
}

void Mapper::close_keyframe() {
  prepare_keyframe();
  refine();

  const KeyframeScan& last = scans_[open_ - 1];
  T_map_odom_ = last.pose * last.odom.inverse();
  score_and_update_map();
  ++stats_.keyframes;
  open_ = 0;
}

}  // namespace cndt::slam
