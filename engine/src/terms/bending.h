// Bending (SheetDef::bending): E = ½ k_b Σ |x_a − 2 x_b + x_c|² over every three
// consecutive points a, b, c of a grid line, along rows and along columns.
//
// Why this model: it is the quadratic bending energy of Bergou et al. ("A quadratic bending
// model for inextensible surfaces", 2006) for a flat rest state on a regular grid, with the
// second difference along grid lines in place of the cotangent Laplacian. While the grid
// springs keep lengths nearly constant it measures curvature (|x_a − 2x_b + x_c| ≈ h²|κ|),
// it is zero for any straight line and unchanged by rigid motions, and its Hessian is the
// constant k_b·DᵀD: the force is linear in x (no square root, no division), and implicit
// Euler's matrix blocks are constants. Cost: per point and substep, two second differences
// and their scatter, about as much as the grid springs; it reads two rows on each side
// (reach 2), so a wave carrying it lags two rows per substep. Flexion springs over two
// cells would cost the same reach with a square root each and no stiffness across the fold
// for small angles (their length changes only to second order); a dihedral-angle energy
// (discrete shells) handles curved rest shapes, which a sheet that starts flat never needs,
// at several times the arithmetic. Equivalent beam: a line of spacing h stores
// ½ k_b Σ h⁴ κ² ≈ ½ (k_b h³) ∫ κ² ds, so it bends like a beam of EI = k_b·h³.
#pragma once

#include "rows.h"

