#include "contacts.h"

#include <algorithm>
#include <cmath>
#include <optional>

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

namespace {

template <class Real>
struct V3 {
  Real x, y, z;
};
template <class Real>
V3<Real> sub(V3<Real> a, V3<Real> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class Real>
Real dot(V3<Real> a, V3<Real> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// max(a, 0) without a comparison, so the loop below vectorises even where GCC will not
// turn a floating-point comparison into a select (AVX2 with -ftrapping-math): exact, as
// a + |a| is 2a or 0 and halving is exact.
template <class Real>
Real positive_part(Real a) { return (a + std::abs(a)) * Real(0.5); }

// gap2[t] = squared distance from x to box t, for t < count: one vectorised pass. Along
// each axis the gap is max(lo − x, x − hi, 0) = max(lo − x, 0) + max(x − hi, 0), as
// lo ≤ hi makes at least one of the two zero.
template <class Real>
void box_gaps(V3<Real> x, const Real* const lo[3], const Real* const hi[3], std::uint32_t count,
              Real* __restrict gap2) {
  const Real* __restrict lx = lo[0];
  const Real* __restrict ly = lo[1];
  const Real* __restrict lz = lo[2];
  const Real* __restrict hx = hi[0];
  const Real* __restrict hy = hi[1];
  const Real* __restrict hz = hi[2];
  for (std::uint32_t t = 0; t < count; ++t) {
    const Real ex = positive_part(lx[t] - x.x) + positive_part(x.x - hx[t]);
    const Real ey = positive_part(ly[t] - x.y) + positive_part(x.y - hy[t]);
    const Real ez = positive_part(lz[t] - x.z) + positive_part(x.z - hz[t]);
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
V3<Real> closest_weights(V3<Real> p, V3<Real> a, V3<Real> b, V3<Real> c) {
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

// The nearest triangle found so far for one point.
template <class Real>
struct Nearest {
  Real dist2;
  std::uint32_t tri[3];
  V3<Real> v[3], w;
};

template <class Real>
void consider(V3<Real> p, std::uint32_t i0, std::uint32_t i1, std::uint32_t i2, V3<Real> a, V3<Real> b, V3<Real> c,
              Nearest<Real>& best) {
  const V3<Real> w = closest_weights(p, a, b, c);
  const V3<Real> q{w.x * a.x + w.y * b.x + w.z * c.x, w.x * a.y + w.y * b.y + w.z * c.y,
                   w.x * a.z + w.y * b.z + w.z * c.z};
  const V3<Real> d = sub(p, q);
  const Real dist2 = dot(d, d);
  if (!(dist2 < best.dist2)) return;  // ties keep the first: the candidate order is fixed
  best = {dist2, {i0, i1, i2}, {a, b, c}, w};
}

// The point against the nearest triangle: pushes the force on the point to `on_q` and the
// three opposite shares to `on_s`.
template <class Real>
V3<Real> velocity(const Sheet<Real>& s, std::uint32_t p) {
  return {s.velocity.x[p], s.velocity.y[p], s.velocity.z[p]};
}

// Coulomb friction on point q of sheet qs against the triangle `best` of sheet ss, whose
// repulsion on q is `force` along the unit normal d (contacts.h): returns the force to add.
template <class Real>
V3<Real> rub(const Sheet<Real>& qs, std::uint32_t q, const Sheet<Real>& ss, const Nearest<Real>& best, V3<Real> d,
             Real force, const ContactParams<Real>& prm) {
  const Real w[3] = {best.w.x, best.w.y, best.w.z};
  V3<Real> rel = velocity(qs, q);
  Real inv_mass = qs.inv_mass[q];
  for (int k = 0; k < 3; ++k) {
    const V3<Real> u = velocity(ss, best.tri[k]);
    rel = {rel.x - w[k] * u.x, rel.y - w[k] * u.y, rel.z - w[k] * u.z};
    inv_mass += w[k] * w[k] * ss.inv_mass[best.tri[k]];
  }
  const Real normal = dot(rel, d);
  const V3<Real> slip{rel.x - normal * d.x, rel.y - normal * d.y, rel.z - normal * d.z};
  const Real speed = std::sqrt(dot(slip, slip));
  if (!(speed > 0) || !(inv_mass > 0)) return {0, 0, 0};
  const Real k = std::min(prm.friction * force / speed, Real(1) / (inv_mass * prm.dt));
  return {-k * slip.x, -k * slip.y, -k * slip.z};
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
  // −dE/dd, shifted to reach 0 at the cut-off; d ≥ 0 bounds it by (c/ξ)·exp(h/ξ)
  const Real f = prm.strength / prm.xi * (std::exp((prm.thickness - dist) / prm.xi) - prm.tail);
  V3<Real> F{f * d.x, f * d.y, f * d.z};
  if (prm.friction > 0) {
    const V3<Real> t = rub(qs, q, ss, best, d, f, prm);
    F = {F.x + t.x, F.y + t.y, F.z + t.z};
  }
  on_q.push(q, F.x, F.y, F.z);
  const Real wt[3] = {best.w.x, best.w.y, best.w.z};
  for (int k = 0; k < 3; ++k)
    if (wt[k] != 0) on_s.push(best.tri[k], -wt[k] * F.x, -wt[k] * F.y, -wt[k] * F.z);
}

// Where a position falls in the narrow-phase grid over a region: grid cell `cell(k, v)`
// along axis k, monotone in v, so a range of positions maps to a range of cells; bins
// numbered with axis ax[2] innermost, so a row of bins along it is contiguous.
struct GridLayout {
  double lo[3], inv[3];
  int dims[3], ax[3];  // ax: axes from outermost to innermost
  double width[3];     // the widest binned box along each axis
  double margin[3];    // slack against rounding when a query range is turned into cells
  int cell(int k, double v) const { return std::clamp(int((v - lo[k]) * inv[k]), 0, dims[k] - 1); }
  std::size_t bin(const int c[3]) const {
    return (std::size_t(c[ax[0]]) * dims[ax[1]] + c[ax[1]]) * dims[ax[2]] + c[ax[2]];
  }
  std::size_t bins() const { return std::size_t(dims[0]) * dims[1] * dims[2]; }
};

// Bins the cells of s whose boxes, grown by R, meet `region` into grid's CSR arrays.
// Nothing when there is none.
template <class Real>
std::optional<GridLayout> bin_cells(const Sheet<Real>& s, const Aabb& region, double R, ContactGrid<Real>& grid) {
  GridLayout layout;
  using Cell = typename ContactGrid<Real>::Cell;
  const auto& ts = *s.topology;
  const std::uint32_t n = ts.n, cols = ts.cols();
  // The cells whose boxes, grown by R, meet the region: only they can be within R of a
  // point inside it. `width`: their widest box along each axis.
  grid.cells.clear();
  double* width = layout.width;
  std::fill(width, width + 3, 0.0);
  const auto& X = s.position;
  for (std::uint32_t i = 0; i < ts.m; ++i)
    for (std::uint32_t j = 0; j < n; ++j) {
      const std::uint32_t p[4] = {i * cols + j, i * cols + j + 1, (i + 1) * cols + j, (i + 1) * cols + j + 1};
      Cell cell{{}, {}, p[0], 0};
      Aabb box;
      for (int k = 0; k < 3; ++k) {
        const auto& a = k == 0 ? X.x : k == 1 ? X.y : X.z;
        cell.lo[k] = std::min(std::min(a[p[0]], a[p[1]]), std::min(a[p[2]], a[p[3]]));
        cell.hi[k] = std::max(std::max(a[p[0]], a[p[1]]), std::max(a[p[2]], a[p[3]]));
        box.lo[k] = cell.lo[k] - R;
        box.hi[k] = cell.hi[k] + R;
      }
      if (!overlaps(box, region)) continue;
      for (int k = 0; k < 3; ++k) width[k] = std::max(width[k], double(cell.hi[k] - cell.lo[k]));
      grid.cells.push_back(cell);
    }
  if (grid.cells.empty()) return std::nullopt;

  // A cell is binned once, by its box's low corner. A point x reaches every cell whose box
  // is within R of it by the grid cells over [x − R − width, x + R] (its box's low corner
  // lies there, its "span"), widened by `margin` against rounding. The grid cells of one
  // row along the innermost axis are contiguous, so a query reads one stretch per row it
  // crosses: the axis with the most cells goes innermost and is cut finer (a quarter of the
  // span, against a whole span across), as its cells cost no extra stretch. Never more
  // grid cells than twice the binned cells, so building stays linear.
  double span[3], size[3];
  double* margin = layout.margin;
  for (int k = 0; k < 3; ++k) {
    span[k] = 2 * R + width[k];
    margin[k] = 1e-6 * (span[k] + std::abs(region.lo[k]) + std::abs(region.hi[k]));
  }
  int inner = 0;
  for (int k = 1; k < 3; ++k)
    if ((region.hi[k] - region.lo[k]) / span[k] > (region.hi[inner] - region.lo[inner]) / span[inner]) inner = k;
  int* ax = layout.ax;
  for (int k = 0, o = 0; k < 3; ++k)
    if (k != inner) ax[o++] = k;
  ax[2] = inner;
  for (int k = 0; k < 3; ++k) size[k] = k == ax[2] ? span[k] / 4 : span[k];
  const double cap = 2.0 * grid.cells.size() + 8;
  int* dims = layout.dims;
  for (;;) {
    double total = 1;
    for (int k = 0; k < 3; ++k) {
      dims[k] = std::max(1, std::min(256, int((region.hi[k] - region.lo[k]) / size[k])));
      total *= dims[k];
    }
    if (total <= cap) break;
    for (double& e : size) e *= 1.5;
  }
  for (int k = 0; k < 3; ++k) {
    const double e = region.hi[k] - region.lo[k];
    layout.lo[k] = region.lo[k];
    layout.inv[k] = e > 0 ? dims[k] / e : 0.0;
  }

  // Counting sort into CSR arrays, in the sheet's cell order: each grid cell's candidates
  // ascend, and its boxes lie contiguous for the gap test.
  const std::size_t grid_cells = layout.bins();
  grid.start.assign(grid_cells + 1, 0);
  for (Cell& cell : grid.cells) {
    const int c[3] = {layout.cell(0, cell.lo[0]), layout.cell(1, cell.lo[1]), layout.cell(2, cell.lo[2])};
    cell.bin = std::uint32_t(layout.bin(c));
    ++grid.start[cell.bin + 1];
  }
  for (std::size_t g = 0; g < grid_cells; ++g) grid.start[g + 1] += grid.start[g];
  const std::size_t binned = grid.cells.size();
  for (int k = 0; k < 3; ++k) {
    grid.lo[k].resize(binned);
    grid.hi[k].resize(binned);
    grid.run_lo[k].resize(binned);
    grid.run_hi[k].resize(binned);
  }
  grid.corner.resize(binned);
  grid.run_corner.resize(binned);
  grid.gap2.resize(binned);
  grid.near.resize(binned);
  grid.pick.resize(binned);
  for (const Cell& cell : grid.cells) {
    const std::uint32_t t = grid.start[cell.bin]++;  // start[g] becomes the end of g, then
    for (int k = 0; k < 3; ++k) {                     // the shift below restores it
      grid.lo[k][t] = cell.lo[k];
      grid.hi[k][t] = cell.hi[k];
    }
    grid.corner[t] = cell.corner;
  }
  for (std::size_t g = grid_cells; g > 0; --g) grid.start[g] = grid.start[g - 1];
  grid.start[0] = 0;
  return layout;
}

// Point p of q (at x) against `near`, its cells of s within R in ascending cell order with
// their boxes' squared gaps: the cell whose box is nearest (the first of equally near ones)
// is tested first, then the others in order while their boxes are still nearer than the
// best triangle (a cell whose box is no nearer cannot win); the nearest triangle repels.
template <class Real>
void repel_nearest(const Sheet<Real>& q, std::uint32_t p, V3<Real> x, const Sheet<Real>& s,
                   const typename ContactGrid<Real>::Near* near, std::uint32_t found, const ContactParams<Real>& prm,
                   ContactForces<Real>& on_q, ContactForces<Real>& on_s) {
  const std::uint32_t cols = s.topology->cols();
  auto test = [&](std::uint32_t p00, Nearest<Real>& best) {
    const std::uint32_t p01 = p00 + 1, p10 = p00 + cols, p11 = p10 + 1;
    const V3<Real> x00 = at(s, p00), x01 = at(s, p01), x10 = at(s, p10), x11 = at(s, p11);
    consider(x, p00, p01, p11, x00, x01, x11, best);
    consider(x, p00, p11, p10, x00, x11, x10, best);
  };
  std::uint32_t nearest = 0;
  for (std::uint32_t e = 1; e < found; ++e)
    if (near[e].gap2 < near[nearest].gap2) nearest = e;
  const Real R2 = prm.range * prm.range;
  Nearest<Real> best{};
  best.dist2 = R2;
  test(near[nearest].corner, best);
  for (std::uint32_t e = 0; e < found; ++e)
    if (e != nearest && near[e].gap2 < best.dist2) test(near[e].corner, best);
  if (best.dist2 < R2) repel(q, p, x, s, best, prm, on_q, on_s);
}

// The candidates of every point of q inside `region`: the cells of s whose boxes are within
// R (≥ prm.range) of it, found through a uniform grid over the region, in ascending cell
// order, into `out` (emptied first; points outside the region get none). `ring` < 0: no
// exclusion; otherwise q == s and cells within `ring` rows/columns of the point are left
// out. In the same pass each point is repelled from its nearest triangle among the
// candidates within prm.range, exactly as points_against_candidates would.
template <class Real>
void candidates_in_grid(const Sheet<Real>& q, const Sheet<Real>& s, const Aabb& region, Real R, int ring,
                        const ContactParams<Real>& prm, Candidates& out, ContactForces<Real>& on_q,
                        ContactForces<Real>& on_s, ContactGrid<Real>& grid) {
  const std::uint32_t qsize = std::uint32_t(q.size());
  out.start.assign(qsize + 1, 0);
  out.cell.clear();
  if (s.topology->m == 0 || s.topology->n == 0) return;  // a line of points has no cells
  const std::uint32_t cols = s.topology->cols();
  const Real R2 = R * R;
  const std::optional<GridLayout> binned = bin_cells(s, region, double(R), grid);
  if (!binned) return;
  const GridLayout layout = *binned;  // a copy no call can reach: it stays in registers
  const double* width = layout.width;
  const double* margin = layout.margin;
  const int* ax = layout.ax;

  // Points go in runs of up to `run_points` consecutive points of one row, near each other.
  // A run asks the grid once, for the cells within R of its box (each axis apart, widened
  // by `margin`), and gathers them contiguous; each point then measures its gap to every
  // gathered box in one pass. A run with no cell near is skipped whole.
  constexpr std::uint32_t run_points = 8;
  Real* rlo[3] = {grid.run_lo[0].data(), grid.run_lo[1].data(), grid.run_lo[2].data()};
  Real* rhi[3] = {grid.run_hi[0].data(), grid.run_hi[1].data(), grid.run_hi[2].data()};
  std::uint32_t* rcorner = grid.run_corner.data();
  Real* gap2 = grid.gap2.data();
  std::uint32_t* pick = grid.pick.data();
  typename ContactGrid<Real>::Near* near = grid.near.data();
  const Real inner2 = prm.range * prm.range;
  const std::uint32_t qcols = q.topology->cols();
  const auto& Q = q.position;
  auto inside = [&](std::uint32_t p) {
    return !(Q.x[p] < region.lo[0] || Q.x[p] > region.hi[0] || Q.y[p] < region.lo[1] || Q.y[p] > region.hi[1] ||
             Q.z[p] < region.lo[2] || Q.z[p] > region.hi[2]);
  };
  for (std::uint32_t p0 = 0; p0 < qsize;) {
    const std::uint32_t p1 = std::min({p0 + run_points, (p0 / qcols + 1) * qcols, qsize});
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (std::uint32_t p = p0; p < p1; ++p) {
      if (!inside(p)) continue;
      const double v[3] = {Q.x[p], Q.y[p], Q.z[p]};
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], v[k]);
        hi[k] = std::max(hi[k], v[k]);
      }
    }
    const std::uint32_t run_first = p0;
    p0 = p1;
    if (!(lo[0] <= hi[0])) continue;  // no point of the run inside the region
    int g0[3], g1[3];
    double keep_lo[3], keep_hi[3];  // a cell can be within R of a point of the run only
    for (int k = 0; k < 3; ++k) {   // if its box's low corner is below keep_hi and its
      keep_lo[k] = lo[k] - double(R) - margin[k];  // high corner above keep_lo, on every axis
      keep_hi[k] = hi[k] + double(R) + margin[k];
      g0[k] = layout.cell(k, keep_lo[k] - width[k]);
      g1[k] = layout.cell(k, keep_hi[k]);
    }
    std::uint32_t count = 0;
    int c[3];
    for (c[ax[0]] = g0[ax[0]]; c[ax[0]] <= g1[ax[0]]; ++c[ax[0]])
      for (c[ax[1]] = g0[ax[1]]; c[ax[1]] <= g1[ax[1]]; ++c[ax[1]]) {
        c[ax[2]] = g0[ax[2]];
        const std::uint32_t first = grid.start[layout.bin(c)];
        c[ax[2]] = g1[ax[2]];
        const std::uint32_t last = grid.start[layout.bin(c) + 1];
        for (std::uint32_t t = first; t < last; ++t) {
          unsigned keep = 1;  // branch-free: bitwise on 0/1, not && on bools
          for (int k = 0; k < 3; ++k) {
            rlo[k][count] = grid.lo[k][t];
            rhi[k][count] = grid.hi[k][t];
            keep &= unsigned(grid.lo[k][t] <= keep_hi[k]) & unsigned(grid.hi[k][t] >= keep_lo[k]);
          }
          rcorner[count] = grid.corner[t];
          count += keep;
        }
      }
    if (count == 0) continue;

    for (std::uint32_t p = run_first; p < p1; ++p) {
      if (!inside(p)) continue;
      const V3<Real> x{Q.x[p], Q.y[p], Q.z[p]};
      box_gaps(x, rlo, rhi, count, gap2);
      // The cells within R, kept without a branch (which pass differs from point to
      // point); self-contact then drops the point's own neighbourhood.
      std::uint32_t found = 0;
      for (std::uint32_t t = 0; t < count; ++t) {
        pick[found] = t;
        found += gap2[t] < R2;
      }
      if (ring >= 0) {
        const std::int64_t pi = p / qcols, pj = p % qcols;
        std::uint32_t kept = 0;
        for (std::uint32_t e = 0; e < found; ++e) {
          const std::int64_t ci = rcorner[pick[e]] / cols, cj = rcorner[pick[e]] % cols;
          pick[kept] = pick[e];
          kept += !(ci >= pi - ring && ci < pi + ring && cj >= pj - ring && cj < pj + ring);
        }
        found = kept;
      }
      // In ascending cell order, whichever grid cells they came from: the order in which
      // they are tested, and so which of two equally near triangles wins, is the sheet's.
      for (std::uint32_t e = 0; e < found; ++e) near[e] = {rcorner[pick[e]], gap2[pick[e]]};
      for (std::uint32_t e = 1; e < found; ++e)
        for (std::uint32_t f = e; f > 0 && near[f].corner < near[f - 1].corner; --f) std::swap(near[f], near[f - 1]);
      std::uint32_t within = 0;
      for (std::uint32_t e = 0; e < found; ++e) {
        out.cell.push_back(near[e].corner);
        near[within] = near[e];
        within += near[e].gap2 < inner2;
      }
      out.start[p + 1] = found;
      if (within > 0) repel_nearest(q, p, x, s, near, within, prm, on_q, on_s);
    }
  }
  for (std::uint32_t p = 0; p < qsize; ++p) out.start[p + 1] += out.start[p];
}

// Points of q against their candidate cells of s: each point measures its gap to every
// candidate's box now, keeps those under R, and tests their triangles for the nearest one,
// the nearest box first and then the others in ascending cell order while their boxes are
// still nearer than the best triangle (a cell whose box is no nearer cannot win).
template <class Real>
void points_against_candidates(const Sheet<Real>& q, const Sheet<Real>& s, const Candidates& cand,
                               const ContactParams<Real>& prm, ContactForces<Real>& on_q, ContactForces<Real>& on_s,
                               ContactGrid<Real>& grid) {
  if (cand.cell.empty()) return;
  const std::uint32_t m = s.topology->m, n = s.topology->n, cols = s.topology->cols();
  const Real R2 = prm.range * prm.range;
  // every cell's box now, by its first corner: a cell is a candidate of many points
  const auto& X = s.position;
  for (int k = 0; k < 3; ++k) {
    grid.cell_lo[k].resize(s.size());
    grid.cell_hi[k].resize(s.size());
  }
  for (std::uint32_t i = 0; i < m; ++i)
    for (int k = 0; k < 3; ++k) {
      const Real* a = (k == 0 ? X.x : k == 1 ? X.y : X.z).data() + std::size_t(i) * cols;
      const Real* b = a + cols;
      Real* __restrict lo = grid.cell_lo[k].data() + std::size_t(i) * cols;
      Real* __restrict hi = grid.cell_hi[k].data() + std::size_t(i) * cols;
      for (std::uint32_t j = 0; j < n; ++j) {
        lo[j] = std::min(std::min(a[j], a[j + 1]), std::min(b[j], b[j + 1]));
        hi[j] = std::max(std::max(a[j], a[j + 1]), std::max(b[j], b[j + 1]));
      }
    }
  std::uint32_t widest = 0;
  for (std::size_t p = 0; p + 1 < cand.start.size(); ++p) widest = std::max(widest, cand.start[p + 1] - cand.start[p]);
  for (int k = 0; k < 3; ++k) {
    grid.run_lo[k].resize(widest);
    grid.run_hi[k].resize(widest);
  }
  grid.gap2.resize(widest);
  grid.near.resize(widest);
  Real* rlo[3] = {grid.run_lo[0].data(), grid.run_lo[1].data(), grid.run_lo[2].data()};
  Real* rhi[3] = {grid.run_hi[0].data(), grid.run_hi[1].data(), grid.run_hi[2].data()};
  Real* gap2 = grid.gap2.data();
  typename ContactGrid<Real>::Near* near = grid.near.data();
  const std::uint32_t qsize = std::uint32_t(q.size());
  for (std::uint32_t p = 0; p < qsize; ++p) {
    const std::uint32_t b = cand.start[p], count = cand.start[p + 1] - b;
    if (count == 0) continue;
    const std::uint32_t* cell = cand.cell.data() + b;
    for (int k = 0; k < 3; ++k)
      for (std::uint32_t t = 0; t < count; ++t) {
        rlo[k][t] = grid.cell_lo[k][cell[t]];
        rhi[k][t] = grid.cell_hi[k][cell[t]];
      }
    const V3<Real> x = at(q, p);
    box_gaps(x, rlo, rhi, count, gap2);
    std::uint32_t found = 0;  // kept without a branch, in the list's ascending order
    for (std::uint32_t t = 0; t < count; ++t) {
      near[found] = {cell[t], gap2[t]};
      found += gap2[t] < R2;
    }
    if (found > 0) repel_nearest(q, p, x, s, near, found, prm, on_q, on_s);
  }
}

Aabb intersection(const Aabb& a, const Aabb& b) {
  Aabb r;
  for (int k = 0; k < 3; ++k) {
    r.lo[k] = std::max(a.lo[k], b.lo[k]);
    r.hi[k] = std::min(a.hi[k], b.hi[k]);
  }
  return r;
}

}  // namespace

namespace {

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

// Whether the lists kept in `w` were made for these sheets and still hold every cell
// within R of every point (PairContacts): no point moved more than 0.45·skin since.
template <class Real>
bool lists_hold(PairContacts<Real>& w, const Sheet<Real>& a, const Sheet<Real>& b) {
  if (w.kept_a != &a || w.kept_b != &b || w.kept_topology_a != a.topology.get() ||
      w.kept_topology_b != b.topology.get() || w.made_at_a.x.size() != a.size() || w.made_at_b.x.size() != b.size())
    return false;
  const Real limit2 = (Real(0.45) * w.skin) * (Real(0.45) * w.skin);
  const bool hold = within(a, w.made_at_a, limit2) && (&a == &b || within(b, w.made_at_b, limit2));
  w.kept_for += hold;
  return hold;
}

// The skin for lists about to be made: R/4 at first, then following how long the last
// lists served (PairContacts).
template <class Real>
Real next_skin(const PairContacts<Real>& w, const ContactParams<Real>& prm) {
  if (!(w.skin > 0)) return prm.skin;
  if (w.kept_for == 0 || w.kept_for > 32) return std::max(w.skin / 2, prm.range / 16);
  if (w.kept_for < 4) return std::min(w.skin * 2, prm.range / 2);
  return w.skin;
}

template <class Real>
void remember(Vec3Array<Real>& to, const Sheet<Real>& s) {
  to.x.assign(s.position.x.begin(), s.position.x.end());
  to.y.assign(s.position.y.begin(), s.position.y.end());
  to.z.assign(s.position.z.begin(), s.position.z.end());
}

template <class Real>
void keep_lists_for(PairContacts<Real>& w, const Sheet<Real>& a, const Sheet<Real>& b, Real skin) {
  w.skin = skin;
  w.kept_for = 0;
  w.kept_a = &a;
  w.kept_b = &b;
  w.kept_topology_a = a.topology.get();
  w.kept_topology_b = b.topology.get();
  remember(w.made_at_a, a);
  remember(w.made_at_b, b);
  ++w.grid_builds;
}

}  // namespace

template <class Real>
void pair_contacts(const Sheet<Real>& a, const Aabb& box_a, const Sheet<Real>& b, const Aabb& box_b,
                   const ContactParams<Real>& prm, PairContacts<Real>& work, ContactGrid<Real>& grid) {
  work.on_a.clear();
  work.on_b.clear();
  const Aabb region = intersection(box_a.inflated(prm.range), box_b.inflated(prm.range));
  if (!overlaps(region, region)) return;
  ContactParams<Real> pair = prm;
  pair.friction = static_cast<Real>(std::max(a.friction, b.friction));
  if (lists_hold(work, a, b)) {
    points_against_candidates(a, b, work.a_near_b, pair, work.on_a, work.on_b, grid);
    points_against_candidates(b, a, work.b_near_a, pair, work.on_b, work.on_a, grid);
    return;
  }
  const Real skin = next_skin(work, prm), reach = prm.range + skin;
  const Aabb wide = intersection(box_a.inflated(reach), box_b.inflated(reach));
  candidates_in_grid(a, b, wide, reach, -1, pair, work.a_near_b, work.on_a, work.on_b, grid);
  candidates_in_grid(b, a, wide, reach, -1, pair, work.b_near_a, work.on_b, work.on_a, grid);
  keep_lists_for(work, a, b, skin);
}

template <class Real>
std::uint32_t self_contact_ring(const Sheet<Real>& s, const ContactParams<Real>& prm) {
  const auto& t = *s.topology;
  Real spacing = std::min(t.rest_length.front(), t.rest_length.back());
  if (!(spacing > 0)) return 16;
  return std::min<std::uint32_t>(16, 1 + static_cast<std::uint32_t>(std::ceil(prm.range / spacing)));
}

template <class Real>
void self_contacts(const Sheet<Real>& s, const Aabb& box, const ContactParams<Real>& prm, PairContacts<Real>& work,
                   ContactGrid<Real>& grid) {
  work.on_a.clear();
  work.on_b.clear();
  ContactParams<Real> own = prm;
  own.friction = static_cast<Real>(s.friction);
  if (lists_hold(work, s, s)) {
    points_against_candidates(s, s, work.a_near_b, own, work.on_a, work.on_a, grid);
    return;
  }
  const Real skin = next_skin(work, prm), reach = prm.range + skin;
  candidates_in_grid(s, s, box.inflated(reach), reach, int(self_contact_ring(s, prm)), own, work.a_near_b, work.on_a,
                     work.on_a, grid);
  keep_lists_for(work, s, s, skin);
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
  template void pair_contacts<Real>(const Sheet<Real>&, const Aabb&, const Sheet<Real>&, const Aabb&,        \
                                    const ContactParams<Real>&, PairContacts<Real>&, ContactGrid<Real>&);      \
  template void self_contacts<Real>(const Sheet<Real>&, const Aabb&, const ContactParams<Real>&,              \
                                    PairContacts<Real>&, ContactGrid<Real>&);                                  \
  template struct ContactGrid<Real>;                                                                           \
  template std::uint32_t self_contact_ring<Real>(const Sheet<Real>&, const ContactParams<Real>&);            \
  template void gather_contacts<Real>(std::span<const ContactForces<Real>* const>, Vec3Array<Real>&,           \
                                      std::size_t, std::size_t);
DRAPE_CONTACTS(double)
DRAPE_CONTACTS(float)
#undef DRAPE_CONTACTS

}  // namespace drape::detail
