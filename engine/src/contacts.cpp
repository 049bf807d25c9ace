// The narrow phase (contacts.h): sheet boxes, the search for each point's nearest triangle
// of the other sheet (or of its own, away from the point), the repulsion and friction it
// gives, and the lists and kept contact sets that let later substeps skip the search.
//
// Highway's foreach_target compiles the per-point part — the search through strip and cell
// boxes (box_gaps, explicit vectors), the walk of a kept contact set, the triangle tests
// and the force — once per instruction set (simd/targets.h), and the pair's code dispatches
// to the widest the CPU has once per direction of a pair. Contraction into FMA is off here
// (engine/CMakeLists.txt), and the force's exp is the obstacle term's polynomial
// (simd/exp-inl.h), one value or a vector of them at a time, so every target gives the same
// bits. The rest (boxes, whether kept lists still hold, the pair's bookkeeping) is compiled
// once.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "contacts.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "contacts.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "simd/exp-inl.h"
#include "simd/kernels.h"

// What every target shares, compiled once.
#ifndef DRAPE_CONTACTS_SHARED_
#define DRAPE_CONTACTS_SHARED_
namespace drape::detail {
namespace {

// max(a, 0) without a comparison, so a loop of it vectorises even where GCC will not turn
// a floating-point comparison into a select (AVX2 with -ftrapping-math): exact, as a + |a|
// is 2a or 0 and halving is exact, and a NaN stays a NaN.
template <class Real>
Real positive_part(Real a) { return (a + std::abs(a)) * Real(0.5); }

constexpr std::uint32_t kNoCell = ~std::uint32_t(0);

// The pair's travel (ContactParams::travel) below which an entry beyond R, at least √dist2
// from every triangle of the other sheet, skips its walk: 0.99 of its slack from now
// (KeptContacts::until).
inline double skip_until(double travel, double dist2, double range) {
  return travel + 0.99 * (std::sqrt(dist2) - range);
}

// The energy whose −d/dd is the repulsion at distance d (repel, before damping and friction):
// E = c·(eˣ − t) − c·t·(x + (R − h)/ξ) with x = (h − d)/ξ and t the tail, zero at d = R;
// past the exponent cap it goes on linearly, with the capped force's slope.
template <class Real>
double contact_potential(double dist, const ContactParams<Real>& prm) {
  const double c = prm.strength, t = prm.tail, xi = prm.xi, h = prm.thickness;
  const double x = (h - dist) / xi, capped = std::min(x, double(prm.exponent_cap)), e = std::exp(capped);
  return c * (e - t) - c * t * (capped + (double(prm.range) - h) / xi) + c * (e - t) * (x - capped);
}

}  // namespace
}  // namespace drape::detail
#endif  // DRAPE_CONTACTS_SHARED_

