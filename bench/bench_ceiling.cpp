// The machine ceiling: the simplest explicit spring step this machine can run for the same
// sheets, with no engine around it. Plain arrays, one structured grid, one stiffness, one
// rest length, one mass, semi-implicit Euler, corners pinned; the arithmetic runs as the
// engine runs it: the engine's vector kernels (simd/kernels-inl.h) inlined into a step
// compiled for every instruction set, dispatched to the widest the CPU has once per sheet
// step, as the engine's row sweep is. Every engine figure in the report is printed as a
// fraction of these rates, measured in the same run.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bench_ceiling.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "bench_common.h"
#include "sheet_data.h"
#include "simd/kernels.h"

#include "simd/kernels-inl.h"

// The sheet, compiled once (foreach_target re-includes this file for every target).
#ifndef DRAPE_BENCH_CEILING_SHEET_
#define DRAPE_BENCH_CEILING_SHEET_
namespace {

struct PlainSheet {
  std::uint32_t side = 0;  // points per row and per column
  // 64-byte aligned like the engine's arrays: alignment is the machine's to give, not the engine's
  using Array = std::vector<double, drape::detail::CacheAligned<double>>;
  Array x, y, z, vx, vy, vz, fx, fy, fz;
  Array sx, sy, sz;  // one row of horizontal spring forces, from `pad` on (the engine's row_scratch)
  static constexpr std::uint32_t pad = 64 / sizeof(double);
  Array inv_mass_row;  // one mass for all points: one row of it, for the kernel's per-point 1/m
  double k = 100.0, rest = 0, inv_mass = 0, dt = 0, gz = -9.81;

  PlainSheet(std::uint32_t points_per_side, double offset_z) : side(points_per_side) {
    const std::size_t count = std::size_t(side) * side;
    for (auto* a : {&x, &y, &z, &vx, &vy, &vz, &fx, &fy, &fz}) a->assign(count, 0.0);
    for (auto* a : {&sx, &sy, &sz}) a->assign(pad + side, 0.0);
    rest = 1.0 / (side - 1);
    for (std::uint32_t i = 0; i < side; ++i)
      for (std::uint32_t j = 0; j < side; ++j) {
        x[std::size_t(i) * side + j] = j * rest - 0.5;
        y[std::size_t(i) * side + j] = i * rest - 0.5;
        z[std::size_t(i) * side + j] = offset_z;
      }
    const double mass = 1.0 / double(count);
    inv_mass = 1.0 / mass;
    inv_mass_row.assign(side, inv_mass);
    dt = 0.5 * 2.0 / std::sqrt(2.0 * 4.0 * k / mass);  // same rule as the engine's scenes
  }
};

// Hard pins at the four corners: back on the pin, at rest.
void hold_corners(PlainSheet& s) {
  const std::uint32_t w = s.side;
  const std::size_t last = std::size_t(w - 1) * w;
  for (std::size_t p : {std::size_t(0), std::size_t(w - 1), last, last + w - 1}) {
    const std::uint32_t i = std::uint32_t(p / w), j = std::uint32_t(p % w);
    s.x[p] = j * s.rest - 0.5;
    s.y[p] = i * s.rest - 0.5;
    s.z[p] = 0.0;
    s.vx[p] = s.vy[p] = s.vz[p] = 0.0;
  }
}

}  // namespace
#endif  // DRAPE_BENCH_CEILING_SHEET_

