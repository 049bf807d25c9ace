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
Extent<double> ExtentF64(const double* x, const double* y, const double* z, std::size_t count) {
  return points_extent_of(x, y, z, count);
}
Extent<float> ExtentF32(const float* x, const float* y, const float* z, std::size_t count) {
  return points_extent_of(x, y, z, count);
}
void CellBoxesF64(const CellRow<double>& r) { cell_boxes_of(r); }
void CellBoxesF32(const CellRow<float>& r) { cell_boxes_of(r); }
void AirCellsF64(const AirCells<double>& r) { air_cells_of(r); }
void AirCellsF32(const AirCells<float>& r) { air_cells_of(r); }
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
HWY_EXPORT(ExtentF64);
HWY_EXPORT(ExtentF32);
HWY_EXPORT(CellBoxesF64);
HWY_EXPORT(CellBoxesF32);
HWY_EXPORT(AirCellsF64);
HWY_EXPORT(AirCellsF32);
HWY_EXPORT(Name);

void springs(const SpringRun<double>& run) { HWY_DYNAMIC_DISPATCH(SpringsF64)(run); }
void springs(const SpringRun<float>& run) { HWY_DYNAMIC_DISPATCH(SpringsF32)(run); }
void update_points(const PointUpdate<double>& u) { HWY_DYNAMIC_DISPATCH(UpdateF64)(u); }
void update_points(const PointUpdate<float>& u) { HWY_DYNAMIC_DISPATCH(UpdateF32)(u); }
Extent<double> points_extent(const double* x, const double* y, const double* z, std::size_t count) {
  return HWY_DYNAMIC_DISPATCH(ExtentF64)(x, y, z, count);
}
Extent<float> points_extent(const float* x, const float* y, const float* z, std::size_t count) {
  return HWY_DYNAMIC_DISPATCH(ExtentF32)(x, y, z, count);
}
void cell_boxes(const CellRow<double>& row) { HWY_DYNAMIC_DISPATCH(CellBoxesF64)(row); }
void cell_boxes(const CellRow<float>& row) { HWY_DYNAMIC_DISPATCH(CellBoxesF32)(row); }
void air_cells(const AirCells<double>& cells) { HWY_DYNAMIC_DISPATCH(AirCellsF64)(cells); }
void air_cells(const AirCells<float>& cells) { HWY_DYNAMIC_DISPATCH(AirCellsF32)(cells); }
const char* target_name() { return HWY_DYNAMIC_DISPATCH(Name)(); }

std::vector<std::int64_t> supported_targets() { return hwy::SupportedAndGeneratedTargets(); }

void use_target(std::int64_t target) { hwy::SetSupportedTargetsForTest(target); }

}  // namespace drape::detail::simd
#endif
