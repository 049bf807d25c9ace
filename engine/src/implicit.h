// Implicit (backward) Euler linearised once per step, after Baraff & Witkin, "Large steps in
// cloth simulation" (SIGGRAPH 1998): one Newton step of
//   M Δv = dt·f(x + dt(v + Δv), v + Δv)
// with f expanded to first order, i.e. the symmetric system
//   (M − dt·∂f/∂v − dt²·∂f/∂x) Δv = dt·(f + dt·∂f/∂x·v),
// assembled as an Eigen sparse matrix and solved by preconditioned conjugate gradient, with
// one of two preconditioners (Preconditioner, types.h):
//   block Jacobi: the inverses of its 3×3 diagonal blocks (one per point);
//   Cholesky: a sparse Cholesky factor of the matrix itself, in 3×3 blocks on the symbolic
//     structure (pattern of L, fill-reducing permutation) of local/global's factored
//     matrix, whose point graph is the same (local_global.h), by supernodes with dense
//     kernels (supernodal.h); in float first, in double when float's factor does not bring
//     CG to its tolerance; kept for later steps while it still brings their CG to the
//     tolerance within a few iterations (cholesky_cg, ImplicitMemory, implicit.cpp).
// The factored mass–spring matrix of local/global (M̃ + dt²·L, the same for x, y and z) was
// tried as the preconditioner first and measured worse than block Jacobi: it counts every
// spring as stiff in all three directions, while the system is stiff only along each
// spring (u uᵀ), so the modes a grid of springs barely resists (out of plane, and in-plane
// shear of a grid without diagonals) come out of it with eigenvalues near m/(dt²k), and CG
// took hundreds of iterations at k ≥ 1e3 N/m on 64×64 (docs/integrators.md). A factor kept
// from an earlier step fails the same way once springs have turned far enough, hence its
// small budget and back-off (implicit.cpp).
#pragma once

#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <array>
#include <vector>

#include "integrate.h"
#include "supernodal.h"

namespace drape::detail {

// Which Cholesky factor preconditions implicit Euler's solves (implicit.cpp).
enum class FactorKind { None = 0, Single = 1, Full = 2 };

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
  std::vector<Real> spring_direction;  // per spring: u and the transverse factor (spring_jacobian.h)
  Vector rhs, dv;                 // dv: the solution (its copy in Sheet::integrator_scratch is the next guess)
  Vector residual, direction, preconditioned, product;  // the solve's work vectors
  Vector best;  // the iterate of smallest residual so far: what a solve that diverged returns
  std::vector<Real> block_inverse;  // per point: the inverse of its 3×3 diagonal block, row-major

  // Auto's rule reads the sheet's stiffest spring mode, sheet_spring_frequency (Gershgorin).
  double omega_max = 0;
  // The Cholesky preconditioner: L on the pattern of local/global's point factor, by
  // supernodes (`factor`); `source`: per 3×3 block of that pattern that is in `system`
  // (not fill), its entry in the pattern, its column and the offsets in `system` of its
  // three rows. Built for one factor of local/global (`structure`,
  // `structure_factorisations`) and one pattern of `system`.
  const void* structure = nullptr;
  std::uint64_t structure_factorisations = 0;
  struct Source {
    int entry, column;
    std::array<int, 3> row;
  };
  std::vector<Source> source;
  std::vector<int> point_of;                 // factor row → point
  // The factor in float first (half the memory traffic, twice the vector width; a few CG
  // iterations instead of one), in double when float's does not serve (implicit.cpp).
  SupernodalFactor<float> single;
  SupernodalFactor<double> full;
  bool full_analysed = false;
  FactorKind held = FactorKind::None;  // the factor in `single` or `full`, kept across steps
  std::vector<Real> held_key;          // the memory's key it was made for (implicit.cpp)
  SupernodalFactor<float>::Aligned single_work;
  SupernodalFactor<double>::Aligned full_work;
};

template <class Real>
void implicit_euler_step(Sheet<Real>& sheet, const StepParams<Real>& params);

}  // namespace drape::detail