// The step, per target, with the kernels inlined.
HWY_BEFORE_NAMESPACE();
namespace drape::bench::ceiling {
namespace HWY_NAMESPACE {
namespace kernels = drape::detail::simd::HWY_NAMESPACE;

// Horizontal springs of one row of w points through the engine's vector kernel (eq 6, one
// k and ℓ), stored as the engine's row sweep stores them: spring j at net[j], between zeros
// at net[−1] and net[w − 1], net on a cache line.
HWY_INLINE void horizontal(std::uint32_t w, double k, double rest, const double* __restrict x, const double* __restrict y,
                           const double* __restrict z, double* __restrict nx, double* __restrict ny, double* __restrict nz) {
  nx[-1] = ny[-1] = nz[-1] = 0.0;
  nx[w - 1] = ny[w - 1] = nz[w - 1] = 0.0;
  kernels::springs_loop<false, true, false, false>(
      drape::detail::simd::SpringRun<double>::between(w - 1, x, y, z, x + 1, y + 1, z + 1).same(rest, k).store(nx, ny, nz));
}

// The first row's forces, which no vertical springs above it net: net[j] − net[j − 1].
HWY_INLINE void net_forces(std::uint32_t w, const double* __restrict net, double* __restrict f) {
  const double* left = net - 1;
  for (std::uint32_t j = 0; j < w; ++j) f[j] = net[j] - left[j];
}

// Vertical springs between row a and row b below it, added to row a's forces and taken
// from row b's horizontal springs netted (SpringRun::netted), which makes row b's forces.
HWY_INLINE void vertical(std::uint32_t w, double k, double rest, const double* xa, const double* ya, const double* za,
                         const double* xb, const double* yb, const double* zb, double* fxa, double* fya, double* fza,
                         double* fxb, double* fyb, double* fzb, const double* nx, const double* ny, const double* nz) {
  kernels::springs_loop<false, false, true, true, true>(drape::detail::simd::SpringRun<double>::between(w, xa, ya, za, xb, yb, zb)
                                                            .same(rest, k)
                                                            .add(fxa, fya, fza)
                                                            .sub(fxb, fyb, fzb)
                                                            .netted(nx, ny, nz));
}

// Row b's horizontal springs and the vertical springs between rows a and b in one pass, as
// the engine's row sweep runs them where it can (simd::rows_joined); false where not.
HWY_INLINE bool joined(std::uint32_t w, double k, double rest, const double* xa, const double* ya, const double* za,
                       const double* xb, const double* yb, const double* zb, double* fxa, double* fya, double* fza,
                       double* fxb, double* fyb, double* fzb) {
  using Run = drape::detail::simd::SpringRun<double>;
  return kernels::rows_joined<false>(
      Run::between(w - 1, xb, yb, zb, xb + 1, yb + 1, zb + 1).same(rest, k),
      Run::between(w, xa, ya, za, xb, yb, zb).same(rest, k).add(fxa, fya, fza).sub(fxb, fyb, fzb));
}

// Semi-implicit Euler on one row, through the engine's vector kernel.
HWY_INLINE void integrate(std::uint32_t w, const PlainSheet& s, const double* inv_mass, double* x, double* y, double* z,
               double* vx, double* vy, double* vz, const double* fx, const double* fy, const double* fz) {
  kernels::update_loop<true>(
      drape::detail::simd::PointUpdate<double>::of(w, x, y, z, vx, vy, vz, fx, fy, fz, inv_mass).step(s.dt, 0, 0, s.gz, true));
}

HWY_INLINE void step(PlainSheet& s) {
  const std::uint32_t w = s.side;
  double *x = s.x.data(), *y = s.y.data(), *z = s.z.data();
  double *vx = s.vx.data(), *vy = s.vy.data(), *vz = s.vz.data();
  double *fx = s.fx.data(), *fy = s.fy.data(), *fz = s.fz.data();
  double *nx = s.sx.data() + s.pad, *ny = s.sy.data() + s.pad, *nz = s.sz.data() + s.pad;
  const double* im = s.inv_mass_row.data();
  horizontal(w, s.k, s.rest, x, y, z, nx, ny, nz);
  net_forces(w, nx, fx);
  net_forces(w, ny, fy);
  net_forces(w, nz, fz);
  for (std::uint32_t i = 0; i + 1 < w; ++i) {
    const std::size_t a = std::size_t(i) * w, b = a + w;
    // row i is complete once its vertical springs are in, and no later spring reads it
    if (!joined(w, s.k, s.rest, x + a, y + a, z + a, x + b, y + b, z + b, fx + a, fy + a, fz + a, fx + b, fy + b,
                fz + b)) {
      horizontal(w, s.k, s.rest, x + b, y + b, z + b, nx, ny, nz);
      vertical(w, s.k, s.rest, x + a, y + a, z + a, x + b, y + b, z + b, fx + a, fy + a, fz + a, fx + b, fy + b,
               fz + b, nx, ny, nz);
    }
    integrate(w, s, im, x + a, y + a, z + a, vx + a, vy + a, vz + a, fx + a, fy + a, fz + a);
  }
  const std::size_t last = std::size_t(w - 1) * w;
  integrate(w, s, im, x + last, y + last, z + last, vx + last, vy + last, vz + last, fx + last, fy + last, fz + last);
  hold_corners(s);
}

void Step(PlainSheet& s) { step(s); }

}  // namespace HWY_NAMESPACE
}  // namespace drape::bench::ceiling
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape::bench::ceiling {

HWY_EXPORT(Step);

void plain_step(PlainSheet& s) { HWY_DYNAMIC_DISPATCH(Step)(s); }

// One sheet of side×side points, one substep per call: the ceiling of BM_Fig13.
void BM_CeilingSheet(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  PlainSheet sheet(side, 0.0);
  for (auto _ : state) plain_step(sheet);
  benchmark::DoNotOptimize(sheet.z.data());
  drape::bench::set_point_rate(state, double(side) * side);
}
BENCHMARK(BM_CeilingSheet)->RangeMultiplier(2)->Range(16, 1024);

// 48 sheets of 64×64 on one core, one substep per call: the ceiling of the feature
// benchmarks (bench_features.cpp).
void BM_CeilingSheets48(benchmark::State& state) {
  std::vector<PlainSheet> sheets;
  for (int s = 0; s < 48; ++s) sheets.emplace_back(64, 0.0);
  for (auto _ : state)
    for (auto& sheet : sheets) plain_step(sheet);
  benchmark::DoNotOptimize(sheets.front().z.data());
  drape::bench::set_point_rate(state, 48.0 * 64 * 64);
}
BENCHMARK(BM_CeilingSheets48);  // CPU time, like the feature benchmarks, which step once per call

// The same 48 sheets a frame at a time, as a program steps them and as BM_Sheets48 steps
// the engine (bench_common.h's step_frames): each sheet takes the frame's substeps in turn
// while its arrays are in this core's caches, where one substep at a time streams all 48
// sheets through them every substep. The ceiling of BM_Sheets48.
void BM_CeilingSheets48Frames(benchmark::State& state) {
  std::vector<PlainSheet> sheets;
  for (int s = 0; s < 48; ++s) sheets.emplace_back(64, 0.0);
  for (auto _ : state)
    for (auto& sheet : sheets)
      for (int substep = 0; substep < drape::bench::frame_substeps; ++substep) plain_step(sheet);
  benchmark::DoNotOptimize(sheets.front().z.data());
  drape::bench::set_point_rate(state, 48.0 * 64 * 64, drape::bench::frame_substeps);
}
BENCHMARK(BM_CeilingSheets48Frames)->UseRealTime();  // wall time, like the thread benchmarks

}  // namespace drape::bench::ceiling
#endif  // HWY_ONCE
