// The row sweep and the paper's kernels: springs (eqs 6–7), damping (eq 4's C), anchors
// (eq 8). The other terms live in terms/ (their list: terms/terms.h); obstacles (eq 9) in
// obstacles.cpp.
//
// Highway's foreach_target compiles this file once per instruction set (simd/targets.h):
// the sweep, the terms it calls, the vector kernels of simd/kernels-inl.h and an explicit
// integrator's point update all inline into one function per target, and the entry points
// at the end dispatch to the widest the CPU has once per sheet or block of rows. Contraction
// into FMA is off here (engine/CMakeLists.txt), so every target gives the same bits.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "forces.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "forces.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <type_traits>
#include <utility>

#include "obstacles.h"
#include "simd/kernels.h"
#include "terms/terms.h"

#include "simd/kernels-inl.h"

// What every target shares, compiled once: the cache budget and a wave's row ranges.
#ifndef DRAPE_FORCES_SHARED_
#define DRAPE_FORCES_SHARED_
namespace drape::detail {
namespace {

constexpr std::size_t cache_budget = std::size_t(1) << 20;  // bytes: about an L2 cache
constexpr std::size_t values_per_point = 11;                // x, v, f, 1/m, damping
// Points a row sweep's update moves per call (sheet_forces_by_rows_with): their 11 arrays in
// about 20 KiB in double, within the nearest cache beside the sweep's own rows.
constexpr std::size_t update_run_points = 256;

// The rows a block's wave steps: the block and up to `halo` = levels·R rows beyond each
// edge. A halo row's neighbours outside the range are missing, so its state goes wrong R
// rows further in at every substep: after `levels` substeps exactly the halo is wrong.
struct WaveRange {
  std::uint32_t lo, hi;
};
inline WaveRange wave_range(std::uint32_t rows, std::uint32_t halo, std::uint32_t row_begin, std::uint32_t row_end) {
  return {row_begin > halo ? row_begin - halo : 0, std::min(rows, row_end + halo)};
}

template <class Real>
std::uint32_t wave_halo(const Sheet<Real>& s, std::uint32_t levels) {
  return levels * force_reach(s);
}

// Where halo row i lives in the block's copies: the rows above the block, then below.
inline std::size_t halo_slot(WaveRange r, std::uint32_t row_begin, std::uint32_t row_end, std::uint32_t i) {
  return i < row_begin ? i - r.lo : (row_begin - r.lo) + (i - row_end);
}

template <class Real>
Vec3Ptr<Real> at(Vec3Array<Real>& a, std::size_t offset) {
  return {a.x.data() + offset, a.y.data() + offset, a.z.data() + offset};
}

// The rows a sweep reads (RowWindow's access): plain pointer arithmetic, compiled for no
// target, so that RowWindow (terms/rows.h, no target either) inlines them and every target's
// sweep inlines both; defined per target, GCC could not inline them into RowWindow and left a
// call per row in the portable build.

// Rows of one sheet's arrays (a whole sheet, or a block of it that reads all rows).
template <class Real>
struct ArrayRows {
  ConstVec3Ptr<Real> xs, vs;
  Vec3Ptr<Real> fs;
  std::size_t cols;
  ConstVec3Ptr<Real> x(std::uint32_t i) const {
    const std::size_t p = i * cols;
    return {xs.x + p, xs.y + p, xs.z + p};
  }
  ConstVec3Ptr<Real> v(std::uint32_t i) const {
    const std::size_t p = i * cols;
    return {vs.x + p, vs.y + p, vs.z + p};
  }
  Vec3Ptr<Real> f(std::uint32_t i) const {
    const std::size_t p = i * cols;
    return {fs.x + p, fs.y + p, fs.z + p};
  }
};

// A wave's rows: the block's own from the sheet, halo rows from the copies, forces from
// the ring.
template <class Real>
struct WaveRows {
  Sheet<Real>* s;
  WaveScratch<Real>* w;
  WaveRange range;
  std::uint32_t row_begin, row_end, cols, mask;
  Vec3Ptr<Real> state(Vec3Array<Real>& own, Vec3Array<Real>& halo, std::uint32_t i) const {
    if (i >= row_begin && i < row_end) return at(own, std::size_t(i) * cols);
    return at(halo, halo_slot(range, row_begin, row_end, i) * cols);
  }
  Vec3Ptr<Real> xm(std::uint32_t i) const { return state(s->position, w->halo_x, i); }
  Vec3Ptr<Real> vm(std::uint32_t i) const { return state(s->velocity, w->halo_v, i); }
  ConstVec3Ptr<Real> x(std::uint32_t i) const { return xm(i); }
  ConstVec3Ptr<Real> v(std::uint32_t i) const { return vm(i); }
  Vec3Ptr<Real> f(std::uint32_t i) const { return at(w->forces, std::size_t((i - range.lo) & mask) * cols); }
};

}  // namespace
}  // namespace drape::detail
#endif  // DRAPE_FORCES_SHARED_

