// Backward Euler by local/global iterations, after Liu, Bargteil, O'Brien and Kavan, "Fast
// Simulation of Mass-Spring Systems" (SIGGRAPH Asia 2013). The step's positions x minimise
//   ½ (x − x̂)ᵀ M̃ (x − x̂) + dt²·Σ_e ½ k_e (|x_a − x_b| − ℓ_e)² + dt²·(anchor energy, eq 8)
// (M̃ = M + dt·C, x̂ the inertial prediction with every other force held at the start of the
// step), whose minimiser is exactly the backward-Euler step. Each iteration:
//   local:  every spring's direction, d_e = ℓ_e (x_a − x_b)/|x_a − x_b| (the nearest vector of
//           its rest length to the present one). Springs are the grid's (eqs 6–7) and, with
//           SheetDef::shear, the cells' diagonals: they are springs of eq (6) too;
//   global: (M̃ + dt²·L + dt²·K_anchor + dt²·K_bend) x = M̃ x̂ + dt²·J d + dt²·K_anchor p0, with
//           L the Laplacian of the springs weighted by k and K_bend = k_b DᵀD the constant
//           Hessian of the quadratic bending energy (terms/bending.h), which therefore needs no
//           local step. That matrix depends only on the grid, the masses, the damping, the
//           anchors, the pins and dt: it is factored once (sparse Cholesky) and refactored
//           only when one of those changes, and it is the same for x, y and z.
// So springs, shear springs, bending, damping and anchors are implicit; every other force
// (air, contacts, obstacles) is held at the start of the step.
// The iteration count is fixed (the knob); fewer iterations leave the step short of
// backward Euler, never unstable (each iteration lowers the energy above).
#pragma once

#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "integrate.h"

namespace drape::detail {

struct LocalGlobalScratch {
  using Matrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

  // What the factored matrix was built from; any change rebuilds it.
  std::shared_ptr<const void> topology;  // held, so a freed topology's address cannot come back
  double dt = 0;
  std::vector<double> mass, damping, anchor_stiffness;
  std::vector<std::uint32_t> anchor_point, pin_point;
  // Every spring of the step: the topology's, then the shear diagonals (their stiffness and
  // rest length repeated per spring).
  std::vector<std::uint32_t> edge_a, edge_b;
  std::vector<double> rest, stiffness;
  bool implicit_bending = false;       // local/global: bending in the matrix; vertex block descent: held

  // The Cholesky factor L (compressed columns, diagonal entry first in each column) and its
  // fill-reducing permutation, copied out of Eigen so the three axes share one pass over L.
  std::vector<int> column_start, row_index, permutation;  // permutation: point → factor row
  std::vector<double> value, inverse_diagonal;
  std::uint64_t factorisations = 0;    // counts build_factor's factors, so a reader sees a new one
  std::vector<double> work;            // 3 per factor row: x, y, z interleaved

  std::vector<char> pinned;            // per point
  Eigen::VectorXd inertia[3];          // M̃ x̂ + dt²·(anchor targets and pinned neighbours) per axis
  Eigen::VectorXd rhs[3], solution[3];
  std::vector<double> start[3];        // x at the start of the step
  std::vector<double> spring_force[3], other_force[3];  // spring_force: springs, and bending when implicit
  std::vector<double> direction[3];    // per spring: d_e
};

template <class Real>
void local_global_step(Sheet<Real>& sheet, const StepParams<Real>& params);

// The factored matrix above, current for this sheet and dt (factored again only when its
// key changed). Implicit Euler reads its symbolic structure: the pattern of L and the
// fill-reducing permutation are those of its own matrix's point graph (springs, shear
// diagonals, bending's reach of two), so it factors its 3×3 blocks on them.
template <class Real>
void prepare_factor(LocalGlobalScratch& scratch, const Sheet<Real>& sheet, double dt);
// Only the symbolic part of it: the pattern of L and the permutation, without the numeric
// factor (value and inverse_diagonal stay empty, so a later prepare_factor makes it).
template <class Real>
void prepare_pattern(LocalGlobalScratch& scratch, const Sheet<Real>& sheet, double dt);

// The pattern of the Cholesky factor of the symmetric matrix whose lower triangle is
// `lower`, in the ordering Eigen's SimplicialLLT with AMD gives it, found from the pattern
// alone (its elimination tree and each row's reach in it, Davis, "Direct Methods for Sparse
// Linear Systems", §4): the same column_start, row_index (the diagonal first, rows
// ascending) and permutation as that factor's, without its arithmetic.
void cholesky_pattern(const LocalGlobalScratch::Matrix& lower, std::vector<int>& column_start, std::vector<int>& row_index,
                      std::vector<int>& permutation);

// What local/global and vertex block descent share: begin sets up a backward-Euler step
// (start state, the forces held explicit, M̃ x̂ into `inertia`, the first iterate x + dt·v
// into `solution`, and with `factor` the factored matrix, bending then implicit); finish
// measures the residual of the backward-Euler equations at `solution`, records the solve
// and writes x and v.
template <class Real>
void backward_euler_begin(LocalGlobalScratch& scratch, Sheet<Real>& sheet, const StepParams<Real>& params, bool factor);
template <class Real>
void backward_euler_finish(LocalGlobalScratch& scratch, Sheet<Real>& sheet, const StepParams<Real>& params,
                           int iterations);

}  // namespace drape::detail
