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
  // The objective minimised: S, plus the prior's w |t - t_prior|^2 / 2 when there is one. The
  // scorings stay S's own (the result reports them); the prior's terms are added where the
  // solver reads the objective.
  double w = 0.0;
  if (prior != nullptr && prior->relative_weight > 0.0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cur.hessian.topLeftCorner<3, 3>(),
                                                            Eigen::EigenvaluesOnly);
    w = prior->relative_weight * std::max(es.eigenvalues()(2), 0.0);
  }
  struct Objective {
    double value;
    Vector6d gradient;
  };
  auto objective = [&](const ScoreResult& s, const core::Pose6& x) {
    Objective f{s.score, s.gradient};
    if (w > 0.0) {
      const Eigen::Vector3d d = x.head<3>() - prior->center.head<3>();
      f.value += 0.5 * w * d.squaredNorm();
      f.gradient.head<3>() += w * d;
    }
    return f;
  };
  Objective f_cur = objective(cur, res.pose);
  for (int it = 0; it < o.max_iterations; ++it) {
    res.iterations = it + 1;
    // Newton direction on a positive definite Hessian: eigenvalues made positive and bounded
    // below, so that a saddle or a ridge still gives a descent direction.
    Matrix6d hessian = 0.5 * (cur.hessian + cur.hessian.transpose());
    hessian.topLeftCorner<3, 3>().diagonal().array() += w;  // the prior's
    Eigen::SelfAdjointEigenSolver<Matrix6d> es(hessian);
    Vector6d ev = es.eigenvalues().cwiseAbs();
    const double floor = std::max(ev.maxCoeff() * 1e-6, 1e-9);
    ev = ev.cwiseMax(floor);
    Vector6d step = -(es.eigenvectors() * ev.cwiseInverse().asDiagonal() *
                      es.eigenvectors().transpose() * f_cur.gradient);
    const double tn = step.head<3>().norm(), rn = step.tail<3>().norm();
    const double scale = std::min({1.0, o.max_translation_step / std::max(tn, 1e-12),
                                   o.max_rotation_step / std::max(rn, 1e-12)});
    step *= scale;
    // Backtracking line search (Armijo) on the objective. The full step is usually accepted, so
    // its trial carries the derivatives the next iteration needs. A rejected trial's slope along
    // the step places the next one at the minimum of the cubic through both ends
    // (backtrack_length). On NDT's thin planes a quarter of the steps overshoot, and halving
    // took two trials to place each of them; the cubic takes fewer and lands nearer the minimum
    // along the step.
    const double slope = f_cur.gradient.dot(step);
    double t = 1.0;
    core::Pose6 next = res.pose + step;
    ScoreResult trial = ndt_score(grid, points, next, true, mask, o.neighbours, cache, motion);
    Objective f_trial = objective(trial, next);
    for (int k = 0; k < 10 && f_trial.value > f_cur.value + 1e-4 * t * slope; ++k) {
      t = backtrack_length(f_cur.value, slope, t, f_trial.value, f_trial.gradient.dot(step));
      next = res.pose + t * step;
      trial = ndt_score(grid, points, next, true, mask, o.neighbours, cache, motion);
      f_trial = objective(trial, next);
    }
    if (f_trial.value > f_cur.value) {
      res.converged = true;  // no step improves S: at the minimum to numerical precision
      break;
    }
    const double change =
        std::abs(f_trial.value - f_cur.value) / std::max(1.0, std::abs(f_cur.value));
    res.pose = next;
    cur = trial;
    f_cur = f_trial;
    res.score = cur.score;
    res.matched = cur.matched;
    res.hessian = cur.hessian;
    const bool small_step = t * tn * scale < o.translation_eps && t * rn * scale < o.rotation_eps;
    if (small_step || change < o.score_eps) {
      res.converged = true;
      break;
    }
  }
  return res;
}

}  // namespace cndt::ndt
