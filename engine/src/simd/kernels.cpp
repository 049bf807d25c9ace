// Highway's foreach_target re-includes this file once per target; everything between
// HWY_BEFORE_NAMESPACE and HWY_AFTER_NAMESPACE is compiled for each, the HWY_ONCE part
// (the dispatching entry points of kernels.h) once.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "simd/kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "simd/kernels.h"

HWY_BEFORE_NAMESPACE();
namespace drape::detail::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// eq (6) on the springs [e, e + Lanes(d)): the same operations, in the same order, as
// spring_scale in terms/rows.h, so a lane gives the scalar kernel's bits.
template <class D, bool PerSpring, bool Store, bool Add, bool Sub, class Real>
HWY_INLINE void springs_at(D d, const SpringRun<Real>& r, std::size_t e) {
  const auto dx = hn::Sub(hn::LoadU(d, r.ax + e), hn::LoadU(d, r.bx + e));
  const auto dy = hn::Sub(hn::LoadU(d, r.ay + e), hn::LoadU(d, r.by + e));
  const auto dz = hn::Sub(hn::LoadU(d, r.az + e), hn::LoadU(d, r.bz + e));
  const auto rest = PerSpring ? hn::LoadU(d, r.rest + e) : hn::Set(d, r.rest_same);
  const auto k = PerSpring ? hn::LoadU(d, r.k + e) : hn::Set(d, r.k_same);
  const auto len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz)));
  // a zero-length spring has no direction: its lane's 1/0 is dropped, not used
  const auto inv = hn::IfThenElseZero(hn::Gt(len, hn::Zero(d)), hn::Div(hn::Set(d, Real(1)), len));
  const auto s = hn::Mul(hn::Mul(hn::Neg(k), hn::Sub(len, rest)), inv);
  const auto fx = hn::Mul(s, dx), fy = hn::Mul(s, dy), fz = hn::Mul(s, dz);
  if constexpr (Store) {
    hn::StoreU(fx, d, r.store_x + e);
    hn::StoreU(fy, d, r.store_y + e);
    hn::StoreU(fz, d, r.store_z + e);
  }
  if constexpr (Add) {
    hn::StoreU(hn::Add(hn::LoadU(d, r.add_x + e), fx), d, r.add_x + e);
    hn::StoreU(hn::Add(hn::LoadU(d, r.add_y + e), fy), d, r.add_y + e);
    hn::StoreU(hn::Add(hn::LoadU(d, r.add_z + e), fz), d, r.add_z + e);
  }
  if constexpr (Sub) {
    hn::StoreU(hn::Sub(hn::LoadU(d, r.sub_x + e), fx), d, r.sub_x + e);
    hn::StoreU(hn::Sub(hn::LoadU(d, r.sub_y + e), fy), d, r.sub_y + e);
    hn::StoreU(hn::Sub(hn::LoadU(d, r.sub_z + e), fz), d, r.sub_z + e);
  }
}

// Whole vectors, then the remainder one lane at a time with the same code: every spring
// gets the same bits wherever the run starts, so a row split between blocks changes nothing.
template <bool PerSpring, bool Store, bool Add, bool Sub, class Real>
HWY_INLINE void springs_loop(const SpringRun<Real>& r) {
  const hn::ScalableTag<Real> d;
  const std::size_t lanes = hn::Lanes(d);
  std::size_t e = 0;
  for (; e + lanes <= r.count; e += lanes) springs_at<decltype(d), PerSpring, Store, Add, Sub>(d, r, e);
  const hn::CappedTag<Real, 1> one;
  for (; e < r.count; ++e) springs_at<decltype(one), PerSpring, Store, Add, Sub>(one, r, e);
}

