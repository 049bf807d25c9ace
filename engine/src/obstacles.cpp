// Obstacles (paper §3, eq 9): implicit functions of plane, sphere, ellipsoid, torus and box
// with analytic gradients, and the repulsion c·exp(−f/ξ) around them.
//
// Highway's foreach_target compiles the eq (9) term once per instruction set
// (simd/targets.h), like the row sweep (forces.cpp), and obstacle_forces dispatches to the
// widest the CPU has once per sheet and obstacle. The term is written in Highway vectors of
// doubles (a float sheet's values promoted on load, rounded back on store): the shapes' f and
// ∇f with masks for their degenerate points, the force scale through a polynomial exp, the
// projection on the sheet normal and friction, each lane doing the scalar formula's
// operations in its order. Contraction into FMA is off here (engine/CMakeLists.txt) and no
// op fuses, so every target, and a one-lane vector, gives the same bits. The potential's sum
// over a sheet (its energy, which the guard reads after every step() call) runs in the same
// vectors; it adds its lanes in an order of the vector's width, so targets may differ in its
// last bits. The rest (validation, placement) is compiled once and runs the build's own
// target's copy of the same shapes and force scale one lane at a time.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "obstacles.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "obstacles.h"
#include "simd/exp-inl.h"
#include "simd/kernels-inl.h"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <sstream>
#include <type_traits>

