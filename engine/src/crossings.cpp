// Sheets passing through each other (crossings.h): every edge of one sheet's surface against
// the triangles of the other whose boxes it meets, patch by patch, strip by strip, cell by
// cell, each candidate decided by the signs of exact-enough orientation volumes in double.
#include "crossings.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace drape::detail {
namespace {

using P3 = std::array<double, 3>;

P3 minus(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

// The signed volume (b − a)·((c − a) × (d − a)): six times the tetrahedron's.
double orient(const P3& a, const P3& b, const P3& c, const P3& d) {
  const P3 u = minus(b, a), v = minus(c, a), w = minus(d, a);
  return u[0] * (v[1] * w[2] - v[2] * w[1]) + u[1] * (v[2] * w[0] - v[0] * w[2]) + u[2] * (v[0] * w[1] - v[1] * w[0]);
}

// Whether segment pq passes through the inside of triangle abc: its ends strictly on either
// side of the triangle's plane, and the line through them strictly inside all three edges
// (the three volumes of the line with an edge share a sign). Touching, grazing and
// coplanar cases are not crossings. `t`: where along pq it meets the plane.
bool crosses(const P3& p, const P3& q, const P3& a, const P3& b, const P3& c, double& t) {
  const double sp = orient(a, b, c, p), sq = orient(a, b, c, q);
  if (!((sp > 0 && sq < 0) || (sp < 0 && sq > 0))) return false;
  const double e1 = orient(p, q, a, b), e2 = orient(p, q, b, c), e3 = orient(p, q, c, a);
  if (!((e1 > 0 && e2 > 0 && e3 > 0) || (e1 < 0 && e2 < 0 && e3 < 0))) return false;
  t = sp / (sp - sq);
  return true;
}

template <class Real>
P3 point(const Sheet<Real>& s, std::uint32_t p) {
  return {double(s.position.x[p]), double(s.position.y[p]), double(s.position.z[p])};
}

Aabb segment_box(const P3& p, const P3& q) { return Aabb::segment({p[0], p[1], p[2]}, {q[0], q[1], q[2]}); }

double distance2(const P3& a, const P3& b) {
  const P3 d = minus(a, b);
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

// Counts the crossing of edge (u, v) of q with each triangle of cell c of s (a cell's first
// corner) into `out`, naming the points of the first one found (q's as point_a when q_is_a).
template <class Real>
void edge_against_cell(const Sheet<Real>& q, std::uint32_t u, std::uint32_t v, const Sheet<Real>& s, std::uint32_t c,
                       bool q_is_a, Crossings& out) {
  const std::uint32_t cols = s.topology->cols();
  const std::uint32_t triangles[2][3] = {{c, c + 1, c + cols + 1}, {c, c + cols + 1, c + cols}};
  const P3 pu = point(q, u), pv = point(q, v);
  for (const auto& tri : triangles) {
    const P3 corner[3] = {point(s, tri[0]), point(s, tri[1]), point(s, tri[2])};
    double at = 0;
    if (!crosses(pu, pv, corner[0], corner[1], corner[2], at)) continue;
    if (out.count++ != 0) continue;
    const P3 hit{pu[0] + at * (pv[0] - pu[0]), pu[1] + at * (pv[1] - pu[1]), pu[2] + at * (pv[2] - pu[2])};
    const std::uint32_t mine = at < 0.5 ? u : v;
    int nearest = 0;
    for (int k = 1; k < 3; ++k)
      if (distance2(corner[k], hit) < distance2(corner[nearest], hit)) nearest = k;
    out.point_a = q_is_a ? mine : tri[nearest];
    out.point_b = q_is_a ? tri[nearest] : mine;
  }
}

// The edges of q through the triangles of s, counted into `out`. Each edge belongs to one
// cell of q: its top, left and diagonal edges, and the bottom (right) one in the last row
// (column); a cell's box holds them, so only the cells of s whose boxes meet it are tried:
// patch against patch, then strip of q against the strips of s, then cell against cell.
// q == s: cells that share a point are not tried (a sheet folds through itself many cells
// away). A sheet without cells (a line) has its edges tried one by one.
template <class Real>
void edges_through(const Sheet<Real>& q, const SheetBoxes<Real>& bq, const Sheet<Real>& s, const SheetBoxes<Real>& bs,
                   bool q_is_a, Crossings& out) {
  if (bs.m == 0 || bs.n == 0) return;  // a line of points has no triangles
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  const bool self = &q == &s;
  const std::uint32_t qm = q.topology->m, qn = q.topology->n, qcols = q.topology->cols(), cols = s.topology->cols();
  const std::uint32_t patches = bs.patch_rows * bs.patch_cols;
  if (qm == 0 || qn == 0) {
    for (std::uint32_t u = 0; u + 1 < q.size(); ++u) {
      const Aabb edge = segment_box(point(q, u), point(q, u + 1));
      for (std::uint32_t t = 0; t < patches; ++t)
        if (overlaps(edge, box_at(bs.patch_lo, bs.patch_hi, t)))
          cells_meeting(bs, t, edge, [&](std::uint32_t c) { edge_against_cell(q, u, u + 1, s, c, q_is_a, out); });
    }
    return;
  }
  for (std::uint32_t bi = 0; bi < bq.patch_rows; ++bi)
    for (std::uint32_t bj = 0; bj < bq.patch_cols; ++bj) {
      const Aabb block = box_at(bq.patch_lo, bq.patch_hi, std::size_t(bi) * bq.patch_cols + bj);
      const std::uint32_t i1 = std::min(bi * P + P, qm), j1 = std::min(bj * P + P, qn);
      for (std::uint32_t t = 0; t < patches; ++t) {
        if (!overlaps(block, box_at(bs.patch_lo, bs.patch_hi, t))) continue;
        for (std::uint32_t i = bi * P; i < i1; ++i) {
          const Aabb strip = box_at(bq.strip_lo, bq.strip_hi, std::size_t(i) * bq.patch_cols + bj);
          cells_meeting(bs, t, strip, [&](std::uint32_t c) {
            const std::uint32_t ci = c / cols, cj = c % cols;
            const Aabb cell = box_at(bs.cell_lo, bs.cell_hi, c);
            for (std::uint32_t j = bj * P; j < j1; ++j) {
              if (self && ci + 1 >= i && ci <= i + 1 && cj + 1 >= j && cj <= j + 1) continue;
              const std::uint32_t u = i * qcols + j;
              if (!overlaps(cell, box_at(bq.cell_lo, bq.cell_hi, u))) continue;
              edge_against_cell(q, u, u + 1, s, c, q_is_a, out);
              edge_against_cell(q, u, u + qcols, s, c, q_is_a, out);
              edge_against_cell(q, u, u + qcols + 1, s, c, q_is_a, out);
              if (i + 1 == qm) edge_against_cell(q, u + qcols, u + qcols + 1, s, c, q_is_a, out);
              if (j + 1 == qn) edge_against_cell(q, u + 1, u + qcols + 1, s, c, q_is_a, out);
            }
          });
        }
      }
    }
}

}  // namespace

template <class Real>
Crossings sheet_crossings(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                          const SheetBoxes<Real>& boxes_b) {
  Crossings out;
  edges_through(a, boxes_a, b, boxes_b, true, out);
  if (&a != &b) edges_through(b, boxes_b, a, boxes_a, false, out);
  return out;
}

template Crossings sheet_crossings<double>(const Sheet<double>&, const SheetBoxes<double>&, const Sheet<double>&,
                                           const SheetBoxes<double>&);
template Crossings sheet_crossings<float>(const Sheet<float>&, const SheetBoxes<float>&, const Sheet<float>&,
                                          const SheetBoxes<float>&);

}  // namespace drape::detail
