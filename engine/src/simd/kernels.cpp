// Highway's foreach_target re-includes this file once per target; everything between
// HWY_BEFORE_NAMESPACE and HWY_AFTER_NAMESPACE is compiled for each, the HWY_ONCE part
// (the dispatching entry points of kernels.h) once.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "simd/kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "simd/kernels.h"

#include "simd/kernels-inl.h"

HWY_BEFORE_NAMESPACE();
namespace drape::detail::simd {
namespace HWY_NAMESPACE {

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