HWY_BEFORE_NAMESPACE();
namespace drape::detail {
namespace HWY_NAMESPACE {

namespace hn = hwy::HWY_NAMESPACE;
namespace lanes = simd::HWY_NAMESPACE;  // over_lanes, Whole, FirstLanes, first_min, first_max, exp_lanes

// What f and ∇f read of an obstacle: its pose, its size and the size's reciprocals. The row
// loop holds a copy (RowForce): it stores into the sheet's forces, which could alias the
// Obstacle as far as the compiler knows, so it would load the obstacle again for every vector.
struct Frame {
  double center[3], rot[3][3];  // as in Obstacle
  Vec3 size, inv;               // inv = (1/size.x, 1/size.y, 1/size.z), where the shape divides by them
};

Frame frame_of(const Obstacle& o) {
  Frame r{{o.center[0], o.center[1], o.center[2]}, {}, o.def.size, {}};
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < 3; ++l) r.rot[k][l] = o.rot[k][l];
  if (o.def.shape == ObstacleShape::Ellipsoid) r.inv = {1.0 / r.size.x, 1.0 / r.size.y, 1.0 / r.size.z};
  return r;
}

// Local implicit functions: f and ∇f at points p of the obstacle's own frame, a vector of
// them at a time, with one division per point (a reciprocal, then products). Where the
// gradient has no direction (a sphere's centre, a torus's axis or core circle) a fixed unit
// direction is used, so a point there is still pushed out and never gets 0/0 or 0·∞: such a
// lane's value is computed and dropped by its mask.
struct PlaneF {
  static constexpr bool constant_gradient = true;  // ∇f is the plane's unit normal everywhere
  template <class D, class V>
  static HWY_INLINE void at(D d, V, V, V z, const Frame&, V& f, V& gx, V& gy, V& gz) {
    f = z;
    gx = hn::Zero(d);
    gy = hn::Zero(d);
    gz = hn::Set(d, 1.0);
  }
};

struct SphereF {
  static constexpr bool constant_gradient = false;
  template <class D, class V>
  static HWY_INLINE void at(D d, V x, V y, V z, const Frame& o, V& f, V& gx, V& gy, V& gz) {
    const Vec3& s = o.size;
    const V r = hn::Sqrt(hn::Add(hn::Add(hn::Mul(x, x), hn::Mul(y, y)), hn::Mul(z, z)));
    const auto centre = hn::Eq(r, hn::Zero(d));
    const V inv = hn::Div(hn::Set(d, 1.0), r);
    f = hn::IfThenElse(centre, hn::Set(d, -s.x), hn::Sub(r, hn::Set(d, s.x)));
    gx = hn::IfThenElse(centre, hn::Zero(d), hn::Mul(x, inv));
    gy = hn::IfThenElse(centre, hn::Zero(d), hn::Mul(y, inv));
    gz = hn::IfThenElse(centre, hn::Set(d, 1.0), hn::Mul(z, inv));
  }
};

// Not the exact distance (which has no closed form): k·(q − 1), q the point's radius in the
// unit-sphere coordinates (x/a, y/b, z/c), scaled by k = the smallest semi-axis so f is
// measured in metres, matches the distance on the smallest axis and never exceeds it
// elsewhere, and ξ keeps its meaning as a length.
struct EllipsoidF {
  static constexpr bool constant_gradient = false;
  template <class D, class V>
  static HWY_INLINE void at(D d, V x, V y, V z, const Frame& o, V& f, V& gx, V& gy, V& gz) {
    const Vec3 &s = o.size, &a = o.inv;
    const double k = std::min({s.x, s.y, s.z});
    const V ux = hn::Mul(x, hn::Set(d, a.x)), uy = hn::Mul(y, hn::Set(d, a.y)), uz = hn::Mul(z, hn::Set(d, a.z));
    const V q = hn::Sqrt(hn::Add(hn::Add(hn::Mul(ux, ux), hn::Mul(uy, uy)), hn::Mul(uz, uz)));
    const auto centre = hn::Eq(q, hn::Zero(d));
    const V inv = hn::Div(hn::Set(d, 1.0), q);
    f = hn::IfThenElse(centre, hn::Set(d, -k), hn::Mul(hn::Set(d, k), hn::Sub(q, hn::Set(d, 1.0))));
    gx = hn::IfThenElse(centre, hn::Zero(d), hn::Mul(hn::Mul(hn::Set(d, k * a.x), ux), inv));
    gy = hn::IfThenElse(centre, hn::Zero(d), hn::Mul(hn::Mul(hn::Set(d, k * a.y), uy), inv));
    gz = hn::IfThenElse(centre, hn::Set(d, 1.0), hn::Mul(hn::Mul(hn::Set(d, k * a.z), uz), inv));
  }
};

// Exact signed distance to a torus around local z: major radius R = s.x, minor r = s.y.
struct TorusF {
  static constexpr bool constant_gradient = false;
  template <class D, class V>
  static HWY_INLINE void at(D d, V x, V y, V z, const Frame& o, V& f, V& gx, V& gy, V& gz) {
    const Vec3& s = o.size;
    const V one = hn::Set(d, 1.0);
    const V rho = hn::Sqrt(hn::Add(hn::Mul(x, x), hn::Mul(y, y)));
    const auto off_axis = hn::Gt(rho, hn::Zero(d));
    const V inv_rho = hn::Div(one, rho);
    const V cx = hn::IfThenElse(off_axis, hn::Mul(x, inv_rho), one);
    const V cy = hn::IfThenElseZero(off_axis, hn::Mul(y, inv_rho));
    const V dr = hn::Sub(rho, hn::Set(d, s.x));
    const V len = hn::Sqrt(hn::Add(hn::Mul(dr, dr), hn::Mul(z, z)));
    const auto core = hn::Eq(len, hn::Zero(d));
    const V inv_len = hn::Div(one, len);
    const V along = hn::Mul(dr, inv_len);
    f = hn::IfThenElse(core, hn::Set(d, -s.y), hn::Sub(len, hn::Set(d, s.y)));
    gx = hn::IfThenElse(core, hn::Zero(d), hn::Mul(along, cx));
    gy = hn::IfThenElse(core, hn::Zero(d), hn::Mul(along, cy));
    gz = hn::IfThenElse(core, one, hn::Mul(z, inv_len));
  }
};

// −1 where v < 0, else 1 (a function, not a lambda: clang gives a lambda in target code no
// target of its own).
template <class D, class V>
HWY_INLINE V sign_of(D d, V v) {
  return hn::IfThenElse(hn::Lt(v, hn::Zero(d)), hn::Set(d, -1.0), hn::Set(d, 1.0));
}

// Exact signed distance to a box of half extents s. Outside it is continuously
// differentiable; inside, the gradient points to the nearest face (the first of x, y, z
// among equally near ones) and jumps across the planes where two faces are equally near
// (documented choice: the force there still pushes out through a nearest face).
struct BoxF {
  static constexpr bool constant_gradient = false;
  template <class D, class V>
  static HWY_INLINE void at(D d, V x, V y, V z, const Frame& o, V& f, V& gx, V& gy, V& gz) {
    const Vec3& s = o.size;
    const V qx = hn::Sub(hn::Abs(x), hn::Set(d, s.x)), qy = hn::Sub(hn::Abs(y), hn::Set(d, s.y)),
            qz = hn::Sub(hn::Abs(z), hn::Set(d, s.z));
    const auto px = hn::Gt(qx, hn::Zero(d)), py = hn::Gt(qy, hn::Zero(d)), pz = hn::Gt(qz, hn::Zero(d));
    // each part is +0 or positive, so the sum is the one from 0 in x, y, z order
    const V out2 = hn::Add(hn::Add(hn::IfThenElseZero(px, hn::Mul(qx, qx)), hn::IfThenElseZero(py, hn::Mul(qy, qy))),
                           hn::IfThenElseZero(pz, hn::Mul(qz, qz)));
    const auto outside = hn::Gt(out2, hn::Zero(d));
    const V out = hn::Sqrt(out2), inv_out = hn::Div(hn::Set(d, 1.0), out);
    const V sx = sign_of(d, x), sy = sign_of(d, y), sz = sign_of(d, z);
    const auto xy = hn::Ge(qx, qy), xz = hn::Ge(qx, qz), yz = hn::Ge(qy, qz);
    const auto face_x = hn::And(xy, xz), face_y = hn::AndNot(xy, yz), face_z = hn::Not(hn::Or(face_x, face_y));
    f = hn::IfThenElse(outside, out, hn::IfThenElse(face_x, qx, hn::IfThenElse(face_y, qy, qz)));
    gx = hn::IfThenElse(outside, hn::IfThenElseZero(px, hn::Mul(hn::Mul(sx, qx), inv_out)), hn::IfThenElseZero(face_x, sx));
    gy = hn::IfThenElse(outside, hn::IfThenElseZero(py, hn::Mul(hn::Mul(sy, qy), inv_out)), hn::IfThenElseZero(face_y, sy));
    gz = hn::IfThenElse(outside, hn::IfThenElseZero(pz, hn::Mul(hn::Mul(sz, qz), inv_out)), hn::IfThenElseZero(face_z, sz));
  }
};

// Local coordinate l of world points p (d = p − center): the obstacle's axis l dotted with d.
// For a plane, l = 2 is f.
template <class D, class V>
HWY_INLINE V local_axis(D d, const Frame& o, int l, V dx, V dy, V dz) {
  return hn::Add(hn::Add(hn::Mul(hn::Set(d, o.rot[0][l]), dx), hn::Mul(hn::Set(d, o.rot[1][l]), dy)),
                 hn::Mul(hn::Set(d, o.rot[2][l]), dz));
}

// f and ∇f at world points: to the obstacle's frame, the shape, ∇f back to the world's.
template <class Shape, class D, class V>
HWY_INLINE void sample_lanes(D d, const Frame& o, V px, V py, V pz, V& f, V& gx, V& gy, V& gz) {
  const V dx = hn::Sub(px, hn::Set(d, o.center[0])), dy = hn::Sub(py, hn::Set(d, o.center[1])),
          dz = hn::Sub(pz, hn::Set(d, o.center[2]));
  V lx, ly, lz;
  Shape::at(d, local_axis(d, o, 0, dx, dy, dz), local_axis(d, o, 1, dx, dy, dz), local_axis(d, o, 2, dx, dy, dz),
            o, f, lx, ly, lz);
  const auto world = [&](int k) HWY_ATTR {
    return hn::Add(hn::Add(hn::Mul(hn::Set(d, o.rot[k][0]), lx), hn::Mul(hn::Set(d, o.rot[k][1]), ly)),
                   hn::Mul(hn::Set(d, o.rot[k][2]), lz));
  };
  gx = world(0);
  gy = world(1);
  gz = world(2);
}

// One point through the same code, for what runs once (implicit_at, may_touch).
template <class Shape>
ImplicitSample sample(const Obstacle& o, const double p[3]) {
  const hn::CappedTag<double, 1> d;
  hn::Vec<decltype(d)> f, gx, gy, gz;
  sample_lanes<Shape>(d, frame_of(o), hn::Set(d, p[0]), hn::Set(d, p[1]), hn::Set(d, p[2]), f, gx, gy, gz);
  return {hn::GetLane(f), {hn::GetLane(gx), hn::GetLane(gy), hn::GetLane(gz)}};
}

// The cut-off, shifted eq (9): −dE/df, zero at and beyond the reach.
struct ForceScale {
  double c_over_xi, minus_inv_xi, cap, tail, reach;  // tail = e^−reach_exponent
  // The scale where f < reach; the caller drops the lanes beyond.
  template <class D, class V>
  HWY_INLINE V within(D d, V f) const {
    const V e = lanes::first_min(hn::Mul(f, hn::Set(d, minus_inv_xi)), hn::Set(d, cap));
    // ≥ 0 even for a cap below −reach
    return hn::Mul(hn::Set(d, c_over_xi), lanes::first_max(hn::Sub(lanes::exp_lanes(d, e), hn::Set(d, tail)), hn::Zero(d)));
  }
  template <class D, class V>
  HWY_INLINE V operator()(D d, V f) const {
    return hn::IfThenElseZero(hn::Lt(f, hn::Set(d, reach)), within(d, f));
  }
  double operator()(double f) const {
    const hn::CappedTag<double, 1> d;
    return hn::GetLane((*this)(d, hn::Set(d, f)));
  }
};

ForceScale force_scale_of(const ObstacleDef& d, double cap) {
  return {d.c / d.xi, -(1.0 / d.xi), cap, std::exp(-reach_exponent), reach_exponent * d.xi};
}

// The potential whose −dE/df is ForceScale, where f < reach: c·(e^ê − t)·(1 + e − ê) −
// c·t·(r + ê), e = −f/ξ, ê = min(e, cap), t = e^−r: the exponential below the cap (there
// 1 + e − ê is 1), continued linearly in e past it. potential_energy is the same function
// one value at a time, through the C library's exp.
struct Potential {
  double c, minus_inv_xi, cap, tail, reach;
  template <class D, class V>
  HWY_INLINE V within(D d, V f) const {
    const V e = hn::Mul(f, hn::Set(d, minus_inv_xi));
    const V capped = lanes::first_min(e, hn::Set(d, cap));
    const V c_ = hn::Set(d, c), t = hn::Set(d, tail);
    const V rising =
        hn::Mul(hn::Mul(c_, hn::Sub(lanes::exp_lanes(d, capped), t)), hn::Add(hn::Set(d, 1.0), hn::Sub(e, capped)));
    return hn::Sub(rising, hn::Mul(hn::Mul(c_, t), hn::Add(hn::Set(d, reach_exponent), capped)));
  }
};

// Loads and stores of a sheet's Real through lanes l of doubles: a float sheet's lanes are
// promoted on the way in and rounded back (as static_cast<float>) on the way out.
template <class D>
HWY_INLINE auto floats_of(lanes::Whole<D>) {
  return lanes::Whole<hn::Rebind<float, D>>{};
}
template <class D>
HWY_INLINE auto floats_of(lanes::FirstLanes<D> l) {
  const hn::Rebind<float, D> df;
  return lanes::FirstLanes<hn::Rebind<float, D>>{df, hn::FirstN(df, hn::CountTrue(l.d, l.mask))};
}
template <class Real, class Lanes>
HWY_INLINE auto load_real(Lanes l, const Real* p) {
  if constexpr (std::is_same_v<Real, double>)
    return l.load(p);
  else
    return floats_of(l).load(p);
}
template <class Lanes, class V>
HWY_INLINE auto widen(Lanes l, V v) {
  if constexpr (std::is_same_v<hn::TFromV<V>, double>)
    return v;
  else
    return hn::PromoteTo(l.d, v);
}
template <class Real, class Lanes>
HWY_INLINE auto load_wide(Lanes l, const Real* p) {
  return widen(l, load_real(l, p));
}
// f[p] += F as the sheet's Real where `add` holds, f[p] unchanged elsewhere: a float sheet
// adds F rounded to float.
template <class Lanes, class M, class VR, class V, class Real>
HWY_INLINE void store_sum(Lanes l, M add, VR before, V F, Real* p) {
  if constexpr (std::is_same_v<Real, double>) {
    l.store(hn::IfThenElse(add, hn::Add(before, F), before), p);
  } else {
    const auto lf = floats_of(l);
    // the mask carried over as a value: Highway 1.0 rebinds masks only between lanes of one size
    const auto keep = hn::Gt(hn::DemoteTo(lf.d, hn::IfThenElseZero(add, hn::Set(l.d, 1.0))), hn::Zero(lf.d));
    lf.store(hn::IfThenElse(keep, hn::Add(before, hn::DemoteTo(lf.d, F)), before), p);
  }
}
// Lanes where m holds and that l covers (a part vector's masked lanes load zeros).
template <class D, class M>
HWY_INLINE M covered(lanes::Whole<D>, M m) {
  return m;
}
template <class D, class M>
HWY_INLINE M covered(lanes::FirstLanes<D> l, M m) {
  return hn::And(m, l.mask);
}

// eq (9)'s projection on the sheet's unit normal n = a × b, a and b the differences across
// the point along its row and its column: F·n/|n|² n. A lone point or row has no normal
// (|n| = 0) and keeps the full gradient.
template <class D, class V>
HWY_INLINE void project_on_normal(D d, V ax, V ay, V az, V bx, V by, V bz, V& fx, V& fy, V& fz) {
  const V nx = hn::Sub(hn::Mul(ay, bz), hn::Mul(az, by)), ny = hn::Sub(hn::Mul(az, bx), hn::Mul(ax, bz)),
          nz = hn::Sub(hn::Mul(ax, by), hn::Mul(ay, bx));
  const V nn = hn::Add(hn::Add(hn::Mul(nx, nx), hn::Mul(ny, ny)), hn::Mul(nz, nz));
  const auto has = hn::Gt(nn, hn::Zero(d));
  const V dot = hn::Div(hn::Add(hn::Add(hn::Mul(fx, nx), hn::Mul(fy, ny)), hn::Mul(fz, nz)),
                        hn::IfThenElse(has, nn, hn::Set(d, 1.0)));
  fx = hn::IfThenElse(has, hn::Mul(dot, nx), fx);
  fy = hn::IfThenElse(has, hn::Mul(dot, ny), fy);
  fz = hn::IfThenElse(has, hn::Mul(dot, nz), fz);
}

// 1/|g|² (0 where g = 0) and its square root, what friction divides by: per point, or once
// per call where ∇f is the same everywhere (the plane), with the same bits.
template <class D, class V>
HWY_INLINE void inverse_norms(D d, V gx, V gy, V gz, V& inv_g2, V& inv_g) {
  const V g2 = hn::Add(hn::Add(hn::Mul(gx, gx), hn::Mul(gy, gy)), hn::Mul(gz, gz));
  inv_g2 = hn::IfThenElseZero(hn::Gt(g2, hn::Zero(d)), hn::Div(hn::Set(d, 1.0), g2));
  inv_g = hn::Sqrt(inv_g2);
}

// Coulomb friction on points (docs/scene-format.md, Friction): N the repulsion F's part
// along g = ∇f, v* the velocity the substep would leave the point with (its total force
// so far, F included, and gravity) relative to the obstacle's surface there (v is passed
// in relative already), and the force against v*'s tangential part, the smaller
// of μ·N and m·|v*_t|/dt (what stops the slip within the substep). Adds it to F.
struct Rub {
  double mu, dt, gravity[3];
  template <class D, class V>
  HWY_INLINE void operator()(D d, V gx, V gy, V gz, V inv_g2, V inv_g, V& Fx, V& Fy, V& Fz, V tx, V ty, V tz, V vx,
                             V vy, V vz, V inv_mass) const {
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0), step = hn::Set(d, dt);
    const V along = hn::Add(hn::Add(hn::Mul(Fx, gx), hn::Mul(Fy, gy)), hn::Mul(Fz, gz));
    const V load = hn::IfThenElseZero(hn::Gt(along, zero), hn::Mul(along, inv_g));  // N
    const V wx = hn::Add(vx, hn::Mul(step, hn::Add(hn::Mul(inv_mass, tx), hn::Set(d, gravity[0]))));
    const V wy = hn::Add(vy, hn::Mul(step, hn::Add(hn::Mul(inv_mass, ty), hn::Set(d, gravity[1]))));
    const V wz = hn::Add(vz, hn::Mul(step, hn::Add(hn::Mul(inv_mass, tz), hn::Set(d, gravity[2]))));
    const V wn = hn::Mul(hn::Add(hn::Add(hn::Mul(wx, gx), hn::Mul(wy, gy)), hn::Mul(wz, gz)), inv_g2);
    const V sx = hn::Sub(wx, hn::Mul(wn, gx)), sy = hn::Sub(wy, hn::Mul(wn, gy)), sz = hn::Sub(wz, hn::Mul(wn, gz));
    // The force is k·v*_t with k = μN/|v*_t|, or m/dt where that stops the slip, i.e. where the
    // slip is slower than μN·dt/m (decided on squares): a division either way, and a square
    // root only for a vector with a lane that slides.
    const V slip2 = hn::Add(hn::Add(hn::Mul(sx, sx), hn::Mul(sy, sy)), hn::Mul(sz, sz));
    const V mu_load = hn::Mul(hn::Set(d, mu), load), per_force = hn::Mul(inv_mass, step);  // μN, dt/m
    const V held = hn::Mul(mu_load, per_force);  // the slip μN stops
    const auto stops = hn::Lt(slip2, hn::Mul(held, held)), moving = hn::Gt(slip2, zero);
    V over = per_force;
    if (!hn::AllTrue(d, hn::Or(stops, hn::Not(moving))))
      over = hn::IfThenElse(stops, over, hn::Sqrt(hn::IfThenElse(moving, slip2, one)));
    const V k = hn::IfThenElseZero(moving, hn::Div(hn::IfThenElse(stops, one, mu_load), over));
    Fx = hn::Sub(Fx, hn::Mul(k, sx));
    Fy = hn::Sub(Fy, hn::Mul(k, sy));
    Fz = hn::Sub(Fz, hn::Mul(k, sz));
  }
};

