#include "cndt/ndt/newton.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace cndt::ndt {

namespace {

// Where to try next along a step after the trial at length t failed: the minimiser of the cubic
// through S(0) = s0 and S(t) = st with slopes d0 (< 0) and dt along the step (Nocedal and
// Wright, eq 3.59), or of the parabola through s0, d0 and st when the cubic has none, kept
// within [0.1 t, 0.5 t] so that the search shrinks at least as fast as halving.
double backtrack_length(double s0, double d0, double t, double st, double dt) {
  const double d1 = d0 + dt - 3.0 * (st - s0) / t;
  const double disc = d1 * d1 - d0 * dt;
  double next = 0.5 * t;
  if (disc >= 0.0) {
    const double d2 = std::sqrt(disc);
    const double denom = dt - d0 + 2.0 * d2;
    if (denom != 0.0) next = t - t * (dt + d2 - d1) / denom;
  } else if (const double curvature = st - s0 - d0 * t; curvature > 0.0) {
    next = -d0 * t * t / (2.0 * curvature);
  }
  if (!std::isfinite(next)) next = 0.5 * t;
  return std::clamp(next, 0.1 * t, 0.5 * t);
}

}  // namespace

NewtonResult newton_solve(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& initial, const NewtonOptions& o, VoxelMask mask,
                          LookupCache* cache, const ScanMotion* motion,
                          const PositionPrior* prior) {
  NewtonResult res;
  res.pose = initial;
  ScoreResult cur = ndt_score(grid, points, res.pose, true, mask, o.neighbours, cache, motion);
  res.score = cur.score;
  res.matched = cur.matched;
  res.hessian = cur.hessian;
  if (cur.matched == 0) return res;
  // The objective minimised: S, plus the prior's term when there is one.
  double w = 0.0;
  if (prior != nullptr && prior->relative_weight > 0.0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cur.hessian.topLeftCorner<3, 3>(),
                                                            Eigen::EigenvaluesOnly);
    w = prior->relative_weight * std::max(es.eigenvalues()(2), 0.0);
  }
  auto add_prior = [&](const core::Pose6& x, ScoreResult& s) {
    if (w <= 0.0) return;
    const Eigen::Vector3d d = x.head<3>() - prior->center.head<3>();
    s.score += 0.5 * w * d.squaredNorm();
    s.gradient.head<3>() += w * d;
    s.hessian.topLeftCorner<3, 3>().diagonal().array() += w;
  };
  auto remove_prior = [&](const core::Pose6& x, ScoreResult& s) {
    if (w <= 0.0) return;
    const Eigen::Vector3d d = x.head<3>() - prior->center.head<3>();
    s.score -= 0.5 * w * d.squaredNorm();
    s.hessian.topLeftCorner<3, 3>().diagonal().array() -= w;
  };
  add_prior(res.pose, cur);
  for (int it = 0; it < o.max_iterations; ++it) {
    res.iterations = it + 1;
    // Newton direction on a positive definite Hessian: eigenvalues made positive and bounded
    // below, so that a saddle or a ridge still gives a descent direction.
    Eigen::SelfAdjointEigenSolver<Matrix6d> es(0.5 * (cur.hessian + cur.hessian.transpose()));
    Vector6d ev = es.eigenvalues().cwiseAbs();
    const double floor = std::max(ev.maxCoeff() * 1e-6, 1e-9);
    ev = ev.cwiseMax(floor);
    Vector6d step = -(es.eigenvectors() * ev.cwiseInverse().asDiagonal() *
                      es.eigenvectors().transpose() * cur.gradient);
    const double tn = step.head<3>().norm(), rn = step.tail<3>().norm();
    const double scale = std::min({1.0, o.max_translation_step / std::max(tn, 1e-12),
                                   o.max_rotation_step / std::max(rn, 1e-12)});
    step *= scale;
    // Backtracking line search (Armijo) on S. The full step is usually accepted, so its trial
    // carries the derivatives the next iteration needs. A rejected trial's slope along the step
    // places the next one at the minimum of the cubic through both ends (backtrack_length).
    // On NDT's thin planes a quarter of the steps overshoot, and halving took two trials to
    // place each of them; the cubic takes fewer and lands nearer the minimum along the step.
    const double slope = cur.gradient.dot(step);
    double t = 1.0;
    core::Pose6 next = res.pose + step;
    ScoreResult trial = ndt_score(grid, points, next, true, mask, o.neighbours, cache, motion);
    add_prior(next, trial);
    for (int k = 0; k < 10 && trial.score > cur.score + 1e-4 * t * slope; ++k) {
      t = backtrack_length(cur.score, slope, t, trial.score, trial.gradient.dot(step));
      next = res.pose + t * step;
      trial = ndt_score(grid, points, next, true, mask, o.neighbours, cache, motion);
      add_prior(next, trial);
    }
    if (trial.score > cur.score) {
      res.converged = true;  // no step improves S: at the minimum to numerical precision
      break;
    }
    const double change = std::abs(trial.score - cur.score) / std::max(1.0, std::abs(cur.score));
    res.pose = next;
    cur = trial;
    ScoreResult own = cur;  // S's alone
    remove_prior(next, own);
    res.score = own.score;
    res.matched = own.matched;
    res.hessian = own.hessian;
    const bool small_step = t * tn * scale < o.translation_eps && t * rn * scale < o.rotation_eps;
    if (small_step || change < o.score_eps) {
      res.converged = true;
      break;
    }
  }
  return res;
}

}  // namespace cndt::ndt
