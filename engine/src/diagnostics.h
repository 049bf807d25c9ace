// Read-only measurements of one sheet: energies, strain, finiteness, stable step.
// Computed on demand, never inside the step.
#pragma once

#include <drape/world.h>

#include "sheet_data.h"

namespace drape::detail {

// Energies only: what the stability guard needs every frame (no strain pass).
template <class Real>
Energies sheet_energies(const Sheet<Real>& sheet, Vec3 gravity);

template <class Real>
SheetDiagnostics sheet_diagnostics(const Sheet<Real>& sheet, Vec3 gravity);

template <class Real>
bool sheet_finite(const Sheet<Real>& sheet);

template <class Real>
double sheet_stable_step(const Sheet<Real>& sheet);

}  // namespace drape::detail