// Hunt–Crossley damping of the force F on the lanes' points (ObstacleDef::damping):
// F·(1 + max(−c·ḋ, −1)), ḋ = v·∇f/|∇f| the rate at which the point leaves the surface (v
// relative to it), c = α, or kDampingShare·(m/dt)/|F| where α|F| would pass that share of m/dt:
// the force α|F|·ḋ of the damper capped, so it stays well inside what an explicit step
// resolves. Whether a lane is capped is decided on squares (α|F|·dt/m against the share), so a
// vector with none capped, the usual case, takes no square root and no division; a pinned
// point (1/m = 0) is never capped and does not move anyway.
struct Damp {
  double alpha, dt;
  template <class D, class V>
  HWY_INLINE void operator()(D d, V gx, V gy, V gz, V inv_g, V& Fx, V& Fy, V& Fz, V vx, V vy, V vz, V inv_mass) const {
    const V rate = hn::Mul(hn::Add(hn::Add(hn::Mul(vx, gx), hn::Mul(vy, gy)), hn::Mul(vz, gz)), inv_g);
    const V size2 = hn::Add(hn::Add(hn::Mul(Fx, Fx), hn::Mul(Fy, Fy)), hn::Mul(Fz, Fz));
    const V per_force = hn::Mul(inv_mass, hn::Set(d, dt)), damper = hn::Mul(hn::Set(d, alpha), per_force);  // dt/m, α·dt/m
    const auto capped = hn::Gt(hn::Mul(hn::Mul(damper, damper), size2), hn::Set(d, kDampingShare * kDampingShare));
    V c = hn::Set(d, alpha);
    if (!hn::AllFalse(d, capped)) {
      const V cap = hn::Div(hn::Set(d, kDampingShare),
                            hn::Mul(per_force, hn::Sqrt(hn::IfThenElse(capped, size2, hn::Set(d, 1.0)))));
      c = hn::IfThenElse(capped, cap, c);
    }
    const V scale = lanes::first_max(hn::Neg(hn::Mul(c, rate)), hn::Set(d, -1.0));
    Fx = hn::Add(Fx, hn::Mul(scale, Fx));
    Fy = hn::Add(Fy, hn::Mul(scale, Fy));
    Fz = hn::Add(Fz, hn::Mul(scale, Fz));
  }
};

