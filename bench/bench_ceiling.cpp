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

#include "obstacles.h"
#include "simd/exp-inl.h"
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

// A floor z = height (eq 9, normal +z) in the form the force takes per point: −dE/df =
// (c/ξ)·(e^min(−f/ξ, cap) − e^−16) where f = z − height < reach, projected on the sheet's
// normal (a × b, a and b the differences across the point along its row and its column,
// one-sided at the edges), as the engine's obstacle term computes it (obstacles.cpp).
struct PlainFloor {
  double height, c_over_xi, minus_inv_xi, cap, tail, reach;
  bool project;  // false: along ∇f, the plane's normal (ObstacleDef::full_gradient)
};

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

namespace hn = hwy::HWY_NAMESPACE;
namespace lanes = drape::detail::simd::HWY_NAMESPACE;

// The floor's force on the lanes' points p, p + 1, … of a row from its column j on (masked by
// `mine`), their neighbours along the row at l and r and across it at u and dn (the same
// point where a side is missing: a lane in the row's first or last column takes its own
// point for the neighbour it lacks), added to f where the point is within reach; a vector
// with none within reach costs f and one test, as in the engine.
template <class D, class M>
HWY_INLINE void floor_lanes(D d, M mine, const PlainFloor& fl, const PlainSheet& s, std::size_t p, std::size_t j,
                            std::size_t l, std::size_t r, std::size_t u, std::size_t dn, double* fx, double* fy,
                            double* fz) {
  using V = hn::Vec<D>;
  const double *x = s.x.data(), *y = s.y.data(), *z = s.z.data();
  const V f = hn::Sub(hn::LoadU(d, z + p), hn::Set(d, fl.height));
  const auto within = hn::And(mine, hn::Lt(f, hn::Set(d, fl.reach)));
  if (hn::AllFalse(d, within)) return;
  const V e = lanes::first_min(hn::Mul(f, hn::Set(d, fl.minus_inv_xi)), hn::Set(d, fl.cap));
  const V scale = hn::Mul(hn::Set(d, fl.c_over_xi),
                          lanes::first_max(hn::Sub(drape::detail::simd::HWY_NAMESPACE::exp_lanes(d, e), hn::Set(d, fl.tail)),
                                           hn::Zero(d)));
  if (!fl.project) {
    hn::StoreU(hn::Add(hn::LoadU(d, fz + p), hn::IfThenElseZero(within, scale)), d, fz + p);
    return;
  }
  const V column = hn::Iota(d, double(j));
  const auto first = hn::Eq(column, hn::Zero(d)), last = hn::Eq(column, hn::Set(d, double(s.side - 1)));
  const auto along_row = [&](const double* a) HWY_ATTR {
    const V at = hn::LoadU(d, a + p);
    return hn::Sub(hn::IfThenElse(last, at, hn::LoadU(d, a + r)), hn::IfThenElse(first, at, hn::LoadU(d, a + l)));
  };
  const auto across = [&](const double* a) HWY_ATTR { return hn::Sub(hn::LoadU(d, a + u), hn::LoadU(d, a + dn)); };
  const V ax = along_row(x), ay = along_row(y), az = along_row(z);
  const V bx = across(x), by = across(y), bz = across(z);
  const V nx = hn::Sub(hn::Mul(ay, bz), hn::Mul(az, by)), ny = hn::Sub(hn::Mul(az, bx), hn::Mul(ax, bz)),
          nz = hn::Sub(hn::Mul(ax, by), hn::Mul(ay, bx));
  const V nn = hn::Add(hn::Add(hn::Mul(nx, nx), hn::Mul(ny, ny)), hn::Mul(nz, nz));
  const auto has = hn::Gt(nn, hn::Zero(d));
  // F = scale·(0, 0, 1), so F·n = scale·nz
  const V along = hn::Div(hn::Mul(scale, nz), hn::IfThenElse(has, nn, hn::Set(d, 1.0)));
  const V Fx = hn::IfThenElseZero(has, hn::Mul(along, nx)), Fy = hn::IfThenElseZero(has, hn::Mul(along, ny));
  const V Fz = hn::IfThenElse(has, hn::Mul(along, nz), scale);
  hn::StoreU(hn::Add(hn::LoadU(d, fx + p), hn::IfThenElseZero(within, Fx)), d, fx + p);
  hn::StoreU(hn::Add(hn::LoadU(d, fy + p), hn::IfThenElseZero(within, Fy)), d, fy + p);
  hn::StoreU(hn::Add(hn::LoadU(d, fz + p), hn::IfThenElseZero(within, Fz)), d, fz + p);
}

