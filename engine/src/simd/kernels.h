// The hot loops' vector kernels (issue 15): eq (6) over a run of springs and the explicit
// integrators' per-point update, written once with Google Highway (simd/kernels-inl.h) and
// compiled for every instruction set Highway targets on this architecture (SSE4, AVX2,
// AVX-512, … or NEON/SVE); each call runs the widest one the CPU has, picked at run time.
// The row sweep (forces.cpp) compiles itself per target with these kernels inlined and
// dispatches once per sheet or block; the entry points here serve a block's update, the
// ceiling benchmark and the tests. The kernels use no fused
// multiply-add and the same operations in the same order as the scalar spring_scale
// (terms/rows.h), so every target gives the same bits; sqrt and division are IEEE on all.
// Plain pointers only: this file sits below the row sweep and the integrators.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace drape::detail::simd {

// Springs e in [0, count) between points a[e] and b[e], d = a − b: the force on a is
// s·d with s = −k(|d| − ℓ)/|d| (eq 6, zero for |d| = 0). rest and k point to per-spring
// values, or are null and every spring has rest_same and k_same. Each non-null output
// array set takes s·d: `store` is assigned, `add` added to, `sub` subtracted from. With
// `netted` set, what `sub` takes s·d from is not read from sub but is net[e] − net[e − 1]:
// a row's horizontal spring forces (spring j at net[j], zeros at net[−1] and net[count − 1])
// summed into each point's force on the way, eq (6) giving point j the spring on its right
// minus the one on its left.
template <class Real>
struct SpringRun {
  std::size_t count = 0;
  const Real *ax = nullptr, *ay = nullptr, *az = nullptr;
  const Real *bx = nullptr, *by = nullptr, *bz = nullptr;
  const Real* rest = nullptr;
  const Real* k = nullptr;
  Real rest_same = 0, k_same = 0;
  Real *store_x = nullptr, *store_y = nullptr, *store_z = nullptr;
  Real *add_x = nullptr, *add_y = nullptr, *add_z = nullptr;
  Real *sub_x = nullptr, *sub_y = nullptr, *sub_z = nullptr;
  const Real *net_x = nullptr, *net_y = nullptr, *net_z = nullptr;

  // A run is set up as between(...) then where k and ℓ come from, then its outputs:
  // SpringRun::between(n, a…, b…).same(rest, k).store(x, y, z)
  static SpringRun between(std::size_t count, const Real* ax, const Real* ay, const Real* az, const Real* bx,
                           const Real* by, const Real* bz) {
    SpringRun r;
    r.count = count;
    r.ax = ax;
    r.ay = ay;
    r.az = az;
    r.bx = bx;
    r.by = by;
    r.bz = bz;
    return r;
  }
  SpringRun& per_spring(const Real* rest_of, const Real* k_of) {
    rest = rest_of;
    k = k_of;
    return *this;
  }
  SpringRun& same(Real rest_all, Real k_all) {
    rest_same = rest_all;
    k_same = k_all;
    return *this;
  }
  SpringRun& store(Real* x, Real* y, Real* z) {
    store_x = x;
    store_y = y;
    store_z = z;
    return *this;
  }
  SpringRun& add(Real* x, Real* y, Real* z) {
    add_x = x;
    add_y = y;
    add_z = z;
    return *this;
  }
  SpringRun& sub(Real* x, Real* y, Real* z) {
    sub_x = x;
    sub_y = y;
    sub_z = z;
    return *this;
  }
  SpringRun& netted(const Real* x, const Real* y, const Real* z) {
    net_x = x;
    net_y = y;
    net_z = z;
    return *this;
  }
};

void springs(const SpringRun<double>& run);
void springs(const SpringRun<float>& run);

// A box of points, per coordinate k the smallest lo[k] and the largest hi[k] as the scalar
// loop  lo = v < lo ? v : lo;  hi = v > hi ? v : hi  grows them: a NaN is skipped unless
// it is where the box started. none() is the box before any point (the first one included
// becomes it); points_extent and the integrators' update (PointUpdate::grow) both grow
// boxes this way, in vectors, and merge them here.
template <class Real>
struct Extent {
  Real lo[3] = {0, 0, 0};
  Real hi[3] = {0, 0, 0};

  static Extent none() {
    constexpr Real inf = std::numeric_limits<Real>::infinity();
    return {{inf, inf, inf}, {-inf, -inf, -inf}};
  }
  void include(int k, Real low, Real high) {
    lo[k] = low < lo[k] ? low : lo[k];
    hi[k] = high > hi[k] ? high : hi[k];
  }
  void include(Real x, Real y, Real z) {
    include(0, x, x);
    include(1, y, y);
    include(2, z, z);
  }
  void include(const Extent& e) {
    for (int k = 0; k < 3; ++k) include(k, e.lo[k], e.hi[k]);
  }
};

