// Time integrators of one sheet. Each is one function over the sheet's SoA buffers;
// integrate() dispatches once per sheet and substep, never per point. Every force
// evaluation goes through sheet_forces(), so a term added there works with every integrator.
#pragma once

#include "sheet_data.h"

namespace drape::detail {

template <class Real>
struct StepParams {
  Real dt;
  Real gx, gy, gz;  // gravity, applied as an acceleration of every point
  // implicit Euler only: conjugate gradient's relative residual target and iteration cap
  double cg_tolerance = 1e-6;
  int cg_max_iterations = 200;
};

template <class Real>
void integrate(Integrator integrator, Sheet<Real>& sheet, const StepParams<Real>& params);

// Implicit Euler's last conjugate-gradient solve on this sheet: iterations and relative
// residual; {0, 0} before its first implicit step.
struct SolveStats {
  int iterations = 0;
  double relative_residual = 0;
};
template <class Real>
SolveStats implicit_solve_stats(const Sheet<Real>& sheet);

}  // namespace drape::detail