HWY_BEFORE_NAMESPACE();
namespace drape::detail {
namespace HWY_NAMESPACE {

namespace hn = hwy::HWY_NAMESPACE;
namespace lanes = simd::HWY_NAMESPACE;  // exp_lanes, exp_one

namespace {

template <class Real>
struct V3 {
  Real x, y, z;
};
template <class Real>
V3<Real> sub(V3<Real> a, V3<Real> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class Real>
Real dot(V3<Real> a, V3<Real> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// positive_part of each lane (a function, not a lambda: clang gives a lambda in target code
// no target of its own).
template <class V>
HWY_INLINE V positive_lanes(V a, V half) {
  return hn::Mul(hn::Add(a, hn::Abs(a)), half);
}

// gap2[t] = squared distance from x to box t, for t < count, a vector of boxes at a time in
// d's lanes and the tail one box at a time by the same operations, so every box gets the
// same bits on every target. Along each axis the gap is max(lo − x, 0) + max(x − hi, 0), as
// lo ≤ hi makes at least one of the two zero; max(a, 0) is positive_part's (a + |a|)/2,
// which keeps a NaN a NaN (x86's max would turn it into 0 on some targets and not others).
template <class D, class Real = hn::TFromD<D>>
HWY_INLINE void box_gaps(D d, V3<Real> x, const Real* const lo[3], const Real* const hi[3], std::uint32_t count,
                         Real* HWY_RESTRICT gap2) {
  const std::uint32_t N = static_cast<std::uint32_t>(hn::Lanes(d));
  const auto half = hn::Set(d, Real(0.5));
  const auto px = hn::Set(d, x.x), py = hn::Set(d, x.y), pz = hn::Set(d, x.z);
  std::uint32_t t = 0;
  for (; t + N <= count; t += N) {
    const auto ex = hn::Add(positive_lanes(hn::Sub(hn::LoadU(d, lo[0] + t), px), half),
                            positive_lanes(hn::Sub(px, hn::LoadU(d, hi[0] + t)), half));
    const auto ey = hn::Add(positive_lanes(hn::Sub(hn::LoadU(d, lo[1] + t), py), half),
                            positive_lanes(hn::Sub(py, hn::LoadU(d, hi[1] + t)), half));
    const auto ez = hn::Add(positive_lanes(hn::Sub(hn::LoadU(d, lo[2] + t), pz), half),
                            positive_lanes(hn::Sub(pz, hn::LoadU(d, hi[2] + t)), half));
    hn::StoreU(hn::Add(hn::Add(hn::Mul(ex, ex), hn::Mul(ey, ey)), hn::Mul(ez, ez)), d, gap2 + t);
  }
  for (; t < count; ++t) {
    const Real ex = positive_part(lo[0][t] - x.x) + positive_part(x.x - hi[0][t]);
    const Real ey = positive_part(lo[1][t] - x.y) + positive_part(x.y - hi[1][t]);
    const Real ez = positive_part(lo[2][t] - x.z) + positive_part(x.z - hi[2][t]);
    gap2[t] = ex * ex + ey * ey + ez * ez;
  }
}

template <class Real>
V3<Real> at(const Sheet<Real>& s, std::uint32_t p) {
  return {s.position.x[p], s.position.y[p], s.position.z[p]};
}

// Barycentric weights (of a, b, c) of the point of triangle abc closest to p, found by
// the Voronoi region of p: a vertex, an edge or the face.
template <class Real>
[[gnu::always_inline]] inline V3<Real> closest_weights(V3<Real> p, V3<Real> a, V3<Real> b, V3<Real> c) {
  const V3<Real> ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const Real d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const V3<Real> bp = sub(p, b);
  const Real d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const Real vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const Real t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const V3<Real> cp = sub(p, c);
  const Real d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const Real vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const Real t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const Real va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const Real t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const Real sum = va + vb + vc;
  if (!(sum > 0)) return {1, 0, 0};  // degenerate (collinear) triangle: its first vertex
  const Real v = vb / sum, w = vc / sum;
  return {1 - v - w, v, w};
}

// The nearest triangle found so far for one point; `key` orders triangles at the same
// distance: 2·(the cell's first corner) + (0 or 1, the cell's triangle).
template <class Real>
struct Nearest {
  Real dist2;
  std::uint32_t key;
  std::uint32_t tri[3];
  V3<Real> v[3], w;
};

template <class Real>
[[gnu::always_inline]] inline void consider(V3<Real> p, std::uint32_t key, std::uint32_t i0, std::uint32_t i1,
                                            std::uint32_t i2, V3<Real> a, V3<Real> b, V3<Real> c,
                                            Nearest<Real>& best) {
  const V3<Real> w = closest_weights(p, a, b, c);
  const V3<Real> q{w.x * a.x + w.y * b.x + w.z * c.x, w.x * a.y + w.y * b.y + w.z * c.y,
                   w.x * a.z + w.y * b.z + w.z * c.z};
  const V3<Real> d = sub(p, q);
  const Real dist2 = dot(d, d);
  // the nearest, and of equally near ones the lowest key: the same whatever the order
  if (dist2 < best.dist2 || (dist2 == best.dist2 && key < best.key))
    best = {dist2, key, {i0, i1, i2}, {a, b, c}, w};
}

// The point against the nearest triangle: pushes the force on the point to `on_q` and the
// three opposite shares to `on_s`.
template <class Real>
V3<Real> velocity(const Sheet<Real>& s, std::uint32_t p) {
  return {s.velocity.x[p], s.velocity.y[p], s.velocity.z[p]};
}

// Damping and Coulomb friction of a contact whose two sides move apart at `rel` (the
// velocity of one side's contact point less the other's) with inverse mass `inv_mass` along
// the contact (Σ w²/m over the weighted points of both sides), and whose repulsion is
// `force` along the unit normal d (contacts.h): returns the force to add on the first side.
// Without damping the friction alone, through the same operations.
template <class Real>
V3<Real> dissipate_motion(V3<Real> rel, Real inv_mass, V3<Real> d, Real force, const ContactParams<Real>& prm) {
  if (!(inv_mass > 0)) return {0, 0, 0};
  const Real normal = dot(rel, d);  // ḋ: > 0 parting, < 0 approaching
  V3<Real> damped{0, 0, 0};
  if (prm.damping > 0) {
    // α·f, capped at the share of m/dt; whether it is, decided without a division
    const Real b = prm.damping * force * inv_mass * prm.dt > Real(kDampingShare) ? Real(kDampingShare) / (inv_mass * prm.dt)
                                                                                 : prm.damping * force;
    const Real change = std::max(-b * normal, -force);
    damped = {change * d.x, change * d.y, change * d.z};
    force += change;
  }
  if (!(prm.friction > 0)) return damped;
  const V3<Real> slip{rel.x - normal * d.x, rel.y - normal * d.y, rel.z - normal * d.z};
  const Real slip2 = dot(slip, slip);
  if (!(slip2 > 0)) return damped;
  // μ·N/|slip|, or m/dt where that stops the slip within the substep (a slip slower than
  // μ·N·dt/m, decided on squares): one division, and a square root only while it slides
  const Real held = prm.friction * force * inv_mass * prm.dt;
  const Real k = slip2 < held * held ? Real(1) / (inv_mass * prm.dt) : prm.friction * force / std::sqrt(slip2);
  if (!(prm.damping > 0)) return {-k * slip.x, -k * slip.y, -k * slip.z};
  return {damped.x - k * slip.x, damped.y - k * slip.y, damped.z - k * slip.z};
}

// dissipate_motion for point q of sheet qs against the triangle `best` of sheet ss.
template <class Real>
V3<Real> dissipate(const Sheet<Real>& qs, std::uint32_t q, const Sheet<Real>& ss, const Nearest<Real>& best, V3<Real> d,
                   Real force, const ContactParams<Real>& prm) {
  const Real w[3] = {best.w.x, best.w.y, best.w.z};
  V3<Real> rel = velocity(qs, q);
  Real inv_mass = qs.inv_mass[q];
  for (int k = 0; k < 3; ++k) {
    const V3<Real> u = velocity(ss, best.tri[k]);
    rel = {rel.x - w[k] * u.x, rel.y - w[k] * u.y, rel.z - w[k] * u.z};
    inv_mass += w[k] * w[k] * ss.inv_mass[best.tri[k]];
  }
  return dissipate_motion(rel, inv_mass, d, force, prm);
}

// The exponent (h − d)/ξ of the force at distance `dist`, capped (contacts.h): min(e, +∞)
// is e, so an uncapped pair gets the same bits.
template <class Real>
Real exponent_at(Real dist, const ContactParams<Real>& prm) {
  return std::min((prm.thickness - dist) / prm.xi, prm.exponent_cap);
}

// e^x of the force through the polynomial of simd/exp-inl.h in double (a float's exponent
// promoted, its e^x rounded back), as the force in lanes (force_lanes) takes it: within
// 10⁻¹⁵ of std::exp, and the same bits on every target and in every lane.
template <class Real>
Real force_exp(Real x) { return static_cast<Real>(lanes::exp_one(double(x))); }

// The force f along the unit direction d on point q, plus the dissipative force t (damping and
// friction, dissipate's or dissipate_lanes'), pushed to `on_q`, and −w_k times it to corner k
// of the triangle `best` for each nonzero weight w_k, in that order (best's corners'
// positions are not read).
template <class Real>
void push_repulsion(std::uint32_t q, const Nearest<Real>& best, V3<Real> d, Real f, V3<Real> t,
                    const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_s) {
  V3<Real> F{f * d.x, f * d.y, f * d.z};
  if (prm.friction > 0 || prm.damping > 0) F = {F.x + t.x, F.y + t.y, F.z + t.z};
  on_q.push(q, F.x, F.y, F.z);
  const Real wt[3] = {best.w.x, best.w.y, best.w.z};
  for (int k = 0; k < 3; ++k)
    if (wt[k] != 0) on_s.push(best.tri[k], -wt[k] * F.x, -wt[k] * F.y, -wt[k] * F.z);
}

// The same with its damping and friction computed here (dissipate).
template <class Real>
void push_repulsion(const Sheet<Real>& qs, std::uint32_t q, const Sheet<Real>& ss, const Nearest<Real>& best,
                    V3<Real> d, Real f, const ContactParams<Real>& prm, ContactForces<Real>& on_q,
                    ContactForces<Real>& on_s) {
  const V3<Real> t = prm.friction > 0 || prm.damping > 0 ? dissipate(qs, q, ss, best, d, f, prm) : V3<Real>{0, 0, 0};
  push_repulsion(q, best, d, f, t, prm, on_q, on_s);
}

template <class Real>
void repel(const Sheet<Real>& qs, std::uint32_t q, V3<Real> p, const Sheet<Real>& ss, const Nearest<Real>& best,
           const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_s) {
  const V3<Real>* v = best.v;
  const V3<Real> c{best.w.x * v[0].x + best.w.y * v[1].x + best.w.z * v[2].x,
                   best.w.x * v[0].y + best.w.y * v[1].y + best.w.z * v[2].y,
                   best.w.x * v[0].z + best.w.y * v[1].z + best.w.z * v[2].z};
  V3<Real> d = sub(p, c);
  const Real dist = std::sqrt(best.dist2);
  if (dist > 0) {
    d = {d.x / dist, d.y / dist, d.z / dist};
  } else {  // p on the triangle: push along its normal
    const V3<Real> e1 = sub(v[1], v[0]), e2 = sub(v[2], v[0]);
    V3<Real> nrm{e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x};
    const Real len = std::sqrt(dot(nrm, nrm));
    if (!(len > 0)) return;
    d = {nrm.x / len, nrm.y / len, nrm.z / len};
  }
  // −dE/dd, shifted to reach 0 at the cut-off; d ≥ 0 bounds it by (c/ξ)·exp(h/ξ), and the
  // exponent cap by what the substep resolves
  const Real f = prm.strength / prm.xi * (force_exp(exponent_at(dist, prm)) - prm.tail);
  push_repulsion(qs, q, ss, best, d, f, prm, on_q, on_s);
}


// --- Rims: edges against edges (contacts.h, pair_contacts with ContactParams::rims) ---

// Two edges p0p1 and q0q1 that pass each other at an angle, their nearest points inside
// both: p0 + s·(p1 − p0) and q0 + t·(q1 − q0), 0.01 < s, t < 0.99, diff the first less the
// second (the lines' common perpendicular). False where the nearest points lie at or near an
// end of either (a point near the other sheet, which the points' contacts hold; edges that
// meet in line with a grid, such as stacked sheets' rims, rounded off their ends) or where the
// edges lie within about 6° of parallel (edges lying along each other cannot hook; their
// nearest points are ill-conditioned).
template <class Real>
struct EdgePair {
  Real s, t, dist2;
  V3<Real> diff;
};

template <class Real>
bool edges_passing(V3<Real> p0, V3<Real> p1, V3<Real> q0, V3<Real> q1, EdgePair<Real>& out) {
  const V3<Real> dp = sub(p1, p0), dq = sub(q1, q0), r = sub(p0, q0);
  const Real a = dot(dp, dp), e = dot(dq, dq), b = dot(dp, dq);
  const Real denom = a * e - b * b;  // a·e·sin² of the angle between them
  if (!(denom > Real(0.01) * a * e)) return false;
  const Real c = dot(dp, r), f = dot(dq, r);
  // s and t times denom (> 0) against their bounds, before any division: most candidates
  // fail here
  constexpr Real end = Real(0.01);  // of an edge's length: nearer its end the end's point holds it
  const Real sd = b * f - c * e, td = a * f - b * c, lo = end * denom, hi = (1 - end) * denom;
  if (!(sd > lo && sd < hi && td > lo && td < hi)) return false;
  const Real s = sd / denom, t = td / denom;
  out.s = s;
  out.t = t;
  out.diff = {r.x + s * dp.x - t * dq.x, r.y + s * dp.y - t * dq.y, r.z + s * dp.z - t * dq.z};
  out.dist2 = dot(out.diff, out.diff);
  return true;
}

// The force F between edge uv of q and edge pw of s, at its closest points' weights s and t
// along them, shared by each edge's ends: + on uv's, − on pw's.
template <class Real>
void push_edges(std::uint32_t u, std::uint32_t v, std::uint32_t p, std::uint32_t w, Real s, Real t, V3<Real> F,
                ContactForces<Real>& on_q, ContactForces<Real>& on_s) {
  const Real wq[2] = {1 - s, s}, ws[2] = {1 - t, t};
  const std::uint32_t iq[2] = {u, v}, is[2] = {p, w};
  for (int k = 0; k < 2; ++k)
    if (wq[k] != 0) on_q.push(iq[k], wq[k] * F.x, wq[k] * F.y, wq[k] * F.z);
  for (int k = 0; k < 2; ++k)
    if (ws[k] != 0) on_s.push(is[k], -ws[k] * F.x, -ws[k] * F.y, -ws[k] * F.z);
}

// Edge uv of q and edge pw of s at their closest points c (within R): the repulsion of the
// points' law at that distance along their difference, with damping and friction of the
// edges' motion there, shared by each edge's ends in the weights of the closest points.
template <class Real>
void repel_edges(const Sheet<Real>& qs, std::uint32_t u, std::uint32_t v, const Sheet<Real>& ss, std::uint32_t p,
                 std::uint32_t w, const EdgePair<Real>& c, const ContactParams<Real>& prm, ContactForces<Real>& on_q,
                 ContactForces<Real>& on_s) {
  const Real dist = std::sqrt(c.dist2);
  if (!(dist > 0)) return;  // the edges cross: no direction (sheet_crossings finds it)
  const V3<Real> d{c.diff.x / dist, c.diff.y / dist, c.diff.z / dist};
  const Real f = prm.strength / prm.xi * (force_exp(exponent_at(dist, prm)) - prm.tail);
  V3<Real> F{f * d.x, f * d.y, f * d.z};
  const Real wq[2] = {1 - c.s, c.s}, ws[2] = {1 - c.t, c.t};
  const std::uint32_t iq[2] = {u, v}, is[2] = {p, w};
  if (prm.friction > 0 || prm.damping > 0) {
    V3<Real> rel{0, 0, 0};
    Real inv_mass = 0;
    for (int k = 0; k < 2; ++k) {
      const V3<Real> a = velocity(qs, iq[k]), b = velocity(ss, is[k]);
      rel = {rel.x + wq[k] * a.x - ws[k] * b.x, rel.y + wq[k] * a.y - ws[k] * b.y, rel.z + wq[k] * a.z - ws[k] * b.z};
      inv_mass += wq[k] * wq[k] * qs.inv_mass[iq[k]] + ws[k] * ws[k] * ss.inv_mass[is[k]];
    }
    const V3<Real> t = dissipate_motion(rel, inv_mass, d, f, prm);
    F = {F.x + t.x, F.y + t.y, F.z + t.z};
  }
  push_edges(u, v, p, w, c.s, c.t, F, on_q, on_s);
}

// The squared distance between edges p0p1 and q0q1 (their nearest points, ends included;
// Ericson, Real-Time Collision Detection, 5.1.9): no two points of the edges are nearer, so
// it bounds edges_passing's distance from below.
template <class Real>
Real edge_distance2(V3<Real> p0, V3<Real> p1, V3<Real> q0, V3<Real> q1) {
  const V3<Real> dp = sub(p1, p0), dq = sub(q1, q0), r = sub(p0, q0);
  const Real a = dot(dp, dp), e = dot(dq, dq), b = dot(dp, dq), c = dot(dp, r), f = dot(dq, r);
  auto unit = [](Real x) { return std::min(std::max(x, Real(0)), Real(1)); };
  const Real denom = a * e - b * b;
  Real s = denom > 0 ? unit((b * f - c * e) / denom) : Real(0);
  Real t = e > 0 ? (b * s + f) / e : Real(0);
  if (t < 0) {
    t = 0;
    s = a > 0 ? unit(-c / a) : Real(0);
  } else if (t > 1) {
    t = 1;
    s = a > 0 ? unit((b - c) / a) : Real(0);
  }
  const V3<Real> d{r.x + s * dp.x - t * dq.x, r.y + s * dp.y - t * dq.y, r.z + s * dp.z - t * dq.z};
  return dot(d, d);
}

// Calls f(u, v, p, w) for each edge uv of q's rim (its first and last point rows and
// columns) and each edge pw of s owned by a cell whose box is within `reach` of the edge's
// box: q's border patches against s's patches, then each rim edge against the cells of s
// near it, and of each such cell the edges it owns (its top, left and diagonal; the bottom
// one in the last row, the right one in the last column), so each edge of s comes once.
// `skip_rim_of_s`: leave out the edges of s's rim (the other direction met them). In the
// order of q's rim edges (first row, last row, first column, last column), then of s's
// patches, cells and edges.
template <class Real, class F>
void rim_edge_pairs(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s, const SheetBoxes<Real>& bs,
                    double reach, bool skip_rim_of_s, std::vector<std::uint32_t>& near, F&& f) {
  const std::uint32_t qm = q.topology->m, qn = q.topology->n, qcols = q.topology->cols();
  const std::uint32_t sm = s.topology->m, sn = s.topology->n, cols = s.topology->cols();
  if (qm == 0 || qn == 0 || sm == 0 || sn == 0) return;  // a line of points has no rim of a surface
  reach = reach * (1 + 1e-6) + 1e-12;                     // widened against rounding
  const std::uint32_t patches = bs.patch_rows * bs.patch_cols;
  auto edge_pairs = [&](std::uint32_t u, std::uint32_t v) {
    const V3<Real> x0 = at(q, u), x1 = at(q, v);
    const Aabb edge = Aabb::segment({double(x0.x), double(x0.y), double(x0.z)}, {double(x1.x), double(x1.y), double(x1.z)})
                          .inflated(reach);
    for (std::uint32_t t : near) {
      if (!overlaps(edge, box_at(bs.patch_lo, bs.patch_hi, t))) continue;
      cells_meeting(bs, t, edge, [&](std::uint32_t c) {
        const std::uint32_t i = c / cols, j = c % cols;
        if (!skip_rim_of_s || i > 0) f(u, v, c, c + 1);
        if (!skip_rim_of_s || j > 0) f(u, v, c, c + cols);
        f(u, v, c, c + cols + 1);
        if (i + 1 == sm && !skip_rim_of_s) f(u, v, c + cols, c + cols + 1);
        if (j + 1 == sn && !skip_rim_of_s) f(u, v, c + 1, c + cols + 1);
      });
    }
  };
  // the patches of s near border patch (bi, bj) of q
  auto near_patch = [&](std::uint32_t bi, std::uint32_t bj) {
    const Aabb block = box_at(bq.patch_lo, bq.patch_hi, std::size_t(bi) * bq.patch_cols + bj).inflated(reach);
    near.clear();
    for (std::uint32_t t = 0; t < patches; ++t)
      if (overlaps(block, box_at(bs.patch_lo, bs.patch_hi, t))) near.push_back(t);
  };
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  for (std::uint32_t row : {0u, qm}) {  // the first and last rows' edges, patch by patch
    const std::uint32_t bi = row == 0 ? 0 : bq.patch_rows - 1;
    for (std::uint32_t bj = 0; bj < bq.patch_cols; ++bj) {
      near_patch(bi, bj);
      if (near.empty()) continue;
      for (std::uint32_t j = bj * P; j < std::min(bj * P + P, qn); ++j)
        edge_pairs(row * qcols + j, row * qcols + j + 1);
    }
  }
  for (std::uint32_t col : {0u, qn}) {  // the first and last columns' edges
    const std::uint32_t bj = col == 0 ? 0 : bq.patch_cols - 1;
    for (std::uint32_t bi = 0; bi < bq.patch_rows; ++bi) {
      near_patch(bi, bj);
      if (near.empty()) continue;
      for (std::uint32_t i = bi * P; i < std::min(bi * P + P, qm); ++i)
        edge_pairs(i * qcols + col, (i + 1) * qcols + col);
    }
  }
}

// The rim pairs of q and s (one direction) within `reach` of each other now, into `out`.
template <class Real>
void rim_candidates(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s, const SheetBoxes<Real>& bs,
                    Real reach, bool skip_rim_of_s, std::vector<std::uint32_t>& near,
                    std::vector<std::array<std::uint32_t, 4>>& out) {
  out.clear();
  const Real reach2 = reach * reach;
  rim_edge_pairs(q, bq, s, bs, double(reach), skip_rim_of_s, near,
                 [&](std::uint32_t u, std::uint32_t v, std::uint32_t p, std::uint32_t w) {
                   if (edge_distance2(at(q, u), at(q, v), at(s, p), at(s, w)) < reach2) out.push_back({u, v, p, w});
                 });
}

template <class Real>
void rim_side(const Sheet<Real>& q, const Sheet<Real>& o, const std::vector<std::array<std::uint32_t, 4>>& candidates,
              const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_o);

// A pair's rims this substep (contacts.h, PairContacts::rims_ab): its candidates (edge pairs
// within R + R/2) made again when due (both sheets' boxes then current), then each candidate
// pair passing within R repelled, a's rim edges first.
template <class Real>
void rims_of_pair(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b, const SheetBoxes<Real>& bb,
                  const ContactParams<Real>& prm, PairContacts<Real>& work, ContactScratch<Real>& sc) {
  const Real skin = prm.range / 2;
  if (rims_due(work, a, b, prm.travel)) {
    rim_candidates(a, ba, b, bb, prm.range + skin, false, sc.patches, work.rims_ab);
    rim_candidates(b, bb, a, ba, prm.range + skin, true, sc.patches, work.rims_ba);
    work.rims_until =
        std::isfinite(prm.travel) ? prm.travel + 0.99 * double(skin) : -std::numeric_limits<double>::infinity();
    work.rims_topology_a = a.topology.get();
    work.rims_topology_b = b.topology.get();
    ++work.rim_searches;
  }
  rim_side(a, b, work.rims_ab, prm, work.on_a, work.on_b);
  rim_side(b, a, work.rims_ba, prm, work.on_b, work.on_a);
}

// The potential of the same edge pairs (contact_potential at their distance), summed in
// their order, from a search now.
template <class Real>
double rims_energy(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b, const SheetBoxes<Real>& bb,
                   const ContactParams<Real>& prm) {
  double energy = 0;
  std::vector<std::uint32_t> near;
  const Real R2 = prm.range * prm.range;
  for (int k = 0; k < 2; ++k) {
    const Sheet<Real>& q = k == 0 ? a : b;
    const Sheet<Real>& s = k == 0 ? b : a;
    rim_edge_pairs(q, k == 0 ? ba : bb, s, k == 0 ? bb : ba, double(prm.range), k == 1, near,
                   [&](std::uint32_t u, std::uint32_t v, std::uint32_t p, std::uint32_t w) {
                     EdgePair<Real> c;
                     if (edges_passing(at(q, u), at(q, v), at(s, p), at(s, w), c) && c.dist2 < R2)
                       energy += contact_potential(std::sqrt(double(c.dist2)), prm);
                   });
  }
  return energy;
}

// The cell of s at first corner p00 (its two triangles) against the point x.
template <class Real>
[[gnu::always_inline]] inline void test_cell(const Sheet<Real>& s, std::uint32_t cols, V3<Real> x, std::uint32_t p00,
                                             Nearest<Real>& best) {
  const std::uint32_t p01 = p00 + 1, p10 = p00 + cols, p11 = p10 + 1;
  const V3<Real> x00 = at(s, p00), x01 = at(s, p01), x10 = at(s, p10), x11 = at(s, p11);
  consider(x, 2 * p00, p00, p01, p11, x00, x01, x11, best);
  consider(x, 2 * p00 + 1, p00, p11, p10, x00, x11, x10, best);
}

// The index of the first of the nearest boxes among near[0, found), found > 0.
template <class Real>
std::uint32_t nearest_box(const typename ContactScratch<Real>::Near* near, std::uint32_t found) {
  std::uint32_t nearest = 0;
  for (std::uint32_t e = 1; e < found; ++e)
    if (near[e].gap2 < near[nearest].gap2) nearest = e;
  return nearest;
}

// Point p of q (at x) against `near`, its cells of s whose boxes are within R (and any
// farther ones: their boxes are no nearer than the bound below, so they are never tested),
// with their boxes' squared gaps: `last` (the point's nearest cell of the last substep, if it
// had one) is tested first, else the cell whose box is nearest (the first of equally near
// ones; `nearest`, its index in `near`, when the caller knows it), then the others in their
// order while their boxes are still nearer than the best triangle (a cell whose box is no
// nearer cannot hold a nearer one); the nearest triangle repels, and becomes `last`.
template <class Real>
void repel_nearest(const Sheet<Real>& q, std::uint32_t p, V3<Real> x, const Sheet<Real>& s,
                   const typename ContactScratch<Real>::Near* near, std::uint32_t found, const ContactParams<Real>& prm,
                   ContactForces<Real>& on_q, ContactForces<Real>& on_s, std::uint32_t& last,
                   std::uint32_t nearest = kNoCell) {
  const std::uint32_t cols = s.topology->cols();
  const Real R2 = prm.range * prm.range;
  Nearest<Real> best{};
  best.dist2 = R2;
  best.key = ~std::uint32_t(0);
  // Last substep's nearest cell first (a guess that is usually right, which makes the
  // bound tight at once), else the cell whose box is nearest.
  std::uint32_t first = last;
  if (first == kNoCell) {
    if (nearest == kNoCell) nearest = nearest_box<Real>(near, found);
    first = near[nearest].corner;
  }
  test_cell(s, cols, x, first, best);
  for (std::uint32_t e = 0; e < found; ++e)
    if (near[e].corner != first && near[e].gap2 < best.dist2) test_cell(s, cols, x, near[e].corner, best);
  if (best.dist2 < R2) {
    last = best.tri[0];  // the cell's first corner: both triangles start there
    repel(q, p, x, s, best, prm, on_q, on_s);
  } else {
    last = kNoCell;
  }
}

// The contact potential (J) of the points of q against the surface of s (bq, bs: their
// boxes made from their positions now): each point's nearest triangle within R (cells
// within `ring` rows and columns of the point left out when ring ≥ 0, as the search leaves
// them), block by block of q as the search goes (the patches of s within R of the block's
// box, then per point the patch, strip and cell boxes nearer than the best triangle so far).
template <class Real>
double contact_energy(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,
                      const SheetBoxes<Real>& bs, int ring, const ContactParams<Real>& prm) {
  if (bs.m == 0 || bs.n == 0) return 0;  // a line of points has no surface
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  const std::uint32_t cols = s.topology->cols(), qcols = q.topology->cols();
  const Real R2 = prm.range * prm.range;
  const double reach = double(prm.range) * (1 + 1e-6) + 1e-12;  // widened against rounding
  auto gap2 = [](V3<Real> x, const std::vector<Real>(&lo)[3], const std::vector<Real>(&hi)[3], std::size_t k) {
    const Real c[3] = {x.x, x.y, x.z};
    Real g2 = 0;
    for (int a = 0; a < 3; ++a) {
      const Real e = positive_part(lo[a][k] - c[a]) + positive_part(c[a] - hi[a][k]);
      g2 += e * e;
    }
    return g2;
  };
  auto box = [](const SheetBoxes<Real>& b, std::size_t patch) {
    Aabb out;
    for (int k = 0; k < 3; ++k) {
      out.lo[k] = b.patch_lo[k][patch];
      out.hi[k] = b.patch_hi[k][patch];
    }
    return out;
  };
  std::vector<std::uint32_t> near;  // patches of s within R of the block
  double energy = 0;
  for (std::uint32_t bi = 0; bi < bq.patch_rows; ++bi)
    for (std::uint32_t bj = 0; bj < bq.patch_cols; ++bj) {
      const Aabb block = box(bq, std::size_t(bi) * bq.patch_cols + bj).inflated(reach);
      near.clear();
      for (std::uint32_t t = 0; t < bs.patch_rows * bs.patch_cols; ++t)
        if (overlaps(block, box(bs, t))) near.push_back(t);
      if (near.empty()) continue;
      const std::uint32_t i1 = bq.end_point(bi, bq.patch_rows, bq.m), j1 = bq.end_point(bj, bq.patch_cols, bq.n);
      for (std::uint32_t pi = bq.first(bi); pi < i1; ++pi)
        for (std::uint32_t pj = bq.first(bj); pj < j1; ++pj) {
          const std::uint32_t p = pi * qcols + pj;
          const V3<Real> x = at(q, p);
          Nearest<Real> best{};
          best.dist2 = R2;
          best.key = ~std::uint32_t(0);
          for (std::uint32_t t : near) {
            if (!(gap2(x, bs.patch_lo, bs.patch_hi, t) < best.dist2)) continue;
            const std::uint32_t tr = t / bs.patch_cols, tc = t % bs.patch_cols;
            const std::uint32_t ci1 = std::min(tr * P + P, bs.m), cj1 = std::min(tc * P + P, bs.n);
            for (std::uint32_t i = tr * P; i < ci1; ++i) {
              if (!(gap2(x, bs.strip_lo, bs.strip_hi, std::size_t(i) * bs.patch_cols + tc) < best.dist2)) continue;
              const bool ring_row = ring >= 0 && std::int64_t(i) >= std::int64_t(pi) - ring &&
                                    std::int64_t(i) < std::int64_t(pi) + ring;
              for (std::uint32_t j = tc * P; j < cj1; ++j) {
                if (ring_row && std::int64_t(j) >= std::int64_t(pj) - ring && std::int64_t(j) < std::int64_t(pj) + ring)
                  continue;
                const std::uint32_t cell = i * cols + j;
                if (gap2(x, bs.cell_lo, bs.cell_hi, cell) < best.dist2) test_cell(s, cols, x, cell, best);
              }
            }
          }
          if (best.dist2 < R2) energy += contact_potential(std::sqrt(double(best.dist2)), prm);
        }
    }
  return energy;
}

// Points of q against the cells of s through both sheets' boxes (contacts.h): block by
// block, the patches of s within reach of the block and, of those, the strips within
// reach of it, gathered contiguous; point by point, the gathered strips within R, and of
// their cells those within R, of which the nearest triangle repels. `ring` < 0: no
// exclusion; otherwise q is s and the cells within `ring` rows/columns of the point are
// left out.
//
// The entries [e0, e1) of `kept`, walked (defined below).
template <class Real>
void points_walking(const Sheet<Real>& q, const Sheet<Real>& s, int ring, KeptContacts& kept, std::size_t e0,
                    std::size_t e1, const ContactParams<Real>& prm, ContactForces<Real>& on_q,
                    ContactForces<Real>& on_s, std::uint32_t* last);

// With `lists`, it also makes each point's candidate list (PairContacts): the cells whose
// boxes are within R + skin of it, in the order this search meets them. With `kept`, it
// makes the kept contact set instead; with `before` too (the set so far, for these sheets),
// the entries of `before` walk and move to `kept` as they are, block by block, and only a
// block's points outside `before` are searched (a partial search, KeptContacts).
template <class Real>
void points_against_cells(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,
                          const SheetBoxes<Real>& bs, int ring, const ContactParams<Real>& prm,
                          ContactForces<Real>& on_q, ContactForces<Real>& on_s, ContactScratch<Real>& sc,
                          std::uint32_t* last, Candidates* lists, Real skin, KeptContacts* kept,
                          KeptContacts* before, std::uint32_t block_from, std::uint32_t block_to) {
  // lists and kept come cleared, kept's open and block_begin sized (start_search)
  const std::size_t blocks = std::size_t(bq.patch_rows) * bq.patch_cols;
  if (before && (before->open.size() != blocks || before->block_begin.size() != blocks + 1)) before = nullptr;
  if (bs.m == 0 || bs.n == 0) return;  // a line of points has no cells
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  const Real R2 = prm.range * prm.range;
  const Real L2 = (prm.range + skin) * (prm.range + skin);  // cells kept on a list: ≥ R²
  // Box tests are a necessary condition only: widened against rounding, so a cell the
  // exact test (gap² < L²) keeps is never dropped before it.
  const double reach = double(prm.range + skin) * (1 + 1e-6) + 1e-12;
  if (!overlaps(bq.box.inflated(reach), bs.box)) return;
  const std::uint32_t scols = bs.n + 1, qcols = bq.n + 1;
  const std::uint32_t spatches = bs.patch_rows * bs.patch_cols;
  const std::size_t strips = std::size_t(bs.m) * bs.patch_cols;
  sc.patches.resize(spatches);
  for (int k = 0; k < 3; ++k) {
    sc.run_lo[k].resize(strips);
    sc.run_hi[k].resize(strips);
  }
  sc.run_corner.resize(strips);
  sc.run_row.resize(strips);
  sc.run_col.resize(strips);
  sc.gap2.resize(std::max<std::size_t>(strips, P));
  sc.pick.resize(strips);
  sc.near.resize(strips * P);
  Real* rlo[3] = {sc.run_lo[0].data(), sc.run_lo[1].data(), sc.run_lo[2].data()};
  Real* rhi[3] = {sc.run_hi[0].data(), sc.run_hi[1].data(), sc.run_hi[2].data()};
  std::uint32_t* rcorner = sc.run_corner.data();  // a strip's first cell
  std::uint32_t* rrow = sc.run_row.data();        // its grid row
  std::uint32_t* rcount = sc.run_col.data();      // its number of cells
  Real* gap2 = sc.gap2.data();
  std::uint32_t* pick = sc.pick.data();
  typename ContactScratch<Real>::Near* near = sc.near.data();
  const Real* plo[3] = {bs.patch_lo[0].data(), bs.patch_lo[1].data(), bs.patch_lo[2].data()};
  const Real* phi[3] = {bs.patch_hi[0].data(), bs.patch_hi[1].data(), bs.patch_hi[2].data()};
  const Real* clo[3] = {bs.cell_lo[0].data(), bs.cell_lo[1].data(), bs.cell_lo[2].data()};
  const Real* chi[3] = {bs.cell_hi[0].data(), bs.cell_hi[1].data(), bs.cell_hi[2].data()};
  const auto& Q = q.position;
  Real cell_gap2[P];

  block_to = std::min(block_to, std::uint32_t(blocks));
  for (std::uint32_t block = block_from; block < block_to; ++block) {
    const std::uint32_t bi = block / bq.patch_cols, bj = block % bq.patch_cols;
    if (kept) kept->block_begin[block] = std::uint32_t(kept->point.size());
    const std::size_t entries_before = kept ? kept->point.size() : 0;
    // The block's points in the set walk and stay in it; only a block with points
    // outside the set is searched, and only for those points.
    std::uint32_t e0 = 0, e1 = 0;
    if (before) {
      e0 = before->block_begin[block];
      e1 = before->block_begin[block + 1];
      points_walking(q, s, ring, *before, e0, e1, prm, on_q, on_s, last);
      kept->point.insert(kept->point.end(), before->point.begin() + e0, before->point.begin() + e1);
      kept->cell.insert(kept->cell.end(), before->cell.begin() + e0, before->cell.begin() + e1);
      kept->until.insert(kept->until.end(), before->until.begin() + e0, before->until.begin() + e1);
      if (!before->open[block]) {
        kept->open[block] = 0;
        continue;
      }
    }
    Aabb bb;
    for (int k = 0; k < 3; ++k) {
      bb.lo[k] = bq.patch_lo[k][block];
      bb.hi[k] = bq.patch_hi[k][block];
    }
    if (!overlaps(bb.inflated(reach), bs.box)) continue;
    // The patches of s within reach of the block, kept without a branch.
    std::uint32_t np = 0;
    for (std::uint32_t t = 0; t < spatches; ++t) {
      unsigned keep = 1;
      for (int k = 0; k < 3; ++k)
        keep &= unsigned(double(plo[k][t]) <= bb.hi[k] + reach) & unsigned(double(phi[k][t]) >= bb.lo[k] - reach);
      sc.patches[np] = t;
      np += keep;
    }
    if (np == 0) continue;
    // Their strips within reach of the block, gathered contiguous.
    std::uint32_t count = 0;
    for (std::uint32_t e = 0; e < np; ++e) {
      const std::uint32_t t = sc.patches[e];
      const std::uint32_t ti = t / bs.patch_cols, tj = t % bs.patch_cols;
      const std::uint32_t ci1 = std::min((ti + 1) * P, bs.m), cj0 = tj * P, cj1 = std::min(cj0 + P, bs.n);
      for (std::uint32_t ci = ti * P; ci < ci1; ++ci) {
        const std::size_t strip = std::size_t(ci) * bs.patch_cols + tj;
        unsigned keep = 1;  // branch-free: bitwise on 0/1, not && on bools
        for (int k = 0; k < 3; ++k) {
          rlo[k][count] = bs.strip_lo[k][strip];
          rhi[k][count] = bs.strip_hi[k][strip];
          keep &= unsigned(double(bs.strip_lo[k][strip]) <= bb.hi[k] + reach) &
                  unsigned(double(bs.strip_hi[k][strip]) >= bb.lo[k] - reach);
        }
        rcorner[count] = ci * scols + cj0;
        rrow[count] = ci;
        rcount[count] = cj1 - cj0;
        count += keep;
      }
    }
    if (count == 0) continue;
    const std::uint32_t i0 = bq.first(bi), i1 = bq.end_point(bi, bq.patch_rows, bq.m);
    const std::uint32_t j0 = bq.first(bj), j1 = bq.end_point(bj, bq.patch_cols, bq.n);
    if (before) {
      sc.in_set.resize(q.size());
      for (std::uint32_t e = e0; e < e1; ++e) sc.in_set[before->point[e]] = 1;
    }
    for (std::uint32_t i = i0; i < i1; ++i)
      for (std::uint32_t j = j0; j < j1; ++j) {
        const std::uint32_t p = i * qcols + j;
        if (before && sc.in_set[p]) continue;  // walked above
        const V3<Real> x{Q.x[p], Q.y[p], Q.z[p]};
        // The gathered strips within R, then their cells within R.
        box_gaps(hn::ScalableTag<Real>(), x, rlo, rhi, count, gap2);
        std::uint32_t strips_near = 0;
        for (std::uint32_t t = 0; t < count; ++t) {
          pick[strips_near] = t;
          strips_near += gap2[t] < L2;
        }
        std::uint32_t found = 0;
        for (std::uint32_t e = 0; e < strips_near; ++e) {
          const std::uint32_t t = pick[e], c0 = rcorner[t], cells = rcount[t];
          const Real* lo[3] = {clo[0] + c0, clo[1] + c0, clo[2] + c0};
          const Real* hi[3] = {chi[0] + c0, chi[1] + c0, chi[2] + c0};
          box_gaps(hn::CappedTag<Real, P>(), x, lo, hi, P, cell_gap2);  // all 8: the arrays are padded
          if (ring >= 0) {  // self-contact: not the cells of the point's own neighbourhood
            const std::int64_t ci = rrow[t];
            if (ci >= std::int64_t(i) - ring && ci < std::int64_t(i) + ring) {
              const std::int64_t cj0 = c0 - ci * scols;
              for (std::uint32_t c = 0; c < cells; ++c) {
                const std::int64_t cj = cj0 + c;
                near[found] = {c0 + c, cell_gap2[c]};
                found += cell_gap2[c] < L2 && !(cj >= std::int64_t(j) - ring && cj < std::int64_t(j) + ring);
              }
              continue;
            }
          }
          for (std::uint32_t c = 0; c < cells; ++c) {
            near[found] = {c0 + c, cell_gap2[c]};
            found += cell_gap2[c] < L2;
          }
        }
        // A point within R + skin joins the kept set at the cell whose box is nearest,
        // or at its nearest triangle's cell if that is within R.
        std::uint32_t start = kNoCell, nearest = kNoCell;
        Real nearest_gap2 = 0;  // no triangle of s is nearer (every cell within R + skin is in `near`)
        if (kept && found > 0) {
          nearest = nearest_box<Real>(near, found);
          start = near[nearest].corner;
          nearest_gap2 = near[nearest].gap2;
          // repel_nearest passes over the cells beyond R (their boxes are no nearer than
          // its bound), so the whole list serves; within R only if the nearest box is
          if (!(nearest_gap2 < R2)) found = 0;
        }
        if (lists) {  // the list, then only the cells within R
          lists->begin[p] = std::uint32_t(lists->cell.size());
          lists->count[p] = found;
          std::uint32_t within = 0;
          for (std::uint32_t e = 0; e < found; ++e) {
            lists->cell.push_back(near[e].corner);
            near[within] = near[e];
            within += near[e].gap2 < R2;
          }
          found = within;
        }
        bool repelled = false;
        if (found > 0) {
          repel_nearest(q, p, x, s, near, found, prm, on_q, on_s, last[p], nearest);
          repelled = last[p] != kNoCell;
          if (kept && repelled) start = last[p];
        }
        if (start != kNoCell) {
          kept->point.push_back(p);
          kept->cell.push_back(start);
          // beyond R: walked again once the pair has travelled the gap to the nearest box
          kept->until.push_back(repelled ? -std::numeric_limits<double>::infinity()
                                         : skip_until(prm.travel, double(nearest_gap2), double(prm.range)));
        }
      }
    if (before)
      for (std::uint32_t e = e0; e < e1; ++e) sc.in_set[before->point[e]] = 0;
    // The block visited rows [i0, i1) × columns [j0, j1): open unless all are in the set.
    if (kept) kept->open[block] = kept->point.size() - entries_before < std::size_t(i1 - i0) * (j1 - j0);
  }
  if (kept && block_to == blocks) kept->block_begin[blocks] = std::uint32_t(kept->point.size());
}

// Points of q against their candidate lists of cells of s (PairContacts), in the order
// points_against_cells visits points and meets cells: each point measures its gap to
// its listed cells' boxes now and keeps those under R, which are then exactly the cells
// points_against_cells would find, in its order, so the forces are the same bit for bit.
template <class Real>
void points_against_lists(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,
                          const SheetBoxes<Real>& bs, const Candidates& lists, const ContactParams<Real>& prm,
                          ContactForces<Real>& on_q, ContactForces<Real>& on_s, ContactScratch<Real>& sc,
                          std::uint32_t* last) {
  if (lists.cell.empty()) return;
  const Real R2 = prm.range * prm.range;
  std::uint32_t widest = 0;
  for (std::uint32_t c : lists.count) widest = std::max(widest, c);
  for (int k = 0; k < 3; ++k) {
    sc.run_lo[k].resize(widest);
    sc.run_hi[k].resize(widest);
  }
  sc.gap2.resize(widest);
  sc.near.resize(widest);
  Real* rlo[3] = {sc.run_lo[0].data(), sc.run_lo[1].data(), sc.run_lo[2].data()};
  Real* rhi[3] = {sc.run_hi[0].data(), sc.run_hi[1].data(), sc.run_hi[2].data()};
  Real* gap2 = sc.gap2.data();
  typename ContactScratch<Real>::Near* near = sc.near.data();
  const std::uint32_t qcols = bq.n + 1;
  for (std::uint32_t bi = 0; bi < bq.patch_rows; ++bi)
    for (std::uint32_t bj = 0; bj < bq.patch_cols; ++bj) {
      const std::uint32_t i0 = bq.first(bi), i1 = bq.end_point(bi, bq.patch_rows, bq.m);
      const std::uint32_t j0 = bq.first(bj), j1 = bq.end_point(bj, bq.patch_cols, bq.n);
      for (std::uint32_t i = i0; i < i1; ++i)
        for (std::uint32_t j = j0; j < j1; ++j) {
          const std::uint32_t p = i * qcols + j, count = lists.count[p];
          if (count == 0) continue;
          const std::uint32_t* cell = lists.cell.data() + lists.begin[p];
          for (int k = 0; k < 3; ++k)
            for (std::uint32_t t = 0; t < count; ++t) {
              rlo[k][t] = bs.cell_lo[k][cell[t]];
              rhi[k][t] = bs.cell_hi[k][cell[t]];
            }
          const V3<Real> x = at(q, p);
          box_gaps(hn::ScalableTag<Real>(), x, rlo, rhi, count, gap2);
          std::uint32_t found = 0;  // kept without a branch, in the list's order
          for (std::uint32_t t = 0; t < count; ++t) {
            near[found] = {cell[t], gap2[t]};
            found += gap2[t] < R2;
          }
          if (found > 0) repel_nearest(q, p, x, s, near, found, prm, on_q, on_s, last[p]);
        }
    }
}

// Within this of zero, a closest point's weight or the cosine between x − v and an edge
// of v is zero for the walk: √ε of the precision. Sheets whose grids are aligned (a stack
// of equal sheets, a sheet folded along a grid line) put points straight over the other
// sheet's vertices, where the exact tests below decide by rounding alone which cell is
// nearer; measured on a fold, nearly every vertex test that failed did so with a cosine
// under 10⁻¹⁰, and each failure cost three more cells' tests and often a move back and forth.
// Taking v where x − v leans at most √ε past 90° from its edges moves the closest point by
// at most about √ε·|x − v| (a force direction off by as much) and the distance by about
// ε·|x − v|, its own rounding (contacts_test.cpp holds walked forces to the exact search).
template <class Real>
constexpr Real kWalkTie = std::is_same_v<Real, float> ? Real(3.5e-4) : Real(1.5e-8);

// Whether grid point (vi, vj) of s is the point of every triangle around it nearest to x:
// x − v makes an angle of at least 90° (less kWalkTie's cosine) with each of its edges (to
// its four grid neighbours and, along the cells' diagonals, to (vi ± 1, vj ± 1)), which
// puts x in v's vertex region of each triangle (closest_weights). Then no cell around v
// holds a nearer point, and a walk that reached v stops without testing their triangles.
template <class Real>
bool vertex_is_nearest(const Sheet<Real>& s, V3<Real> x, std::int64_t vi, std::int64_t vj) {
  const std::int64_t rows = s.topology->m + 1, cols = s.topology->n + 1;
  const V3<Real> v = at(s, std::uint32_t(vi * cols + vj));
  const V3<Real> d = sub(x, v);
  const Real tie2 = kWalkTie<Real> * kWalkTie<Real> * dot(d, d);
  constexpr int kEdges[6][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {1, 1}, {-1, -1}};
  unsigned outside = 1;
  for (const auto& e : kEdges) {
    const std::int64_t ui = vi + e[0], uj = vj + e[1];
    if (ui < 0 || uj < 0 || ui >= rows || uj >= cols) continue;
    const V3<Real> edge = sub(at(s, std::uint32_t(ui * cols + uj)), v);
    const Real along = dot(d, edge);  // cos·|d|·|edge|
    outside &= unsigned(along <= 0) | unsigned(along * along <= tie2 * dot(edge, edge));
  }
  return outside != 0;
}

// The nearest of a kept cell's two triangles, for a vector of kept entries at once: the
// operations of closest_weights and consider, in their order, on every lane, each Voronoi
// region's weights computed and the first region that holds (in closest_weights' order)
// selected, so a lane gets the bits the scalar test gets. Most walks end at their first
// cell, and this test is most of what they cost: branch-free, it no longer pays a
// mispredicted branch per region.
template <class Real, class V>
struct V3s {
  V x, y, z;
};

// u − v and u·v lane by lane, in sub's and dot's order (functions, not lambdas, as
// positive_lanes).
template <class Real, class V>
HWY_INLINE V3s<Real, V> sub_lanes(const V3s<Real, V>& u, const V3s<Real, V>& v) {
  return {hn::Sub(u.x, v.x), hn::Sub(u.y, v.y), hn::Sub(u.z, v.z)};
}
template <class Real, class V>
HWY_INLINE V dot_lanes(const V3s<Real, V>& u, const V3s<Real, V>& v) {
  return hn::Add(hn::Add(hn::Mul(u.x, v.x), hn::Mul(u.y, v.y)), hn::Mul(u.z, v.z));
}

template <class D, class V>
HWY_INLINE void closest_lanes(D d, const V3s<hn::TFromD<D>, V>& p, const V3s<hn::TFromD<D>, V>& a,
                              const V3s<hn::TFromD<D>, V>& b, const V3s<hn::TFromD<D>, V>& c, V& dist2, V& wa,
                              V& wb, V& wc, V3s<hn::TFromD<D>, V>& gap) {
  using Real = hn::TFromD<D>;
  const V zero = hn::Zero(d), one = hn::Set(d, Real(1));
  const auto ab = sub_lanes(b, a), ac = sub_lanes(c, a), ap = sub_lanes(p, a), bp = sub_lanes(p, b), cp = sub_lanes(p, c);
  const V d1 = dot_lanes(ab, ap), d2 = dot_lanes(ac, ap), d3 = dot_lanes(ab, bp), d4 = dot_lanes(ac, bp), d5 = dot_lanes(ab, cp),
          d6 = dot_lanes(ac, cp);
  const V vc = hn::Sub(hn::Mul(d1, d4), hn::Mul(d3, d2));
  const V vb = hn::Sub(hn::Mul(d5, d2), hn::Mul(d1, d6));
  const V va = hn::Sub(hn::Mul(d3, d6), hn::Mul(d5, d4));
  const V sum = hn::Add(hn::Add(va, vb), vc);
  const V d43 = hn::Sub(d4, d3), d56 = hn::Sub(d5, d6);
  // The regions, in closest_weights' order: vertex a, vertex b, edge ab, vertex c, edge ac,
  // edge bc, a degenerate triangle, the face; the first that holds is the lane's.
  const auto at_a = hn::And(hn::Le(d1, zero), hn::Le(d2, zero));
  const auto at_b = hn::And(hn::Ge(d3, zero), hn::Le(d4, d3));
  const auto on_ab = hn::And(hn::And(hn::Le(vc, zero), hn::Ge(d1, zero)), hn::Le(d3, zero));
  const auto at_c = hn::And(hn::Ge(d6, zero), hn::Le(d5, d6));
  const auto on_ac = hn::And(hn::And(hn::Le(vb, zero), hn::Ge(d2, zero)), hn::Le(d6, zero));
  const auto on_bc = hn::And(hn::And(hn::Le(va, zero), hn::Ge(d43, zero)), hn::Ge(d56, zero));
  // Two divisions, not five: a lane whose region is an edge divides that edge's operands
  // (of the edges that hold, the first in that order is the lane's unless a vertex before
  // it holds, whose weights need no quotient), a face lane vb/sum, and every lane vc/sum,
  // which only the face uses; each quotient has the operands, so the bits, of
  // closest_weights' own.
  const auto edge = hn::Or(hn::Or(on_ab, on_ac), on_bc);
  const V edge_num = hn::IfThenElse(on_ab, d1, hn::IfThenElse(on_ac, d2, d43));
  const V edge_den = hn::IfThenElse(on_ab, hn::Sub(d1, d3), hn::IfThenElse(on_ac, hn::Sub(d2, d6), hn::Add(d43, d56)));
  const V t = hn::Div(hn::IfThenElse(edge, edge_num, vb), hn::IfThenElse(edge, edge_den, sum));
  const V fw = hn::Div(vc, sum);
  // the face, then each region before it in closest_weights' order overriding it
  V u = hn::Sub(hn::Sub(one, t), fw), v = t, w = fw;
  auto take = [&](auto region, V ru, V rv, V rw) {
    u = hn::IfThenElse(region, ru, u);
    v = hn::IfThenElse(region, rv, v);
    w = hn::IfThenElse(region, rw, w);
  };
  take(hn::Not(hn::Gt(sum, zero)), one, zero, zero);  // degenerate: the first vertex
  const V rest = hn::Sub(one, t);
  take(on_bc, zero, rest, t);
  take(on_ac, rest, zero, t);
  take(at_c, zero, zero, one);
  take(on_ab, rest, t, zero);
  take(at_b, zero, one, zero);
  take(at_a, one, zero, zero);
  const V3s<Real, V> q{hn::Add(hn::Add(hn::Mul(u, a.x), hn::Mul(v, b.x)), hn::Mul(w, c.x)),
                       hn::Add(hn::Add(hn::Mul(u, a.y), hn::Mul(v, b.y)), hn::Mul(w, c.y)),
                       hn::Add(hn::Add(hn::Mul(u, a.z), hn::Mul(v, b.z)), hn::Mul(w, c.z))};
  gap = sub_lanes(p, q);
  dist2 = dot_lanes(gap, gap);
  wa = u;
  wb = v;
  wc = w;
}

// For kept entries of points[0, count) at cells[0, count), count a multiple of the lanes:
// the squared distance of the nearer of each entry's cell's two triangles (NaN when neither
// gives a number: no triangle), 1 where it is the second, and its weights, as test_cell from an empty best;
// then (force_lanes) the repulsion repel would give that triangle: its unit direction and
// force.
template <class Real>
struct FirstTests {
  static constexpr std::size_t kSize = 64;
  alignas(64) Real dist2[kSize], second[kSize], w[3][kSize];
  alignas(64) Real unit[3][kSize];  // p − q, then (force_lanes) divided by the distance
  alignas(64) Real force[kSize];    // the exponent, then (force_lanes) the force f
  alignas(64) Real extra[3][kSize];  // dissipate_lanes: damping and friction, as dissipate gives them
  // 1 where the walk ends at this triangle without testing another cell, at a positive
  // distance: the closest point is off the cell's outer edges (points_walking's move test
  // finds no row or column to cross), or at a corner inside the grid that vertex_is_nearest
  // takes.
  alignas(64) Real ends[kSize];
  // (push_lanes) the force on the point, F = f·unit (+ extra), as push_repulsion computes it
  alignas(64) Real push[3][kSize];
};

// A vector of point indices from `from` (one per lane), as the gathers of di's lanes take them.
template <class DI>
HWY_INLINE hn::Vec<DI> lane_indices(DI di, const std::uint32_t* from) {
  if constexpr (sizeof(hn::TFromD<DI>) == 8)
    return hn::PromoteTo(di, hn::LoadU(hn::Rebind<std::int32_t, DI>(), reinterpret_cast<const std::int32_t*>(from)));
  else
    return hn::BitCast(di, hn::LoadU(hn::RebindToUnsigned<DI>(), from));
}

template <class Real>
HWY_INLINE void first_tests(const Sheet<Real>& q, const Sheet<Real>& s, const std::uint32_t* points,
                            const std::uint32_t* cells, std::size_t count, FirstTests<Real>& out) {
  const hn::ScalableTag<Real> d;
  using V = hn::Vec<decltype(d)>;
  const hn::RebindToSigned<decltype(d)> di;
  using Index = hn::TFromD<decltype(di)>;
  auto indices = [&](const std::uint32_t* from) { return lane_indices(di, from); };
  const auto cols = hn::Set(di, Index(s.topology->cols())), one = hn::Set(di, Index(1));
  // A corner's row and column come from a quotient in Real, rounded down exactly while
  // index + columns stays below 2^24 in float (2^53 in double): larger float sheets leave
  // their corners to the walk.
  const bool corners = std::is_same_v<Real, double> || s.size() <= (std::size_t(1) << 23);
  auto gather = [&](const Sheet<Real>& sheet, auto at) {
    return V3s<Real, V>{hn::GatherIndex(d, sheet.position.x.data(), at), hn::GatherIndex(d, sheet.position.y.data(), at),
                        hn::GatherIndex(d, sheet.position.z.data(), at)};
  };
  // Where a vector's points are consecutive and its cells too, rising or falling (a stack
  // of equal grids, or a sheet folded onto its mirror image: entries follow their points in
  // order, each over the same corner of its cell), the positions are loaded (and reversed
  // for falling cells), not gathered: the same values, without a gather's cost. Lane i of
  // such a run reads index first + step·i; step 0: gathered at `index`.
  const std::size_t N = hn::Lanes(d);
  const std::ptrdiff_t last = std::ptrdiff_t(N) - 1, stride = std::ptrdiff_t(s.topology->cols());
  auto positions = [&](const Sheet<Real>& sheet, auto index, std::ptrdiff_t first, int step) {
    if (step == 0) return gather(sheet, index);
    const std::size_t from = std::size_t(step > 0 ? first : first - last);
    const V3s<Real, V> v{hn::LoadU(d, sheet.position.x.data() + from), hn::LoadU(d, sheet.position.y.data() + from),
                         hn::LoadU(d, sheet.position.z.data() + from)};
    if (step > 0) return v;
    return V3s<Real, V>{hn::Reverse(d, v.x), hn::Reverse(d, v.y), hn::Reverse(d, v.z)};
  };
  const auto lane = hn::Iota(di, 0);
  auto runs = [&](auto index, std::uint32_t first, int step) {
    return hn::AllTrue(di, hn::Eq(index, hn::Add(hn::Set(di, Index(first)), hn::Mul(hn::Set(di, Index(step)), lane))));
  };
  for (std::size_t k = 0; k < count; k += N) {
    const std::uint32_t* point = points + k;
    const std::uint32_t* cell = cells + k;
    const auto p = indices(point), c00 = indices(cell), c01 = hn::Add(c00, one), c10 = hn::Add(c00, cols),
               c11 = hn::Add(c10, one);
    // (a run of cells never crosses a row: a row's last index starts no cell)
    const bool points_run = runs(p, point[0], 1);
    const int step = !points_run ? 0 : runs(c00, cell[0], 1) ? 1 : runs(c00, cell[0], -1) ? -1 : 0;
    const std::ptrdiff_t c0 = cell[0];
    const V3s<Real, V> x = positions(q, p, point[0], step != 0 ? 1 : 0);
    const V3s<Real, V> x00 = positions(s, c00, c0, step), x01 = positions(s, c01, c0 + 1, step),
                       x10 = positions(s, c10, c0 + stride, step), x11 = positions(s, c11, c0 + stride + 1, step);
    V d0, u0, v0, w0, d1, u1, v1, w1;
    V3s<Real, V> g0, g1;
    closest_lanes(d, x, x00, x01, x11, d0, u0, v0, w0, g0);
    closest_lanes(d, x, x00, x11, x10, d1, u1, v1, w1, g1);
    // consider's rule from an empty best: the first triangle unless its distance is not a
    // number, the second if nearer (or the first is not a number)
    const auto second = hn::Or(hn::Lt(d1, d0), hn::And(hn::IsNaN(d0), hn::Not(hn::IsNaN(d1))));
    const V dist2 = hn::IfThenElse(second, d1, d0), u = hn::IfThenElse(second, u1, u0),
            v = hn::IfThenElse(second, v1, v0), w = hn::IfThenElse(second, w1, w0);
    hn::Store(dist2, d, out.dist2 + k);
    hn::Store(hn::IfThenElseZero(second, hn::Set(d, Real(1))), d, out.second + k);
    hn::Store(u, d, out.w[0] + k);
    hn::Store(v, d, out.w[1] + k);
    hn::Store(w, d, out.w[2] + k);
    // points_walking's move test: the weights on corners 00, 01, 11, 10 (triangle 0 is
    // (00, 01, 11), triangle 1 (00, 11, 10)) and whether a row's or column's two are zero
    // (within kWalkTie)
    const V zero = hn::Zero(d), w00 = u, w01 = hn::IfThenElse(second, zero, v), w11 = hn::IfThenElse(second, v, w),
            w10 = hn::IfThenElse(second, w, zero);
    const V tie = hn::Set(d, kWalkTie<Real>);
    const auto row_lo = hn::Le(hn::Add(w10, w11), tie), row_hi = hn::Le(hn::Add(w00, w01), tie);
    const auto col_lo = hn::Le(hn::Add(w01, w11), tie), col_hi = hn::Le(hn::Add(w00, w10), tie);
    const auto edge = hn::Or(hn::Or(row_lo, row_hi), hn::Or(col_lo, col_hi));
    auto ends = hn::Not(edge);
    // At a corner (the walk's first move would be diagonal): vertex_is_nearest of that
    // corner, lane by lane in its operations, where the corner is inside the grid (all six
    // neighbours exist; at the border the walk tests it). Its row and column neighbours
    // are this cell's corners, the other four are gathered.
    const auto at_corner = hn::And(hn::Or(row_lo, row_hi), hn::Or(col_lo, col_hi));
    if (corners && !hn::AllFalse(d, at_corner)) {
      const auto a = hn::AndNot(row_lo, row_hi), b = hn::AndNot(col_lo, col_hi);  // the walk's di > 0, dj > 0
      auto pick = [](auto mask, const V3s<Real, V>& yes, const V3s<Real, V>& no) {
        return V3s<Real, V>{hn::IfThenElse(mask, yes.x, no.x), hn::IfThenElse(mask, yes.y, no.y),
                            hn::IfThenElse(mask, yes.z, no.z)};
      };
      const V3s<Real, V> v = pick(a, pick(b, x11, x10), pick(b, x01, x00));
      const V3s<Real, V> in_row = pick(a, pick(b, x01, x00), pick(b, x11, x10));  // (vi ∓ 1, vj)
      const V3s<Real, V> in_col = pick(b, pick(a, x10, x00), pick(a, x11, x01));  // (vi, vj ∓ 1)
      const auto ai = hn::RebindMask(di, a), bi = hn::RebindMask(di, b);
      const auto vi = hn::Add(hn::Add(c00, hn::IfThenElseZero(ai, cols)), hn::IfThenElseZero(bi, one));
      // The corner's row and column, in Real: exact below `corners`' bound.
      const V index = hn::ConvertTo(d, vi), width = hn::Set(d, Real(s.topology->cols()));
      const V row = hn::Floor(hn::Div(index, width)), col = hn::Sub(index, hn::Mul(row, width));
      const V first = hn::Set(d, Real(1));
      const auto inside = hn::And(hn::And(hn::Ge(row, first), hn::Lt(row, hn::Set(d, Real(s.topology->m)))),
                                  hn::And(hn::Ge(col, first), hn::Lt(col, hn::Set(d, Real(s.topology->n)))));
      const auto last_point = hn::Set(di, Index(s.size() - 1));
      // The corners' neighbours: runs too where every lane turns to the same corner of its
      // cell and all of them lie in the sheet; a lane outside reads a neighbour clamped
      // into it, which it does not use.
      const bool all_a = hn::AllTrue(d, a), all_b = hn::AllTrue(d, b);
      const std::ptrdiff_t v0 = c0 + (all_a ? stride : 0) + (all_b ? 1 : 0);
      const bool same = (all_a || hn::AllFalse(d, a)) && (all_b || hn::AllFalse(d, b));
      const int corner_step = same && v0 + std::min<std::ptrdiff_t>(0, step * last) - stride - 1 >= 0 &&
                                      v0 + std::max<std::ptrdiff_t>(0, step * last) + stride + 1 < std::ptrdiff_t(s.size())
                                  ? step
                                  : 0;
      auto near = [&](auto index, std::ptrdiff_t offset) {
        return positions(s, hn::Min(hn::Max(index, hn::Zero(di)), last_point), v0 + offset, corner_step);
      };
      const V3s<Real, V> out_row = near(hn::IfThenElse(bi, hn::Add(vi, one), hn::Sub(vi, one)), all_b ? 1 : -1);
      const V3s<Real, V> out_col = near(hn::IfThenElse(ai, hn::Add(vi, cols), hn::Sub(vi, cols)), all_a ? stride : -stride);
      const V3s<Real, V> up_left = near(hn::Sub(hn::Sub(vi, cols), one), -stride - 1),
                         down_right = near(hn::Add(hn::Add(vi, cols), one), stride + 1);
      const V3s<Real, V> dv = sub_lanes(x, v);
      const V tie2 = hn::Mul(hn::Mul(tie, tie), dot_lanes(dv, dv));
      auto away = [&](const V3s<Real, V>& u) {  // vertex_is_nearest's test of the edge to u
        const V3s<Real, V> e = sub_lanes(u, v);
        const V along = dot_lanes(dv, e);
        return hn::Or(hn::Le(along, zero), hn::Le(hn::Mul(along, along), hn::Mul(tie2, dot_lanes(e, e))));
      };
      const auto nearest = hn::And(hn::And(hn::And(away(in_row), away(in_col)), hn::And(away(out_row), away(out_col))),
                                   hn::And(away(up_left), away(down_right)));
      ends = hn::Or(ends, hn::And(hn::And(at_corner, nearest), inside));
    }
    hn::Store(hn::IfThenElseZero(hn::And(ends, hn::Gt(dist2, zero)), hn::Set(d, Real(1))), d, out.ends + k);
    hn::Store(hn::IfThenElse(second, g1.x, g0.x), d, out.unit[0] + k);
    hn::Store(hn::IfThenElse(second, g1.y, g0.y), d, out.unit[1] + k);
    hn::Store(hn::IfThenElse(second, g1.z, g0.z), d, out.unit[2] + k);
  }
}

// The repulsion of entries [0, count) of `t` (first_tests'), count a multiple of the lanes,
// as repel computes it for a point at a positive distance, each lane doing its operations
// in their order: the distance, the unit direction (p − q)/d, the capped exponent, e^x
// (force_exp's, in lanes of doubles) and the force f. A lane at distance 0 (repel then
// takes the triangle's normal), beyond R or not a number gets values nobody reads, and a
// vector with no lane within R is skipped whole: most of a stack's walked entries are
// beyond R, in runs (a block's entries follow each other, and a pair two layers apart has
// few within R), and this is a square root, four divisions and an e^x per vector.
template <class Real>
HWY_INLINE void force_lanes(const ContactParams<Real>& prm, std::size_t count, FirstTests<Real>& t) {
  const hn::ScalableTag<Real> d;
  const std::size_t N = hn::Lanes(d);
  const auto h = hn::Set(d, prm.thickness), xi = hn::Set(d, prm.xi), cap = hn::Set(d, prm.exponent_cap);
  const auto R2 = hn::Set(d, prm.range * prm.range);
  bool within[FirstTests<Real>::kSize];  // per vector of N entries: some lane within R
  for (std::size_t k = 0; k < count; k += N) {  // the unit direction, and exponent_at
    within[k / N] = !hn::AllFalse(d, hn::Lt(hn::Load(d, t.dist2 + k), R2));
    if (!within[k / N]) continue;
    const auto dist = hn::Sqrt(hn::Load(d, t.dist2 + k));
    for (int c = 0; c < 3; ++c) hn::Store(hn::Div(hn::Load(d, t.unit[c] + k), dist), d, t.unit[c] + k);
    const auto ratio = hn::Div(hn::Sub(h, dist), xi);
    hn::Store(lanes::first_min(ratio, cap), d, t.force + k);
  }
  const hn::ScalableTag<double> dd;
  for (std::size_t k = 0; k < count; k += hn::Lanes(dd)) {  // force_exp
    if (!within[k / N]) continue;  // (a float vector holds two of doubles)
    if constexpr (std::is_same_v<Real, double>) {
      hn::Store(lanes::exp_lanes(dd, hn::Load(dd, t.force + k)), dd, t.force + k);
    } else {
      const hn::Rebind<float, decltype(dd)> df;
      hn::Store(hn::DemoteTo(df, lanes::exp_lanes(dd, hn::PromoteTo(dd, hn::Load(df, t.force + k)))), df, t.force + k);
    }
  }
  const auto c_over_xi = hn::Set(d, prm.strength / prm.xi), tail = hn::Set(d, prm.tail);
  for (std::size_t k = 0; k < count; k += N)
    if (within[k / N]) hn::Store(hn::Mul(c_over_xi, hn::Sub(hn::Load(d, t.force + k), tail)), d, t.force + k);
}

// push_repulsion's force on the point for entries [0, count) of `t` (first_tests',
// force_lanes' and, with `dissipative`, dissipate_lanes'), count a multiple of the lanes,
// into t.push: each lane does push_repulsion's operations in their order, so the same bits.
// Vectors with no lane within R are skipped.
template <class Real>
HWY_INLINE void push_lanes(const ContactParams<Real>& prm, std::size_t count, bool dissipative, FirstTests<Real>& t) {
  const hn::ScalableTag<Real> d;
  const std::size_t N = hn::Lanes(d);
  const auto R2 = hn::Set(d, prm.range * prm.range);
  for (std::size_t k = 0; k < count; k += N) {
    if (hn::AllFalse(d, hn::Lt(hn::Load(d, t.dist2 + k), R2))) continue;
    const auto f = hn::Load(d, t.force + k);
    for (int c = 0; c < 3; ++c) {
      auto F = hn::Mul(f, hn::Load(d, t.unit[c] + k));
      if (dissipative) F = hn::Add(F, hn::Load(d, t.extra[c] + k));
      hn::Store(F, d, t.push[c] + k);
    }
  }
}

// dissipate_motion in lanes, for each lane's relative velocity rel, Σ w²/m, unit direction n
// and force: each lane does dissipate_motion's operations in their order, both sides of each
// choice taken and the lane's one kept, so every lane gets the bits dissipate_motion gives.
template <class D, class V = hn::Vec<D>, class Real = hn::TFromD<D>>
HWY_INLINE V3s<Real, V> dissipate_motion_lanes(D d, const V3s<Real, V>& rel, V inv_mass, const V3s<Real, V>& n, V force,
                                               const ContactParams<Real>& prm) {
  const V zero = hn::Zero(d), dt = hn::Set(d, prm.dt);
  const V damping = hn::Set(d, prm.damping), friction = hn::Set(d, prm.friction);
  const V share = hn::Set(d, Real(kDampingShare)), one = hn::Set(d, Real(1));
  const V normal = dot_lanes(rel, n);
  V3s<Real, V> damped{zero, zero, zero};
  if (prm.damping > 0) {
    const V alpha_f = hn::Mul(damping, force);
    const auto capped = hn::Gt(hn::Mul(hn::Mul(alpha_f, inv_mass), dt), share);
    const V b = hn::IfThenElse(capped, hn::Div(share, hn::Mul(inv_mass, dt)), alpha_f);
    const V pushed = hn::Mul(hn::Neg(b), normal), floor = hn::Neg(force);
    const V change = lanes::first_max(pushed, floor);
    damped = {hn::Mul(change, n.x), hn::Mul(change, n.y), hn::Mul(change, n.z)};
    force = hn::Add(force, change);
  }
  V3s<Real, V> out = damped;
  if (prm.friction > 0) {
    const V3s<Real, V> slip{hn::Sub(rel.x, hn::Mul(normal, n.x)), hn::Sub(rel.y, hn::Mul(normal, n.y)),
                            hn::Sub(rel.z, hn::Mul(normal, n.z))};
    const V slip2 = dot_lanes(slip, slip);
    const V mu_f = hn::Mul(friction, force);
    const V held = hn::Mul(hn::Mul(mu_f, inv_mass), dt);
    const V stop = hn::Div(one, hn::Mul(inv_mass, dt)), slide = hn::Div(mu_f, hn::Sqrt(slip2));
    const V kf = hn::IfThenElse(hn::Lt(slip2, hn::Mul(held, held)), stop, slide), neg_k = hn::Neg(kf);
    // damped − k·slip with damping, (−k)·slip without: dissipate_motion's two returns
    const V3s<Real, V> sum =
        prm.damping > 0
            ? V3s<Real, V>{hn::Sub(damped.x, hn::Mul(kf, slip.x)), hn::Sub(damped.y, hn::Mul(kf, slip.y)),
                           hn::Sub(damped.z, hn::Mul(kf, slip.z))}
            : V3s<Real, V>{hn::Mul(neg_k, slip.x), hn::Mul(neg_k, slip.y), hn::Mul(neg_k, slip.z)};
    const auto slides = hn::Gt(slip2, zero);
    out = {hn::IfThenElse(slides, sum.x, damped.x), hn::IfThenElse(slides, sum.y, damped.y),
           hn::IfThenElse(slides, sum.z, damped.z)};
  }
  const auto moves = hn::Gt(inv_mass, zero);
  return {hn::IfThenElseZero(moves, out.x), hn::IfThenElseZero(moves, out.y), hn::IfThenElseZero(moves, out.z)};
}

// dissipate_motion_lanes for the vector of entries from k of `t` (force_lanes' unit direction
// and force) into t.extra.
template <class D, class V = hn::Vec<D>, class Real = hn::TFromD<D>>
HWY_INLINE void dissipate_into(D d, const V3s<Real, V>& rel, V inv_mass, const ContactParams<Real>& prm,
                               FirstTests<Real>& t, std::size_t k) {
  const V3s<Real, V> n{hn::Load(d, t.unit[0] + k), hn::Load(d, t.unit[1] + k), hn::Load(d, t.unit[2] + k)};
  const V3s<Real, V> out = dissipate_motion_lanes(d, rel, inv_mass, n, hn::Load(d, t.force + k), prm);
  hn::Store(out.x, d, t.extra[0] + k);
  hn::Store(out.y, d, t.extra[1] + k);
  hn::Store(out.z, d, t.extra[2] + k);
}

// The velocities of a sheet's points at the indices of di's lanes.
template <class D, class I, class Real = hn::TFromD<D>>
HWY_INLINE V3s<Real, hn::Vec<D>> velocity_lanes(D d, const Sheet<Real>& sheet, I at) {
  return {hn::GatherIndex(d, sheet.velocity.x.data(), at), hn::GatherIndex(d, sheet.velocity.y.data(), at),
          hn::GatherIndex(d, sheet.velocity.z.data(), at)};
}

// dissipate's force (damping and friction, dissipate_motion) for entries [0, count) of `t`
// (first_tests' triangle and weights, force_lanes' unit direction and force), count a
// multiple of the lanes, into t.extra: each lane does dissipate's operations in their order,
// both sides of each choice taken and the lane's one kept, so every entry gets the bits
// dissipate gives it one at a time. Vectors with no lane within R are skipped, as
// force_lanes skips them; a lane beyond R gets values nobody reads.
template <class Real>
HWY_INLINE void dissipate_lanes(const Sheet<Real>& q, const Sheet<Real>& s, const std::uint32_t* points,
                                const std::uint32_t* cells, std::size_t count, const ContactParams<Real>& prm,
                                FirstTests<Real>& t) {
  const hn::ScalableTag<Real> d;
  using V = hn::Vec<decltype(d)>;
  const hn::RebindToSigned<decltype(d)> di;
  using Index = hn::TFromD<decltype(di)>;
  const std::size_t N = hn::Lanes(d);
  auto indices = [&](const std::uint32_t* from) { return lane_indices(di, from); };
  auto velocity_at = [&](const Sheet<Real>& sheet, auto at) { return velocity_lanes(d, sheet, at); };
  const auto cols = hn::Set(di, Index(s.topology->cols())), one_i = hn::Set(di, Index(1));
  const V zero = hn::Zero(d), R2 = hn::Set(d, prm.range * prm.range);
  for (std::size_t k = 0; k < count; k += N) {
    if (hn::AllFalse(d, hn::Lt(hn::Load(d, t.dist2 + k), R2))) continue;
    // dissipate: the point's velocity less the triangle's at the weights, and Σ w²/m
    const auto p = indices(points + k), c00 = indices(cells + k);
    const auto c01 = hn::Add(c00, one_i), c10 = hn::Add(c00, cols), c11 = hn::Add(c10, one_i);
    const auto second = hn::RebindMask(di, hn::Ne(hn::Load(d, t.second + k), zero));
    const decltype(c00) tri[3] = {c00, hn::IfThenElse(second, c11, c01), hn::IfThenElse(second, c10, c11)};
    V3s<Real, V> rel = velocity_at(q, p);
    V inv_mass = hn::GatherIndex(d, q.inv_mass.data(), p);
    for (int c = 0; c < 3; ++c) {
      const V w = hn::Load(d, t.w[c] + k);
      const V3s<Real, V> u = velocity_at(s, tri[c]);
      rel = {hn::Sub(rel.x, hn::Mul(w, u.x)), hn::Sub(rel.y, hn::Mul(w, u.y)), hn::Sub(rel.z, hn::Mul(w, u.z))};
      inv_mass = hn::Add(inv_mass, hn::Mul(hn::Mul(w, w), hn::GatherIndex(d, s.inv_mass.data(), tri[c])));
    }
    dissipate_into(d, rel, inv_mass, prm, t, k);
  }
}

// A side of a pair's rims: the candidates (u, v of q's rim, p, w of o) passing within R,
// with their closest points' weights s, t (the perpendicular and its squared length in the
// FirstTests beside them: unit, dist2).
template <class Real>
struct RimTests {
  std::uint32_t edge[4][FirstTests<Real>::kSize];
  alignas(64) Real s[FirstTests<Real>::kSize], t[FirstTests<Real>::kSize];
};

// repel_edges' damping and friction (dissipate_motion of the edges' relative motion at their
// closest points) for entries [0, count) of `r` and `t` (force_lanes' unit and force), count a
// multiple of the lanes, into t.extra: each lane does repel_edges' operations in their order,
// so every entry gets the bits it gives one at a time.
template <class Real>
HWY_INLINE void rim_dissipate_lanes(const Sheet<Real>& q, const Sheet<Real>& o, const RimTests<Real>& r,
                                    std::size_t count, const ContactParams<Real>& prm, FirstTests<Real>& t) {
  const hn::ScalableTag<Real> d;
  using V = hn::Vec<decltype(d)>;
  const hn::RebindToSigned<decltype(d)> di;
  const std::size_t N = hn::Lanes(d);
  auto velocity_at = [&](const Sheet<Real>& sheet, auto at) { return velocity_lanes(d, sheet, at); };
  const V zero = hn::Zero(d), one = hn::Set(d, Real(1));
  for (std::size_t k = 0; k < count; k += N) {
    const V s = hn::Load(d, r.s + k), tt = hn::Load(d, r.t + k);
    const V wq[2] = {hn::Sub(one, s), s}, ws[2] = {hn::Sub(one, tt), tt};
    V3s<Real, V> rel{zero, zero, zero};
    V inv_mass = zero;
    for (int e = 0; e < 2; ++e) {
      const auto iq = lane_indices(di, r.edge[e] + k), is = lane_indices(di, r.edge[2 + e] + k);
      const V3s<Real, V> a = velocity_at(q, iq), b = velocity_at(o, is);
      rel = {hn::Sub(hn::Add(rel.x, hn::Mul(wq[e], a.x)), hn::Mul(ws[e], b.x)),
             hn::Sub(hn::Add(rel.y, hn::Mul(wq[e], a.y)), hn::Mul(ws[e], b.y)),
             hn::Sub(hn::Add(rel.z, hn::Mul(wq[e], a.z)), hn::Mul(ws[e], b.z))};
      inv_mass = hn::Add(inv_mass, hn::Add(hn::Mul(hn::Mul(wq[e], wq[e]), hn::GatherIndex(d, q.inv_mass.data(), iq)),
                                           hn::Mul(hn::Mul(ws[e], ws[e]), hn::GatherIndex(d, o.inv_mass.data(), is))));
    }
    dissipate_into(d, rel, inv_mass, prm, t, k);
  }
}

// A side of rims_of_pair: each of q's rim candidates against o that passes within R repels
// (repel_edges), in order. The passing ones are gathered a chunk at a time and their forces,
// damping and friction computed in lanes where the CPU gathers in hardware (AVX2 and
// AVX-512, as points_walking's first tests), the chunk's last entries short of a whole vector
// and every entry elsewhere one by one; either way each entry gets repel_edges' bits, pushed
// in the same order.
template <class Real>
void rim_side(const Sheet<Real>& q, const Sheet<Real>& o, const std::vector<std::array<std::uint32_t, 4>>& candidates,
              const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_o) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2
  constexpr bool vectors = true;
#else
  constexpr bool vectors = false;
#endif
  constexpr std::size_t kChunk = FirstTests<Real>::kSize;
  const std::size_t lanes = vectors ? hn::Lanes(hn::ScalableTag<Real>()) : kChunk + 1;
  const bool dissipative = prm.friction > 0 || prm.damping > 0;
  const Real R2 = prm.range * prm.range;
  FirstTests<Real> t;
  RimTests<Real> r;
  std::size_t count = 0;
  auto flush = [&] {
    const std::size_t tested_end = count / lanes * lanes;
    if constexpr (vectors) {
      if (tested_end > 0) {
        force_lanes(prm, tested_end, t);
        if (dissipative) rim_dissipate_lanes(q, o, r, tested_end, prm, t);
      }
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::uint32_t u = r.edge[0][k], v = r.edge[1][k], p = r.edge[2][k], w = r.edge[3][k];
      if (k >= tested_end) {
        const EdgePair<Real> c{r.s[k], r.t[k], t.dist2[k], {t.unit[0][k], t.unit[1][k], t.unit[2][k]}};
        repel_edges(q, u, v, o, p, w, c, prm, on_q, on_o);
        continue;
      }
      if (!(t.dist2[k] > 0)) continue;  // the edges cross: no direction (repel_edges)
      const Real f = t.force[k];
      V3<Real> F{f * t.unit[0][k], f * t.unit[1][k], f * t.unit[2][k]};
      if (dissipative) F = {F.x + t.extra[0][k], F.y + t.extra[1][k], F.z + t.extra[2][k]};
      push_edges(u, v, p, w, r.s[k], r.t[k], F, on_q, on_o);
    }
    count = 0;
  };
  for (const auto& [u, v, p, w] : candidates) {
    EdgePair<Real> c;
    if (!(edges_passing(at(q, u), at(q, v), at(o, p), at(o, w), c) && c.dist2 < R2)) continue;
    r.edge[0][count] = u;
    r.edge[1][count] = v;
    r.edge[2][count] = p;
    r.edge[3][count] = w;
    r.s[count] = c.s;
    r.t[count] = c.t;
    t.dist2[count] = c.dist2;
    t.unit[0][count] = c.diff.x;
    t.unit[1][count] = c.diff.y;
    t.unit[2][count] = c.diff.z;
    if (++count == kChunk) flush();
  }
  flush();
}

// The entries [e0, e1) of `kept` (points of q against cells of s), in order: each walks
// from its cell to a local minimum of the distance (KeptContacts), which becomes its cell,
// and repels if within R. Self-contact (`ring` ≥ 0): cells within `ring` rows/columns of
// the point are never entered.
template <class Real>
void points_walking(const Sheet<Real>& q, const Sheet<Real>& s, int ring, KeptContacts& kept, std::size_t e0,
                    std::size_t e1, const ContactParams<Real>& prm, ContactForces<Real>& on_q,
                    ContactForces<Real>& on_s, std::uint32_t* last) {
  const std::uint32_t cols = s.topology->cols(), m = s.topology->m, n = s.topology->n;
  const std::uint32_t qcols = q.topology->cols();
  const Real R2 = prm.range * prm.range;
  // At most this many moves per substep: a point's nearest triangle rarely moves by more
  // than a cell in one, and the bound keeps a walk on a crumpled sheet short.
  constexpr int kMaxMoves = 8;
  // Each entry's first cell tested a vector of entries at a time (first_tests), a chunk
  // of the entries due ahead of their walks, where the CPU gathers in hardware (AVX2 and
  // AVX-512: the stacked sheets of BM_World48SheetsInContact 15-25 % faster); the due
  // entries after the last whole vector, and every entry elsewhere, one by one (test_cell:
  // SSE4 ran the stack 10 % slower with the vectors).
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2
  constexpr bool vectors = true;
#else
  constexpr bool vectors = false;
#endif
  FirstTests<Real> first;
  constexpr std::size_t kChunk = FirstTests<Real>::kSize;
  const bool dissipative = prm.friction > 0 || prm.damping > 0;
  const std::size_t lanes = vectors ? hn::Lanes(hn::ScalableTag<Real>()) : kChunk + 1;
  // An entry beyond R is walked again once the pair has travelled its slack (until): until
  // then no point of it can be within R, in the walk's view of the nearest triangle.
  const double travel = prm.travel;
  auto beyond = [&](std::size_t e, Real dist2) { kept.until[e] = skip_until(travel, double(dist2), double(prm.range)); };
  constexpr double kAlways = -std::numeric_limits<double>::infinity();
  if (kept.until.size() != kept.point.size()) kept.until.assign(kept.point.size(), kAlways);
  // The entries due, a chunk at a time: their indices, points and cells, contiguous.
  std::size_t due[kChunk];
  std::uint32_t due_point[kChunk], due_cell[kChunk];
  // The corners of the triangle the lanes found nearest for entry k at `cell`: triangle 0 of
  // the cell is (00, 01, 11), triangle 1 (00, 11, 10).
  auto corners_of = [&](std::size_t k, std::uint32_t cell, std::uint32_t (&tri)[3]) {
    const std::uint32_t p00 = cell, p01 = p00 + 1, p10 = p00 + cols, p11 = p10 + 1;
    const bool second = first.second[k] != 0;
    tri[0] = p00;
    tri[1] = second ? p11 : p01;
    tri[2] = second ? p10 : p11;
  };
  // That triangle (its corners' positions not read), as test_cell from an empty best finds it.
  auto tested_triangle = [&](std::size_t k, std::uint32_t cell, Nearest<Real>& best) {
    best.dist2 = first.dist2[k];
    best.key = 2 * cell + (first.second[k] != 0 ? 1 : 0);
    corners_of(k, cell, best.tri);
    best.w = {first.w[0][k], first.w[1][k], first.w[2][k]};
  };
  std::size_t next = e0;
  while (next < e1) {
    // The next chunk's entries due; those skipped have no triangle within R. Without a
    // branch on the skip (which half the entries of a settling stack take, unpredictably):
    // every entry is written at the chunk's end and counted only when due, and every
    // point's last cell cleared, which a due entry's walk below sets again.
    std::size_t count = 0;
    for (; next < e1 && count < kChunk; ++next) {
      const std::uint32_t p = kept.point[next];
      last[p] = kNoCell;
      due[count] = next;
      due_point[count] = p;
      due_cell[count] = kept.cell[next];
      count += !(travel < kept.until[next]);
    }
    // Whole vectors in lanes, the rest (and every entry without vectors) one by one.
    const std::size_t tested_end = count / lanes * lanes;
    if constexpr (vectors) {
      if (tested_end > 0) {
        first_tests(q, s, due_point, due_cell, tested_end, first);
        force_lanes(prm, tested_end, first);
        if (dissipative) dissipate_lanes(q, s, due_point, due_cell, tested_end, prm, first);
        push_lanes(prm, tested_end, dissipative, first);
      }
    }
    // Room for the pushes of the chunk's first tested_end entries, made in order: each pushes
    // at most its point to on_q and three corners to on_s (to on_q too in self-contact),
    // whether the lanes finish it or it walks, so the unchecked pushes below stay in it.
    on_q.reserve_more(4 * tested_end);
    on_s.reserve_more(3 * tested_end);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = due[k];
      const std::uint32_t p = due_point[k];
      std::uint32_t cell = due_cell[k];
      if (k < tested_end && first.ends[k] != 0) {  // the walk ends at its first cell: lanes did it all
        kept.until[e] = kAlways;
        if (first.dist2[k] < R2) {
          last[p] = cell;
          // push_repulsion's pushes, in its order and with its operations, from the force the
          // lanes computed as it does (push_lanes), into the room made for them
          const Real F[3] = {first.push[0][k], first.push[1][k], first.push[2][k]};
          on_q.push_unchecked(p, F[0], F[1], F[2]);
          std::uint32_t tri[3];
          corners_of(k, cell, tri);
          for (int w = 0; w < 3; ++w) {
            const Real weight = first.w[w][k];
            if (weight != 0) on_s.push_unchecked(tri[w], -weight * F[0], -weight * F[1], -weight * F[2]);
          }
        } else {
          last[p] = kNoCell;
          beyond(e, first.dist2[k]);
        }
        continue;
      }
      kept.until[e] = kAlways;
      const V3<Real> x = at(q, p);
      const std::int64_t pi = p / qcols, pj = p % qcols;
      auto allowed = [&](std::int64_t ci, std::int64_t cj) {
        if (ci < 0 || cj < 0 || ci >= std::int64_t(m) || cj >= std::int64_t(n)) return false;
        return ring < 0 || !(ci >= pi - ring && ci < pi + ring && cj >= pj - ring && cj < pj + ring);
      };
      Nearest<Real> best{};
      best.dist2 = std::numeric_limits<Real>::infinity();
      best.key = ~std::uint32_t(0);
      // The key of the triangle tested in lanes, whose force the lanes hold; best's corners
      // are not read for it.
      std::uint32_t lanes_key = ~std::uint32_t(0);
      if (k < tested_end) {
        if (first.dist2[k] == first.dist2[k]) {  // else not a number: no triangle (best stays empty)
          tested_triangle(k, cell, best);
          lanes_key = best.key;
        }
      } else {
        test_cell(s, cols, x, cell, best);
      }
      if (best.key == ~std::uint32_t(0)) {  // not a number: no triangle, no force
        last[p] = kNoCell;
        continue;
      }
      bool settled = false;  // the walk reached its local minimum within its moves
      for (int move = 0; move < kMaxMoves; ++move) {
        // The closest point's weights on the cell's corners 00, 01, 10, 11: triangle 0 is
        // (00, 01, 11), triangle 1 (00, 11, 10). Zero weight on a row's (column's) two
        // corners (within kWalkTie: a closest point within rounding of a corner is taken
        // there, and the corner's test decides) puts it on the opposite row (column) edge.
        Real w00 = best.w.x, w01, w10, w11;
        if (best.key & 1) {
          w01 = 0;
          w11 = best.w.y;
          w10 = best.w.z;
        } else {
          w01 = best.w.y;
          w11 = best.w.z;
          w10 = 0;
        }
        constexpr Real tie = kWalkTie<Real>;
        const int di = w10 + w11 <= tie ? -1 : (w00 + w01 <= tie ? 1 : 0);
        const int dj = w01 + w11 <= tie ? -1 : (w00 + w10 <= tie ? 1 : 0);
        if (di == 0 && dj == 0) {
          settled = true;
          break;
        }
        const std::int64_t ci = cell / cols, cj = cell % cols;
        // At a corner: no cell around it holds a nearer point (of the cells outside the grid
        // there are none to test; of those in the ring, the test asks more than it needs).
        if (di != 0 && dj != 0 && vertex_is_nearest(s, x, ci + (di > 0), cj + (dj > 0))) {
          settled = true;
          break;
        }
        const std::uint32_t key = best.key;
        auto corner = [&](std::int64_t i, std::int64_t j) { return std::uint32_t(i * cols + j); };
        if (di != 0 && allowed(ci + di, cj)) test_cell(s, cols, x, corner(ci + di, cj), best);
        if (dj != 0 && allowed(ci, cj + dj)) test_cell(s, cols, x, corner(ci, cj + dj), best);
        if (di != 0 && dj != 0 && allowed(ci + di, cj + dj)) test_cell(s, cols, x, corner(ci + di, cj + dj), best);
        if (best.key == key) {  // no neighbour holds a nearer triangle
          settled = true;
          break;
        }
        cell = best.key / 2;
      }
      kept.cell[e] = cell;
      if (best.dist2 < R2) {
        last[p] = cell;
        if (best.key == lanes_key && best.dist2 > 0) {  // the triangle the lanes tested: their force
          const V3<Real> unit{first.unit[0][k], first.unit[1][k], first.unit[2][k]};
          push_repulsion(p, best, unit, first.force[k], {first.extra[0][k], first.extra[1][k], first.extra[2][k]}, prm,
                         on_q, on_s);
        } else {  // moved, or on the triangle (its normal): the scalar force, from the corners
          if (best.key == lanes_key)
            for (int c = 0; c < 3; ++c) best.v[c] = at(s, best.tri[c]);
          repel(q, p, x, s, best, prm, on_q, on_s);
        }
      } else {
        last[p] = kNoCell;
        if (settled) beyond(e, best.dist2);
      }
    }
  }
}

}  // namespace

// The entry points HWY_EXPORT names, one per precision: a direction of a pair each.
#define DRAPE_CONTACTS_ENTRIES(Suffix, Real)                                                                         \
  void PointsAgainstCells##Suffix(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,            \
                                  const SheetBoxes<Real>& bs, int ring, const ContactParams<Real>& prm,              \
                                  ContactForces<Real>& on_q, ContactForces<Real>& on_s, ContactScratch<Real>& sc,    \
                                  std::uint32_t* last, Candidates* lists, Real skin, KeptContacts* kept,             \
                                  KeptContacts* before, std::uint32_t block_from, std::uint32_t block_to) {          \
    points_against_cells(q, bq, s, bs, ring, prm, on_q, on_s, sc, last, lists, skin, kept, before, block_from,       \
                         block_to);                                                                                  \
  }                                                                                                                  \
  void PointsAgainstLists##Suffix(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,            \
                                  const SheetBoxes<Real>& bs, const Candidates& lists,                               \
                                  const ContactParams<Real>& prm, ContactForces<Real>& on_q,                         \
                                  ContactForces<Real>& on_s, ContactScratch<Real>& sc, std::uint32_t* last) {        \
    points_against_lists(q, bq, s, bs, lists, prm, on_q, on_s, sc, last);                                            \
  }                                                                                                                  \
  void PointsWalking##Suffix(const Sheet<Real>& q, const Sheet<Real>& s, int ring, KeptContacts& kept,              \
                             std::size_t e0, std::size_t e1, const ContactParams<Real>& prm,                         \
                             ContactForces<Real>& on_q, ContactForces<Real>& on_s, std::uint32_t* last) {            \
    points_walking(q, s, ring, kept, e0, e1, prm, on_q, on_s, last);                                                 \
  }                                                                                                                  \
  void RimContacts##Suffix(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b,                   \
                          const SheetBoxes<Real>& bb, const ContactParams<Real>& prm, PairContacts<Real>& work,      \
                          ContactScratch<Real>& sc) {                                                                \
    rims_of_pair(a, ba, b, bb, prm, work, sc);                                                                       \
  }                                                                                                                  \
  double RimEnergy##Suffix(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b,                   \
                           const SheetBoxes<Real>& bb, const ContactParams<Real>& prm) {                             \
    return rims_energy(a, ba, b, bb, prm);                                                                           \
  }                                                                                                                  \
  double ContactEnergy##Suffix(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,               \
                               const SheetBoxes<Real>& bs, int ring, const ContactParams<Real>& prm) {               \
    return contact_energy(q, bq, s, bs, ring, prm);                                                                  \
  }
