// Implicit (backward) Euler linearised once per step, after Baraff & Witkin, "Large steps in
// cloth simulation" (SIGGRAPH 1998): one Newton step of
//   M Δv = dt·f(x + dt(v + Δv), v + Δv)
// with f expanded to first order, i.e. the symmetric system
//   (M − dt·∂f/∂v − dt²·∂f/∂x) Δv = dt·(f + dt·∂f/∂x·v),
// assembled as an Eigen sparse matrix and solved by conjugate gradient preconditioned with
// the inverses of its 3×3 diagonal blocks (one per point).
#pragma once

#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <vector>

#include "integrate.h"

namespace drape::detail {

template <class Real>
struct ImplicitScratch {
  using Matrix = Eigen::SparseMatrix<Real, Eigen::RowMajor, int>;
  using Vector = Eigen::Matrix<Real, Eigen::Dynamic, 1>;

  // The topology and pins the pattern below was built for: a scratch is rebuilt when either changes.
  const Topology<Real>* topology = nullptr;
  std::size_t pin_count = 0;

  Matrix system;                  // 3N×3N, fixed pattern: 3×3 block per point and per spring end pair
  std::vector<int> diagonal;      // per scalar row 3p+r: value offset of entry (3p+r, 3p)
  std::vector<int> upper, lower;  // per spring e and r: offsets of (3a+r, 3b) and (3b+r, 3a)
  std::vector<Real> free;         // per point: 1, or 0 for a pinned point (its rows and columns are dropped)
  Vector rhs, dv;                 // dv: the solution (its copy in Sheet::integrator_scratch is the next guess)
  Vector residual, direction, preconditioned, product;  // the solve's work vectors
  std::vector<Real> block_inverse;  // per point: the inverse of its 3×3 diagonal block, row-major
};

template <class Real>
void implicit_euler_step(Sheet<Real>& sheet, const StepParams<Real>& params);

}  // namespace drape::detail