HWY_BEFORE_NAMESPACE();
namespace drape::detail {
namespace HWY_NAMESPACE {

namespace kernels = simd::HWY_NAMESPACE;

// Where a kernel finds k and ℓ of spring e: per-spring arrays, or one constant for the
// whole run (Topology::uniform). The choice is made once per row (arrive), so
// the sweeps around them compile once for both (a template parameter would double this
// file's code and compile time for a branch per row).
template <class Real>
struct SpringSource {
  const Real* rest = nullptr;  // null: every spring has rest_same and k_same
  const Real* k = nullptr;
  Real rest_same = 0, k_same = 0;
  bool per_spring() const { return rest != nullptr; }
  template <bool PerSpring>
  SpringSource offset(std::size_t e) const {
    SpringSource s = *this;
    if constexpr (PerSpring) {
      s.rest += e;
      s.k += e;
    }
    return s;
  }
  template <bool PerSpring>
  simd::SpringRun<Real>& into(simd::SpringRun<Real>& run) const {
    if constexpr (PerSpring) return run.per_spring(rest, k);
    return run.same(rest_same, k_same);
  }
};

// Horizontal springs of one row, spring j joining points j and j + 1, stored at net[j]
// between zeros at net[−1] and net[n] (a row of Sheet::row_scratch from its pad on). No
// point's force is written here: point j gets net[j] − net[j − 1], the spring on its right
// minus the one on its left, summed in as the vertical springs above the row are subtracted
// from it (SpringRun::netted), or by net_row where there are none. Each point's force comes
// from the same two operands either way, so its bits do not depend on the path. (Scattered
// by a loop of its own, the springs cost the 1024-point step held to AVX2 5 % more.)
template <bool PerSpring, class Real, class Springs>
HWY_INLINE void row_springs(std::uint32_t n, const Real* __restrict x, const Real* __restrict y, const Real* __restrict z,
                            Springs springs, Vec3Ptr<Real> net) {
  net.x[-1] = net.y[-1] = net.z[-1] = Real(0);
  net.x[n] = net.y[n] = net.z[n] = Real(0);
  auto run = simd::SpringRun<Real>::between(n, x, y, z, x + 1, y + 1, z + 1);
  kernels::springs_loop<PerSpring, true, false, false>(springs.template into<PerSpring>(run).store(net.x, net.y, net.z));
}

// The forces of a row's n + 1 points from their horizontal springs alone (row_springs' net).
template <class Real>
HWY_INLINE void net_row(std::uint32_t n, const Real* __restrict net, Real* __restrict f) {
  const Real* left = net - 1;  // net[j − 1], with j unsigned
  for (std::uint32_t j = 0; j <= n; ++j) f[j] = net[j] - left[j];
}

// Vertical springs between row `a` and the row below it, `b`: no two iterations touch
// the same point, and the kernel adds to both rows directly, row b's forces starting from
// its horizontal springs' net (row_springs). A block of rows that does not own row a (or
// b) still evaluates the spring, with the same arithmetic, and adds only to its own row:
// forces of a row are then bit-identical however the sheet is split.
template <bool PerSpring, bool ToA, bool ToB, class Real, class Springs>
HWY_INLINE void column_springs(std::uint32_t cols, const Real* xa, const Real* ya, const Real* za, const Real* xb,
                               const Real* yb, const Real* zb, Springs springs, Real* fxa, Real* fya, Real* fza,
                               Real* fxb, Real* fyb, Real* fzb, ConstVec3Ptr<Real> net) {
  auto run = simd::SpringRun<Real>::between(cols, xa, ya, za, xb, yb, zb);
  springs.template into<PerSpring>(run);
  if constexpr (ToA) run.add(fxa, fya, fza);
  if constexpr (ToB) run.sub(fxb, fyb, fzb).netted(net.x, net.y, net.z);
  kernels::springs_loop<PerSpring, false, ToA, ToB, ToB>(run);
}

// The rows terms 2–4 of terms/terms.h read when row q arrives, q − 2 to q (those the window
// can read), as plain pointers. last_rows fills them in the window it returns (not in a
// LastRows of its own copied in at the end: GCC copied that with vector moves, whose loads
// could not be forwarded from the pointers' scalar stores just made, a stall every row that
// cost small cloth sheets a fifth of their step; BM_SceneSheetsAlone/rain_torus).
template <class Real>
struct LastRows {
  ConstVec3Ptr<Real> xs[3] = {}, vs[3] = {};
  Vec3Ptr<Real> fs[3] = {};
  std::uint32_t first = 0;  // the row in slot 0, q − 2 (modulo 2³², so q − 1 and q stay in 1, 2)
  ConstVec3Ptr<Real> x(std::uint32_t i) const { return xs[i - first]; }
  ConstVec3Ptr<Real> v(std::uint32_t i) const { return vs[i - first]; }
  Vec3Ptr<Real> f(std::uint32_t i) const { return fs[i - first]; }
};

template <class Real, class Access>
RowWindow<Real, LastRows<Real>> last_rows(const RowWindow<Real, Access>& w, std::uint32_t q) {
  RowWindow<Real, LastRows<Real>> out{{}, w.read_lo, w.own_lo, w.own_hi, w.scratch};
  LastRows<Real>& rows = out.access;
  rows.first = q - 2;
  for (std::uint32_t slot = 0; slot < 3; ++slot) {
    const std::uint32_t i = q - 2 + slot;
    if (i > q || i < w.read_lo) continue;  // above row 0, or above what the window holds
    rows.xs[slot] = w.x(i);
    rows.vs[slot] = w.v(i);
    rows.fs[slot] = w.f(i);
  }
  return out;
}

// A run of springs that adds to one row and subtracts from another (shear's diagonals).
template <class Real>
HWY_INLINE void add_springs(const simd::SpringRun<Real>& r) {
  kernels::springs_loop<false, false, true, true>(r);
}

// Terms 2–4 on the rows they read, compiled for this target and once per precision: not
// inlined into every kind of sweep, window and spring parameters, which made this file's
// compile three times as long for the same code. One call per row. The terms' row code
// (terms/) is compiled for no target of its own: their row kernels are forced inline here
// (DRAPE_ROW_INLINE), and those with a square root or a division hand back runs for the
// vector kernels, which GCC would not force into code of no target (and leaves scalar on
// AVX2 and SSE4 when written as plain loops: it vectorises a guarded division only with
// AVX-512's masks).
template <class Real>
HWY_NOINLINE void terms_arrive(const RowTerms<Real>& terms, const RowWindow<Real, LastRows<Real>>& w,
                               std::uint32_t q) {
  const std::uint32_t n = terms.n;
  if (terms.shear) {
    add_springs(shear::diagonals<Real>(*terms.shear, n, w, q, false));
    add_springs(shear::diagonals<Real>(*terms.shear, n, w, q, true));
  }
  if (terms.bending) bending::arrive<Real>(*terms.bending, n, w, q);
  if (terms.air) {
    const simd::AirCells<Real> cells = air::cells(*terms.air, n, w, q);
    if (cells.count == 0) return;
    kernels::air_cells_of(cells);
    air::spread<Real>(n, w, q);
  }
}

// Row q arrives in a sweep: every row stencil whose last row is q adds its forces, in the
// order of terms/terms.h: row q's own grid springs (which write, not add, its forces, so f
// needs no clearing pass), the grid springs between rows q−1 and q, then the other terms.
// A call per row (the vector kernels inline into it); inlined into every sweep it only
// multiplies the code. The spring source is picked once per row, for both directions.
template <bool PerSpring, class Real, class Springs, class Terms, class Window>
HWY_INLINE void arrive_with(const Topology<Real>& t, Springs horizontal_springs, Springs vertical_springs,
                            const Terms& terms, const Window& w, std::uint32_t q) {
  const std::uint32_t n = t.n, cols = t.cols();
  const bool above = q > w.read_lo;  // the vertical springs between rows q − 1 and q
  constexpr std::uint32_t pad = Topology<Real>::scratch_pad;
  const Vec3Ptr<Real> net{w.scratch.x + pad, w.scratch.y + pad, w.scratch.z + pad};
  // row q's horizontal springs and the vertical ones above it in one pass where the
  // target and row allow (simd::rows_joined), with the operands and bits of the two below
  auto join = [&]() __attribute__((always_inline)) {
    const ConstVec3Ptr<Real> xa = w.x(q - 1), xb = w.x(q);
    const Vec3Ptr<Real> fa = w.f(q - 1), fb = w.f(q);
    auto h = simd::SpringRun<Real>::between(n, xb.x, xb.y, xb.z, xb.x + 1, xb.y + 1, xb.z + 1);
    auto v = simd::SpringRun<Real>::between(cols, xa.x, xa.y, xa.z, xb.x, xb.y, xb.z);
    horizontal_springs.template offset<PerSpring>(std::size_t(q) * n).template into<PerSpring>(h);
    vertical_springs.template offset<PerSpring>(std::size_t(q - 1) * cols).template into<PerSpring>(v);
    return kernels::rows_joined<PerSpring>(h, v.add(fa.x, fa.y, fa.z).sub(fb.x, fb.y, fb.z));
  };
  const bool joined = above && w.owns(q) && w.owns(q - 1) && join();
  if (!joined && w.owns(q)) {
    const ConstVec3Ptr<Real> x = w.x(q);
    row_springs<PerSpring>(n, x.x, x.y, x.z, horizontal_springs.template offset<PerSpring>(std::size_t(q) * n), net);
    if (!above) {
      const Vec3Ptr<Real> f = w.f(q);
      net_row(n, net.x, f.x);
      net_row(n, net.y, f.y);
      net_row(n, net.z, f.z);
    }
  }
  if (!joined && above) {
    const ConstVec3Ptr<Real> xa = w.x(q - 1), xb = w.x(q);
    const Vec3Ptr<Real> fa = w.f(q - 1), fb = w.f(q);
    auto vertical = [&]<bool ToA, bool ToB>() __attribute__((always_inline)) {
      column_springs<PerSpring, ToA, ToB>(cols, xa.x, xa.y, xa.z, xb.x, xb.y, xb.z,
                                          vertical_springs.template offset<PerSpring>(std::size_t(q - 1) * cols), fa.x,
                                          fa.y, fa.z, fb.x, fb.y, fb.z, ConstVec3Ptr<Real>(net));
    };
    const bool to_a = w.owns(q - 1), to_b = w.owns(q);
    if (to_a && to_b)
      vertical.template operator()<true, true>();
    else if (to_b)
      vertical.template operator()<false, true>();
    else if (to_a)
      vertical.template operator()<true, false>();
  }
  if constexpr (!std::is_same_v<Terms, NoRowTerms>) terms_arrive(terms, last_rows(w, q), q);
}

template <class Real, class Springs, class Terms, class Window>
HWY_NOINLINE void arrive(const Topology<Real>& t, Springs horizontal_springs, Springs vertical_springs, const Terms& terms,
                         const Window& w, std::uint32_t q) {
  if (horizontal_springs.per_spring())
    arrive_with<true>(t, horizontal_springs, vertical_springs, terms, w, q);
  else
    arrive_with<false>(t, horizontal_springs, vertical_springs, terms, w, q);
}

// The row sweep of a sheet's arrays for rows [begin, end): rows arrive in order, reading
// up to `reach` rows beyond the range, and done(i) is called as soon as row i's stencil
// forces are final, while the row is still in cache, so per-point terms (and an
// integrator's update) run in the same sweep instead of another pass over the sheet.
template <class Real, class Springs, class Terms, class RowDone>
void sweep_rows(const Topology<Real>& t, Springs horizontal_springs, Springs vertical_springs, const Terms& terms,
                ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f, Vec3Ptr<Real> row, std::uint32_t begin,
                std::uint32_t end, RowDone done) {
  if (begin >= end) return;
  const RowWindow<Real, ArrayRows<Real>> w{{x, v, f, t.cols()}, 0, begin, end, row};
  const std::uint32_t reach = terms.reach(), last = std::min(end - 1 + reach, t.m);
  for (std::uint32_t q = begin; q <= last; ++q) {
    arrive(t, horizontal_springs, vertical_springs, terms, w, q);
    if (q >= begin + reach) done(q - reach);
  }
  for (std::uint32_t i = last + 1 >= begin + reach ? last + 1 - reach : begin; i < end; ++i) done(i);
}

// Calls body(horizontal springs, vertical springs) with the spring parameters of the
// sheet: constants when the topology is uniform, per-spring arrays otherwise.
template <class Real, class Body>
void with_springs(const Topology<Real>& t, Body body) {
  if (t.uniform) {
    const auto& u = *t.uniform;
    body(SpringSource<Real>{nullptr, nullptr, u.rest_h, u.stiffness},
         SpringSource<Real>{nullptr, nullptr, u.rest_v, u.stiffness});
  } else {
    const Real* rest = t.rest_length.data();
    const Real* k = t.stiffness.data();
    const std::size_t vertical = t.horizontal_count();
    body(SpringSource<Real>{rest, k}, SpringSource<Real>{rest + vertical, k + vertical});
  }
}

// The sweep with the sheet's terms picked once: the paper's kernel alone (NoRowTerms)
// when the sheet has none of the others.
template <class Real, class RowDone>
void sheet_sweep(const Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                 std::uint32_t row_begin, std::uint32_t row_end, RowDone done) {
  const Topology<Real>& t = *s.topology;
  with_springs(t, [&](auto horizontal, auto vertical) {
    if (has_row_terms(s))
      sweep_rows(t, horizontal, vertical, row_terms_of(s), x, v, f, row, row_begin, row_end, done);
    else
      sweep_rows(t, horizontal, vertical, NoRowTerms{}, x, v, f, row, row_begin, row_end, done);
  });
}

// Contact forces the host stage gathered for this substep (contacts.h), on `count` points.
template <class Real>
inline void add_contacts(std::size_t count, const Real* __restrict cx, const Real* __restrict cy,
                         const Real* __restrict cz, Real* __restrict fx, Real* __restrict fy, Real* __restrict fz) {
  for (std::size_t i = 0; i < count; ++i) {
    fx[i] += cx[i];
    fy[i] += cy[i];
    fz[i] += cz[i];
  }
}

// eq (4): −C ẋ on `count` points, C diagonal.
template <class Real>
inline void damp(std::size_t count, const Real* __restrict c, const Real* __restrict vx, const Real* __restrict vy,
                 const Real* __restrict vz, Real* __restrict fx, Real* __restrict fy, Real* __restrict fz) {
  for (std::size_t i = 0; i < count; ++i) {
    fx[i] -= c[i] * vx[i];
    fy[i] -= c[i] * vy[i];
    fz[i] -= c[i] * vz[i];
  }
}

// What a sweep does with a row once its force is final: nothing (forces only), or one
// explicit Euler step of its points (an integrator's per-point update, simd/kernels.h).
struct NoUpdate {
  template <class Real>
  void operator()(std::size_t, Vec3Ptr<Real>, Vec3Ptr<Real>, ConstVec3Ptr<Real>, const Real*,
                  simd::Extent<Real>* = nullptr) const {}
};

template <bool SemiImplicit, class Real>
struct EulerUpdate {
  simd::EulerStep<Real> step;
  // `grow`, when given, grows to contain the new positions (the update's growing variant)
  HWY_INLINE void operator()(std::size_t count, Vec3Ptr<Real> x, Vec3Ptr<Real> v, ConstVec3Ptr<Real> f,
                             const Real* inv_mass, simd::Extent<Real>* grow = nullptr) const {
    auto u = simd::PointUpdate<Real>::of(count, x.x, x.y, x.z, v.x, v.y, v.z, f.x, f.y, f.z, inv_mass).step(step);
    if (grow)
      kernels::update_loop_growing<SemiImplicit>(u.grow(grow));
    else
      kernels::update_loop<SemiImplicit>(u);
  }
};

// Calls body(update) with the update picked once per sweep: none for a null step.
template <class Real, class Body>
void with_update(const simd::EulerStep<Real>* step, Body body) {
  if (!step)
    body(NoUpdate{});
  else if (step->semi_implicit)
    body(EulerUpdate<true, Real>{*step});
  else
    body(EulerUpdate<false, Real>{*step});
}

template <class Real>
void spring_forces_of(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                      std::uint32_t row_begin, std::uint32_t row_end) {
  with_springs(t, [&](auto horizontal, auto vertical) {
    sweep_rows(t, horizontal, vertical, NoRowTerms{}, x, x, f, row, row_begin, row_end, [](std::uint32_t) {});
  });
}

// Terms 5–6 of terms/terms.h (damping, contacts) on the `count` points from the sheet's
// point p, whose velocities and forces are at v and f (a row of the sheet's arrays, or of
// a wave's copies). Anchors and obstacles follow.
template <class Real>
inline void add_point_terms(const Sheet<Real>& s, std::size_t p, std::size_t count, ConstVec3Ptr<Real> v,
                            Vec3Ptr<Real> f) {
  if (!s.damping.empty()) damp<Real>(count, s.damping.data() + p, v.x, v.y, v.z, f.x, f.y, f.z);
  if (s.has_contacts) {
    const auto& c = s.contact_force;
    add_contacts<Real>(count, c.x.data() + p, c.y.data() + p, c.z.data() + p, f.x, f.y, f.z);
  }
}

// add_point_terms on the sheet's own arrays.
template <class Real>
inline void row_terms(const Sheet<Real>& s, std::size_t p, std::size_t count, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f) {
  add_point_terms(s, p, count, {v.x + p, v.y + p, v.z + p}, {f.x + p, f.y + p, f.z + p});
}

template <class Real>
void sheet_forces_rows_of(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                          Vec3Ptr<Real> row, std::uint32_t row_begin, std::uint32_t row_end) {
  const Topology<Real>& t = *s.topology;
  const std::size_t cols = t.cols();
  sheet_sweep(s, x, v, f, row, row_begin, row_end,
              [&](std::uint32_t i) { row_terms(s, std::size_t(i) * cols, cols, v, f); });
  const auto& an = s.anchors;
  const std::size_t begin = row_begin * cols, end = row_end * cols;
  for (std::size_t a = 0; a < an.point.size(); ++a)
    if (an.point[a] >= begin && an.point[a] < end) add_anchor(an, a, x, f, an.point[a]);
  // eq (9) on these rows: every block's update waits for every block's forces, so the rows
  // on either side of the range, which the normal reads, have not moved
  for (const NearObstacle& o : s.near_obstacles) obstacle_forces(t, o, x, v, s.inv_mass.data(), f, row_begin, row_end);
}

template <class Real, class Update>
void sheet_forces_by_rows_with(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                               Update update, simd::Extent<Real>* box) {
  const Topology<Real>& t = *s.topology;
  const auto& an = s.anchors;
  auto anchor = [&](std::size_t a) { add_anchor(an, a, x, f, an.point[a]); };
  // the update moves the sheet's own points (x and v are the sheet's arrays whenever it runs)
  auto run = [&](std::size_t p, std::size_t end, simd::Extent<Real>* grow) {
    update(end - p, Vec3Ptr<Real>{s.position.x.data() + p, s.position.y.data() + p, s.position.z.data() + p},
           Vec3Ptr<Real>{s.velocity.x.data() + p, s.velocity.y.data() + p, s.velocity.z.data() + p},
           ConstVec3Ptr<Real>{f.x + p, f.y + p, f.z + p}, s.inv_mass.data() + p, grow);
  };
  std::size_t next_pin = 0;
  auto move = [&](std::size_t p, std::size_t count) {
    if (box)
      update_around_pins(s.pins, next_pin, p, p + count, *box, run);
    else
      run(p, p + count, nullptr);
  };
  if (!std::is_sorted(an.point.begin(), an.point.end())) {
    // finish every force first, then update the whole sheet
    sheet_sweep(s, x, v, f, ptr(s.row_scratch), 0, t.rows(),
                [&](std::uint32_t i) { row_terms(s, std::size_t(i) * t.cols(), t.cols(), v, f); });
    for (std::size_t a = 0; a < an.point.size(); ++a) anchor(a);
    for (const NearObstacle& o : s.near_obstacles) obstacle_forces(t, o, x, v, s.inv_mass.data(), f);
    move(0, s.size());
    return;
  }
  // Every term of row i is added as soon as its springs are final (same order as above:
  // springs, damping, contacts, anchors, obstacles), then the rows are updated while they
  // are still in the nearest cache, in runs of whole rows of at least update_run_points
  // points: one call per row would run short rows mostly in their remainders and reduce the
  // box's lanes once per row (BM_Fig13 at small sizes, BM_WorldStep10kSheets), and a sheet's
  // whole update after its sweep reads every row back from a farther cache. A new
  // per-point force term belongs in add_point_terms, a row stencil in terms/terms.h.
  // Obstacle forces (eq 9, only obstacles the host stage found near this sheet) follow the
  // sheet's surface normal, which reads the rows on both sides of a point: they are added to
  // the rows whose springs are final just before a run of rows moves, while the next row has
  // not moved, and the update stays a row behind, so the row before them has not moved
  // either (one call per run of rows, not per row: a call sets up the obstacle's frame).
  //
  // The sweep asks after every row only whether the row has terms of its own or ends a run
  // (inlined into it); the rest is a call. In one piece the callback was a call of its own
  // for every row, whose entry and exit cost the 1024-point sheet on AVX2 a few per cent of
  // its step in rows with nothing to do (the figures are in the commit that split it).
  const std::uint32_t cols = t.cols(), rows = t.rows();
  const std::uint32_t lag = s.near_obstacles.empty() ? 0 : 1;
  const bool row_work = !s.damping.empty() || s.has_contacts || !an.point.empty();
  std::size_t next_anchor = 0, unmoved = 0;
  std::uint32_t unforced = 0;  // the first row without its obstacle forces
  auto ready_after = [&](std::uint32_t i) {
    return i + 1 == rows ? s.size() : std::size_t(i + 1) * cols - std::size_t(lag) * cols;
  };
  auto ends_run = [&](std::uint32_t i, std::size_t ready) {
    return ready > unmoved && (ready - unmoved >= update_run_points || i + 1 == rows);
  };
  auto finish = [&](std::uint32_t i) __attribute__((noinline)) {
    const std::size_t p = std::size_t(i) * cols;
    row_terms(s, p, cols, v, f);
    for (; next_anchor < an.point.size() && an.point[next_anchor] < p + cols; ++next_anchor) anchor(next_anchor);
    const std::size_t ready = ready_after(i);
    if (ends_run(i, ready)) {
      for (const NearObstacle& o : s.near_obstacles) obstacle_forces(t, o, x, v, s.inv_mass.data(), f, unforced, i + 1);
      unforced = i + 1;
      move(unmoved, ready - unmoved);
      unmoved = ready;
    }
  };
  sheet_sweep(s, x, v, f, ptr(s.row_scratch), 0, rows, [&](std::uint32_t i) {
    if (row_work || ends_run(i, ready_after(i))) finish(i);
  });
}

template <class Real>
void sheet_forces_by_rows_of(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                             const simd::EulerStep<Real>* step, simd::Extent<Real>* box) {
  with_update(step, [&](auto update) { sheet_forces_by_rows_with(s, x, v, f, update, step ? box : nullptr); });
}

template <class Real, class Springs, class Terms, class Update>
void wave_rows(Sheet<Real>& s, Springs horizontal_springs, Springs vertical_springs, const Terms& terms,
               std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end, WaveScratch<Real>& w,
               Update update, Aabb* swept) {
  const Topology<Real>& t = *s.topology;
  const std::uint32_t cols = t.cols(), reach = terms.reach();
  const WaveRange range = wave_range(t.rows(), levels * reach, row_begin, row_end);
  const std::uint32_t lo = range.lo, hi = range.hi;
  // A row's force is in use from its arrival at substep 0 to its update at the last
  // substep: levels·R + 1 waves, so a ring of levels·R + 2 rows or more never collides
  // (a power of two: the slot is a mask, not a division, on every row of every substep).
  const std::uint32_t ring = std::bit_ceil(levels * reach + 2), mask = ring - 1;
  if (w.forces.x.size() < std::size_t(ring) * cols) w.forces.resize(std::size_t(ring) * cols);
  if (w.row.x.size() < t.scratch_cols()) w.row.resize(t.scratch_cols());
  const WaveRows<Real> rows{&s, &w, range, row_begin, row_end, cols, mask};
  const RowWindow<Real, WaveRows<Real>> window{rows, lo, lo, hi, ptr(w.row)};
  const auto& an = s.anchors;
  const auto& pins = s.pins;
  const std::size_t first = std::size_t(lo) * cols;
  w.next_anchor.assign(levels, std::size_t(std::lower_bound(an.point.begin(), an.point.end(), first) - an.point.begin()));
  w.next_pin.assign(levels, std::size_t(std::lower_bound(pins.point.begin(), pins.point.end(), first) - pins.point.begin()));
  // Row i's force is final: the per-point terms in sheet_forces_by_rows' order (damping,
  // anchors), the integrator's update, then its pins, as integrate() sets them after a sweep.
  auto finish = [&](std::uint32_t level, std::uint32_t i) {
    const std::size_t p = std::size_t(i) * cols, end = p + cols;
    const Vec3Ptr<Real> x = rows.xm(i), v = rows.vm(i), f = rows.f(i);
    add_point_terms<Real>(s, p, cols, v, f);
    for (std::size_t& a = w.next_anchor[level]; a < an.point.size() && an.point[a] < end; ++a)
      add_anchor(an, a, ConstVec3Ptr<Real>(x), f, an.point[a] - p);
    update(cols, x, v, ConstVec3Ptr<Real>(f), s.inv_mass.data() + p);
    for (std::size_t& k = w.next_pin[level]; k < pins.point.size() && pins.point[k] < end; ++k)
      hold_pin(pins, k, x, v, pins.point[k] - p);
    if (swept && i >= row_begin && i < row_end && cols > 0)
      include_extent(*swept, kernels::points_extent_of<Real>(x.x, x.y, x.z, cols));
  };
  // Step q of one substep's sweep, as in sweep_rows: row lo + q arrives (while there is
  // one), and row lo + q − R is final.
  auto step = [&](std::uint32_t level, std::uint32_t q) {
    if (lo + q < hi) arrive(t, horizontal_springs, vertical_springs, terms, window, lo + q);
    if (q >= reach) finish(level, lo + q - reach);
  };
  // Substep `level` runs R steps behind substep level − 1, which has just moved the last row
  // it needs: every read sees the state of its own substep.
  const std::uint32_t steps = hi - lo + reach;
  for (std::uint32_t wave = 0; wave < steps + (levels - 1) * reach; ++wave)
    for (std::uint32_t level = 0; level < levels && level * reach <= wave; ++level)
      if (wave - level * reach < steps) step(level, wave - level * reach);
}

template <class Real>
void sheet_wave_of(Sheet<Real>& s, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,
                   WaveScratch<Real>& w, const simd::EulerStep<Real>& step, Aabb* swept) {
  if (levels == 0 || row_begin >= row_end) return;
  with_update(&step, [&](auto update) {
    with_springs(*s.topology, [&](auto horizontal, auto vertical) {
      if (has_row_terms(s))
        wave_rows(s, horizontal, vertical, row_terms_of(s), levels, row_begin, row_end, w, update, swept);
      else
        wave_rows(s, horizontal, vertical, NoRowTerms{}, levels, row_begin, row_end, w, update, swept);
    });
  });
}

// The entry points HWY_EXPORT names, one per precision.
#define DRAPE_FORCES_ENTRIES(Suffix, Real)                                                                         \
  void SpringForces##Suffix(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,     \
                            std::uint32_t row_begin, std::uint32_t row_end) {                                      \
    spring_forces_of(t, x, f, row, row_begin, row_end);                                                            \
  }                                                                                                                \
  void SheetForcesRows##Suffix(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,       \
                               Vec3Ptr<Real> row, std::uint32_t row_begin, std::uint32_t row_end) {               \
    sheet_forces_rows_of(s, x, v, f, row, row_begin, row_end);                                                     \
  }                                                                                                                \
  void SheetForcesByRows##Suffix(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,     \
                                 const simd::EulerStep<Real>* step, simd::Extent<Real>* box) {                     \
    sheet_forces_by_rows_of(s, x, v, f, step, box);                                                                \
  }                                                                                                                \
  void SheetWave##Suffix(Sheet<Real>& s, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,    \
                         WaveScratch<Real>& w, const simd::EulerStep<Real>& step, Aabb* swept) {                   \
    sheet_wave_of(s, levels, row_begin, row_end, w, step, swept);                                                  \
  }
