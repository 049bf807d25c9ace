// std::min and std::max in Highway vectors, lane by lane with their bits, for the per-target
// code of the kernels (kernels-inl.h), the exponential (exp-inl.h), the obstacle term and
// the contact force. Re-included once per target (the toggle below is Highway's convention
// for such headers).
#if defined(DRAPE_SIMD_SELECT_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef DRAPE_SIMD_SELECT_INL_H_
#undef DRAPE_SIMD_SELECT_INL_H_
#else
#define DRAPE_SIMD_SELECT_INL_H_
#endif

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace drape::detail::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// std::min(x, y) is x unless y < x; std::max(x, y) is x unless x < y. On x86's vector
// targets one instruction each instead of a compare and a select: minpd/minps(a, b) is
// a < b ? a : b and maxpd/maxps(a, b) is a > b ? a : b, the second operand wherever the
// comparison fails (a NaN, +0 against −0), so Min(y, x) and Max(y, x) are std::min(x, y)
// and std::max(x, y) bit for bit. Highway's Min and Max elsewhere (the scalar target, Arm)
// treat NaN in their own ways, so there the compare and select stay.
template <class V>
HWY_INLINE V first_min(V x, V y) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_SSSE3
  return hn::Min(y, x);
#else
  return hn::IfThenElse(hn::Lt(y, x), y, x);
#endif
}
template <class V>
HWY_INLINE V first_max(V x, V y) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_SSSE3
  return hn::Max(y, x);
#else
  return hn::IfThenElse(hn::Lt(x, y), y, x);
#endif
}

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail::simd
HWY_AFTER_NAMESPACE();

#endif  // DRAPE_SIMD_SELECT_INL_H_ toggle