// The eq (9) term of one obstacle on one row, lanes at a time, in one pass: f (and ∇f) of
// the lanes' points, and only if one of them is within reach, the force, added to f where
// the point is within reach (a point beyond keeps its force bit for bit, whichever lanes
// share its vector, so every width gives the same bits). What the loops read of the
// obstacle is held by value: the stores into f could alias an Obstacle as far as the
// compiler knows, and it would load it again for every vector.
template <class Shape, class Real>
struct RowForce {
  Frame o;
  NearObstacle near;
  ForceScale scale;
  Rub friction;
  Damp damping;
  double inv_g2, inv_g;  // inverse_norms of a constant ∇f (Shape::constant_gradient)
  ConstVec3Ptr<Real> x, v;
  const Real* inv_mass;
  Vec3Ptr<Real> f;
  std::size_t row, up, down;  // first points of the row and of the rows above and below it
  std::uint32_t n;            // the row's last column
  bool project, rub, damp;    // eq (9)'s projection on the sheet normal; friction; damping

  // Points j, j + 1, ... of the row; their neighbours along it start at columns j − 1 and
  // j + 1 (the caller makes sure both exist in memory). Ends: a lane may be column 0 or n,
  // whose missing neighbour is the point itself (one-sided differences at the row's ends).
  template <bool Ends, class Lanes>
  HWY_INLINE void at(Lanes l, std::size_t j, std::size_t left, std::size_t right) const {
    const auto d = l.d;
    using V = hn::Vec<decltype(d)>;
    const std::size_t p = row + j;
    const V px = load_wide(l, x.x + p), py = load_wide(l, x.y + p), pz = load_wide(l, x.z + p);
    V fv, gx, gy, gz;
    if constexpr (Shape::constant_gradient) {  // f is local z, ∇f the local z axis
      fv = local_axis(d, o, 2, hn::Sub(px, hn::Set(d, o.center[0])), hn::Sub(py, hn::Set(d, o.center[1])),
                      hn::Sub(pz, hn::Set(d, o.center[2])));
      gx = hn::Set(d, o.rot[0][2]), gy = hn::Set(d, o.rot[1][2]), gz = hn::Set(d, o.rot[2][2]);
    } else {
      sample_lanes<Shape>(d, o, px, py, pz, fv, gx, gy, gz);
    }
    const auto within = hn::Lt(fv, hn::Set(d, scale.reach));
    if (hn::AllFalse(d, covered(l, within))) return;  // all beyond reach: f is all they cost
    const V s = scale.within(d, fv);
    V Fx = hn::Mul(s, gx), Fy = hn::Mul(s, gy), Fz = hn::Mul(s, gz);
    if (project) {
      const std::size_t pl = row + left, pr = row + right;  // (row − 1 for left = −1, wrapped)
      V lx = load_wide(l, x.x + pl), ly = load_wide(l, x.y + pl), lz = load_wide(l, x.z + pl);
      V rx = load_wide(l, x.x + pr), ry = load_wide(l, x.y + pr), rz = load_wide(l, x.z + pr);
      if constexpr (Ends) {
        const V column = hn::Iota(d, double(j));
        const auto first = hn::Eq(column, hn::Zero(d)), last = hn::Eq(column, hn::Set(d, double(n)));
        lx = hn::IfThenElse(first, px, lx), ly = hn::IfThenElse(first, py, ly), lz = hn::IfThenElse(first, pz, lz);
        rx = hn::IfThenElse(last, px, rx), ry = hn::IfThenElse(last, py, ry), rz = hn::IfThenElse(last, pz, rz);
      }
      const auto across = [&](const Real* a) HWY_ATTR {
        return hn::Sub(load_wide(l, a + up + j), load_wide(l, a + down + j));
      };
      project_on_normal(d, hn::Sub(rx, lx), hn::Sub(ry, ly), hn::Sub(rz, lz), across(x.x), across(x.y), across(x.z),
                        Fx, Fy, Fz);
    }
    const auto before_x = load_real(l, f.x + p), before_y = load_real(l, f.y + p), before_z = load_real(l, f.z + p);
    if (rub || damp) {
      // the velocity relative to the obstacle's surface here: v − (linear + angular × (x − center))
      const double* w = near.angular;
      const V rx = hn::Sub(px, hn::Set(d, near.center[0]));
      const V ry = hn::Sub(py, hn::Set(d, near.center[1]));
      const V rz = hn::Sub(pz, hn::Set(d, near.center[2]));
      const auto cross = [&](double a, V b, double e, V g) HWY_ATTR {
        return hn::Sub(hn::Mul(hn::Set(d, a), b), hn::Mul(hn::Set(d, e), g));
      };
      const V vx = hn::Sub(load_wide(l, v.x + p), hn::Add(hn::Set(d, near.linear[0]), cross(w[1], rz, w[2], ry)));
      const V vy = hn::Sub(load_wide(l, v.y + p), hn::Add(hn::Set(d, near.linear[1]), cross(w[2], rx, w[0], rz)));
      const V vz = hn::Sub(load_wide(l, v.z + p), hn::Add(hn::Set(d, near.linear[2]), cross(w[0], ry, w[1], rx)));
      V inv_g2_at, inv_g_at;
      if constexpr (Shape::constant_gradient)
        inv_g2_at = hn::Set(d, inv_g2), inv_g_at = hn::Set(d, inv_g);
      else
        inverse_norms(d, gx, gy, gz, inv_g2_at, inv_g_at);
      const V point_inv_mass = load_wide(l, inv_mass + p);
      if (damp) damping(d, gx, gy, gz, inv_g_at, Fx, Fy, Fz, vx, vy, vz, point_inv_mass);
      if (rub)
        friction(d, gx, gy, gz, inv_g2_at, inv_g_at, Fx, Fy, Fz, hn::Add(widen(l, before_x), Fx), hn::Add(widen(l, before_y), Fy),
                 hn::Add(widen(l, before_z), Fz), vx, vy, vz, point_inv_mass);
    }
    store_sum(l, within, before_x, Fx, f.x + p);
    store_sum(l, within, before_y, Fy, f.y + p);
    store_sum(l, within, before_z, Fz, f.z + p);
  }
};

