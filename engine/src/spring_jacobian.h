// eq (6)'s Jacobian, the one place the implicit integrators take it from. With d = xa − xb,
// L = |d|, u = d/L, the force on a has ∂fa/∂xa = −G, G = k [u uᵀ + (1 − ℓ/L)(I − u uᵀ)].
// A compressed spring (L < ℓ) makes (1 − ℓ/L) negative and G indefinite, which would cost
// the systems their positive definiteness (implicit Euler's CG, vertex block descent's 3×3
// solves): the transverse factor is clamped at 0 (Baraff & Witkin's and Choi & Ko's remedy).
// Only the linearisation changes; the force stays exact. A zero-length spring with ℓ = 0 is
// linear, G = k·I; with ℓ > 0 it has no direction and the force kernel applies no force, so
// G = 0.
#pragma once

#include <algorithm>
#include <cmath>

namespace drape::detail {

// The two halves of G: the spring's direction u and transverse factor (1 − ℓ/L, clamped),
// where the square root and divisions are; then G from them. A loop over many springs can
// run the first for all of them before the second, so their latencies overlap.
template <class Real>
inline void spring_direction(const Real d[3], Real rest, Real u[3], Real& transverse) {
  const Real len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  u[0] = u[1] = u[2] = Real(0);
  if (len > Real(0)) {
    for (int r = 0; r < 3; ++r) u[r] = d[r] / len;
    transverse = std::max(Real(0), Real(1) - rest / len);
  } else {
    transverse = rest == Real(0) ? Real(1) : Real(0);
  }
}

template <class Real>
inline void spring_block(Real k, const Real u[3], Real transverse, Real g[3][3]) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g[r][c] = k * ((Real(1) - transverse) * u[r] * u[c] + (r == c ? transverse : Real(0)));
}

template <class Real>
inline void spring_stiffness_block(const Real d[3], Real k, Real rest, Real g[3][3]) {
  Real u[3], transverse;
  spring_direction(d, rest, u, transverse);
  spring_block(k, u, transverse, g);
}

}  // namespace drape::detail