// The floor on row i, whose neighbours i − 1 and i + 1 have not moved: in whole vectors from
// column 0, the row's ends fixed lane by lane, where the points before and after the row
// exist in memory (every row but the sheet's first and last when whole vectors fill a row);
// else its two end points one lane at a time and its inner points in whole vectors, the last
// one shifted back to end at the row's last inner point with the lanes done before masked off.
HWY_INLINE void floor_row(const PlainFloor& fl, PlainSheet& s, std::uint32_t i) {
  const std::uint32_t w = s.side;
  const std::size_t row = std::size_t(i) * w;
  const std::size_t up = std::size_t(std::min(i + 1, w - 1)) * w, down = std::size_t(i > 0 ? i - 1 : 0) * w;
  double *fx = s.fx.data(), *fy = s.fy.data(), *fz = s.fz.data();
  const hn::ScalableTag<double> d;
  const std::size_t n = hn::Lanes(d);
  auto at = [&](auto tag, auto mine, std::size_t j, std::size_t l, std::size_t r) HWY_ATTR {
    floor_lanes(tag, mine, fl, s, row + j, j, row + l, row + r, up + j, down + j, fx, fy, fz);
  };
  if (i > 0 && i + 1 < w && w % n == 0) {
    for (std::size_t j = 0; j < w; j += n) at(d, hn::FirstN(d, n), j, j - 1, j + 1);  // j − 1 wraps to the row before's last point
    return;
  }
  const hn::CappedTag<double, 1> one;
  at(one, hn::FirstN(one, 1), 0, 0, 1);
  at(one, hn::FirstN(one, 1), w - 1, w - 2, w - 1);
  const std::size_t inner_end = w - 1;
  std::size_t j = 1;
  for (; j + n <= inner_end; j += n) at(d, hn::FirstN(d, n), j, j - 1, j + 1);
  if (j < inner_end) {
    if (inner_end - 1 >= n) {  // back to end at the last inner point; lanes before j are done
      const std::size_t start = inner_end - n;
      at(d, hn::Not(hn::FirstN(d, j - start)), start, start - 1, start + 1);
    } else {
      for (; j < inner_end; ++j) at(one, hn::FirstN(one, 1), j, j - 1, j + 1);
    }
  }
}

// The springs of every row, and done(i) as soon as row i's forces are complete (its
// vertical springs in, no later spring reading it), rows 0 … w − 1 in order.
template <class Done>
HWY_INLINE void sweep(PlainSheet& s, Done done) {
  const std::uint32_t w = s.side;
  const double *x = s.x.data(), *y = s.y.data(), *z = s.z.data();
  double *fx = s.fx.data(), *fy = s.fy.data(), *fz = s.fz.data();
  double *nx = s.sx.data() + s.pad, *ny = s.sy.data() + s.pad, *nz = s.sz.data() + s.pad;
  horizontal(w, s.k, s.rest, x, y, z, nx, ny, nz);
  net_forces(w, nx, fx);
  net_forces(w, ny, fy);
  net_forces(w, nz, fz);
  for (std::uint32_t i = 0; i + 1 < w; ++i) {
    const std::size_t a = std::size_t(i) * w, b = a + w;
    if (!joined(w, s.k, s.rest, x + a, y + a, z + a, x + b, y + b, z + b, fx + a, fy + a, fz + a, fx + b, fy + b,
                fz + b)) {
      horizontal(w, s.k, s.rest, x + b, y + b, z + b, nx, ny, nz);
      vertical(w, s.k, s.rest, x + a, y + a, z + a, x + b, y + b, z + b, fx + a, fy + a, fz + a, fx + b, fy + b,
               fz + b, nx, ny, nz);
    }
    done(i);
  }
  done(w - 1);
}

// Semi-implicit Euler on row i of the sheet.
HWY_INLINE void move_row(PlainSheet& s, std::uint32_t i) {
  const std::size_t a = std::size_t(i) * s.side;
  integrate(s.side, s, s.inv_mass_row.data(), s.x.data() + a, s.y.data() + a, s.z.data() + a, s.vx.data() + a,
            s.vy.data() + a, s.vz.data() + a, s.fx.data() + a, s.fy.data() + a, s.fz.data() + a);
}

// Each row moves as soon as its forces are complete.
HWY_INLINE void step(PlainSheet& s) {
  sweep(s, [&](std::uint32_t i) HWY_ATTR { move_row(s, i); });
  hold_corners(s);
}

// With the floor: row i's floor force once its springs are in, and its update a row later
// (the floor on row i + 1 reads row i where it was).
HWY_INLINE void step_on_floor(PlainSheet& s, const PlainFloor& fl) {
  sweep(s, [&](std::uint32_t i) HWY_ATTR {
    floor_row(fl, s, i);
    if (i > 0) move_row(s, i - 1);
    if (i + 1 == s.side) move_row(s, i);
  });
  hold_corners(s);
}

void StepOnFloor(PlainSheet& s, const PlainFloor& fl) { step_on_floor(s, fl); }
void FloorRow(const PlainFloor& fl, PlainSheet& s, std::uint32_t i) { floor_row(fl, s, i); }

