// A sheet's force terms, as one list built from its definition (SheetDef → Topology and
// Sheet), in the one order every path adds them to a point:
//
//   row stencils, as each row arrives in the sweep (forces.cpp, arrive):
//     1. grid springs, eqs (6)–(7)         forces.cpp (row_springs, column_springs)
//     2. shear springs                     terms/shear.h
//     3. bending                           terms/bending.h
//     4. air                               terms/air.h
//   per point, once a row's stencils are final (forces.cpp, add_point_terms):
//     5. damping, eq (4)'s C               forces.cpp
//     6. contacts (the host stage's sums)  contacts.cpp gathers them
//     7. anchors, eq (8)                   forces.h (add_anchor)
//   whole sheet, after every row:
//     8. obstacles, eq (9)                 obstacles.cpp (obstacle_forces)
//
// A sheet without terms 2–4 runs the sweep with NoRowTerms: the paper's kernel, with no
// branch or call for them. Each term file gives its force (arrive, or runs for the sweep's
// vector kernels: shear's diagonals, air's cells), its energy (for the
// guard and diagnostics), its Jacobian for implicit Euler (add_jacobian; air has none: it
// depends on velocity and is taken explicitly) and its share of the stable-step bound.
#pragma once

#include "air.h"
#include "bending.h"
#include "shear.h"

namespace drape::detail {

// Terms 2–4 of one sheet, each present or not.
template <class Real>
struct RowTerms {
  const typename Topology<Real>::Shear* shear = nullptr;
  const Real* bending = nullptr;
  const Air<Real>* air = nullptr;
  std::uint32_t n = 0;

  // Rows on each side a term reads to finish a row's force: the sweep finishes row q − reach
  // when row q arrives, and a wave lags this many rows per substep.
  std::uint32_t reach() const { return bending ? 2 : 1; }

  // Their forces as row q arrives are added by the sweep (forces.cpp, terms_arrive), in
  // this order: shear (shear::diagonals), bending (bending::arrive), air (air::cells, then
  // air::spread). Shear and air hand it runs for its vector kernels.
};

// The paper's sheet: the grid springs alone.
struct NoRowTerms {
  static constexpr std::uint32_t reach() { return 1; }
};

template <class Real>
RowTerms<Real> row_terms_of(const Sheet<Real>& s) {
  const Topology<Real>& t = *s.topology;
  return {t.shear ? &*t.shear : nullptr, t.bending ? &*t.bending : nullptr, s.air ? &*s.air : nullptr, t.n};
}

template <class Real>
bool has_row_terms(const Sheet<Real>& s) {
  return s.topology->shear || s.topology->bending || s.air;
}

// The rows on each side that finish a row's force for this sheet.
template <class Real>
std::uint32_t force_reach(const Sheet<Real>& s) {
  return row_terms_of(s).reach();
}

// Energies of terms 2–3 at positions x: shear springs count as springs.
template <class Real>
void add_term_energies(const Sheet<Real>& s, ConstVec3Ptr<Real> x, double& spring, double& bend) {
  const Topology<Real>& t = *s.topology;
  if (t.shear) spring += shear::energy(t, x);
  if (t.bending) bend += bending::energy(t, x);
}

// The Jacobians of terms 2–3 at positions x, block by block (rows.h).
template <class Real, class Add>
void add_term_jacobians(const Sheet<Real>& s, ConstVec3Ptr<Real> x, Add add) {
  const Topology<Real>& t = *s.topology;
  if (t.shear) shear::add_jacobian(t, x, add);
  if (t.bending) bending::add_jacobian(t, add);
}

// out += J·dx for terms 2–3: the Jacobian-vector product a matrix-free solver needs.
template <class Real>
void term_jvp(const Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> dx, Vec3Ptr<Real> out) {
  add_term_jacobians(s, x, [&](std::uint32_t p, std::uint32_t q, const Real (&j)[3][3]) {
    const Real d[3] = {dx.x[q], dx.y[q], dx.z[q]};
    Real* o[3] = {out.x + p, out.y + p, out.z + p};
    for (int r = 0; r < 3; ++r) *o[r] += j[r][0] * d[0] + j[r][1] * d[1] + j[r][2] * d[2];
  });
}

// Terms 2–3's share of the Gershgorin bound on each point's stiffness (diagnostics.cpp).
template <class Real>
void add_term_stiffness_bounds(const Sheet<Real>& s, double* k_sum) {
  const Topology<Real>& t = *s.topology;
  if (t.shear) shear::add_stiffness_bound(t, k_sum);
  if (t.bending) bending::add_stiffness_bound(t, k_sum);
}

}  // namespace drape::detail