DRAPE_CONTACTS_ENTRIES(F64, double)
DRAPE_CONTACTS_ENTRIES(F32, float)
#undef DRAPE_CONTACTS_ENTRIES

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace drape::detail {

template <class Real>
ContactParams<Real> ContactParams<Real>::make(double thickness, double xi, double strength, double range_in_xi) {
  ContactParams p;
  p.thickness = static_cast<Real>(thickness);
  p.xi = static_cast<Real>(xi);
  p.strength = static_cast<Real>(strength);
  p.range = static_cast<Real>(thickness + range_in_xi * xi);
  p.tail = static_cast<Real>(std::exp(-range_in_xi));
  p.skin = static_cast<Real>(0.25 * (thickness + range_in_xi * xi));
  return p;
}

HWY_EXPORT(PointsAgainstCellsF64);
HWY_EXPORT(PointsAgainstCellsF32);
HWY_EXPORT(PointsAgainstListsF64);
HWY_EXPORT(PointsAgainstListsF32);
HWY_EXPORT(PointsWalkingF64);
HWY_EXPORT(PointsWalkingF32);
HWY_EXPORT(ContactEnergyF64);
HWY_EXPORT(ContactEnergyF32);
HWY_EXPORT(RimContactsF64);
HWY_EXPORT(RimContactsF32);
HWY_EXPORT(RimEnergyF64);
HWY_EXPORT(RimEnergyF32);

namespace {

// The outputs of a search of q's `blocks` blocks, emptied: lists, and the kept set with
// every block open and none holding entries yet.
inline void start_search(std::size_t points, std::size_t blocks, Candidates* lists, KeptContacts* kept) {
  if (lists) {
    lists->begin.assign(points, 0);
    lists->count.assign(points, 0);
    lists->cell.clear();
  }
  if (kept) {
    kept->clear();
    kept->open.assign(blocks, 1);
    kept->block_begin.assign(blocks + 1, 0);
  }
}

// The per-target search (above) on the widest target the CPU has, of q's blocks
// [block_from, block_to) into outputs start_search emptied: see its definitions.
template <class Real>
void search_blocks(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s, const SheetBoxes<Real>& bs,
                   int ring, const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_s,
                   ContactScratch<Real>& sc, std::uint32_t* last, Candidates* lists, Real skin, KeptContacts* kept,
                   KeptContacts* before, std::uint32_t block_from, std::uint32_t block_to) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(PointsAgainstCellsF64)(q, bq, s, bs, ring, prm, on_q, on_s, sc, last, lists, skin, kept, before,
                                                block_from, block_to);
  else
    HWY_DYNAMIC_DISPATCH(PointsAgainstCellsF32)(q, bq, s, bs, ring, prm, on_q, on_s, sc, last, lists, skin, kept, before,
                                                block_from, block_to);
}

// Every block of q (search_blocks), its outputs emptied first.
template <class Real>
void points_against_cells(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,
                          const SheetBoxes<Real>& bs, int ring, const ContactParams<Real>& prm,
                          ContactForces<Real>& on_q, ContactForces<Real>& on_s, ContactScratch<Real>& sc,
                          std::uint32_t* last, Candidates* lists = nullptr, Real skin = 0,
                          KeptContacts* kept = nullptr, KeptContacts* before = nullptr) {
  const std::uint32_t blocks = bq.patch_rows * bq.patch_cols;
  start_search(q.size(), blocks, lists, kept);
  search_blocks(q, bq, s, bs, ring, prm, on_q, on_s, sc, last, lists, skin, kept, before, 0, blocks);
}

template <class Real>
void points_against_lists(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s,
                          const SheetBoxes<Real>& bs, const Candidates& lists, const ContactParams<Real>& prm,
                          ContactForces<Real>& on_q, ContactForces<Real>& on_s, ContactScratch<Real>& sc,
                          std::uint32_t* last) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(PointsAgainstListsF64)(q, bq, s, bs, lists, prm, on_q, on_s, sc, last);
  else
    HWY_DYNAMIC_DISPATCH(PointsAgainstListsF32)(q, bq, s, bs, lists, prm, on_q, on_s, sc, last);
}

