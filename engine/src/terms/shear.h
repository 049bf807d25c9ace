// Shear springs (SheetDef::shear): both diagonals of every cell, each with the spring force
// of eq (6), one stiffness and one rest length for the sheet. A row stencil of reach 1: the
// diagonals of the cells between rows q−1 and q arrive with row q.
#pragma once

#include <cmath>

#include "../simd/kernels.h"
#include "rows.h"

namespace drape::detail::shear {

// Row q has arrived: the diagonals of the cells between rows q−1 and q, as two runs of n
// springs of eq (6) (simd/kernels.h) for the sweep's vector kernel (forces.cpp,
// terms_arrive), in this order: `up` false, "down", joins (q−1, j)–(q, j+1); `up` true
// joins (q−1, j+1)–(q, j). Each adds s·d to its endpoint in row q−1 and subtracts it from
// the one in row q; a row the window does not own gets its share in the window's scratch
// row instead, which nothing reads (a block's edge: one kernel for every case keeps the
// per-target code, and its compile time, small). An empty run when the window cannot read
// row q−1 or owns neither row. One run at a time, by value: inlined, it stays in registers.
template <class Real, class Window>
DRAPE_ROW_INLINE simd::SpringRun<Real> diagonals(const typename Topology<Real>::Shear& sh, std::uint32_t n,
                                                 const Window& w, std::uint32_t q, bool up) {
  if (q == 0 || q - 1 < w.read_lo || (!w.owns(q - 1) && !w.owns(q))) return {};
  const std::uint32_t sa = up ? 1 : 0, sb = up ? 0 : 1;  // shifts along rows q−1 and q
  const auto a = w.x(q - 1), b = w.x(q);
  const auto fa = w.owns(q - 1) ? w.f(q - 1) : w.scratch, fb = w.owns(q) ? w.f(q) : w.scratch;
  return simd::SpringRun<Real>::between(n, a.x + sa, a.y + sa, a.z + sa, b.x + sb, b.y + sb, b.z + sb)
      .same(sh.rest, sh.stiffness)
      .add(fa.x + sa, fa.y + sa, fa.z + sa)
      .sub(fb.x + sb, fb.y + sb, fb.z + sb);
}

// Calls spring(a, b) for every diagonal spring of the sheet.
template <class Real, class Spring>
void for_each_spring(const Topology<Real>& t, Spring spring) {
  const std::uint32_t cols = t.cols();
  for (std::uint32_t i = 0; i < t.m; ++i)
    for (std::uint32_t j = 0; j < t.n; ++j) {
      const std::uint32_t p = i * cols + j;
      spring(p, p + cols + 1);
      spring(p + 1, p + cols);
    }
}

// ½ k (|xa − xb| − ℓ)² over the diagonals.
template <class Real>
double energy(const Topology<Real>& t, ConstVec3Ptr<Real> x) {
  double e = 0;
  const double k = t.shear->stiffness, rest = t.shear->rest;
  for_each_spring(t, [&](std::uint32_t a, std::uint32_t b) {
    const double dx = double(x.x[a]) - x.x[b], dy = double(x.y[a]) - x.y[b], dz = double(x.z[a]) - x.z[b];
    const double stretch = std::sqrt(dx * dx + dy * dy + dz * dz) - rest;
    e += 0.5 * k * stretch * stretch;
  });
  return e;
}

// eq (6)'s Jacobian per diagonal (spring_stiffness_block, spring_jacobian.h, clamped where compressed).
template <class Real, class Add>
void add_jacobian(const Topology<Real>& t, ConstVec3Ptr<Real> x, Add add) {
  const Real k = t.shear->stiffness, rest = t.shear->rest;
  for_each_spring(t, [&](std::uint32_t a, std::uint32_t b) {
    const Real d[3] = {x.x[a] - x.x[b], x.y[a] - x.y[b], x.z[a] - x.z[b]};
    Real g[3][3], minus_g[3][3];
    spring_stiffness_block(d, k, rest, g);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) minus_g[r][c] = -g[r][c];
    add(a, a, minus_g);
    add(b, b, minus_g);
    add(a, b, g);
    add(b, a, g);
  });
}

// Gershgorin, as for the grid springs: 2k to both ends of every diagonal.
template <class Real>
void add_stiffness_bound(const Topology<Real>& t, double* k_sum) {
  const double k = t.shear->stiffness;
  for_each_spring(t, [&](std::uint32_t a, std::uint32_t b) {
    k_sum[a] += 2 * k;
    k_sum[b] += 2 * k;
  });
}

}  // namespace drape::detail::shear
