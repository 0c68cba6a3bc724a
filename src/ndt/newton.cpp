#include "cndt/ndt/newton.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace cndt::ndt {

NewtonResult newton_solve(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                          const core::Pose6& initial, const NewtonOptions& o, VoxelMask mask,
                          LookupCache* cache, const ScanMotion* motion) {
  NewtonResult res;
  res.pose = initial;
  ScoreResult cur = ndt_score(grid, points, res.pose, true, mask, o.neighbours, cache, motion);
  res.score = cur.score;
  res.matched = cur.matched;
  res.hessian = cur.hessian;
  if (cur.matched == 0) return res;
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
    // carries the derivatives the next iteration needs.
    const double slope = cur.gradient.dot(step);
    double t = 1.0;
    core::Pose6 next = res.pose + step;
    ScoreResult trial = ndt_score(grid, points, next, true, mask, o.neighbours, cache, motion);
    bool trial_has_derivatives = true;
    for (int k = 0; k < 10 && trial.score > cur.score + 1e-4 * t * slope; ++k) {
      t *= 0.5;
      next = res.pose + t * step;
      trial = ndt_score(grid, points, next, false, mask, o.neighbours, cache, motion);
      trial_has_derivatives = false;
    }
    if (trial.score > cur.score) {
      res.converged = true;  // no step improves S: at the minimum to numerical precision
      break;
    }
    const double change = std::abs(trial.score - cur.score) / std::max(1.0, std::abs(cur.score));
    res.pose = next;
    cur = trial_has_derivatives
              ? trial
              : ndt_score(grid, points, res.pose, true, mask, o.neighbours, cache, motion);
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