template <class Real>
void points_walking(const Sheet<Real>& q, const Sheet<Real>& s, int ring, KeptContacts& kept, std::size_t e0,
                    std::size_t e1, const ContactParams<Real>& prm, ContactForces<Real>& on_q,
                    ContactForces<Real>& on_s, std::uint32_t* last) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(PointsWalkingF64)(q, s, ring, kept, e0, e1, prm, on_q, on_s, last);
  else
    HWY_DYNAMIC_DISPATCH(PointsWalkingF32)(q, s, ring, kept, e0, e1, prm, on_q, on_s, last);
}

// Whether no point of s has moved farther than √limit2 from `then`: blocks of points, each
// a vectorised maximum, stopping at the first block that has.
template <class Real>
bool within(const Sheet<Real>& s, const Vec3Array<Real>& then, Real limit2) {
  const Real *x = s.position.x.data(), *y = s.position.y.data(), *z = s.position.z.data();
  const Real *tx = then.x.data(), *ty = then.y.data(), *tz = then.z.data();
  constexpr std::size_t block = 512;
  for (std::size_t p0 = 0; p0 < s.size(); p0 += block) {
    const std::size_t p1 = std::min(s.size(), p0 + block);
    Real most = 0;
#pragma omp simd reduction(max : most)
    for (std::size_t p = p0; p < p1; ++p) {
      const Real dx = x[p] - tx[p], dy = y[p] - ty[p], dz = z[p] - tz[p];
      most = std::max(most, dx * dx + dy * dy + dz * dz);
    }
    if (!(most <= limit2)) return false;
  }
  return true;
}

