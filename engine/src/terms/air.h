// Air (SheetDef::air, WorldDef::wind): per cell of the grid, against a uniform wind. With
// c = d1 × d2 the cross product of the cell's diagonals (|c| = 2A for a flat cell, c/|c| its
// normal n) and v the mean velocity of its four corners relative to the wind:
//   pressure  F = −½ρC_n A |v·n| (v·n) n = −¼ρC_n |v·c| (v·c) c / |c|²
//   friction  F = −½ρC_t A |v_t| v_t,   v_t = v − (v·c) c / |c|²
// a quarter of F on each corner. The pressure is the drag of a sheet falling flat and, on a
// cell inclined to the flow, also its lift (the force is along n, not against v).
// A row stencil of reach 1 that reads velocities: the cells between rows q−1 and q arrive
// with row q. It depends on v, so it has no potential energy and no position Jacobian:
// implicit Euler takes it explicitly.
#pragma once

#include <cmath>

#include "rows.h"

namespace drape::detail::air {

// The force on each cell between rows a and b into f (n values per component). Every
// pointer is a restrict parameter (GCC ignores restrict on locals here and gives up on the
// run-time alias checks of so many arrays), so the loop vectorises.
template <class Real>
DRAPE_ROW_INLINE void cells(std::uint32_t n, Real half_pressure, Real half_friction, Real wx, Real wy, Real wz,
                  const Real* __restrict ax, const Real* __restrict ay, const Real* __restrict az,
                  const Real* __restrict bx, const Real* __restrict by, const Real* __restrict bz,
                  const Real* __restrict avx, const Real* __restrict avy, const Real* __restrict avz,
                  const Real* __restrict bvx, const Real* __restrict bvy, const Real* __restrict bvz,
                  Real* __restrict fx, Real* __restrict fy, Real* __restrict fz) {
  const Real quarter = Real(0.25);
  for (std::uint32_t j = 0; j < n; ++j) {
    const Real d1x = bx[j + 1] - ax[j], d1y = by[j + 1] - ay[j], d1z = bz[j + 1] - az[j];
    const Real d2x = bx[j] - ax[j + 1], d2y = by[j] - ay[j + 1], d2z = bz[j] - az[j + 1];
    const Real cx = d1y * d2z - d1z * d2y, cy = d1z * d2x - d1x * d2z, cz = d1x * d2y - d1y * d2x;
    const Real vx = quarter * (avx[j] + avx[j + 1] + bvx[j] + bvx[j + 1]) - wx;
    const Real vy = quarter * (avy[j] + avy[j + 1] + bvy[j] + bvy[j + 1]) - wy;
    const Real vz = quarter * (avz[j] + avz[j + 1] + bvz[j] + bvz[j + 1]) - wz;
    const Real cc = cx * cx + cy * cy + cz * cz;
    const Real inv = cc > Real(0) ? Real(1) / cc : Real(0);  // a collapsed cell feels no air
    const Real vc = vx * cx + vy * cy + vz * cz;
    const Real normal = -half_pressure * std::abs(vc) * vc * inv;
    const Real tx = vx - vc * inv * cx, ty = vy - vc * inv * cy, tz = vz - vc * inv * cz;
    // ½ρC_t A |v_t| with A = |c|/2
    const Real tangential = -half_friction * std::sqrt(cc * (tx * tx + ty * ty + tz * tz));
    fx[j] = normal * cx + tangential * tx;
    fy[j] = normal * cy + tangential * ty;
    fz[j] = normal * cz + tangential * tz;
  }
}

template <class Real>
DRAPE_ROW_INLINE void cell_forces(std::uint32_t n, const Air<Real>& air, ConstVec3Ptr<Real> xa, ConstVec3Ptr<Real> xb,
                        ConstVec3Ptr<Real> va, ConstVec3Ptr<Real> vb, Vec3Ptr<Real> cell) {
  cells(n, Real(0.5) * air.pressure, Real(0.5) * air.friction, air.wind[0], air.wind[1], air.wind[2], xa.x, xa.y,
        xa.z, xb.x, xb.y, xb.z, va.x, va.y, va.z, vb.x, vb.y, vb.z, cell.x, cell.y, cell.z);
}

// A quarter of the force of each cell next to point j of one component of a row (cells
// j−1 and j).
template <class Real>
DRAPE_ROW_INLINE void add_to_line(std::uint32_t n, const Real* __restrict cell, Real* __restrict f) {
  const Real quarter = Real(0.25);
  f[0] += quarter * cell[0];
  for (std::uint32_t j = 1; j < n; ++j) f[j] += quarter * (cell[j - 1] + cell[j]);
  f[n] += quarter * cell[n - 1];
}

template <class Real>
DRAPE_ROW_INLINE void add_to_row(std::uint32_t n, ConstVec3Ptr<Real> cell, Vec3Ptr<Real> f) {
  add_to_line(n, cell.x, f.x);
  add_to_line(n, cell.y, f.y);
  add_to_line(n, cell.z, f.z);
}

// Row q has arrived: the cells between rows q−1 and q.
template <class Real, class Window>
DRAPE_ROW_INLINE void arrive(const Air<Real>& air, std::uint32_t n, const Window& w, std::uint32_t q) {
  if (q == 0 || n == 0 || q - 1 < w.read_lo) return;
  const bool to_a = w.owns(q - 1), to_b = w.owns(q);
  if (!to_a && !to_b) return;
  cell_forces(n, air, w.x(q - 1), w.x(q), w.v(q - 1), w.v(q), w.scratch);
  if (to_a) add_to_row<Real>(n, w.scratch, w.f(q - 1));
  if (to_b) add_to_row<Real>(n, w.scratch, w.f(q));
}

}  // namespace drape::detail::air