// One loop per shape, chosen once per obstacle. The projection and friction are branches on
// a flag that holds for the whole call: predicted every time, and a quarter of the code a
// loop per mode took (compiled under the sanitizers, that code took GCC minutes). A row runs
// in whole vectors from column 0 to n, the vectors holding its ends fixing their one-sided
// differences lane by lane; only the sheet's first point (no point before it in memory) and
// its last (none after) go one lane at a time.
template <class Shape, class Real>
void repel(const Topology<Real>& t, const Obstacle& o, const NearObstacle& near, ConstVec3Ptr<Real> x,
           ConstVec3Ptr<Real> v, const Real* inv_mass, Vec3Ptr<Real> f, std::uint32_t row_begin, std::uint32_t row_end) {
  const std::uint32_t m = t.m, n = t.n, cols = t.cols();
  const ForceScale scale = force_scale_of(o.def, near.exponent_cap);
  const Frame frame = frame_of(o);
  const Rub friction{near.friction, near.dt, {near.gravity[0], near.gravity[1], near.gravity[2]}};
  const Damp damping{near.damping, near.dt};
  const hn::CappedTag<double, 1> one;
  const hn::ScalableTag<double> full;
  hn::Vec<decltype(one)> inv_g2, inv_g;  // used only for a constant ∇f, the local z axis
  inverse_norms(one, hn::Set(one, frame.rot[0][2]), hn::Set(one, frame.rot[1][2]), hn::Set(one, frame.rot[2][2]),
                inv_g2, inv_g);
  for (std::uint32_t i = row_begin; i < row_end; ++i) {
    const std::size_t row = std::size_t(i) * cols;
    const std::size_t up = std::size_t(std::min(i + 1, m)) * cols, down = std::size_t(i > 0 ? i - 1 : 0) * cols;
    const RowForce<Shape, Real> at{frame,
                                   near,
                                   scale,
                                   friction,
                                   damping,
                                   hn::GetLane(inv_g2),
                                   hn::GetLane(inv_g),
                                   x,
                                   v,
                                   inv_mass,
                                   f,
                                   row,
                                   up,
                                   down,
                                   n,
                                   !o.def.full_gradient,
                                   near.friction > 0,
                                   near.damping > 0};
    const std::uint32_t begin = i == 0 ? 1 : 0, end = i == m ? n : cols;
    if (i == 0) at.template at<false>(lanes::Whole<decltype(one)>{one}, 0, 0, std::min(1u, n));
    if (end > begin)
      lanes::over_lanes<double>(end - begin, [&](auto l, std::size_t e) __attribute__((always_inline)) {
        const std::size_t j = begin + e;
        if (j == 0 || j + hn::Lanes(full) > n)
          at.template at<true>(l, j, j - 1, j + 1);  // at j = 0, row + j − 1 is the row before's last point
        else
          at.template at<false>(l, j, j - 1, j + 1);
      });
    if (i == m && n >= begin) at.template at<false>(lanes::Whole<decltype(one)>{one}, n, n > 0 ? n - 1 : 0, n);
  }
}

