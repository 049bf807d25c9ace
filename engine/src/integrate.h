// Time integrators of one sheet. Each is one function over the sheet's SoA buffers;
// integrate() dispatches once per sheet and substep, never per point.
#pragma once

#include "sheet_data.h"

namespace drape::detail {

template <class Real>
struct StepParams {
  Real dt;
  Real gx, gy, gz;  // gravity, applied as an acceleration of every point
};

template <class Real>
void integrate(Integrator integrator, Sheet<Real>& sheet, const StepParams<Real>& params);

}  // namespace drape::detail
