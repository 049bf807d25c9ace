#include "contacts.h"

#include <algorithm>
#include <cmath>

namespace drape::detail {

template <class Real>
ContactParams<Real> ContactParams<Real>::make(double thickness, double xi, double strength, double range_in_xi) {
  ContactParams p;
  p.thickness = static_cast<Real>(thickness);
  p.xi = static_cast<Real>(xi);
  p.strength = static_cast<Real>(strength);
  p.range = static_cast<Real>(thickness + range_in_xi * xi);
  p.tail = static_cast<Real>(std::exp(-range_in_xi));
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
void repel(std::uint32_t q, V3<Real> p, const Nearest<Real>& best, const ContactParams<Real>& prm,
           ContactForces<Real>& on_q, ContactForces<Real>& on_s) {
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
  const V3<Real> F{f * d.x, f * d.y, f * d.z};
  on_q.push(q, F.x, F.y, F.z);
  const Real wt[3] = {best.w.x, best.w.y, best.w.z};
  for (int k = 0; k < 3; ++k)
    if (wt[k] != 0) on_s.push(best.tri[k], -wt[k] * F.x, -wt[k] * F.y, -wt[k] * F.z);
}

// Points of q inside `region` against the cells of s binned in a uniform grid over the
// region. `ring` < 0: no exclusion; otherwise q == s and cells within `ring` rows/columns
// of the point are skipped.
template <class Real>
void points_against_cells(const Sheet<Real>& q, const Sheet<Real>& s, const Aabb& region,
                          const ContactParams<Real>& prm, int ring, ContactForces<Real>& on_q,
                          ContactForces<Real>& on_s, ContactGrid<Real>& grid) {
  const auto& ts = *s.topology;
  const std::uint32_t n = ts.n, cols = ts.cols();
  if (ts.m == 0 || ts.n == 0) return;  // a line of points has no cells
  const double R = prm.range;

  // Grid size: cells about as large as the sheet's cells plus the range, and never more
  // grid cells than twice the number of sheet cells, so building it stays linear.
  double spacing = 0;
  for (const Real l : {ts.rest_length.front(), ts.rest_length.back()}) spacing = std::max(spacing, double(l));
  double size = 0.5 * std::max(R, spacing);
  const double cap = 2.0 * ts.m * ts.n + 8;
  int dims[3];
  for (;;) {
    double total = 1;
    for (int k = 0; k < 3; ++k) {
      dims[k] = std::max(1, std::min(256, int((region.hi[k] - region.lo[k]) / size)));
      total *= dims[k];
    }
    if (total <= cap) break;
    size *= 1.5;
  }
  double inv[3];
  for (int k = 0; k < 3; ++k) {
    const double e = region.hi[k] - region.lo[k];
    inv[k] = e > 0 ? dims[k] / e : 0.0;
  }
  auto cell_of = [&](int k, double v) {
    return std::clamp(int((v - region.lo[k]) * inv[k]), 0, dims[k] - 1);
  };

  // Bin the cells whose grown boxes meet the region (CSR: count, prefix sum, fill). Each
  // binned cell keeps its box and corner index in `cells`, read contiguously by queries.
  const std::size_t grid_cells = std::size_t(dims[0]) * dims[1] * dims[2];
  grid.start.assign(grid_cells + 1, 0);
  grid.range.clear();
  grid.cells.clear();
  const auto& X = s.position;
  for (std::uint32_t i = 0; i < ts.m; ++i)
    for (std::uint32_t j = 0; j < n; ++j) {
      const std::uint32_t p[4] = {i * cols + j, i * cols + j + 1, (i + 1) * cols + j, (i + 1) * cols + j + 1};
      typename ContactGrid<Real>::Cell cell{{}, {}, p[0], i, j};
      Aabb box;
      for (int k = 0; k < 3; ++k) {
        const auto& a = k == 0 ? X.x : k == 1 ? X.y : X.z;
        cell.lo[k] = std::min(std::min(a[p[0]], a[p[1]]), std::min(a[p[2]], a[p[3]]));
        cell.hi[k] = std::max(std::max(a[p[0]], a[p[1]]), std::max(a[p[2]], a[p[3]]));
        box.lo[k] = cell.lo[k] - R;
        box.hi[k] = cell.hi[k] + R;
      }
      if (!overlaps(box, region)) continue;
      std::uint32_t g0[3], g1[3];
      for (int k = 0; k < 3; ++k) {
        g0[k] = cell_of(k, std::max(box.lo[k], region.lo[k]));
        g1[k] = cell_of(k, std::min(box.hi[k], region.hi[k]));
      }
      grid.cells.push_back(cell);
      grid.range.insert(grid.range.end(), {g0[0], g0[1], g0[2], g1[0], g1[1], g1[2]});
      for (std::uint32_t a = g0[0]; a <= g1[0]; ++a)
        for (std::uint32_t b = g0[1]; b <= g1[1]; ++b)
          for (std::uint32_t c = g0[2]; c <= g1[2]; ++c) ++grid.start[(std::size_t(a) * dims[1] + b) * dims[2] + c + 1];
    }
  if (grid.cells.empty()) return;
  for (std::size_t g = 0; g < grid_cells; ++g) grid.start[g + 1] += grid.start[g];
  grid.items.resize(grid.start[grid_cells]);
  grid.cursor.assign(grid.start.begin(), grid.start.end() - 1);
  for (std::uint32_t c = 0; c < grid.cells.size(); ++c) {
    const std::uint32_t* g = &grid.range[6 * std::size_t(c)];
    for (std::uint32_t a = g[0]; a <= g[3]; ++a)
      for (std::uint32_t b = g[1]; b <= g[4]; ++b)
        for (std::uint32_t e = g[2]; e <= g[5]; ++e) grid.items[grid.cursor[(std::size_t(a) * dims[1] + b) * dims[2] + e]++] = c;
  }

  const std::uint32_t qcols = q.topology->cols();
  const auto& Q = q.position;
  for (std::uint32_t p = 0; p < q.size(); ++p) {
    const V3<Real> x{Q.x[p], Q.y[p], Q.z[p]};
    if (x.x < region.lo[0] || x.x > region.hi[0] || x.y < region.lo[1] || x.y > region.hi[1] ||
        x.z < region.lo[2] || x.z > region.hi[2])
      continue;
    const std::size_t g = (std::size_t(cell_of(0, x.x)) * dims[1] + cell_of(1, x.y)) * dims[2] + cell_of(2, x.z);
    const std::int64_t pi = p / qcols, pj = p % qcols;
    auto box_gap2 = [&](const typename ContactGrid<Real>::Cell& cell) {
      Real gap2 = 0;
      for (int k = 0; k < 3; ++k) {
        const Real v = k == 0 ? x.x : k == 1 ? x.y : x.z;
        const Real e = std::max(std::max(cell.lo[k] - v, v - cell.hi[k]), Real(0));
        gap2 += e * e;
      }
      return gap2;
    };
    auto test = [&](const typename ContactGrid<Real>::Cell& cell, Nearest<Real>& best) {
      if (ring >= 0 && std::int64_t(cell.i) >= pi - ring && std::int64_t(cell.i) < pi + ring &&
          std::int64_t(cell.j) >= pj - ring && std::int64_t(cell.j) < pj + ring)
        return;
      const std::uint32_t p00 = cell.corner, p01 = p00 + 1, p10 = p00 + cols, p11 = p10 + 1;
      const V3<Real> x00 = at(s, p00), x01 = at(s, p01), x10 = at(s, p10), x11 = at(s, p11);
      consider(x, p00, p01, p11, x00, x01, x11, best);
      consider(x, p00, p11, p10, x00, x11, x10, best);
    };
    Nearest<Real> best{};
    best.dist2 = prm.range * prm.range;
    // The cell whose box is nearest goes first, so the bound below prunes the others:
    // a cell whose box is no nearer than the nearest triangle so far cannot win.
    const std::uint32_t first = grid.start[g], last = grid.start[g + 1];
    if (grid.gap2.size() < last - first) grid.gap2.resize(last - first);
    Real* gap2 = grid.gap2.data();  // box gaps of this grid cell's candidates, gap2[it − first]
    std::uint32_t nearest = last;
    Real nearest_gap2 = best.dist2;
    for (std::uint32_t it = first; it < last; ++it) {
      gap2[it - first] = box_gap2(grid.cells[grid.items[it]]);
      if (gap2[it - first] < nearest_gap2) {
        nearest_gap2 = gap2[it - first];
        nearest = it;
      }
    }
    if (nearest == last) continue;
    test(grid.cells[grid.items[nearest]], best);
    for (std::uint32_t it = first; it < last; ++it)
      if (it != nearest && gap2[it - first] < best.dist2) test(grid.cells[grid.items[it]], best);
    if (best.dist2 < prm.range * prm.range) repel(p, x, best, prm, on_q, on_s);
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

template <class Real>
void pair_contacts(const Sheet<Real>& a, const Aabb& box_a, const Sheet<Real>& b, const Aabb& box_b,
                   const ContactParams<Real>& prm, PairContacts<Real>& work, ContactGrid<Real>& grid) {
  work.on_a.clear();
  work.on_b.clear();
  const Aabb region = intersection(box_a.inflated(prm.range), box_b.inflated(prm.range));
  if (!overlaps(region, region)) return;
  points_against_cells(a, b, region, prm, -1, work.on_a, work.on_b, grid);
  points_against_cells(b, a, region, prm, -1, work.on_b, work.on_a, grid);
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
  points_against_cells(s, s, box.inflated(prm.range), prm, int(self_contact_ring(s, prm)), work.on_a, work.on_a,
                       grid);
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