// Σ E(f) over `count` points (obstacle_energy): a vector of them at a time, f from the force
// term's own sample_lanes; points at or beyond the reach add nothing, and a vector of them
// only costs its f. Whole vectors sum in lanes, the remainder's lanes one by one after them.
template <class Shape, class Real>
double potential_sum(const Obstacle& o, ConstVec3Ptr<Real> x, std::size_t count, double cap) {
  const Frame frame = frame_of(o);
  const Potential potential{o.def.c, -(1.0 / o.def.xi), cap, std::exp(-reach_exponent), reach_exponent * o.def.xi};
  const hn::ScalableTag<double> full;
  auto whole = hn::Zero(full);
  double rest = 0;
  lanes::over_lanes<double>(count, [&](auto l, std::size_t p) __attribute__((always_inline)) {
    const auto d = l.d;
    using V = hn::Vec<decltype(d)>;
    V f, gx, gy, gz;
    sample_lanes<Shape>(d, frame, load_wide(l, x.x + p), load_wide(l, x.y + p), load_wide(l, x.z + p), f, gx, gy, gz);
    const auto within = covered(l, hn::Lt(f, hn::Set(d, potential.reach)));
    if (hn::AllFalse(d, within)) return;
    const V e = hn::IfThenElseZero(within, potential.within(d, f));
    if constexpr (std::is_same_v<decltype(l), lanes::Whole<decltype(full)>>)
      whole = hn::Add(whole, e);
    else
      rest += hn::GetLane(hn::SumOfLanes(d, e));
  });
  return hn::GetLane(hn::SumOfLanes(full, whole)) + rest;
}

template <class Real>
double obstacle_energy_of(const Obstacle& o, ConstVec3Ptr<Real> x, std::size_t count, double cap) {
  switch (o.def.shape) {
    case ObstacleShape::Plane: return potential_sum<PlaneF>(o, x, count, cap);
    case ObstacleShape::Sphere: return potential_sum<SphereF>(o, x, count, cap);
    case ObstacleShape::Ellipsoid: return potential_sum<EllipsoidF>(o, x, count, cap);
    case ObstacleShape::Torus: return potential_sum<TorusF>(o, x, count, cap);
    case ObstacleShape::Box: return potential_sum<BoxF>(o, x, count, cap);
  }
  return 0;
}

