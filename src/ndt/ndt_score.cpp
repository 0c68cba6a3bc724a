#include "cndt/ndt/ndt_score.hpp"

#include <cmath>

namespace cndt::ndt {
namespace {

// Elementary rotations and their derivatives by the angle.
Eigen::Matrix3d rx(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << 1, 0, 0, 0, c, -s, 0, s, c;
  if (order == 1) m << 0, 0, 0, 0, -s, -c, 0, c, -s;
  if (order == 2) m << 0, 0, 0, 0, -c, s, 0, -s, -c;
  return m;
}
Eigen::Matrix3d ry(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << c, 0, s, 0, 1, 0, -s, 0, c;
  if (order == 1) m << -s, 0, c, 0, 0, 0, -c, 0, -s;
  if (order == 2) m << -c, 0, -s, 0, 0, 0, s, 0, -c;
  return m;
}
Eigen::Matrix3d rz(double a, int order) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix3d m;
  if (order == 0) m << c, -s, 0, s, c, 0, 0, 0, 1;
  if (order == 1) m << -s, -c, 0, c, -s, 0, 0, 0, 0;
  if (order == 2) m << -c, s, 0, -s, -c, 0, 0, 0, 0;
  return m;
}

}  // namespace

PoseDerivatives::PoseDerivatives(const core::Pose6& x) : t_(x.head<3>()) {
  const double phi = x[3], theta = x[4], psi = x[5];
  // Derivative orders of (Rx, Ry, Rz) for R, the three first and the six second derivatives.
  auto R = [&](int a, int b, int c) -> Eigen::Matrix3d {
    return rx(phi, a) * ry(theta, b) * rz(psi, c);  // evaluated: no expression of temporaries
  };
  R_ = R(0, 0, 0);
  d1_ = {R(1, 0, 0), R(0, 1, 0), R(0, 0, 1)};
  d2_ = {R(2, 0, 0), R(1, 1, 0), R(1, 0, 1), R(0, 2, 0), R(0, 1, 1), R(0, 0, 2)};
}

void PoseDerivatives::jacobian(const Eigen::Vector3d& p, Eigen::Matrix<double, 3, 6>& J) const {
  J.leftCols<3>().setIdentity();
  for (int a = 0; a < 3; ++a) J.col(3 + a) = d1_[static_cast<std::size_t>(a)] * p;
}

void PoseDerivatives::second(const Eigen::Vector3d& p, std::array<Eigen::Vector3d, 6>& d2) const {
  for (std::size_t i = 0; i < 6; ++i) d2[i] = d2_[i] * p;
}

ScoreResult ndt_score(const VoxelGrid& grid, std::span<const Eigen::Vector3d> points,
                      const core::Pose6& x, bool derivatives, VoxelMask mask,
                      Neighbours neighbours) {
  const PoseDerivatives pd(x);
  ScoreResult r;
  Eigen::Matrix<double, 3, 6> J = Eigen::Matrix<double, 3, 6>::Zero();
  std::array<Eigen::Vector3d, 6> d2;
  d2.fill(Eigen::Vector3d::Zero());
  constexpr int kPair[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  constexpr int kOffsets[7][3] = {{0, 0, 0},  {1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                  {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  const int lookups = static_cast<int>(neighbours);
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d v = pd.transform(p);
    const VoxelKey key = grid.key_of(v);
    bool have_derivatives = false;
    Vector6d aJ = Vector6d::Zero();
    for (int n = 0; n < lookups; ++n) {
      const VoxelKey k{key.x + kOffsets[n][0], key.y + kOffsets[n][1], key.z + kOffsets[n][2]};
      const std::int64_t idx = grid.index_of(k);
      if (idx < 0) continue;
      const Voxel& vox = grid.voxels()[static_cast<std::size_t>(idx)];
      if (!vox.has_gaussian || (mask != nullptr && (*mask)[static_cast<std::size_t>(idx)] == 0)) {
        continue;
      }
      const Eigen::Vector3d q = v - vox.mean;
      const Eigen::Vector3d a = vox.inv_cov * q;
      const double e = std::exp(-0.5 * q.dot(a));
      r.score -= e;  // eq 5
      ++r.matched;
      if (!derivatives) continue;
      if (!have_derivatives) {  // J and d2 depend on the point only, not on the voxel
        pd.jacobian(p, J);
        pd.second(p, d2);
        have_derivatives = true;
      }
      aJ.noalias() = J.transpose() * a;  // q^T A dq/dx_k
      r.gradient += e * aJ;              // dS/dx_k = e q^T A J_k
      // d2S/dx_k dx_l = e (-(q^T A J_k)(q^T A J_l) + J_k^T A J_l + q^T A d2q/dx_k dx_l)
      const Eigen::Matrix<double, 3, 6> AJ = vox.inv_cov * J;
      Matrix6d h = J.transpose() * AJ - aJ * aJ.transpose();
      for (int k2 = 0; k2 < 3; ++k2) {
        for (int l = 0; l < 3; ++l) {
          h(3 + k2, 3 + l) += a.dot(d2[static_cast<std::size_t>(kPair[k2][l])]);
        }
      }
      r.hessian += e * h;
    }
  }
  return r;
}

}  // namespace cndt::ndt