namespace drape::detail::bending {

// One component of row q's own line: with r_j = x_{j−1} − 2x_j + x_{j+1} for j = 1 … n−1
// (r_0 = r_n = 0), f_j −= k (r_{j−1} − 2 r_j + r_{j+1}). Each r is computed where it is used,
// from x, not stored in a scratch row and loaded back: those loads, one element off the
// stores just made, could not be forwarded from them (a stall per vector on a short row). The
// same operations in the same order as through the scratch row, so the same bits.
template <class Real>
DRAPE_ROW_INLINE Real second_difference(const Real* __restrict x, std::uint32_t j) {
  return x[j - 1] - Real(2) * x[j] + x[j + 1];
}

template <class Real>
DRAPE_ROW_INLINE void along_line(std::uint32_t n, const Real* __restrict x, Real k, Real* __restrict f) {
  const Real zero = Real(0);  // r_0 and r_n
  const Real first = second_difference(x, 1), last = second_difference(x, n - 1);
  f[0] -= k * first;
  if (n == 2) {
    f[1] -= k * (zero - Real(2) * first + zero);
  } else {
    f[1] -= k * (zero - Real(2) * first + second_difference(x, 2));
    for (std::uint32_t j = 2; j + 1 < n; ++j)
      f[j] -= k * (second_difference(x, j - 1) - Real(2) * second_difference(x, j) + second_difference(x, j + 1));
    f[n - 1] -= k * (second_difference(x, n - 2) - Real(2) * last + zero);
  }
  f[n] -= k * last;
}

template <class Real>
DRAPE_ROW_INLINE void along_row(std::uint32_t n, ConstVec3Ptr<Real> x, Real k, Vec3Ptr<Real> f) {
  if (n < 2) return;
  along_line(n, x.x, k, f.x);
  along_line(n, x.y, k, f.y);
  along_line(n, x.z, k, f.z);
}

// One component of the column lines through rows a, b, c (consecutive): r = xa − 2xb + xc
// per column, and −k r, +2k r, −k r on the rows this sweep owns.
template <bool ToA, bool ToB, bool ToC, class Real>
DRAPE_ROW_INLINE void across_line(std::uint32_t cols, const Real* __restrict a, const Real* __restrict b,
                        const Real* __restrict c, Real k, Real* __restrict fa, Real* __restrict fb,
                        Real* __restrict fc) {
  for (std::uint32_t j = 0; j < cols; ++j) {
    const Real r = k * (a[j] - Real(2) * b[j] + c[j]);
    if constexpr (ToA) fa[j] -= r;
    if constexpr (ToB) fb[j] += Real(2) * r;
    if constexpr (ToC) fc[j] -= r;
  }
}

template <bool ToA, bool ToB, bool ToC, class Real>
DRAPE_ROW_INLINE void across_rows(std::uint32_t cols, ConstVec3Ptr<Real> a, ConstVec3Ptr<Real> b, ConstVec3Ptr<Real> c, Real k,
                        Vec3Ptr<Real> fa, Vec3Ptr<Real> fb, Vec3Ptr<Real> fc) {
  across_line<ToA, ToB, ToC>(cols, a.x, b.x, c.x, k, fa.x, fb.x, fc.x);
  across_line<ToA, ToB, ToC>(cols, a.y, b.y, c.y, k, fa.y, fb.y, fc.y);
  across_line<ToA, ToB, ToC>(cols, a.z, b.z, c.z, k, fa.z, fb.z, fc.z);
}

// Row q has arrived: its own line's triples, then the column triples of rows q−2, q−1, q.
template <class Real, class Window>
DRAPE_ROW_INLINE void arrive(Real k, std::uint32_t n, const Window& w, std::uint32_t q) {
  if (w.owns(q)) along_row(n, w.x(q), k, w.f(q));
  if (q < 2 || q - 2 < w.read_lo) return;
  const bool ta = w.owns(q - 2), tb = w.owns(q - 1), tc = w.owns(q);
  const auto a = w.x(q - 2), b = w.x(q - 1), c = w.x(q);
  const auto fa = w.f(q - 2), fb = w.f(q - 1), fc = w.f(q);  // rows not owned are not written
  const std::uint32_t cols = n + 1;
  // the owned rows are contiguous: these are all the cases
  if (ta && tb && tc) across_rows<true, true, true>(cols, a, b, c, k, fa, fb, fc);
  else if (tb && tc) across_rows<false, true, true>(cols, a, b, c, k, fa, fb, fc);
  else if (tc) across_rows<false, false, true>(cols, a, b, c, k, fa, fb, fc);
  else if (ta && tb) across_rows<true, true, false>(cols, a, b, c, k, fa, fb, fc);
  else if (ta) across_rows<true, false, false>(cols, a, b, c, k, fa, fb, fc);
  else if (tb) across_rows<false, true, false>(cols, a, b, c, k, fa, fb, fc);
}

// Calls triple(a, b, c) for every three consecutive points of a grid line: rows first.
template <class Real, class Triple>
void for_each_triple(const Topology<Real>& t, Triple triple) {
  const std::uint32_t cols = t.cols();
  for (std::uint32_t i = 0; i <= t.m; ++i)
    for (std::uint32_t j = 1; j < t.n; ++j) triple(i * cols + j - 1, i * cols + j, i * cols + j + 1);
  for (std::uint32_t i = 1; i < t.m; ++i)
    for (std::uint32_t j = 0; j < cols; ++j) triple((i - 1) * cols + j, i * cols + j, (i + 1) * cols + j);
}

template <class Real>
double energy(const Topology<Real>& t, ConstVec3Ptr<Real> x) {
  double e = 0;
  const double k = *t.bending;
  for_each_triple(t, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const double rx = double(x.x[a]) - 2.0 * x.x[b] + x.x[c];
    const double ry = double(x.y[a]) - 2.0 * x.y[b] + x.y[c];
    const double rz = double(x.z[a]) - 2.0 * x.z[b] + x.z[c];
    e += 0.5 * k * (rx * rx + ry * ry + rz * rz);
  });
  return e;
}

// ∂f_p/∂x_q = −k w_p w_q I for p, q in a triple with weights w = (1, −2, 1): constant.
template <class Real, class Add>
void add_jacobian(const Topology<Real>& t, Add add) {
  const Real k = *t.bending;
  const Real w[3] = {Real(1), Real(-2), Real(1)};
  for_each_triple(t, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const std::uint32_t p[3] = {a, b, c};
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) {
        const Real d = -k * w[r] * w[s];
        const Real j[3][3] = {{d, 0, 0}, {0, d, 0}, {0, 0, d}};
        add(p[r], p[s], j);
      }
  });
}

// Gershgorin: row p of the Hessian sums |k w_p w_q| over its triples (4k as an end, 8k as the middle).
template <class Real>
void add_stiffness_bound(const Topology<Real>& t, double* k_sum) {
  const double k = *t.bending;
  for_each_triple(t, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    k_sum[a] += 4 * k;
    k_sum[b] += 8 * k;
    k_sum[c] += 4 * k;
  });
}

}  // namespace drape::detail::bending
