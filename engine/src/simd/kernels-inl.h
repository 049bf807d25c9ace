// The vector kernels of simd/kernels.h as per-target code, for any file that runs Highway's
// foreach_target: kernels.cpp exports them one by one (tests, the ceiling, a block's update),
// forces.cpp inlines them into the row sweep it compiles per target, so a sheet's whole
// sweep runs on one instruction set after one dispatch. Re-included once per target (the
// toggle below is Highway's convention for such headers).
#if defined(DRAPE_SIMD_KERNELS_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef DRAPE_SIMD_KERNELS_INL_H_
#undef DRAPE_SIMD_KERNELS_INL_H_
#else
#define DRAPE_SIMD_KERNELS_INL_H_
#endif

#include <hwy/highway.h>

#include <type_traits>

#include "simd/kernels.h"
#include "simd/select-inl.h"

HWY_BEFORE_NAMESPACE();
namespace drape::detail::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Loads and stores of whole vectors of tag D (a target's full width, or a part of it:
// Highway's half, quarter, ... vectors load and store only their own lanes), or of the
// first lanes of one: masked lanes load zero and are never stored, and every lane that is
// computes exactly as in a whole vector.
template <class D>
struct Whole {
  D d;
  template <class Real>
  HWY_INLINE auto load(const Real* p) const { return hn::LoadU(d, p); }
  template <class V, class Real>
  HWY_INLINE void store(V v, Real* p) const { hn::StoreU(v, d, p); }
};
template <class D>
struct FirstLanes {
  D d;
  decltype(hn::FirstN(D(), 0)) mask;
  template <class Real>
  HWY_INLINE auto load(const Real* p) const { return hn::MaskedLoad(mask, d, p); }
  template <class V, class Real>
  HWY_INLINE void store(V v, Real* p) const { hn::BlendedStore(v, mask, d, p); }
};

// The remainder after whole vectors of D, fewer than D's lanes: a vector of half D's
// width if that many remain, then a quarter, ..., down to one lane.
template <class D, class Kernel>
HWY_INLINE void over_tail(D, std::size_t count, std::size_t& i, Kernel& kernel) {
  if constexpr (hn::MaxLanes(D()) > 1) {
    const hn::Half<D> half;
    if (count - i >= hn::Lanes(half)) {
      kernel(Whole<hn::Half<D>>{half}, i);
      i += hn::Lanes(half);
    }
    over_tail(half, count, i, kernel);
  }
}

// Runs kernel(lanes, i) over [0, count) in whole vectors, then the remainder:
// - AVX-512: vectors of half, a quarter, ... of the width (over_tail). No masked stores,
//   which the next loads of the same row cannot forward from (tens of cycles on this AMD
//   EPYC; the cloth terms read back what the springs just wrote), and no lane of a short
//   row's tail wasted on the divider. (BM_Scene/rain_torus held to AVX3: 3 % faster than
//   one masked vector; the 1024-point step unchanged.)
// - AVX2: one masked vector (the 1024-point step held to AVX2 ran 5 % slower with
//   over_tail: its scalar tails spill registers).
// - Elsewhere one lane at a time, through the same code.
// Each element gets the same bits in a vector of any width, masked or not, wherever the
// run starts, so a row split between blocks changes nothing.
template <class Real, class Kernel>
HWY_INLINE void over_lanes(std::size_t count, Kernel kernel) {
  const hn::ScalableTag<Real> d;
  const std::size_t lanes = hn::Lanes(d);
  std::size_t i = 0;
  for (; i + lanes <= count; i += lanes) kernel(Whole<decltype(d)>{d}, i);
  if (i == count) return;
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3
  over_tail(d, count, i, kernel);
#elif HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2
  kernel(FirstLanes<decltype(d)>{d, hn::FirstN(d, count - i)}, i);
#else
  const hn::CappedTag<Real, 1> one;
  for (; i < count; ++i) kernel(Whole<decltype(one)>{one}, i);
#endif
}

// over_lanes for a kernel that only stores, each element's values computed from inputs it
// does not write (no element reads what another stores): its remainder is one whole vector
// ending at `count`, which computes some elements again and stores the same bits over them,
// where a masked vector's loads and stores cost AVX2 on this AMD EPYC more than the
// repeated lanes (the 1024-point step's row springs, 31 to a row). Fewer elements than one
// vector take over_lanes' way.
template <class Real, class Kernel>
HWY_INLINE void over_lanes_storing(std::size_t count, Kernel kernel) {
  const hn::ScalableTag<Real> d;
  const std::size_t lanes = hn::Lanes(d);
  if (count < lanes) return over_lanes<Real>(count, kernel);
  std::size_t i = 0;
  for (; i + lanes <= count; i += lanes) kernel(Whole<decltype(d)>{d}, i);
  if (i < count) kernel(Whole<decltype(d)>{d}, count - lanes);
}

// eq (6) on the springs of one vector from e: the same operations, in the same order, as
// spring_scale in terms/rows.h, so a lane gives the scalar kernel's bits.
template <bool PerSpring, class Real, class Lanes, class Use>
HWY_INLINE void spring_forces(Lanes l, const SpringRun<Real>& r, std::size_t e, Use use) {
  const auto d = l.d;
  const auto dx = hn::Sub(l.load(r.ax + e), l.load(r.bx + e));
  const auto dy = hn::Sub(l.load(r.ay + e), l.load(r.by + e));
  const auto dz = hn::Sub(l.load(r.az + e), l.load(r.bz + e));
  const auto rest = PerSpring ? l.load(r.rest + e) : hn::Set(d, r.rest_same);
  const auto k = PerSpring ? l.load(r.k + e) : hn::Set(d, r.k_same);
  const auto len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz)));
  // a zero-length spring has no direction: its lane's 1/0 is dropped, not used
  const auto inv = hn::IfThenElseZero(hn::Gt(len, hn::Zero(d)), hn::Div(hn::Set(d, Real(1)), len));
  const auto s = hn::Mul(hn::Mul(hn::Neg(k), hn::Sub(len, rest)), inv);
  use(hn::Mul(s, dx), hn::Mul(s, dy), hn::Mul(s, dz));
}