// How the points of each patch of s moved since `then`: per patch, the centre of the box
// of its points' displacements and that box's half-diagonal, which no displacement is
// farther from the centre than (rows and columns 8p … 8p + 8, as their boxes). A patch row
// at a time: its point rows are folded into per-column extremes along whole rows, the
// three axes in one vector pass (omp simd: GCC left the per-axis loops scalar), then each
// patch takes the extremes of its 9 columns.
template <class Real>
void patch_motion(const Sheet<Real>& s, const Vec3Array<Real>& then, std::vector<Real> (&mid)[3],
                  std::vector<Real>& radius, ContactScratch<Real>& sc) {
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  const std::uint32_t m = s.topology->m, n = s.topology->n;
  const std::uint32_t patch_rows = SheetBoxes<Real>::patches_along(m), patch_cols = SheetBoxes<Real>::patches_along(n);
  const std::uint32_t cols = n + 1, patches = patch_rows * patch_cols;
  for (int k = 0; k < 3; ++k) mid[k].resize(patches);
  radius.resize(patches);
  const Real* now[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  const Real* old[3] = {then.x.data(), then.y.data(), then.z.data()};
  for (int k = 0; k < 3; ++k) {
    sc.column_lo[k].resize(cols);
    sc.column_hi[k].resize(cols);
  }
  sc.column_nan.resize(cols);
  Real* __restrict nan = sc.column_nan.data();  // NaN where a displacement is (not a number, or infinite)
  Real* __restrict lo_x = sc.column_lo[0].data();
  Real* __restrict lo_y = sc.column_lo[1].data();
  Real* __restrict lo_z = sc.column_lo[2].data();
  Real* __restrict hi_x = sc.column_hi[0].data();
  Real* __restrict hi_y = sc.column_hi[1].data();
  Real* __restrict hi_z = sc.column_hi[2].data();
  constexpr Real inf = std::numeric_limits<Real>::infinity();
  for (std::uint32_t pi = 0; pi < patch_rows; ++pi) {
    const std::uint32_t i0 = pi * P, i1 = std::min(i0 + P, m);
    std::fill(nan, nan + cols, Real(0));
    std::fill(lo_x, lo_x + cols, inf);
    std::fill(lo_y, lo_y + cols, inf);
    std::fill(lo_z, lo_z + cols, inf);
    std::fill(hi_x, hi_x + cols, -inf);
    std::fill(hi_y, hi_y + cols, -inf);
    std::fill(hi_z, hi_z + cols, -inf);
    for (std::uint32_t i = i0; i <= i1; ++i) {
      const std::size_t r = std::size_t(i) * cols;
      const Real* __restrict ax = now[0] + r;
      const Real* __restrict ay = now[1] + r;
      const Real* __restrict az = now[2] + r;
      const Real* __restrict bx = old[0] + r;
      const Real* __restrict by = old[1] + r;
      const Real* __restrict bz = old[2] + r;
#pragma omp simd
      for (std::uint32_t j = 0; j < cols; ++j) {
        const Real dx = ax[j] - bx[j], dy = ay[j] - by[j], dz = az[j] - bz[j];
        lo_x[j] = dx < lo_x[j] ? dx : lo_x[j];  // a NaN is lost here, but not in `nan`
        lo_y[j] = dy < lo_y[j] ? dy : lo_y[j];
        lo_z[j] = dz < lo_z[j] ? dz : lo_z[j];
        hi_x[j] = dx > hi_x[j] ? dx : hi_x[j];
        hi_y[j] = dy > hi_y[j] ? dy : hi_y[j];
        hi_z[j] = dz > hi_z[j] ? dz : hi_z[j];
        nan[j] = ((nan[j] + dx * Real(0)) + dy * Real(0)) + dz * Real(0);
      }
    }
    for (std::uint32_t pj = 0; pj < patch_cols; ++pj) {
      const std::uint32_t j0 = pj * P, j1 = std::min(j0 + P, n);
      const std::uint32_t patch = pi * patch_cols + pj;
      Real r2 = 0, bad = 0;
      for (std::uint32_t j = j0; j <= j1; ++j) bad += nan[j];
      for (int k = 0; k < 3; ++k) {
        const Real* lo = sc.column_lo[k].data();
        const Real* hi = sc.column_hi[k].data();
        Real l = lo[j0], h = hi[j0];
        for (std::uint32_t j = j0 + 1; j <= j1; ++j) {
          l = lo[j] < l ? lo[j] : l;
          h = hi[j] > h ? hi[j] : h;
        }
        mid[k][patch] = Real(0.5) * (l + h);
        r2 += Real(0.25) * (h - l) * (h - l);
      }
      radius[patch] = std::sqrt(r2) + bad;  // NaN fails the check
    }
  }
}

// The gap between every patch box of a and every patch box of b, at row a·patches(b) + b.
template <class Real>
void patch_clearance(const SheetBoxes<Real>& ba, const SheetBoxes<Real>& bb, std::vector<Real>& clearance) {
  const std::uint32_t pa = ba.patch_rows * ba.patch_cols, pb = bb.patch_rows * bb.patch_cols;
  clearance.resize(std::size_t(pa) * pb);
  for (std::uint32_t A = 0; A < pa; ++A)
    for (std::uint32_t B = 0; B < pb; ++B) {
      Real g2 = 0;
      for (int k = 0; k < 3; ++k) {
        const Real e = positive_part(bb.patch_lo[k][B] - ba.patch_hi[k][A]) +
                       positive_part(ba.patch_lo[k][A] - bb.patch_hi[k][B]);
        g2 += e * e;
      }
      clearance[std::size_t(A) * pb + B] = std::sqrt(g2);
    }
}

// The test of every patch pair below in O(patches), enough when the sheets moved nearly
// together: through the middle m of all patch middles, |mid_A − mid_B| ≤ |mid_A − m| +
// |mid_B − m|, so a pair's drift is at most e_A + e_B with e = spread + |mid − m|, and its
// slack is at least the skin. Holds if the largest e over patches that need the test plus
// the largest over all patches of the other sheet is within `limit` (both ways round);
// open_a/open_b null: every patch needs it. False for a NaN.
template <class Real>
bool patches_within_skin(ContactScratch<Real>& sc, std::uint32_t pa, std::uint32_t pb, bool self,
                         const std::uint8_t* open_a, const std::uint8_t* open_b, Real limit) {
  const auto& mid_b = self ? sc.mid_a : sc.mid_b;
  const auto& radius_b = self ? sc.radius_a : sc.radius_b;
  Real lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    const auto [a0, a1] = std::minmax_element(sc.mid_a[k].begin(), sc.mid_a[k].begin() + pa);
    const auto [b0, b1] = std::minmax_element(mid_b[k].begin(), mid_b[k].begin() + pb);
    lo[k] = std::min(*a0, *b0);
    hi[k] = std::max(*a1, *b1);
  }
  const Real m[3] = {Real(0.5) * (lo[0] + hi[0]), Real(0.5) * (lo[1] + hi[1]), Real(0.5) * (lo[2] + hi[2])};
  // Largest e over all patches and over those needing the test, for each sheet.
  auto largest = [&](const std::vector<Real>(&mid)[3], const std::vector<Real>& radius, std::uint32_t count,
                     const std::uint8_t* open, Real& all, Real& needing) {
    all = needing = 0;
    for (std::uint32_t P = 0; P < count; ++P) {
      const Real dx = mid[0][P] - m[0], dy = mid[1][P] - m[1], dz = mid[2][P] - m[2];
      const Real e = radius[P] + std::sqrt(dx * dx + dy * dy + dz * dz);
      if (!(e <= all)) all = e;  // a NaN sticks
      if ((!open || open[P]) && !(e <= needing)) needing = e;
    }
  };
  Real all_a, need_a, all_b, need_b;
  largest(sc.mid_a, sc.radius_a, pa, open_a, all_a, need_a);
  largest(mid_b, radius_b, pb, open_b, all_b, need_b);
  return need_a + all_b <= limit && all_a + need_b <= limit;
}

