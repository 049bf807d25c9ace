// What every force term of a sheet works on: pointers to rows of x, v and f, and the
// window of rows a sweep may read and write. The row sweep (forces.cpp) hands each term
// the rows it needs; terms never see whether they run on a whole sheet, a block of rows
// or a wave (forces.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "../sheet_data.h"
#include "../spring_jacobian.h"

// A row kernel of a force term: forced inline, because the terms are defined outside
// forces.cpp's per-target code. Inlined into each target's sweep they compile, and
// vectorise, for that target; a call left to them would run the build's baseline
// instruction set. (Flattening the sweep's `arrive` did the same at three times the
// compile time.)
#define DRAPE_ROW_INLINE [[gnu::always_inline]] inline

namespace drape::detail {

template <class Real>
struct ConstVec3Ptr {
  const Real* x;
  const Real* y;
  const Real* z;
};

template <class Real>
struct Vec3Ptr {
  Real* x;
  Real* y;
  Real* z;
  operator ConstVec3Ptr<Real>() const { return {x, y, z}; }
};

template <class Real>
ConstVec3Ptr<Real> cptr(const Vec3Array<Real>& a) { return {a.x.data(), a.y.data(), a.z.data()}; }
template <class Real>
Vec3Ptr<Real> ptr(Vec3Array<Real>& a) { return {a.x.data(), a.y.data(), a.z.data()}; }

// Spring force on the first endpoint of a spring whose endpoints differ by d = x1 − x2:
// −k (|d| − ℓ)/|d| · d (eq 6 carries the opposite sign because the paper moves f_spr to
// the right-hand side of eq 4). A zero-length spring has no direction and contributes
// nothing: the select keeps 0/0 out of the result.
template <class Real>
DRAPE_ROW_INLINE Real spring_scale(Real dx, Real dy, Real dz, Real rest, Real k) {
  const Real len = std::sqrt(dx * dx + dy * dy + dz * dz);
  const Real inv = len > Real(0) ? Real(1) / len : Real(0);
  return -k * (len - rest) * inv;
}

// The rows one sweep works on. Rows [read_lo, ...) can be read (a wave has no state above
// its first row); forces go only to rows [own_lo, own_hi), the rows the sweep owns. A
// stencil of rows that touches an owned row is evaluated in full, with the same
// arithmetic whoever owns the other rows, and adds only to its owned rows: so a row's force
// is the same bits however the sheet is cut into blocks.
template <class Real, class Access>
struct RowWindow {
  Access access;  // x(i), v(i), f(i): row i's pointers
  std::uint32_t read_lo, own_lo, own_hi;
  Vec3Ptr<Real> scratch;  // one row of scratch per component, free for any term's use

  DRAPE_ROW_INLINE bool owns(std::uint32_t i) const { return i >= own_lo && i < own_hi; }
  DRAPE_ROW_INLINE ConstVec3Ptr<Real> x(std::uint32_t i) const { return access.x(i); }
  DRAPE_ROW_INLINE ConstVec3Ptr<Real> v(std::uint32_t i) const { return access.v(i); }
  DRAPE_ROW_INLINE Vec3Ptr<Real> f(std::uint32_t i) const { return access.f(i); }
};

// Jacobians: a term's add_jacobian(…, add) calls add(p, q, J) for 3×3 blocks with
// J[r][c] = ∂f_p,r/∂x_q,c (p == q included); implicit integrators assemble them into their
// matrix or apply them to a vector (term_jvp in terms.h).

}  // namespace drape::detail