// One first-order explicit step (eq 4 with M, C diagonal): forward Euler
// (semi_implicit = false) moves x with the old v; semi-implicit Euler with the new one.
// v += dt (f/m + g).
template <class Real>
struct EulerStep {
  Real dt = 0, gx = 0, gy = 0, gz = 0;
  bool semi_implicit = true;
};

// That step on `count` points.
template <class Real>
struct PointUpdate {
  std::size_t count = 0;
  Real *x = nullptr, *y = nullptr, *z = nullptr;
  Real *vx = nullptr, *vy = nullptr, *vz = nullptr;
  const Real *fx = nullptr, *fy = nullptr, *fz = nullptr;
  const Real* inv_mass = nullptr;
  Real dt = 0, gx = 0, gy = 0, gz = 0;
  bool semi_implicit = true;
  // When set, grows to contain every new position, taken from the registers the update
  // computes it in (a compile-time variant of the update: a step that needs no box pays
  // nothing for it), so no later pass reads the points again for their box.
  Extent<Real>* extent = nullptr;

  // PointUpdate::of(n, x…, v…, f…, 1/m).step(dt, g…, semi_implicit)
  static PointUpdate of(std::size_t count, Real* x, Real* y, Real* z, Real* vx, Real* vy, Real* vz, const Real* fx,
                        const Real* fy, const Real* fz, const Real* inv_mass) {
    PointUpdate u;
    u.count = count;
    u.x = x;
    u.y = y;
    u.z = z;
    u.vx = vx;
    u.vy = vy;
    u.vz = vz;
    u.fx = fx;
    u.fy = fy;
    u.fz = fz;
    u.inv_mass = inv_mass;
    return u;
  }
  PointUpdate& step(Real step_dt, Real g_x, Real g_y, Real g_z, bool semi) {
    dt = step_dt;
    gx = g_x;
    gy = g_y;
    gz = g_z;
    semi_implicit = semi;
    return *this;
  }
  PointUpdate& step(const EulerStep<Real>& e) { return step(e.dt, e.gx, e.gy, e.gz, e.semi_implicit); }
  PointUpdate& grow(Extent<Real>* box) {
    extent = box;
    return *this;
  }
};

void update_points(const PointUpdate<double>& u);
void update_points(const PointUpdate<float>& u);

// The box of points [0, count), count ≥ 1, grown from the first point (so a NaN first
// coordinate gives a NaN bound). Exact on every target (min and max round nothing); only
// which of −0 and +0 wins a tie may differ. Bounding boxes (bounds.h) take x, y and z in
// one call.
Extent<double> points_extent(const double* x, const double* y, const double* z, std::size_t count);
Extent<float> points_extent(const float* x, const float* y, const float* z, std::size_t count);

// The boxes of a row of grid cells: cell j of `count` spans points j, j + 1 of rows a and b
// (one coordinate), lo[j] = the smallest of the four as std::min gives it (the first on a
// tie or a NaN), hi[j] the largest as std::max does.
template <class Real>
struct CellRow {
  std::size_t count = 0;
  const Real *a = nullptr, *b = nullptr;
  Real *lo = nullptr, *hi = nullptr;
};
void cell_boxes(const CellRow<double>& row);
void cell_boxes(const CellRow<float>& row);

// Air on a row of `count` grid cells (terms/air.h): cell j has corners j, j + 1 of rows a
// and b, at positions a…, b… and velocities av…, bv…; its force goes to f…[j]. The same
// operations in the same order as the formula there. The row sweep runs it inline (air.h);
// this entry point serves the tests.
template <class Real>
struct AirCells {
  std::size_t count = 0;
  const Real *ax = nullptr, *ay = nullptr, *az = nullptr, *bx = nullptr, *by = nullptr, *bz = nullptr;
  const Real *avx = nullptr, *avy = nullptr, *avz = nullptr, *bvx = nullptr, *bvy = nullptr, *bvz = nullptr;
  Real *fx = nullptr, *fy = nullptr, *fz = nullptr;
  Real half_pressure = 0, half_friction = 0, wx = 0, wy = 0, wz = 0;
};
void air_cells(const AirCells<double>& cells);
void air_cells(const AirCells<float>& cells);

// The instruction set the kernels run with now: "AVX3" (Highway's name for AVX-512),
// "AVX2", "SSE4" or "SCALAR" (portable, one lane) on x86.
const char* target_name();

// Every instruction set compiled into this build that the CPU supports, as Highway target
// bits, widest first. Tests run the kernels with each (use_target).
std::vector<std::int64_t> supported_targets();

// Makes the kernels run with one target from supported_targets(), or 0 to return to the
// widest. Process-wide (Highway's dispatch is), so only tests and benchmarks call it,
// never the engine; not while a world steps on another thread.
void use_target(std::int64_t target);

}  // namespace drape::detail::simd