// The outputs and the parameters' source picked once per run, not per spring.
template <class Real>
HWY_INLINE void springs_run(const SpringRun<Real>& r) {
  auto with_outputs = [&]<bool PerSpring>() {
    const bool store = r.store_x != nullptr, add = r.add_x != nullptr, sub = r.sub_x != nullptr;
    if (store && !add && !sub) return springs_loop<PerSpring, true, false, false>(r);
    if (!store && add && sub) return springs_loop<PerSpring, false, true, true>(r);
    if (!store && add && !sub) return springs_loop<PerSpring, false, true, false>(r);
    if (!store && !add && sub) return springs_loop<PerSpring, false, false, true>(r);
    if (store && sub && !add) return springs_loop<PerSpring, true, false, true>(r);
    if (store && add && !sub) return springs_loop<PerSpring, true, true, false>(r);
    if (store && add && sub) return springs_loop<PerSpring, true, true, true>(r);
  };
  if (r.rest != nullptr)
    with_outputs.template operator()<true>();
  else
    with_outputs.template operator()<false>();
}

// eq (4), first order, on the points [i, i + Lanes(d)).
template <class D, bool SemiImplicit, class Real>
HWY_INLINE void update_at(D d, const PointUpdate<Real>& u, std::size_t i) {
  const auto dt = hn::Set(d, u.dt);
  const auto im = hn::LoadU(d, u.inv_mass + i);
  Real* const xs[3] = {u.x, u.y, u.z};
  Real* const vs[3] = {u.vx, u.vy, u.vz};
  const Real* const fs[3] = {u.fx, u.fy, u.fz};
  const Real gs[3] = {u.gx, u.gy, u.gz};
  for (int c = 0; c < 3; ++c) {
    auto x = hn::LoadU(d, xs[c] + i);
    auto v = hn::LoadU(d, vs[c] + i);
    if constexpr (!SemiImplicit) x = hn::Add(x, hn::Mul(dt, v));
    v = hn::Add(v, hn::Mul(dt, hn::Add(hn::Mul(hn::LoadU(d, fs[c] + i), im), hn::Set(d, gs[c]))));
    if constexpr (SemiImplicit) x = hn::Add(x, hn::Mul(dt, v));
    hn::StoreU(x, d, xs[c] + i);
    hn::StoreU(v, d, vs[c] + i);
  }
}

template <bool SemiImplicit, class Real>
HWY_INLINE void update_loop(const PointUpdate<Real>& u) {
  const hn::ScalableTag<Real> d;
  const std::size_t lanes = hn::Lanes(d);
  std::size_t i = 0;
  for (; i + lanes <= u.count; i += lanes) update_at<decltype(d), SemiImplicit>(d, u, i);
  const hn::CappedTag<Real, 1> one;
  for (; i < u.count; ++i) update_at<decltype(one), SemiImplicit>(one, u, i);
}

template <class Real>
HWY_INLINE void update_run(const PointUpdate<Real>& u) {
  if (u.semi_implicit)
    update_loop<true>(u);
  else
    update_loop<false>(u);
}

void SpringsF64(const SpringRun<double>& r) { springs_run(r); }
void SpringsF32(const SpringRun<float>& r) { springs_run(r); }
void UpdateF64(const PointUpdate<double>& u) { update_run(u); }
void UpdateF32(const PointUpdate<float>& u) { update_run(u); }
const char* Name() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape::detail::simd {

HWY_EXPORT(SpringsF64);
HWY_EXPORT(SpringsF32);
HWY_EXPORT(UpdateF64);
HWY_EXPORT(UpdateF32);
HWY_EXPORT(Name);

void springs(const SpringRun<double>& run) { HWY_DYNAMIC_DISPATCH(SpringsF64)(run); }
void springs(const SpringRun<float>& run) { HWY_DYNAMIC_DISPATCH(SpringsF32)(run); }
void update_points(const PointUpdate<double>& u) { HWY_DYNAMIC_DISPATCH(UpdateF64)(u); }
void update_points(const PointUpdate<float>& u) { HWY_DYNAMIC_DISPATCH(UpdateF32)(u); }
const char* target_name() { return HWY_DYNAMIC_DISPATCH(Name)(); }

std::vector<std::int64_t> supported_targets() { return hwy::SupportedAndGeneratedTargets(); }

void use_target(std::int64_t target) { hwy::SetSupportedTargetsForTest(target); }

}  // namespace drape::detail::simd
#endif