double ObstacleEnergyF64(const Obstacle& o, ConstVec3Ptr<double> x, std::size_t count, double cap) {
  return obstacle_energy_of(o, x, count, cap);
}
double ObstacleEnergyF32(const Obstacle& o, ConstVec3Ptr<float> x, std::size_t count, double cap) {
  return obstacle_energy_of(o, x, count, cap);
}

template <class Real>
void obstacle_forces_of(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                        const Real* inv_mass, Vec3Ptr<Real> f, std::uint32_t row_begin, std::uint32_t row_end) {
  const Obstacle& o = *near.obstacle;
  switch (o.def.shape) {
    case ObstacleShape::Plane: repel<PlaneF>(t, o, near, x, v, inv_mass, f, row_begin, row_end); break;
    case ObstacleShape::Sphere: repel<SphereF>(t, o, near, x, v, inv_mass, f, row_begin, row_end); break;
    case ObstacleShape::Ellipsoid: repel<EllipsoidF>(t, o, near, x, v, inv_mass, f, row_begin, row_end); break;
    case ObstacleShape::Torus: repel<TorusF>(t, o, near, x, v, inv_mass, f, row_begin, row_end); break;
    case ObstacleShape::Box: repel<BoxF>(t, o, near, x, v, inv_mass, f, row_begin, row_end); break;
  }
}

void ObstacleForcesF64(const Topology<double>& t, const NearObstacle& near, ConstVec3Ptr<double> x,
                       ConstVec3Ptr<double> v, const double* inv_mass, Vec3Ptr<double> f, std::uint32_t row_begin,
                       std::uint32_t row_end) {
  obstacle_forces_of(t, near, x, v, inv_mass, f, row_begin, row_end);
}
void ObstacleForcesF32(const Topology<float>& t, const NearObstacle& near, ConstVec3Ptr<float> x,
                       ConstVec3Ptr<float> v, const float* inv_mass, Vec3Ptr<float> f, std::uint32_t row_begin,
                       std::uint32_t row_end) {
  obstacle_forces_of(t, near, x, v, inv_mass, f, row_begin, row_end);
}

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape {

namespace {

bool positive(double v) { return std::isfinite(v) && v > 0; }

}  // namespace

std::string_view obstacle_shape_name(ObstacleShape shape) {
  switch (shape) {
    case ObstacleShape::Plane: return "plane";
    case ObstacleShape::Sphere: return "sphere";
    case ObstacleShape::Ellipsoid: return "ellipsoid";
    case ObstacleShape::Torus: return "torus";
    case ObstacleShape::Box: return "box";
  }
  return "unknown";
}

std::string validate(const ObstacleDef& d) {
  std::ostringstream out;
  auto fail = [&](const char* field, const char* what, double got) {
    out << field << " " << what << " (got " << got << ")";
    return out.str();
  };
  if (!std::isfinite(d.center.x) || !std::isfinite(d.center.y) || !std::isfinite(d.center.z))
    return "center must be finite";
  const Quat& q = d.orientation;
  const double qn = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  if (!(std::abs(qn - 1.0) < 1e-6)) return fail("orientation", "must be a unit quaternion; its norm² is", qn);
  if (!positive(d.c)) return fail("c", "must be positive and finite", d.c);
  if (!positive(d.xi)) return fail("xi", "must be positive and finite", d.xi);
  if (!positive(d.max_exponent)) return fail("max_exponent", "must be positive and finite", d.max_exponent);
  if (!(std::isfinite(d.friction) && d.friction >= 0)) return fail("friction", "must be non-negative and finite", d.friction);
  if (!(std::isfinite(d.damping) && d.damping >= 0)) return fail("damping", "must be non-negative and finite", d.damping);
  if (d.motion)
    if (std::string problem = validate(*d.motion); !problem.empty()) return "motion." + problem;
  switch (d.shape) {
    case ObstacleShape::Plane: break;
    case ObstacleShape::Sphere:
      if (!positive(d.size.x)) return fail("size.x (radius)", "must be positive and finite", d.size.x);
      break;
    case ObstacleShape::Torus:
      if (!positive(d.size.x)) return fail("size.x (major radius)", "must be positive and finite", d.size.x);
      if (!positive(d.size.y)) return fail("size.y (minor radius)", "must be positive and finite", d.size.y);
      break;
    case ObstacleShape::Ellipsoid:
    case ObstacleShape::Box:
      if (!positive(d.size.x)) return fail("size.x", "must be positive and finite", d.size.x);
      if (!positive(d.size.y)) return fail("size.y", "must be positive and finite", d.size.y);
      if (!positive(d.size.z)) return fail("size.z", "must be positive and finite", d.size.z);
      break;
  }
  return {};
}

namespace detail {

// The static target's copy of the per-target code, for what runs once.
namespace here = HWY_NAMESPACE;

HWY_EXPORT(ObstacleForcesF64);
HWY_EXPORT(ObstacleForcesF32);
HWY_EXPORT(ObstacleEnergyF64);
HWY_EXPORT(ObstacleEnergyF32);

Obstacle make_obstacle(const ObstacleDef& def) {
  Obstacle o;
  o.def = def;
  o.center[0] = def.center.x;
  o.center[1] = def.center.y;
  o.center[2] = def.center.z;
  const Vec3 axes[3] = {rotate(def.orientation, {1, 0, 0}), rotate(def.orientation, {0, 1, 0}),
                        rotate(def.orientation, {0, 0, 1})};
  for (int l = 0; l < 3; ++l) {
    o.rot[0][l] = axes[l].x;
    o.rot[1][l] = axes[l].y;
    o.rot[2][l] = axes[l].z;
  }
  const Vec3& s = def.size;
  double half[3] = {0, 0, 0};
  double stretch = 1;  // how much farther than f a point can be: only the ellipsoid's f is not a distance
  switch (def.shape) {
    case ObstacleShape::Plane: o.bounded = false; break;
    case ObstacleShape::Sphere: half[0] = half[1] = half[2] = s.x; break;
    case ObstacleShape::Ellipsoid:
      half[0] = s.x, half[1] = s.y, half[2] = s.z;
      stretch = std::max({s.x, s.y, s.z}) / std::min({s.x, s.y, s.z});
      break;
    case ObstacleShape::Torus: half[0] = half[1] = s.x + s.y, half[2] = s.y; break;
    case ObstacleShape::Box: half[0] = s.x, half[1] = s.y, half[2] = s.z; break;
  }
  o.reach_distance = reach_exponent * def.xi * stretch;
  for (int k = 0; k < 3; ++k) {
    double ext = 0;
    for (int l = 0; l < 3; ++l) ext += std::abs(o.rot[k][l]) * half[l];
    o.reach.lo[k] = o.center[k] - ext - o.reach_distance;
    o.reach.hi[k] = o.center[k] + ext + o.reach_distance;
  }
  return o;
}

ImplicitSample implicit_at(const Obstacle& o, const double p[3]) {
  switch (o.def.shape) {
    case ObstacleShape::Plane: return here::sample<here::PlaneF>(o, p);
    case ObstacleShape::Sphere: return here::sample<here::SphereF>(o, p);
    case ObstacleShape::Ellipsoid: return here::sample<here::EllipsoidF>(o, p);
    case ObstacleShape::Torus: return here::sample<here::TorusF>(o, p);
    case ObstacleShape::Box: return here::sample<here::BoxF>(o, p);
  }
  return {};
}

double stiffness_exponent_cap(double strength, double xi, double lightest_mass, double dt) {
  return std::log(lightest_mass * xi * xi / (strength * dt * dt));
}

double exponent_cap(const ObstacleDef& d, double lightest_mass, double dt) {
  return std::min(d.max_exponent, stiffness_exponent_cap(d.c, d.xi, lightest_mass, dt));
}

double potential_energy(const ObstacleDef& d, double f, double cap) {
  // E(f) = ∫_f^R of the force scale below: c·(e^e − t) − c·t·(r + e), e = −f/ξ, t = e^−r,
  // continued linearly in e past the cap; zero at and beyond R = r·ξ.
  if (!(f < reach_exponent * d.xi)) return 0.0;
  const double t = std::exp(-reach_exponent), e = -f / d.xi;
  if (e <= cap) return d.c * (std::exp(e) - t) - d.c * t * (reach_exponent + e);
  return d.c * (std::exp(cap) - t) * (1.0 + (e - cap)) - d.c * t * (reach_exponent + cap);
}

double potential_force_scale(const ObstacleDef& d, double f, double cap) { return here::force_scale_of(d, cap)(f); }

double vector_exp(double x) { return simd::HWY_NAMESPACE::exp_one(x); }

bool may_touch(const Obstacle& o, const Aabb& box) {
  if (o.bounded) return overlaps(o.reach, box);
  // The plane's f is linear, so its minimum over the box is at one of the eight corners.
  double lowest = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    const double p[3] = {c & 1 ? box.hi[0] : box.lo[0], c & 2 ? box.hi[1] : box.lo[1], c & 4 ? box.hi[2] : box.lo[2]};
    lowest = std::min(lowest, here::sample<here::PlaneF>(o, p).f);
  }
  return lowest < o.reach_distance;
}

// One dispatch per call (a sheet's rows, a row block's, or the run of rows the sweep is
// about to move): the rows, the shapes' f and ∇f, the force scale, the projection and
// friction run on the widest instruction set the CPU has.
template <class Real>
void obstacle_forces(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f, std::uint32_t row_begin, std::uint32_t row_end) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(ObstacleForcesF64)(t, near, x, v, inv_mass, f, row_begin, row_end);
  else
    HWY_DYNAMIC_DISPATCH(ObstacleForcesF32)(t, near, x, v, inv_mass, f, row_begin, row_end);
}