void Step(PlainSheet& s) { step(s); }

}  // namespace HWY_NAMESPACE
}  // namespace drape::bench::ceiling
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape::bench::ceiling {

HWY_EXPORT(Step);
HWY_EXPORT(StepOnFloor);
HWY_EXPORT(FloorRow);

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

// The same 48 sheets lying on a floor that holds them (bench::floor_holding, as
// BM_Feature_obstacle lays them), eq (9) on every point: the ceiling of a floor's price,
// the floor term computed per point as the engine's obstacle term computes it (the same
// exp, the same exponent cap and, with arg 0, the projection on the sheet normal; arg 1:
// along the plane's normal, ObstacleDef::full_gradient), inside the same sweep.
// Counter floor_force: the net force the floor holds, over the sheets' weight (about 1 when
// the floor carries them, so the timed term is the one that works).
void BM_CeilingSheets48Floor(benchmark::State& state) {
  std::vector<PlainSheet> sheets;
  for (int s = 0; s < 48; ++s) sheets.emplace_back(64, 0.0);
  const drape::SheetDef like = drape::bench::square_sheet(64);
  const drape::ObstacleDef def = drape::bench::floor_holding(like);
  const PlainSheet& first = sheets.front();
  const double mass = 1.0 / first.inv_mass;
  const PlainFloor floor{def.center.z,
                         def.c / def.xi,
                         -1.0 / def.xi,
                         drape::detail::exponent_cap(def, mass, first.dt),
                         std::exp(-drape::detail::reach_exponent),
                         drape::detail::reach_exponent * def.xi,
                         state.range(0) == 0};
  for (auto _ : state)
    for (auto& sheet : sheets) HWY_DYNAMIC_DISPATCH(StepOnFloor)(sheet, floor);
  benchmark::DoNotOptimize(sheets.front().z.data());
  // eq (9) alone on the first sheet as it lies now, against its weight
  PlainSheet& s = sheets.front();
  const auto floor_alone = [&](PlainSheet& on) {
    for (auto* f : {&on.fx, &on.fy, &on.fz}) std::fill(f->begin(), f->end(), 0.0);
    for (std::uint32_t i = 0; i < on.side; ++i) HWY_DYNAMIC_DISPATCH(FloorRow)(floor, on, i);
  };
  floor_alone(s);
  double held = 0;
  for (double f : s.fz) held += f;
  state.counters["floor_force"] = held / (-s.gz * mass * double(s.fz.size()));
  // and on a crumpled copy, against eq (9) written out point by point with std::exp: the
  // largest difference over the largest force (rounding, and the polynomial's 1e-15)
  PlainSheet c = s;
  for (std::size_t p = 0; p < c.z.size(); ++p) {
    c.x[p] += 0.004 * std::sin(1.7 * double(p));
    c.z[p] += 0.02 * std::cos(2.3 * double(p));
  }
  floor_alone(c);
  const std::uint32_t w = c.side;
  double largest = 0, difference = 0;
  for (std::uint32_t i = 0; i < w; ++i)
    for (std::uint32_t j = 0; j < w; ++j) {
      const std::size_t p = std::size_t(i) * w + j;
      const auto at = [&](std::uint32_t ii, std::uint32_t jj) { return std::size_t(ii) * w + jj; };
      const std::size_t l = at(i, j > 0 ? j - 1 : j), r = at(i, j + 1 < w ? j + 1 : j);
      const std::size_t u = at(i + 1 < w ? i + 1 : i, j), dn = at(i > 0 ? i - 1 : i, j);
      const double f = c.z[p] - floor.height;
      double F[3] = {0, 0, 0};
      if (f < floor.reach) {
        const double scale = floor.c_over_xi * std::max(std::exp(std::min(-f / def.xi, floor.cap)) - floor.tail, 0.0);
        const double a[3] = {c.x[r] - c.x[l], c.y[r] - c.y[l], c.z[r] - c.z[l]};
        const double b[3] = {c.x[u] - c.x[dn], c.y[u] - c.y[dn], c.z[u] - c.z[dn]};
        const double n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        const double nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
        for (int k = 0; k < 3; ++k) F[k] = nn > 0 ? scale * n[2] / nn * n[k] : (k == 2 ? scale : 0.0);
      }
      const double got[3] = {c.fx[p], c.fy[p], c.fz[p]};
      for (int k = 0; k < 3; ++k) {
        const double want = state.range(0) == 0 ? F[k] : (k == 2 && f < floor.reach ? floor.c_over_xi * std::max(std::exp(std::min(-f / def.xi, floor.cap)) - floor.tail, 0.0) : 0.0);
        largest = std::max(largest, std::abs(want));
        difference = std::max(difference, std::abs(got[k] - want));
      }
    }
  state.counters["difference"] = difference / largest;
  drape::bench::set_point_rate(state, 48.0 * 64 * 64);
}
BENCHMARK(BM_CeilingSheets48Floor)->ArgName("full_gradient")->Arg(0)->Arg(1);  // CPU time, like BM_Feature_obstacle

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