// Whether the lists or set kept in `w` were made for these sheets, in this mode.
template <class Real>
bool made_for(const PairContacts<Real>& w, const Sheet<Real>& a, const Sheet<Real>& b, bool exact) {
  return w.kept_exact == exact && w.kept_a == &a && w.kept_b == &b && w.kept_topology_a == a.topology.get() &&
         w.kept_topology_b == b.topology.get() && w.made_at_a.size() == a.size() && w.made_at_b.size() == b.size();
}

// Substeps a kept contact set with entries serves at most since every block was searched:
// then the search runs again over all, and a walk that stopped at a local minimum
// (KeptContacts) finds the nearest triangle again.
constexpr std::uint32_t kKeptLife = 64;

// Whether the lists kept in `w` were made for these sheets and still hold every cell
// within R of every point (PairContacts): no point moved more than 0.45·skin, or, for
// every patch A of a and B of b, the most a
// point of one can have come nearer to a cell of the other (A's and B's spreads of
// displacement plus the difference of their middles) stays within 0.9 of the slack the
// lists had: the skin, or the patches' gap then less R if that is more.
template <class Real>
bool lists_hold(PairContacts<Real>& w, const Sheet<Real>& a, const Sheet<Real>& b, const ContactParams<Real>& prm,
                ContactScratch<Real>& sc) {
  if (!made_for(w, a, b, prm.exact)) return false;
  if (!prm.exact) {
    if (w.since_full >= kKeptLife && !(w.a_on_b.point.empty() && w.b_on_a.point.empty())) return false;
    // Every point of both sheets in the set: nothing can come into range unseen.
    const auto closed = [](const KeptContacts& k) {
      return std::none_of(k.open.begin(), k.open.end(), [](std::uint8_t o) { return o != 0; });
    };
    if (closed(w.a_on_b) && (&a == &b || closed(w.b_on_a)) && !w.a_on_b.open.empty()) {
      ++w.kept_for;
      return true;
    }
  }
  // No point moved more than 0.45·skin: no gap shrank by more than 0.9·skin (cheap, and
  // enough for a pair at rest); otherwise the patches' relative motion decides.
  const Real limit = Real(0.45) * w.skin, limit2 = limit * limit;
  const auto still = [&](const Sheet<Real>& s, double lo, const Vec3Array<Real>& then) {
    // the sheet's travel since the lists were made bounds every point's move (measure_travel)
    if (measured_in(s, prm.stamp) && s.moved_hi() - lo <= double(limit)) return true;
    return within(s, then, limit2);
  };
  if (still(a, w.moved_lo_a, w.made_at_a.get()) && (&a == &b || still(b, w.moved_lo_b, w.made_at_b.get()))) {
    ++w.kept_for;
    return true;
  }
  patch_motion(a, w.made_at_a.get(), sc.mid_a, sc.radius_a, sc);
  if (&a != &b) patch_motion(b, w.made_at_b.get(), sc.mid_b, sc.radius_b, sc);
  const auto& mid_b = &a != &b ? sc.mid_b : sc.mid_a;
  const auto& radius_b = &a != &b ? sc.radius_b : sc.radius_a;
  const auto patches = [](const Sheet<Real>& s) {
    return SheetBoxes<Real>::patches_along(s.topology->m) * SheetBoxes<Real>::patches_along(s.topology->n);
  };
  const std::uint32_t pa = patches(a), pb = patches(b);
  if (w.clearance.size() != std::size_t(pa) * pb) return false;
  // A kept contact set needs this only where a patch has points outside it: points of A
  // against cells of B if A is open, points of B against cells of A if B is.
  const bool sets = !prm.exact;
  if (sets && (w.a_on_b.open.size() != pa || (&a != &b && w.b_on_a.open.size() != pb))) return false;
  const std::uint8_t* open_a = sets ? w.a_on_b.open.data() : nullptr;
  const std::uint8_t* open_b = sets ? (&a != &b ? w.b_on_a.open.data() : open_a) : nullptr;
  if (patches_within_skin(sc, pa, pb, &a == &b, open_a, open_b, Real(0.9) * w.skin)) {
    ++w.kept_for;
    return true;
  }
  bool hold = true;
  for (std::uint32_t A = 0; A < pa && hold; ++A) {
    const Real* clear = w.clearance.data() + std::size_t(A) * pb;
    unsigned ok = 1;
    for (std::uint32_t B = 0; B < pb; ++B) {
      if (sets && !(open_a[A] | open_b[B])) continue;
      const Real dx = sc.mid_a[0][A] - mid_b[0][B], dy = sc.mid_a[1][A] - mid_b[1][B],
                 dz = sc.mid_a[2][A] - mid_b[2][B];
      const Real drift = sc.radius_a[A] + radius_b[B] + std::sqrt(dx * dx + dy * dy + dz * dz);
      const Real slack = std::max(w.skin, clear[B] - prm.range);
      ok &= unsigned(drift <= Real(0.9) * slack);  // false for NaN
    }
    hold = ok != 0;
  }
  w.kept_for += hold;
  return hold;
}