template <class Real>
void obstacle_forces(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f) {
  obstacle_forces(t, near, x, v, inv_mass, f, 0, t.rows());
}

// One dispatch per sheet and obstacle, as the force: the guard runs this after every step()
// call, and one std::exp per point (potential_energy's way) took three times a substep of
// sheets resting on a floor.
template <class Real>
double obstacle_energy(const Sheet<Real>& s, const Obstacle& o, double cap) {
  const ConstVec3Ptr<Real> x{s.position.x.data(), s.position.y.data(), s.position.z.data()};
  if constexpr (std::is_same_v<Real, double>)
    return HWY_DYNAMIC_DISPATCH(ObstacleEnergyF64)(o, x, s.size(), cap);
  else
    return HWY_DYNAMIC_DISPATCH(ObstacleEnergyF32)(o, x, s.size(), cap);
}

template void obstacle_forces<double>(const Topology<double>&, const NearObstacle&, ConstVec3Ptr<double>,
                                      ConstVec3Ptr<double>, const double*, Vec3Ptr<double>);
template void obstacle_forces<float>(const Topology<float>&, const NearObstacle&, ConstVec3Ptr<float>,
                                     ConstVec3Ptr<float>, const float*, Vec3Ptr<float>);
template void obstacle_forces<double>(const Topology<double>&, const NearObstacle&, ConstVec3Ptr<double>,
                                      ConstVec3Ptr<double>, const double*, Vec3Ptr<double>, std::uint32_t,
                                      std::uint32_t);
template void obstacle_forces<float>(const Topology<float>&, const NearObstacle&, ConstVec3Ptr<float>,
                                     ConstVec3Ptr<float>, const float*, Vec3Ptr<float>, std::uint32_t, std::uint32_t);
template double obstacle_energy<double>(const Sheet<double>&, const Obstacle&, double);
template double obstacle_energy<float>(const Sheet<float>&, const Obstacle&, double);

}  // namespace detail
}  // namespace drape
#endif  // HWY_ONCE