DRAPE_FORCES_ENTRIES(F64, double)
DRAPE_FORCES_ENTRIES(F32, float)
#undef DRAPE_FORCES_ENTRIES

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape::detail {

HWY_EXPORT(SpringForcesF64);
HWY_EXPORT(SpringForcesF32);
HWY_EXPORT(SheetForcesRowsF64);
HWY_EXPORT(SheetForcesRowsF32);
HWY_EXPORT(SheetForcesByRowsF64);
HWY_EXPORT(SheetForcesByRowsF32);
HWY_EXPORT(SheetWaveF64);
HWY_EXPORT(SheetWaveF32);

// One dispatch per call: a sheet, or a block of its rows, per substep (or per wave).
template <class Real>
void spring_forces(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                   std::uint32_t row_begin, std::uint32_t row_end) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(SpringForcesF64)(t, x, f, row, row_begin, row_end);
  else
    HWY_DYNAMIC_DISPATCH(SpringForcesF32)(t, x, f, row, row_begin, row_end);
}

template <class Real>
void spring_forces(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row) {
  spring_forces(t, x, f, row, 0, t.rows());
}

template <class Real>
void sheet_forces_rows(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                       std::uint32_t row_begin, std::uint32_t row_end) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(SheetForcesRowsF64)(s, x, v, f, row, row_begin, row_end);
  else
    HWY_DYNAMIC_DISPATCH(SheetForcesRowsF32)(s, x, v, f, row, row_begin, row_end);
}

