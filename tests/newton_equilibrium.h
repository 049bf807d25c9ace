// An independent static equilibrium for springs under gravity, for tests: Newton's method
// with a backtracking line search on
//   E(x) = Σ_springs ½k(|xa − xb| − ℓ)² + Σ_points m g z,
// with some points held fixed. Written from the energy alone; it shares no code with the
// engine's kernels.
#pragma once

#include <Eigen/Dense>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace drape::testing {

struct Spring {
  std::uint32_t a, b;
  double k, rest;
};

// From `x` (3 values per point), which must stretch every spring so the Hessian is definite.
inline Eigen::VectorXd newton_equilibrium(Eigen::VectorXd x, const std::vector<Spring>& springs,
                                          const std::vector<double>& mass, const std::vector<bool>& fixed, double g) {
  const std::size_t count = mass.size();
  auto energy = [&](const Eigen::VectorXd& y) {
    double e = 0;
    for (const Spring& s : springs) {
      const double len = (y.segment<3>(3 * s.a) - y.segment<3>(3 * s.b)).norm();
      e += 0.5 * s.k * (len - s.rest) * (len - s.rest);
    }
    for (std::size_t p = 0; p < count; ++p) e += mass[p] * g * y[3 * p + 2];
    return e;
  };
  for (int iter = 0; iter < 200; ++iter) {
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(3 * count);
    Eigen::MatrixXd hess = Eigen::MatrixXd::Zero(3 * count, 3 * count);
    for (const Spring& s : springs) {
      const Eigen::Vector3d d = x.segment<3>(3 * s.a) - x.segment<3>(3 * s.b);
      const double len = d.norm();
      const Eigen::Vector3d u = d / len;
      const Eigen::Vector3d ga = s.k * (len - s.rest) * u;
      // ∂²E/∂xa² = k[u uᵀ + (1 − ℓ/len)(I − u uᵀ)], the transverse part clamped at 0
      const Eigen::Matrix3d block =
          s.k * (u * u.transpose() + std::max(0.0, 1 - s.rest / len) * (Eigen::Matrix3d::Identity() - u * u.transpose()));
      grad.segment<3>(3 * s.a) += ga;
      grad.segment<3>(3 * s.b) -= ga;
      hess.block<3, 3>(3 * s.a, 3 * s.a) += block;
      hess.block<3, 3>(3 * s.b, 3 * s.b) += block;
      hess.block<3, 3>(3 * s.a, 3 * s.b) -= block;
      hess.block<3, 3>(3 * s.b, 3 * s.a) -= block;
    }
    for (std::size_t p = 0; p < count; ++p) grad[3 * p + 2] += mass[p] * g;
    for (std::size_t p = 0; p < count; ++p)
      if (fixed[p])
        for (int c = 0; c < 3; ++c) {
          const int r = int(3 * p) + c;
          grad[r] = 0;
          hess.row(r).setZero();
          hess.col(r).setZero();
          hess(r, r) = 1;
        }
    if (grad.norm() < 1e-12) break;
    const Eigen::VectorXd step = hess.ldlt().solve(-grad);
    const double e0 = energy(x);
    double t = 1;
    while (t > 1e-10 && energy(x + t * step) > e0 + 1e-4 * t * grad.dot(step)) t /= 2;
    x += t * step;
  }
  return x;
}

}  // namespace drape::testing