// The skin for lists about to be made: R/4 at first, then following how long the last
// lists served (PairContacts).
template <class Real>
Real next_skin(const PairContacts<Real>& w, const ContactParams<Real>& prm) {
  if (!(w.skin > 0)) return prm.skin;
  // Exact lists grow with the skin and are read every substep, so lists that serve long
  // narrow it; a kept contact set costs one entry per point within R + skin, but one beyond
  // R only walks (and mostly skips its walk), so its skin never narrows below R/2 (from the
  // first R/4, a widening): narrower, a settling stack searched again nearly every substep
  // and ran slower; and it widens up to 2R: at R, the settling stack's pairs three and more
  // layers apart searched again every four substeps or so, finding nothing (their sheets'
  // patches sag past each other faster than R allows; BM_World48SheetsSettling, the
  // figures in the commits that set the floor and the ceiling).
  if (w.kept_for == 0 || (prm.exact && w.kept_for > 32))
    return std::max(w.skin / 2, prm.exact ? prm.range / 16 : prm.range / 2);
  if (w.kept_for < 4) return std::min(w.skin * 2, prm.exact ? prm.range / 2 : 2 * prm.range);
  return w.skin;
}

template <class Real>
void remember(Vec3Array<Real>& to, const Sheet<Real>& s) {
  to.x.assign(s.position.x.begin(), s.position.x.end());
  to.y.assign(s.position.y.begin(), s.position.y.end());
  to.z.assign(s.position.z.begin(), s.position.z.end());
}

template <class Real>
void keep_lists_for(PairContacts<Real>& w, const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b,
                    const SheetBoxes<Real>& bb, Real skin, const ContactParams<Real>& prm) {
  const bool exact = prm.exact;
  const auto lo = [&](const Sheet<Real>& s) {
    return measured_in(s, prm.stamp) ? s.moved_lo() : -std::numeric_limits<double>::infinity();
  };
  w.moved_lo_a = lo(a);
  w.moved_lo_b = lo(b);
  patch_clearance(ba, bb, w.clearance);
  w.kept_exact = exact;
  w.skin = skin;
  w.kept_for = 0;
  w.kept_a = &a;
  w.kept_b = &b;
  w.kept_topology_a = a.topology.get();
  w.kept_topology_b = b.topology.get();
  remember(w.made_at_a.to_write(), a);
  remember(w.made_at_b.to_write(), b);
  ++w.searches;
}

}  // namespace

template <class Real>
void build_boxes(const Sheet<Real>& s, SheetBoxes<Real>& out) {
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch, kPad = P;
  const auto& t = *s.topology;
  const std::uint32_t m = t.m, n = t.n, cols = t.cols();
  out.m = m;
  out.n = n;
  out.patch_rows = std::max<std::uint32_t>(1, (m + P - 1) / P);
  out.patch_cols = std::max<std::uint32_t>(1, (n + P - 1) / P);
  const std::size_t patches = std::size_t(out.patch_rows) * out.patch_cols;
  const auto& X = s.position;
  const Real* axis[3] = {X.x.data(), X.y.data(), X.z.data()};
  for (int k = 0; k < 3; ++k) {
    out.cell_lo[k].resize(s.size() + kPad);  // a strip's 8 boxes are read whole
    out.cell_hi[k].resize(s.size() + kPad);
    out.patch_lo[k].assign(patches, std::numeric_limits<Real>::infinity());
    out.patch_hi[k].assign(patches, -std::numeric_limits<Real>::infinity());
    out.strip_lo[k].resize(std::size_t(m) * out.patch_cols);
    out.strip_hi[k].resize(std::size_t(m) * out.patch_cols);
  }
  // Cell boxes, a row of cells at a time from two rows of points (the widest vectors).
  for (std::uint32_t i = 0; i < m; ++i)
    for (int k = 0; k < 3; ++k) {
      const Real* a = axis[k] + std::size_t(i) * cols;
      simd::cell_boxes(simd::CellRow<Real>{n, a, a + cols, out.cell_lo[k].data() + std::size_t(i) * cols,
                                           out.cell_hi[k].data() + std::size_t(i) * cols});
    }
  // Strip boxes from their cells' boxes.
  for (std::uint32_t i = 0; i < m; ++i)
    for (std::uint32_t pj = 0; pj < out.patch_cols; ++pj)
      for (int k = 0; k < 3; ++k) {
        const std::size_t c0 = std::size_t(i) * cols + pj * P, c1 = std::size_t(i) * cols + std::min(pj * P + P, n);
        Real lo = out.cell_lo[k][c0], hi = out.cell_hi[k][c0];
        for (std::size_t c = c0 + 1; c < c1; ++c) {
          lo = std::min(lo, out.cell_lo[k][c]);
          hi = std::max(hi, out.cell_hi[k][c]);
        }
        out.strip_lo[k][std::size_t(i) * out.patch_cols + pj] = lo;
        out.strip_hi[k][std::size_t(i) * out.patch_cols + pj] = hi;
      }
  // Patch boxes over their points: rows [8pi, 8pi + 8] (to the last row in the last patch
  // row), the same for columns. With cells, the union of the patch's strips (whose cells
  // have exactly those corners); a line of points, from the points.
  for (std::uint32_t pi = 0; pi < out.patch_rows; ++pi) {
    const std::uint32_t i0 = pi * P, i1 = std::min(i0 + P, m);
    for (std::uint32_t pj = 0; pj < out.patch_cols; ++pj) {
      const std::uint32_t j0 = pj * P, j1 = std::min(j0 + P, n);
      Aabb box = empty_box();
      if (m > 0 && n > 0) {
        for (int k = 0; k < 3; ++k) {
          Real lo = std::numeric_limits<Real>::infinity(), hi = -lo;
          for (std::uint32_t i = i0; i < i1; ++i) {
            lo = std::min(lo, out.strip_lo[k][std::size_t(i) * out.patch_cols + pj]);
            hi = std::max(hi, out.strip_hi[k][std::size_t(i) * out.patch_cols + pj]);
          }
          box.lo[k] = lo;
          box.hi[k] = hi;
        }
      } else {
        for (std::uint32_t i = i0; i <= i1; ++i) {
          const std::size_t p0 = std::size_t(i) * cols + j0;
          include_points(box, axis[0] + p0, axis[1] + p0, axis[2] + p0, j1 - j0 + 1);
        }
      }
      const std::size_t patch = std::size_t(pi) * out.patch_cols + pj;
      for (int k = 0; k < 3; ++k) {
        out.patch_lo[k][patch] = static_cast<Real>(box.lo[k]);
        out.patch_hi[k][patch] = static_cast<Real>(box.hi[k]);
      }
      if (pi == 0 && pj == 0) out.box = box;
      else include_box(out.box, box);
    }
  }
}

