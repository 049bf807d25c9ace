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

// 2/ω_max for the explicit integrators, ω_max from the springs' Gershgorin bound and the
// damping of eq (4) at each point (World::stable_step_estimate).
template <class Real>
double sheet_stable_step(const Sheet<Real>& sheet);

// The springs' Gershgorin bound on the highest angular frequency (rad/s), damping left out:
// the stiffness an implicit solve faces, which damping only makes better conditioned.
template <class Real>
double sheet_spring_frequency(const Sheet<Real>& sheet);

}  // namespace drape::detail