template <class Real>
void sheet_forces_by_rows(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                          const simd::EulerStep<Real>* step, simd::Extent<Real>* box) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(SheetForcesByRowsF64)(s, x, v, f, step, box);
  else
    HWY_DYNAMIC_DISPATCH(SheetForcesByRowsF32)(s, x, v, f, step, box);
}

template <class Real>
void sheet_forces(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f) {
  sheet_forces_by_rows<Real>(s, x, v, f, nullptr);
}

template <class Real>
void sheet_wave(Sheet<Real>& s, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,
                WaveScratch<Real>& w, const simd::EulerStep<Real>& step, Aabb* swept) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(SheetWaveF64)(s, levels, row_begin, row_end, w, step, swept);
  else
    HWY_DYNAMIC_DISPATCH(SheetWaveF32)(s, levels, row_begin, row_end, w, step, swept);
}

template <class Real>
bool fits_cache_budget(const Sheet<Real>& s) {
  return s.size() * values_per_point * sizeof(Real) <= cache_budget;
}

template <class Real>
bool wave_ready(const Sheet<Real>& s) {
  return !s.has_contacts && s.near_obstacles.empty() && std::is_sorted(s.anchors.point.begin(), s.anchors.point.end()) &&
         std::is_sorted(s.pins.point.begin(), s.pins.point.end());
}