// eq (6) on the springs of one vector from e, into the run's outputs.
template <bool PerSpring, bool Store, bool Add, bool Sub, bool Net, class Real, class Lanes>
HWY_INLINE void springs_at(Lanes l, const SpringRun<Real>& r, std::size_t e) {
  spring_forces<PerSpring>(l, r, e, [&](auto fx, auto fy, auto fz) __attribute__((always_inline)) {
    if constexpr (Store) {
      l.store(fx, r.store_x + e);
      l.store(fy, r.store_y + e);
      l.store(fz, r.store_z + e);
    }
    if constexpr (Add) {
      l.store(hn::Add(l.load(r.add_x + e), fx), r.add_x + e);
      l.store(hn::Add(l.load(r.add_y + e), fy), r.add_y + e);
      l.store(hn::Add(l.load(r.add_z + e), fz), r.add_z + e);
    }
    if constexpr (Sub) {
      // what the forces are taken from: sub itself, or the netted row (SpringRun::netted)
      auto from = [&](const Real* sub, const Real* net) __attribute__((always_inline)) {
        if constexpr (Net) return hn::Sub(l.load(net + e), l.load(net + e - 1));
        return l.load(sub + e);
      };
      l.store(hn::Sub(from(r.sub_x, r.net_x), fx), r.sub_x + e);
      l.store(hn::Sub(from(r.sub_y, r.net_y), fy), r.sub_y + e);
      l.store(hn::Sub(from(r.sub_z, r.net_z), fz), r.sub_z + e);
    }
  });
}

template <bool PerSpring, bool Store, bool Add, bool Sub, bool Net = false, class Real>
HWY_INLINE void springs_loop(const SpringRun<Real>& r) {
  // forced inline, like the kernels: GCC's inliner otherwise leaves a call per vector in a
  // sweep that has grown large
  auto kernel = [&](auto lanes, std::size_t e) __attribute__((always_inline)) {
    springs_at<PerSpring, Store, Add, Sub, Net>(lanes, r, e);
  };
  if constexpr (Store && !Add && !Sub)
    over_lanes_storing<Real>(r.count, kernel);  // the spring's forces alone, stored apart from its ends
  else
    over_lanes<Real>(r.count, kernel);
}

