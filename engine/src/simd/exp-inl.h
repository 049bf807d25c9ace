// e^x in Highway vectors of doubles, for the per-target code of the obstacle term
// (obstacles.cpp) and the contact force (contacts.cpp): one polynomial, so both give the same
// bits on every instruction set and in a one-lane vector. Re-included once per target (the
// toggle below is Highway's convention for such headers).
#if defined(DRAPE_SIMD_EXP_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef DRAPE_SIMD_EXP_INL_H_
#undef DRAPE_SIMD_EXP_INL_H_
#else
#define DRAPE_SIMD_EXP_INL_H_
#endif

#include <hwy/highway.h>

#include "simd/select-inl.h"

HWY_BEFORE_NAMESPACE();
namespace drape::detail::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// e^x for x in [−700, 709] without a call or a branch, lane by lane (Highway has no exp of
// its own in this version, and std::exp has no vector form); x is clamped to that range
// first, so e^x stays a finite double. x = k·ln2 + r with |r| ≤ ln2/2, e^r by a polynomial
// of degree 10, 2^k put into the exponent bits. The polynomial interpolates e^r at the 11
// Chebyshev nodes of [−ln2/2, ln2/2] (tools/exp_polynomial.py prints its coefficients),
// about 3·10⁻¹⁶ from e^r there, so e^x stays within 10⁻¹⁵ of std::exp
// (Obstacles.VectorExpStaysWithinItsBoundOfStdExp); Taylor's series needed degree 13 for
// that. It is evaluated in Estrin's scheme, whose longest chain is 4 multiplications and 3
// additions where Horner's has 10 of each, for 3 more multiplications. The files that
// include it compile with contraction into FMA off, so no operation fuses.
template <class D, class V>
HWY_INLINE V exp_lanes(D d, V x) {
  const hn::RebindToUnsigned<D> du;
  const V low = hn::Set(d, -700.0), high = hn::Set(d, 709.0);
  x = first_min(first_max(x, low), high);
  const V shifter = hn::Set(d, 0x1.8p52);  // adding it rounds to an integer held in the low bits
  const V shifted = hn::Add(hn::Mul(x, hn::Set(d, 0x1.71547652b82fep0)), shifter);
  const auto k = hn::BitCast(du, shifted);
  const V kd = hn::Sub(shifted, shifter);
  const V r = hn::Sub(hn::Sub(x, hn::Mul(kd, hn::Set(d, 0x1.62e42fefa3800p-1))),
                      hn::Mul(kd, hn::Set(d, 0x1.ef35793c7673p-45)));  // ln2 in two parts
  const auto pair = [&](double a, double b, V t) HWY_ATTR { return hn::Add(hn::Set(d, a), hn::Mul(hn::Set(d, b), t)); };
  const auto join = [&](V a, V b, V t) HWY_ATTR { return hn::Add(a, hn::Mul(b, t)); };
  const V r2 = hn::Mul(r, r), r4 = hn::Mul(r2, r2), r8 = hn::Mul(r4, r4);
  const V p01 = pair(0x1.0000000000000p+0, 0x1.000000000001ep+0, r), p23 = pair(0x1.0000000000005p-1, 0x1.555555554b757p-3, r),
          p45 = pair(0x1.55555555520afp-5, 0x1.1111112dd67c5p-7, r), p67 = pair(0x1.6c16c17f43a58p-10, 0x1.a01978c6baf81p-13, r),
          p89 = pair(0x1.a019a66a75dd4p-16, 0x1.72faf024b693bp-19, r);
  const V p8_10 = join(p89, hn::Set(d, 0x1.28a2c0a7209fbp-22), r2);
  const V p = join(join(join(p01, p23, r2), join(p45, p67, r2), r4), p8_10, r8);
  return hn::BitCast(d, hn::Add(hn::BitCast(du, p), hn::ShiftLeft<52>(k)));
}

// The same on one value, through a one-lane vector: the same operations, so the same bits.
HWY_INLINE double exp_one(double x) {
  const hn::CappedTag<double, 1> d;
  return hn::GetLane(exp_lanes(d, hn::Set(d, x)));
}

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail::simd
HWY_AFTER_NAMESPACE();

#endif  // DRAPE_SIMD_EXP_INL_H_ toggle