std::uint32_t wave_levels(std::uint32_t cols, std::size_t bytes_per_value, std::uint32_t reach) {
  // rows in flight: `reach` per substep, and about four more at the wave's front and back
  const std::size_t rows = cache_budget / (std::max<std::size_t>(cols, 1) * values_per_point * bytes_per_value);
  return rows > 4 + reach ? static_cast<std::uint32_t>(std::min<std::size_t>(64, (rows - 4) / reach)) : 1;
}

template <class Real>
void wave_take_halo(const Sheet<Real>& s, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,
                    WaveScratch<Real>& w) {
  const std::uint32_t cols = s.topology->cols();
  const WaveRange range = wave_range(s.topology->rows(), wave_halo(s, levels), row_begin, row_end);
  const std::size_t rows = (row_begin - range.lo) + (range.hi - row_end);
  if (w.halo_x.x.size() < rows * cols) {
    w.halo_x.resize(rows * cols);
    w.halo_v.resize(rows * cols);
  }
  auto copy = [&](std::uint32_t i) {
    const std::size_t from = std::size_t(i) * cols, to = halo_slot(range, row_begin, row_end, i) * cols;
    for (auto [source, copy] : {std::pair{&s.position, &w.halo_x}, std::pair{&s.velocity, &w.halo_v}}) {
      std::copy_n(source->x.data() + from, cols, copy->x.data() + to);
      std::copy_n(source->y.data() + from, cols, copy->y.data() + to);
      std::copy_n(source->z.data() + from, cols, copy->z.data() + to);
    }
  };
  for (std::uint32_t i = range.lo; i < row_begin; ++i) copy(i);
  for (std::uint32_t i = row_end; i < range.hi; ++i) copy(i);
}