// The outputs and the parameters' source picked once per run, not per spring.
template <class Real>
HWY_INLINE void springs_run(const SpringRun<Real>& r) {
  auto with_outputs = [&]<bool PerSpring>() {
    const bool store = r.store_x != nullptr, add = r.add_x != nullptr, sub = r.sub_x != nullptr;
    if (r.net_x != nullptr) {
      if (!store && add && sub) return springs_loop<PerSpring, false, true, true, true>(r);
      if (!store && !add && sub) return springs_loop<PerSpring, false, false, true, true>(r);
      return;  // netted forces go only with sub and without store
    }
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

// A vector whose lane i holds lane i − 1 of v, and lane 0 the last lane of prev: each
// element's left neighbour, when v follows prev in a row (rows_joined). AVX-512 only, one
// valign: with AVX2's 16 registers the joined pass ran the 1024-point step 5 % slower than
// the netted one (its shift two shuffles, and three more vectors live across the loop),
// and 48 sheets no faster; a shift of one vpermpd/vpermps per vector, the previous
// vector's rotation kept and blended into lane 0, was slower still (the 1024-point step
// +13 %, 48 sheets +7 % in f64 and +14 % in f32). Other targets take the netted pass.
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3
template <class D, class V>
HWY_INLINE V shift_in(D d, V prev, V v) {
  const hn::RebindToUnsigned<D> du;
  const auto a = hn::BitCast(du, v).raw, b = hn::BitCast(du, prev).raw;
  if constexpr (sizeof(hn::TFromD<D>) == 8)
    return hn::BitCast(d, hn::VFromD<decltype(du)>{_mm512_alignr_epi64(a, b, 7)});
  else
    return hn::BitCast(d, hn::VFromD<decltype(du)>{_mm512_alignr_epi32(a, b, 15)});
}

// v in the lanes l loads and stores, +0 in the others.
template <class D, class V>
HWY_INLINE V lanes_only(Whole<D>, V v) {
  return v;
}
template <class D, class V>
HWY_INLINE V lanes_only(FirstLanes<D> l, V v) {
  return hn::IfThenElseZero(l.mask, v);
}
#endif

// A row's horizontal springs h (spring j joins its points j and j + 1; h.count of them, one
// fewer than the row's points) and the vertical springs v between the row above and it
// (v adds to the row above and subtracts from this row's forces, which it writes), in one
// pass: point j of the row gets (h[j] − h[j − 1]) − v[j], with h[−1] = h[count] = 0, the
// operands and order of the netted pass (SpringRun::netted), so the same bits. Each
// vector's h[j − 1] is its own h shifted one lane across from the vector before
// (shift_in), and the last vector's last spring, past the row's end, is +0, so no spring
// is stored and loaded again. With AVX-512, on rows of whole vectors; elsewhere it does
// nothing and returns false, and the caller takes the netted pass.
template <bool PerSpring, class Real>
HWY_INLINE bool rows_joined(const SpringRun<Real>& h, const SpringRun<Real>& v) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3
  const hn::ScalableTag<Real> d;
  const std::size_t lanes = hn::Lanes(d), cols = v.count;
  if (cols % lanes != 0) return false;
  auto prev_x = hn::Zero(d), prev_y = hn::Zero(d), prev_z = hn::Zero(d);
  // the vector from e, whose springs of h are those of hl's lanes
  auto joined = [&](auto hl, std::size_t e) __attribute__((always_inline)) {
    const Whole<decltype(d)> l{d};
    spring_forces<PerSpring>(hl, h, e, [&](auto hx, auto hy, auto hz) __attribute__((always_inline)) {
      hx = lanes_only(hl, hx);  // +0 past the row's end
      hy = lanes_only(hl, hy);
      hz = lanes_only(hl, hz);
      spring_forces<PerSpring>(l, v, e, [&](auto fx, auto fy, auto fz) __attribute__((always_inline)) {
        l.store(hn::Add(l.load(v.add_x + e), fx), v.add_x + e);
        l.store(hn::Add(l.load(v.add_y + e), fy), v.add_y + e);
        l.store(hn::Add(l.load(v.add_z + e), fz), v.add_z + e);
        l.store(hn::Sub(hn::Sub(hx, shift_in(d, prev_x, hx)), fx), v.sub_x + e);
        l.store(hn::Sub(hn::Sub(hy, shift_in(d, prev_y, hy)), fy), v.sub_y + e);
        l.store(hn::Sub(hn::Sub(hz, shift_in(d, prev_z, hz)), fz), v.sub_z + e);
      });
      prev_x = hx;
      prev_y = hy;
      prev_z = hz;
    });
  };
  const std::size_t last = cols - lanes;
  for (std::size_t e = 0; e < last; e += lanes) joined(Whole<decltype(d)>{d}, e);
  joined(FirstLanes<decltype(d)>{d, hn::FirstN(d, lanes - 1)}, last);
  return true;
#else
  (void)h;
  (void)v;
  return false;
#endif
}

// Air on the cells of one vector from j (AirCells; terms/air.h gives the formula).
template <class Real, class Lanes>
HWY_INLINE void air_cells_at(Lanes l, const AirCells<Real>& r, std::size_t j) {
  const auto d = l.d;
  const auto d1x = hn::Sub(l.load(r.bx + j + 1), l.load(r.ax + j));
  const auto d1y = hn::Sub(l.load(r.by + j + 1), l.load(r.ay + j));
  const auto d1z = hn::Sub(l.load(r.bz + j + 1), l.load(r.az + j));
  const auto d2x = hn::Sub(l.load(r.bx + j), l.load(r.ax + j + 1));
  const auto d2y = hn::Sub(l.load(r.by + j), l.load(r.ay + j + 1));
  const auto d2z = hn::Sub(l.load(r.bz + j), l.load(r.az + j + 1));
  const auto cx = hn::Sub(hn::Mul(d1y, d2z), hn::Mul(d1z, d2y));
  const auto cy = hn::Sub(hn::Mul(d1z, d2x), hn::Mul(d1x, d2z));
  const auto cz = hn::Sub(hn::Mul(d1x, d2y), hn::Mul(d1y, d2x));
  const auto quarter = hn::Set(d, Real(0.25));
  auto mean = [&](const Real* a, const Real* b, Real wind) __attribute__((always_inline)) {
    const auto sum = hn::Add(hn::Add(hn::Add(l.load(a + j), l.load(a + j + 1)), l.load(b + j)), l.load(b + j + 1));
    return hn::Sub(hn::Mul(quarter, sum), hn::Set(d, wind));
  };
  const auto vx = mean(r.avx, r.bvx, r.wx), vy = mean(r.avy, r.bvy, r.wy), vz = mean(r.avz, r.bvz, r.wz);
  const auto cc = hn::Add(hn::Add(hn::Mul(cx, cx), hn::Mul(cy, cy)), hn::Mul(cz, cz));
  // a collapsed cell feels no air: its lane's 1/0 is dropped
  const auto inv = hn::IfThenElseZero(hn::Gt(cc, hn::Zero(d)), hn::Div(hn::Set(d, Real(1)), cc));
  const auto vc = hn::Add(hn::Add(hn::Mul(vx, cx), hn::Mul(vy, cy)), hn::Mul(vz, cz));
  const auto normal = hn::Mul(hn::Mul(hn::Mul(hn::Set(d, -r.half_pressure), hn::Abs(vc)), vc), inv);
  const auto vc_inv = hn::Mul(vc, inv);
  const auto tx = hn::Sub(vx, hn::Mul(vc_inv, cx)), ty = hn::Sub(vy, hn::Mul(vc_inv, cy)),
             tz = hn::Sub(vz, hn::Mul(vc_inv, cz));
  const auto tt = hn::Add(hn::Add(hn::Mul(tx, tx), hn::Mul(ty, ty)), hn::Mul(tz, tz));
  const auto tangential = hn::Mul(hn::Set(d, -r.half_friction), hn::Sqrt(hn::Mul(cc, tt)));
  l.store(hn::Add(hn::Mul(normal, cx), hn::Mul(tangential, tx)), r.fx + j);
  l.store(hn::Add(hn::Mul(normal, cy), hn::Mul(tangential, ty)), r.fy + j);
  l.store(hn::Add(hn::Mul(normal, cz), hn::Mul(tangential, tz)), r.fz + j);
}

template <class Real>
HWY_INLINE void air_cells_of(const AirCells<Real>& r) {
  over_lanes<Real>(r.count, [&](auto lanes, std::size_t j) __attribute__((always_inline)) { air_cells_at(lanes, r, j); });
}

// Grows the running bounds lo, hi of one coordinate (vectors of lanes, each lane its own
// box) by v, as Extent::include does; the bounds pass and the integrators' update share it.
template <class V>
HWY_INLINE void extent_take(V v, V& lo, V& hi) {
  lo = first_min(lo, v);  // v < lo ? v : lo
  hi = first_max(hi, v);  // hi < v ? v : hi
}

// Coordinate k of `into` grown by the lanes of lo and hi.
template <class D, class V, class Real>
HWY_INLINE void extent_reduce(D d, V lo, V hi, int k, Extent<Real>& into) {
  into.include(k, hn::GetLane(hn::MinOfLanes(d, lo)), hn::GetLane(hn::MaxOfLanes(d, hi)));
}

// eq (4), first order, on the points of one vector from i; new_position(c, x) sees each
// coordinate's new positions.
template <bool SemiImplicit, class Real, class Lanes, class Seen>
HWY_INLINE void update_at(Lanes l, const PointUpdate<Real>& u, std::size_t i, Seen new_position) {
  const auto d = l.d;
  const auto dt = hn::Set(d, u.dt);
  const auto im = l.load(u.inv_mass + i);
  Real* const xs[3] = {u.x, u.y, u.z};
  Real* const vs[3] = {u.vx, u.vy, u.vz};
  const Real* const fs[3] = {u.fx, u.fy, u.fz};
  const Real gs[3] = {u.gx, u.gy, u.gz};
  for (int c = 0; c < 3; ++c) {
    auto x = l.load(xs[c] + i);
    auto v = l.load(vs[c] + i);
    if constexpr (!SemiImplicit) x = hn::Add(x, hn::Mul(dt, v));
    v = hn::Add(v, hn::Mul(dt, hn::Add(hn::Mul(l.load(fs[c] + i), im), hn::Set(d, gs[c]))));
    if constexpr (SemiImplicit) x = hn::Add(x, hn::Mul(dt, v));
    l.store(x, xs[c] + i);
    l.store(v, vs[c] + i);
    new_position(c, x);
  }
}

template <bool SemiImplicit, class Real>
HWY_INLINE void update_loop(const PointUpdate<Real>& u) {
  over_lanes<Real>(u.count, [&](auto lanes, std::size_t i) __attribute__((always_inline)) {
    update_at<SemiImplicit>(lanes, u, i, [](int, auto) {});
  });
}

// The update that also grows *u.extent by the new positions: whole vectors take them from
// the registers they are computed in; a remainder is read back (it was just stored) as the
// last whole vector, which overlaps the ones before it as in extent_of, or point by point
// when there are fewer points than lanes.
template <bool SemiImplicit, class Real>
HWY_INLINE void update_loop_growing(const PointUpdate<Real>& u) {
  const hn::ScalableTag<Real> d;
  using Full = Whole<decltype(d)>;
  const std::size_t lanes = hn::Lanes(d), count = u.count;
  const Extent<Real> none = Extent<Real>::none();
  // named vectors, not an array: scalable vectors (SVE, RVV) cannot be array elements
  auto lo0 = hn::Set(d, none.lo[0]), hi0 = hn::Set(d, none.hi[0]), lo1 = lo0, hi1 = hi0, lo2 = lo0, hi2 = hi0;
  auto take = [&](int c, auto x) __attribute__((always_inline)) {
    if (c == 0) extent_take(x, lo0, hi0);
    if (c == 1) extent_take(x, lo1, hi1);
    if (c == 2) extent_take(x, lo2, hi2);
  };
  over_lanes<Real>(count, [&](auto l, std::size_t i) __attribute__((always_inline)) {
    if constexpr (std::is_same_v<decltype(l), Full>)
      update_at<SemiImplicit>(l, u, i, take);
    else
      update_at<SemiImplicit>(l, u, i, [](int, auto) {});
  });
  Extent<Real>& e = *u.extent;
  if (count % lanes != 0 && count >= lanes) {
    const std::size_t last = count - lanes;
    take(0, hn::LoadU(d, u.x + last));
    take(1, hn::LoadU(d, u.y + last));
    take(2, hn::LoadU(d, u.z + last));
  } else if (count < lanes) {
    for (std::size_t i = 0; i < count; ++i) e.include(u.x[i], u.y[i], u.z[i]);
  }
  extent_reduce(d, lo0, hi0, 0, e);
  extent_reduce(d, lo1, hi1, 1, e);
  extent_reduce(d, lo2, hi2, 2, e);
}

// The step and whether it grows a box picked once per call, not per point.
template <class Real>
HWY_INLINE void update_run(const PointUpdate<Real>& u) {
  if (u.extent)
    return u.semi_implicit ? update_loop_growing<true>(u) : update_loop_growing<false>(u);
  if (u.semi_implicit)
    update_loop<true>(u);
  else
    update_loop<false>(u);
}

// The extent of a[0, count) (kernels.h): every lane starts from a[0], so the lanes are all
// NaN (a[0] is) or none is; the last vector overlaps the one before it where count is not
// a multiple of the width, which min and max do not mind. Four pairs of running vectors,
// not one: each compare-and-select waits for the one before it on the same vector, so a
// single pair leaves the core idle most of the time (the bounds pass of a sheet near an
// obstacle ran at a quarter of its throughput).
template <class Real>
HWY_INLINE void extent_of(const Real* a, std::size_t count, int k, Extent<Real>& e) {
  const hn::ScalableTag<Real> d;
  using V = hn::Vec<decltype(d)>;
  const std::size_t lanes = hn::Lanes(d);
  e.lo[k] = e.hi[k] = a[0];
  if (count < lanes) {
    for (std::size_t i = 1; i < count; ++i) e.include(k, a[i], a[i]);
    return;
  }
  // named vectors, not an array: scalable vectors (SVE, RVV) cannot be array elements
  V lo0 = hn::Set(d, a[0]), hi0 = lo0, lo1 = lo0, hi1 = lo0, lo2 = lo0, hi2 = lo0, lo3 = lo0, hi3 = lo0;
  std::size_t i = 0;
  for (; i + 4 * lanes <= count; i += 4 * lanes) {
    extent_take(hn::LoadU(d, a + i), lo0, hi0);
    extent_take(hn::LoadU(d, a + i + lanes), lo1, hi1);
    extent_take(hn::LoadU(d, a + i + 2 * lanes), lo2, hi2);
    extent_take(hn::LoadU(d, a + i + 3 * lanes), lo3, hi3);
  }
  for (; i + lanes <= count; i += lanes) extent_take(hn::LoadU(d, a + i), lo0, hi0);
  if (i < count) extent_take(hn::LoadU(d, a + count - lanes), lo0, hi0);
  extent_reduce(d, lo0, hi0, k, e);
  extent_reduce(d, lo1, hi1, k, e);
  extent_reduce(d, lo2, hi2, k, e);
  extent_reduce(d, lo3, hi3, k, e);
}

template <class Real>
HWY_INLINE Extent<Real> points_extent_of(const Real* x, const Real* y, const Real* z, std::size_t count) {
  Extent<Real> e;
  extent_of(x, count, 0, e);
  extent_of(y, count, 1, e);
  extent_of(z, count, 2, e);
  return e;
}

template <class Real>
HWY_INLINE void cell_boxes_of(const CellRow<Real>& r) {
  over_lanes<Real>(r.count, [&](auto l, std::size_t j) __attribute__((always_inline)) {
    const auto a0 = l.load(r.a + j), a1 = l.load(r.a + j + 1), b0 = l.load(r.b + j), b1 = l.load(r.b + j + 1);
    l.store(first_min(first_min(a0, a1), first_min(b0, b1)), r.lo + j);
    l.store(first_max(first_max(a0, a1), first_max(b0, b1)), r.hi + j);
  });
}

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail::simd
HWY_AFTER_NAMESPACE();

#endif  // DRAPE_SIMD_KERNELS_INL_H_ toggle