namespace {

// Substeps a pair searches without lists after lists at the narrowest skin did not outlive
// their substep: making them costs more than it saves while the sheets move that fast.
constexpr std::uint32_t kListRest = 16;

// Kept sets smaller than this (both directions; for a search, points of both sheets) walk or
// are searched in one piece: splitting and appending would cost more than the second
// thread saves.
constexpr std::size_t kPartsFrom = 2048;

// The forces of a pair's parts (walk_in_parts, search_in_parts: `per` parts a direction)
// appended to the pair's, in the order one pass of both directions pushes them: the
// points' forces of a's points, then b's, each direction's parts in order.
template <class Real>
struct PartForces {
  ContactForces<Real>& on_q;  // on the points' sheet
  ContactForces<Real>& on_s;  // on the cells' (the same buffer for a sheet with itself)
};

// Part k's forces (walk_in_parts, search_in_parts), emptied.
template <class Real>
PartForces<Real> part_forces(PairContacts<Real>& w, std::size_t k, bool self) {
  ContactForces<Real>& on_q = w.part_on_q[k];
  ContactForces<Real>& on_s = self ? on_q : w.part_on_s[k];
  on_q.clear();
  on_s.clear();
  return {on_q, on_s};
}

template <class Real>
void append_parts(PairContacts<Real>& w, std::size_t per, bool self) {
  ContactForces<Real>& on_b = self ? w.on_a : w.on_b;
  for (std::size_t k = 0; k < (self ? 1 : 2) * per; ++k) {
    const bool back = k >= per;
    (back ? on_b : w.on_a).append(w.part_on_q[k]);
    if (!self) (back ? w.on_a : on_b).append(w.part_on_s[k]);
  }
}

// The parts of a pair (walk_in_parts, search_in_parts) as tasks. The thread that waits for
// them takes no other task meanwhile (isolate): another pair's, run on this thread, would
// take this thread's scratch (ContactScratch, one per thread) while the first part still
// uses it.
template <class Body>
void in_parts(std::size_t count, Body&& body) {
  tbb::this_task_arena::isolate([&] { tbb::parallel_for(std::size_t(0), count, body); });
}

// A pair's kept sets walked (points_walking) in prm.parts parts per direction, as tasks, each
// into its own forces, which are then appended in the order one walk of both directions
// pushes them: every entry belongs to one part and its point to one entry, so the parts
// share nothing they write, and the forces are the same, bit for bit.
template <class Real>
void walk_in_parts(const Sheet<Real>& a, const Sheet<Real>& b, int ring, const ContactParams<Real>& prm,
                   PairContacts<Real>& w) {
  const bool self = &a == &b;
  const std::size_t per = std::size_t(prm.parts), count = (self ? 1 : 2) * per;
  w.part_on_q.resize(count);
  w.part_on_s.resize(count);
  in_parts(count, [&](std::size_t k) {
    const bool back = k >= per;  // b's points against a's cells
    KeptContacts& kept = back ? w.b_on_a : w.a_on_b;
    const std::size_t part = k % per, size = kept.point.size();
    const PartForces<Real> on = part_forces(w, k, self);
    points_walking(back ? b : a, back ? a : b, ring, kept, size * part / per, size * (part + 1) / per, prm, on.on_q,
                   on.on_s, back ? w.last_b.data() : w.last_a.data());
  });
  append_parts(w, per, self);
}

// A pair's search for its kept sets (search_blocks, with `before` the sets so far in a
// partial search) in prm.parts parts per direction, as tasks: each part a range of the
// query sheet's blocks, into its own forces, kept set and scratch (the first part the
// pair's, `sc`), then the forces appended as append_parts does and each direction's
// kept set made of its parts' in block order (block_begin shifted by the entries before).
// A block's points are its own, so the parts write nothing in common, and the forces and
// sets are those of one search, bit for bit.
template <class Real>
void search_in_parts(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b,
                     const SheetBoxes<Real>& bb, int ring, const ContactParams<Real>& prm, Real skin, bool partial,
                     PairContacts<Real>& w, ContactScratch<Real>& sc) {
  const bool self = &a == &b;
  const std::size_t per = std::size_t(prm.parts), count = (self ? 1 : 2) * per;
  w.part_on_q.resize(count);
  w.part_on_s.resize(count);
  w.part_kept.resize(count);
  w.part_scratch.resize(count - 1);
  auto blocks_of = [](const SheetBoxes<Real>& bq) { return bq.patch_rows * bq.patch_cols; };
  in_parts(count, [&](std::size_t k) {
    const bool back = k >= per;  // b's points against a's cells
    const Sheet<Real>& q = back ? b : a;
    const SheetBoxes<Real>& bq = back ? bb : ba;
    const std::size_t part = k % per, blocks = blocks_of(bq);
    const PartForces<Real> on = part_forces(w, k, self);
    start_search(q.size(), blocks, nullptr, &w.part_kept[k]);
    search_blocks(q, bq, back ? a : b, back ? ba : bb, ring, prm, on.on_q, on.on_s, k == 0 ? sc : w.part_scratch[k - 1],
                  back ? w.last_b.data() : w.last_a.data(), nullptr, skin, &w.part_kept[k],
                  partial ? (back ? &w.b_on_a : &w.a_on_b) : nullptr, std::uint32_t(blocks * part / per),
                  std::uint32_t(blocks * (part + 1) / per));
  });
  append_parts(w, per, self);
  for (std::size_t direction = 0; direction < (self ? 1u : 2u); ++direction) {
    KeptContacts& kept = direction == 0 ? w.spare_a : w.spare_b;
    const std::size_t blocks = blocks_of(direction == 0 ? ba : bb);
    start_search(0, blocks, nullptr, &kept);
    for (std::size_t part = 0; part < per; ++part) {
      const KeptContacts& from = w.part_kept[direction * per + part];
      const std::uint32_t before = std::uint32_t(kept.point.size());
      for (std::size_t block = blocks * part / per; block < blocks * (part + 1) / per; ++block) {
        kept.block_begin[block] = before + from.block_begin[block];
        kept.open[block] = from.open[block];
      }
      kept.point.insert(kept.point.end(), from.point.begin(), from.point.end());
      kept.cell.insert(kept.cell.end(), from.cell.begin(), from.cell.end());
      kept.until.insert(kept.until.end(), from.until.begin(), from.until.end());
    }
    kept.block_begin[blocks] = std::uint32_t(kept.point.size());
  }
}

// Both directions of a pair (one for a sheet with itself, `ring` ≥ 0): through the kept
// lists while they hold, else a search that makes new ones, or, while the pair rests from
// lists that did not outlive a substep at the narrowest skin, a search that makes none.
template <class Real>
void contacts_of_pair(const Sheet<Real>& a, const SheetBoxes<Real>& ba, const Sheet<Real>& b,
                      const SheetBoxes<Real>& bb, int ring, const ContactParams<Real>& prm, PairContacts<Real>& w,
                      ContactScratch<Real>& sc) {
  const bool self = &a == &b;
  w.on_a.clear();
  w.on_b.clear();
  ContactForces<Real>& on_b = self ? w.on_a : w.on_b;
  ContactParams<Real> pair = prm;
  pair.friction = static_cast<Real>(std::max(a.friction, b.friction));
  if (w.guessed_a != a.topology.get() || w.guessed_b != b.topology.get() || w.last_a.size() != a.size() ||
      w.last_b.size() != b.size()) {  // guesses only for the grids they were made on
    w.last_a.assign(a.size(), kNoCell);
    w.last_b.assign(b.size(), kNoCell);
    w.guessed_a = a.topology.get();
    w.guessed_b = b.topology.get();
  }
  const bool hold = w.decided >= 0 ? w.decided != 0 : w.resting == 0 && lists_hold(w, a, b, prm, sc);
  w.decided = -1;
  if (hold) {
    ++w.since_full;
    if (prm.exact) {
      points_against_lists(a, ba, b, bb, w.a_near_b, pair, w.on_a, on_b, sc, w.last_a.data());
      if (!self) points_against_lists(b, bb, a, ba, w.b_near_a, pair, on_b, w.on_a, sc, w.last_b.data());
    } else if (pair.parts > 1 && w.a_on_b.point.size() + w.b_on_a.point.size() >= kPartsFrom) {
      walk_in_parts(a, b, ring, pair, w);
    } else {
      points_walking(a, b, ring, w.a_on_b, 0, w.a_on_b.point.size(), pair, w.on_a, on_b, w.last_a.data());
      if (!self) points_walking(b, a, ring, w.b_on_a, 0, w.b_on_a.point.size(), pair, on_b, w.on_a, w.last_b.data());
    }
    return;
  }
  if (prm.exact && w.resting == 0 && w.kept_a && w.kept_for == 0 && w.skin <= prm.range / 16) w.resting = kListRest;
  if (w.resting > 0) {
    --w.resting;
    w.kept_a = w.kept_b = nullptr;
    w.skin = 0;  // lists start again at the first skin
    points_against_cells(a, ba, b, bb, ring, pair, w.on_a, on_b, sc, w.last_a.data());
    if (!self) points_against_cells(b, bb, a, ba, ring, pair, on_b, w.on_a, sc, w.last_b.data());
    return;
  }
  // A kept contact set made for these sheets, within its life, is searched again only in
  // its blocks with points outside it (KeptContacts); otherwise every block is searched.
  const bool partial = !prm.exact && made_for(w, a, b, false) && w.since_full < kKeptLife;
  w.since_full = partial ? w.since_full + 1 : 0;
  const Real skin = next_skin(w, prm);
  Candidates* lists_a = prm.exact ? &w.a_near_b : nullptr;
  Candidates* lists_b = prm.exact ? &w.b_near_a : nullptr;
  KeptContacts* kept_a = prm.exact ? nullptr : &w.spare_a;
  KeptContacts* kept_b = prm.exact ? nullptr : &w.spare_b;
  if (!prm.exact && pair.parts > 1 && a.size() + (self ? 0 : b.size()) >= kPartsFrom) {
    search_in_parts(a, ba, b, bb, ring, pair, skin, partial, w, sc);
  } else {
    points_against_cells(a, ba, b, bb, ring, pair, w.on_a, on_b, sc, w.last_a.data(), lists_a, skin, kept_a,
                         partial ? &w.a_on_b : nullptr);
    if (!self)
      points_against_cells(b, bb, a, ba, ring, pair, on_b, w.on_a, sc, w.last_b.data(), lists_b, skin, kept_b,
                           partial ? &w.b_on_a : nullptr);
  }
  if (!prm.exact) {
    std::swap(w.a_on_b, w.spare_a);
    std::swap(w.b_on_a, w.spare_b);
  }
  keep_lists_for(w, a, ba, b, bb, skin, prm);
}

}  // namespace

template <class Real>
bool pair_needs_boxes(const Sheet<Real>& a, const Sheet<Real>& b, const ContactParams<Real>& prm,
                      PairContacts<Real>& work, ContactScratch<Real>& scratch) {
  const bool hold = work.resting == 0 && lists_hold(work, a, b, prm, scratch);
  work.decided = hold;
  return !hold || prm.exact;
}

template <class Real>
void pair_contacts(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                   const SheetBoxes<Real>& boxes_b, const ContactParams<Real>& prm, PairContacts<Real>& work,
                   ContactScratch<Real>& scratch) {
  contacts_of_pair(a, boxes_a, b, boxes_b, -1, prm, work, scratch);
  if (!prm.rims) return;
  ContactParams<Real> pair = prm;
  pair.friction = static_cast<Real>(std::max(a.friction, b.friction));
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(RimContactsF64)(a, boxes_a, b, boxes_b, pair, work, scratch);
  else
    HWY_DYNAMIC_DISPATCH(RimContactsF32)(a, boxes_a, b, boxes_b, pair, work, scratch);
}

template <class Real>
double rim_energy(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                  const SheetBoxes<Real>& boxes_b, const ContactParams<Real>& prm) {
  if constexpr (std::is_same_v<Real, double>)
    return HWY_DYNAMIC_DISPATCH(RimEnergyF64)(a, boxes_a, b, boxes_b, prm);
  else
    return HWY_DYNAMIC_DISPATCH(RimEnergyF32)(a, boxes_a, b, boxes_b, prm);
}

template <class Real>
std::uint32_t self_contact_ring(const Sheet<Real>& s, const ContactParams<Real>& prm) {
  const auto& t = *s.topology;
  Real spacing = std::min(t.rest_length.front(), t.rest_length.back());
  if (!(spacing > 0)) return 16;
  return std::min<std::uint32_t>(16, 1 + static_cast<std::uint32_t>(std::ceil(prm.range / spacing)));
}

template <class Real>
void self_contacts(const Sheet<Real>& s, const SheetBoxes<Real>& boxes, const ContactParams<Real>& prm,
                   PairContacts<Real>& work, ContactScratch<Real>& scratch) {
  contacts_of_pair(s, boxes, s, boxes, int(self_contact_ring(s, prm)), prm, work, scratch);
}

template <class Real>
double contact_energy(const Sheet<Real>& q, const SheetBoxes<Real>& boxes_q, const Sheet<Real>& s,
                      const SheetBoxes<Real>& boxes_s, const ContactParams<Real>& prm) {
  const int ring = &q == &s ? int(self_contact_ring(s, prm)) : -1;
  if constexpr (std::is_same_v<Real, double>)
    return HWY_DYNAMIC_DISPATCH(ContactEnergyF64)(q, boxes_q, s, boxes_s, ring, prm);
  else
    return HWY_DYNAMIC_DISPATCH(ContactEnergyF32)(q, boxes_q, s, boxes_s, ring, prm);
}

namespace {

// The largest distance of a point of s from travel_from (of the sheet's size), rounded up a
// little: the square root and the sums round, and entries hold 0.99 of a slack. ∞ where a
// displacement is not a number or infinite.
template <class Real>
double largest_move(const Sheet<Real>& s) {
  const Real *x = s.position.x.data(), *y = s.position.y.data(), *z = s.position.z.data();
  const Real *fx = s.travel_from.x.data(), *fy = s.travel_from.y.data(), *fz = s.travel_from.z.data();
  Real most = 0, bad = 0;  // bad: NaN where a displacement is not a number or infinite
  const std::size_t count = s.size();
#pragma omp simd reduction(max : most) reduction(+ : bad)
  for (std::size_t p = 0; p < count; ++p) {
    const Real dx = x[p] - fx[p], dy = y[p] - fy[p], dz = z[p] - fz[p];
    most = std::max(most, dx * dx + dy * dy + dz * dz);
    bad += (dx + dy + dz) * Real(0);
  }
  return bad == 0 ? std::sqrt(double(most)) * (1 + 1e-6) : std::numeric_limits<double>::infinity();
}

}  // namespace

template <class Real>
void measure_travel(Sheet<Real>& s, std::uint64_t stamp) {
  s.moved_stamp = stamp;
  s.moved = s.travel_from.x.size() == s.size() ? largest_move(s) : std::numeric_limits<double>::infinity();
  s.moved_travel = s.travel;
}

template <class Real>
void advance_travel(Sheet<Real>& s, std::uint64_t stamp) {
  Vec3Array<Real>& from = s.travel_from;
  const bool sized = from.x.size() == s.size();
  if (sized) s.travel += measured_in(s, stamp) ? s.moved : largest_move(s);
  from.x.assign(s.position.x.begin(), s.position.x.end());
  from.y.assign(s.position.y.begin(), s.position.y.end());
  from.z.assign(s.position.z.begin(), s.position.z.end());
}

template <class Real>
void advance_travel(Sheet<Real>& s) {
  advance_travel(s, 0);
}

template <class Real>
void gather_contacts(std::span<const ContactForces<Real>* const> sources, Vec3Array<Real>& out, std::size_t begin,
                     std::size_t end) {
  std::fill(out.x.begin() + begin, out.x.begin() + end, Real(0));
  std::fill(out.y.begin() + begin, out.y.begin() + end, Real(0));
  std::fill(out.z.begin() + begin, out.z.begin() + end, Real(0));
  for (const ContactForces<Real>* src : sources)
    for (std::size_t e = 0; e < src->size(); ++e) {
      const std::uint32_t p = src->point[e];
      if (p < begin || p >= end) continue;
      out.x[p] += src->fx[e];
      out.y[p] += src->fy[e];
      out.z[p] += src->fz[e];
    }
}

#define DRAPE_CONTACTS(Real)                                                                                   \
  template struct ContactParams<Real>;                                                                         \
  template void build_boxes<Real>(const Sheet<Real>&, SheetBoxes<Real>&);                                     \
  template bool pair_needs_boxes<Real>(const Sheet<Real>&, const Sheet<Real>&, const ContactParams<Real>&,     \
                                       PairContacts<Real>&, ContactScratch<Real>&);                            \
  template void pair_contacts<Real>(const Sheet<Real>&, const SheetBoxes<Real>&, const Sheet<Real>&,          \
                                    const SheetBoxes<Real>&, const ContactParams<Real>&, PairContacts<Real>&, \
                                    ContactScratch<Real>&);                                                    \
  template void self_contacts<Real>(const Sheet<Real>&, const SheetBoxes<Real>&, const ContactParams<Real>&,  \
                                    PairContacts<Real>&, ContactScratch<Real>&);                               \
  template std::uint32_t self_contact_ring<Real>(const Sheet<Real>&, const ContactParams<Real>&);            \
  template double contact_energy<Real>(const Sheet<Real>&, const SheetBoxes<Real>&, const Sheet<Real>&,       \
                                       const SheetBoxes<Real>&, const ContactParams<Real>&);                   \
  template double rim_energy<Real>(const Sheet<Real>&, const SheetBoxes<Real>&, const Sheet<Real>&,           \
                                   const SheetBoxes<Real>&, const ContactParams<Real>&);                       \
  template void advance_travel<Real>(Sheet<Real>&);                                                            \
  template void advance_travel<Real>(Sheet<Real>&, std::uint64_t);                                             \
  template void measure_travel<Real>(Sheet<Real>&, std::uint64_t);                                             \
  template void gather_contacts<Real>(std::span<const ContactForces<Real>* const>, Vec3Array<Real>&,           \
                                      std::size_t, std::size_t);
DRAPE_CONTACTS(double)
DRAPE_CONTACTS(float)
#undef DRAPE_CONTACTS

}  // namespace drape::detail
#endif  // HWY_ONCE