template void spring_forces<double>(const Topology<double>&, ConstVec3Ptr<double>, Vec3Ptr<double>, Vec3Ptr<double>);
template void spring_forces<float>(const Topology<float>&, ConstVec3Ptr<float>, Vec3Ptr<float>, Vec3Ptr<float>);
template void spring_forces<double>(const Topology<double>&, ConstVec3Ptr<double>, Vec3Ptr<double>, Vec3Ptr<double>,
                                    std::uint32_t, std::uint32_t);
template void spring_forces<float>(const Topology<float>&, ConstVec3Ptr<float>, Vec3Ptr<float>, Vec3Ptr<float>,
                                   std::uint32_t, std::uint32_t);
template void sheet_forces_rows<double>(Sheet<double>&, ConstVec3Ptr<double>, ConstVec3Ptr<double>, Vec3Ptr<double>,
                                        Vec3Ptr<double>, std::uint32_t, std::uint32_t);
template void sheet_forces_rows<float>(Sheet<float>&, ConstVec3Ptr<float>, ConstVec3Ptr<float>, Vec3Ptr<float>,
                                       Vec3Ptr<float>, std::uint32_t, std::uint32_t);
template void sheet_forces<double>(Sheet<double>&, ConstVec3Ptr<double>, ConstVec3Ptr<double>, Vec3Ptr<double>);
template void sheet_forces<float>(Sheet<float>&, ConstVec3Ptr<float>, ConstVec3Ptr<float>, Vec3Ptr<float>);
template bool wave_ready<double>(const Sheet<double>&);
template bool fits_cache_budget<double>(const Sheet<double>&);
template bool fits_cache_budget<float>(const Sheet<float>&);
template bool wave_ready<float>(const Sheet<float>&);
template void wave_take_halo<double>(const Sheet<double>&, std::uint32_t, std::uint32_t, std::uint32_t,
                                     WaveScratch<double>&);
template void wave_take_halo<float>(const Sheet<float>&, std::uint32_t, std::uint32_t, std::uint32_t,
                                    WaveScratch<float>&);
template void sheet_wave<double>(Sheet<double>&, std::uint32_t, std::uint32_t, std::uint32_t, WaveScratch<double>&,
                                 const simd::EulerStep<double>&, Aabb*);
template void sheet_wave<float>(Sheet<float>&, std::uint32_t, std::uint32_t, std::uint32_t, WaveScratch<float>&,
                                const simd::EulerStep<float>&, Aabb*);
template void sheet_forces_by_rows<double>(Sheet<double>&, ConstVec3Ptr<double>, ConstVec3Ptr<double>, Vec3Ptr<double>,
                                           const simd::EulerStep<double>*, simd::Extent<double>*);
template void sheet_forces_by_rows<float>(Sheet<float>&, ConstVec3Ptr<float>, ConstVec3Ptr<float>, Vec3Ptr<float>,
                                          const simd::EulerStep<float>*, simd::Extent<float>*);

}  // namespace drape::detail
#endif  // HWY_ONCE
