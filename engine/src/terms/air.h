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

#include "../simd/kernels.h"
#include "rows.h"

namespace drape::detail::air {

// Row q has arrived: the cells between rows q−1 and q, as a row of cells for the sweep's
// vector kernel (forces.cpp, terms_arrive; simd/kernels-inl.h, air_cells_of), which puts
// each cell's force into the window's scratch row; then spread() adds it to the owned rows.
// The kernel computes per cell j (corners j, j + 1 of both rows), in this order:
//   d1 = b[j+1] − a[j],  d2 = b[j] − a[j+1],  c = d1 × d2,  cc = c·c
//   v  = ¼ (va[j] + va[j+1] + vb[j] + vb[j+1]) − wind,  vc = v·c,  inv = 1/cc (0 for cc = 0)
//   normal = −½ρC_n |vc| vc inv,  t = v − (vc inv) c,  tangential = −½ρC_t √(cc · t·t)
//   f = normal c + tangential t
// No cells (count 0) when the window cannot read row q−1 or owns neither row.
template <class Real, class Window>
DRAPE_ROW_INLINE simd::AirCells<Real> cells(const Air<Real>& air, std::uint32_t n, const Window& w, std::uint32_t q) {
  simd::AirCells<Real> r;
  if (q == 0 || n == 0 || q - 1 < w.read_lo || (!w.owns(q - 1) && !w.owns(q))) return r;
  const auto xa = w.x(q - 1), xb = w.x(q), va = w.v(q - 1), vb = w.v(q);
  r.count = n;
  r.ax = xa.x, r.ay = xa.y, r.az = xa.z, r.bx = xb.x, r.by = xb.y, r.bz = xb.z;
  r.avx = va.x, r.avy = va.y, r.avz = va.z, r.bvx = vb.x, r.bvy = vb.y, r.bvz = vb.z;
  r.fx = w.scratch.x, r.fy = w.scratch.y, r.fz = w.scratch.z;
  r.half_pressure = Real(0.5) * air.pressure;
  r.half_friction = Real(0.5) * air.friction;
  r.wx = air.wind[0], r.wy = air.wind[1], r.wz = air.wind[2];
  return r;
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

// The cells' forces in the scratch row (after the kernel ran on cells()), a quarter to
// each of their corners on the rows the window owns.
template <class Real, class Window>
DRAPE_ROW_INLINE void spread(std::uint32_t n, const Window& w, std::uint32_t q) {
  if (w.owns(q - 1)) add_to_row<Real>(n, w.scratch, w.f(q - 1));
  if (w.owns(q)) add_to_row<Real>(n, w.scratch, w.f(q));
}

}  // namespace drape::detail::air
