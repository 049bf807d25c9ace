// Shear springs (SheetDef::shear): both diagonals of every cell, each with the spring force
// of eq (6), one stiffness and one rest length for the sheet. A row stencil of reach 1: the
// diagonals of the cells between rows q−1 and q arrive with row q.
#pragma once

#include <cmath>

#include "rows.h"

namespace drape::detail::shear {

// The two diagonals of cell (i, j): "down" joins (i, j)–(i+1, j+1), "up" joins
// (i, j+1)–(i+1, j). Each loop writes two distinct points per iteration and every pointer
// is restrict, so both vectorise like the grid springs.
template <bool ToA, bool ToB, class Real>
DRAPE_ROW_INLINE void diagonals(std::uint32_t n, const Real* __restrict ax, const Real* __restrict ay, const Real* __restrict az,
                      const Real* __restrict bx, const Real* __restrict by, const Real* __restrict bz, Real k,
                      Real rest, Real* __restrict fax, Real* __restrict fay, Real* __restrict faz,
                      Real* __restrict fbx, Real* __restrict fby, Real* __restrict fbz) {
  for (std::uint32_t j = 0; j < n; ++j) {
    const Real dx = ax[j] - bx[j + 1], dy = ay[j] - by[j + 1], dz = az[j] - bz[j + 1];
    const Real s = spring_scale(dx, dy, dz, rest, k);
    if constexpr (ToA) {
      fax[j] += s * dx;
      fay[j] += s * dy;
      faz[j] += s * dz;
    }
    if constexpr (ToB) {
      fbx[j + 1] -= s * dx;
      fby[j + 1] -= s * dy;
      fbz[j + 1] -= s * dz;
    }
  }
  for (std::uint32_t j = 0; j < n; ++j) {
    const Real dx = ax[j + 1] - bx[j], dy = ay[j + 1] - by[j], dz = az[j + 1] - bz[j];
    const Real s = spring_scale(dx, dy, dz, rest, k);
    if constexpr (ToA) {
      fax[j + 1] += s * dx;
      fay[j + 1] += s * dy;
      faz[j + 1] += s * dz;
    }
    if constexpr (ToB) {
      fbx[j] -= s * dx;
      fby[j] -= s * dy;
      fbz[j] -= s * dz;
    }
  }
}

template <bool ToA, bool ToB, class Real>
DRAPE_ROW_INLINE void cell_row(std::uint32_t n, ConstVec3Ptr<Real> a, ConstVec3Ptr<Real> b, Real k, Real rest, Vec3Ptr<Real> fa,
                     Vec3Ptr<Real> fb) {
  diagonals<ToA, ToB>(n, a.x, a.y, a.z, b.x, b.y, b.z, k, rest, fa.x, fa.y, fa.z, fb.x, fb.y, fb.z);
}

// Row q has arrived: the diagonals between rows q−1 and q.
template <class Real, class Window>
DRAPE_ROW_INLINE void arrive(const typename Topology<Real>::Shear& sh, std::uint32_t n, const Window& w, std::uint32_t q) {
  if (q == 0 || q - 1 < w.read_lo) return;
  const bool to_a = w.owns(q - 1), to_b = w.owns(q);
  const auto a = w.x(q - 1), b = w.x(q);
  if (to_a && to_b)
    cell_row<true, true>(n, a, b, sh.stiffness, sh.rest, w.f(q - 1), w.f(q));
  else if (to_a)
    cell_row<true, false>(n, a, b, sh.stiffness, sh.rest, w.f(q - 1), w.f(q));
  else if (to_b)
    cell_row<false, true>(n, a, b, sh.stiffness, sh.rest, w.f(q - 1), w.f(q));
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
