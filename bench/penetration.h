// How far sheets of a stack went into or through each other: one measure for every engine
// the report compares (bench_bullet.cpp), taken outside the timed region from the points
// alone, so it knows nothing of either engine's contact model.
//
// Each sheet is a side×side grid of points, row-major (point (i,j) at i·side + j), cut into
// the triangles (i,j)(i,j+1)(i+1,j+1) and (i,j)(i+1,j+1)(i+1,j), and belongs to a column and
// a layer. The stack must start flat, horizontal, the layers in the order of their height,
// the grids with j along +x and i along +y (both triangles' normals then point up). For every
// point and every other sheet of its column, the nearest point q on that sheet's triangles
// gives the distance |p − q| and the side, the sign of (p − q)·n with n the nearest
// triangle's normal: a point of a higher layer that is now below a lower layer's sheet (or
// the reverse) crossed it. A point is
// beside that sheet, not through it: q anywhere on the other sheet's outermost ring of cells
// or that ring's inner edge, where free edges curl into folds (crossings there are not
// counted). The side is one triangle's: at a fold elsewhere (q on a vertex or edge between
// triangles at a sharp angle) a point beside it may count as crossed; the edge's or vertex's
// pseudo-normal would decide it (docs/architecture.md). Sheets are searched only within `reach` of a point; a
// point that went further through a sheet is not seen (the report says so). A stack whose
// triangles would be listed in more than `max_listed` grid cells (torn-apart sheets) is not
// measured: `measured` says so.
#pragma once

#include <drape/drape.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace drape::bench {

struct MeasuredSheet {
  int column = 0, layer = 0;
  std::vector<Vec3> points;  // side×side, row-major
};

struct Penetration {
  bool measured = true;     // false: some stack's triangles were spread too wide to search (it blew up)
  std::size_t crossed = 0;  // points on the other side of at least one sheet of their column
  double max_depth = 0;     // the largest distance of a crossed point past the sheet it crossed, m
  double min_gap = std::numeric_limits<double>::infinity();  // smallest distance of a point to another
                                                             // sheet of its column it did not cross, m
};

namespace penetration_detail {

inline Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }

// The point of triangle abc nearest to p, as barycentric weights (Ericson, Real-Time
// Collision Detection, 5.1.5: Voronoi regions of the vertices, then edges, then the face).
// The engine's narrow phase has its own (contacts.cpp); the measure keeps this one so that a
// fault there cannot hide itself in the figures that judge it.
inline std::array<double, 3> nearest_weights(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3 bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Vec3 cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) return {1, 0, 0};  // a triangle collapsed to a line: its first corner
  const double v = vb / sum, w = vc / sum;
  return {1 - v - w, v, w};
}

}  // namespace penetration_detail

inline Penetration measure_penetration(const std::vector<MeasuredSheet>& sheets, std::uint32_t side, double reach,
                                       std::uint64_t max_listed = std::uint64_t(1) << 25) {
  using namespace penetration_detail;
  const std::uint32_t cells_per_side = side - 1, tris_per_sheet = 2 * cells_per_side * cells_per_side;
  // triangle t of a sheet: cell (i, j) = t / 2, its first or second triangle
  auto corners = [&](std::uint32_t t) -> std::array<std::uint32_t, 3> {
    const std::uint32_t cell = t / 2, i = cell / cells_per_side, j = cell % cells_per_side;
    const std::uint32_t a = i * side + j, b = a + 1, c = a + side + 1, d = a + side;
    return t % 2 == 0 ? std::array<std::uint32_t, 3>{a, b, c} : std::array<std::uint32_t, 3>{a, c, d};
  };
  auto near_border = [&](std::uint32_t point) {  // on the border or next to it
    const std::uint32_t i = point / side, j = point % side;
    return i <= 1 || j <= 1 || i + 2 >= side || j + 2 >= side;
  };

  Penetration result;
  int columns = 0;
  for (const auto& s : sheets) columns = std::max(columns, s.column + 1);
  for (int column = 0; column < columns; ++column) {
    std::vector<std::uint32_t> members;  // indices into `sheets`
    for (std::uint32_t k = 0; k < sheets.size(); ++k)
      if (sheets[k].column == column) members.push_back(k);
    if (members.size() < 2) continue;

    // A uniform grid of cells of reach/2 over the column's points, each triangle listed in
    // every cell its box meets (CSR); a query visits the cells within reach of the point.
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (std::uint32_t k : members)
      for (const Vec3& p : sheets[k].points) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      }
    double cell = 0.5 * reach;
    auto dims = [&](double h) {
      return std::array<std::int64_t, 3>{std::int64_t((hi.x - lo.x) / h) + 1, std::int64_t((hi.y - lo.y) / h) + 1,
                                         std::int64_t((hi.z - lo.z) / h) + 1};
    };
    while (dims(cell)[0] * dims(cell)[1] * dims(cell)[2] > (std::int64_t(1) << 22)) cell *= 2;  // a sheet flew off
    const auto n = dims(cell);
    auto cell_of = [&](double v, double origin, std::int64_t count) {
      return std::clamp(std::int64_t(std::floor((v - origin) / cell)), std::int64_t(0), count - 1);
    };
    auto cell_range = [&](Vec3 a, Vec3 b, std::array<std::int64_t, 3>& from, std::array<std::int64_t, 3>& to) {
      from = {cell_of(a.x, lo.x, n[0]), cell_of(a.y, lo.y, n[1]), cell_of(a.z, lo.z, n[2])};
      to = {cell_of(b.x, lo.x, n[0]), cell_of(b.y, lo.y, n[1]), cell_of(b.z, lo.z, n[2])};
    };
    // the block of cells triangle t of a member meets; false for a non-finite triangle
    auto triangle_block = [&](std::uint32_t member, std::uint32_t t, std::array<std::int64_t, 3>& from,
                              std::array<std::int64_t, 3>& to) {
      const auto& pts = sheets[members[member]].points;
      const auto v = corners(t);
      Vec3 a = pts[v[0]], b = pts[v[0]];
      for (std::uint32_t q : v) {
        a = {std::min(a.x, pts[q].x), std::min(a.y, pts[q].y), std::min(a.z, pts[q].z)};
        b = {std::max(b.x, pts[q].x), std::max(b.y, pts[q].y), std::max(b.z, pts[q].z)};
      }
      if (!std::isfinite(a.x + a.y + a.z + b.x + b.y + b.z)) return false;
      cell_range(a, b, from, to);
      return true;
    };
    // Sheets torn apart (an engine that blew up) have triangles across the whole grid: listing
    // them would take more memory than the machine has. Such a state has no penetration to
    // speak of; it is reported as not measured.
    std::uint64_t listed = 0;
    for (std::uint32_t m = 0; m < members.size(); ++m)
      for (std::uint32_t t = 0; t < tris_per_sheet; ++t) {
        std::array<std::int64_t, 3> from, to;
        if (triangle_block(m, t, from, to))
          listed += std::uint64_t((to[0] - from[0] + 1) * (to[1] - from[1] + 1) * (to[2] - from[2] + 1));
      }
    if (listed > max_listed) {
      result.measured = false;
      continue;
    }
    std::vector<std::uint32_t> start(std::size_t(n[0] * n[1] * n[2]) + 1, 0), entries;
    auto triangle_cells = [&](std::uint32_t member, std::uint32_t t, auto&& visit) {
      std::array<std::int64_t, 3> from, to;
      if (!triangle_block(member, t, from, to)) return;
      for (std::int64_t x = from[0]; x <= to[0]; ++x)
        for (std::int64_t y = from[1]; y <= to[1]; ++y)
          for (std::int64_t z = from[2]; z <= to[2]; ++z) visit(std::size_t((x * n[1] + y) * n[2] + z));
    };
    for (std::uint32_t m = 0; m < members.size(); ++m)
      for (std::uint32_t t = 0; t < tris_per_sheet; ++t) triangle_cells(m, t, [&](std::size_t c) { ++start[c + 1]; });
    for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
    entries.resize(start.back());
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::uint32_t m = 0; m < members.size(); ++m)
      for (std::uint32_t t = 0; t < tris_per_sheet; ++t)
        triangle_cells(m, t, [&](std::size_t c) { entries[fill[c]++] = m * tris_per_sheet + t; });

    std::vector<double> best(members.size());
    std::vector<std::uint32_t> best_tri(members.size());
    for (std::uint32_t m = 0; m < members.size(); ++m) {
      const MeasuredSheet& own = sheets[members[m]];
      for (const Vec3& p : own.points) {
        if (!std::isfinite(p.x + p.y + p.z)) continue;
        std::fill(best.begin(), best.end(), reach * reach);
        std::fill(best_tri.begin(), best_tri.end(), tris_per_sheet);  // none within reach
        std::array<std::int64_t, 3> from, to;
        cell_range({p.x - reach, p.y - reach, p.z - reach}, {p.x + reach, p.y + reach, p.z + reach}, from, to);
        for (std::int64_t x = from[0]; x <= to[0]; ++x)
          for (std::int64_t y = from[1]; y <= to[1]; ++y)
            for (std::int64_t z = from[2]; z <= to[2]; ++z) {
              const std::size_t c = std::size_t((x * n[1] + y) * n[2] + z);
              for (std::uint32_t e = start[c]; e < start[c + 1]; ++e) {
                const std::uint32_t other = entries[e] / tris_per_sheet, t = entries[e] % tris_per_sheet;
                if (other == m) continue;
                const auto& pts = sheets[members[other]].points;
                const auto v = corners(t);
                const auto w = nearest_weights(p, pts[v[0]], pts[v[1]], pts[v[2]]);
                const Vec3 q{w[0] * pts[v[0]].x + w[1] * pts[v[1]].x + w[2] * pts[v[2]].x,
                             w[0] * pts[v[0]].y + w[1] * pts[v[1]].y + w[2] * pts[v[2]].y,
                             w[0] * pts[v[0]].z + w[1] * pts[v[1]].z + w[2] * pts[v[2]].z};
                const Vec3 d = sub(p, q);
                const double d2 = dot(d, d);
                if (d2 < best[other] || (d2 == best[other] && t < best_tri[other])) {
                  best[other] = d2;
                  best_tri[other] = t;
                }
              }
            }
        bool crossed = false;
        double depth = 0;
        for (std::uint32_t other = 0; other < members.size(); ++other) {
          if (best_tri[other] == tris_per_sheet) continue;
          const auto& pts = sheets[members[other]].points;
          const auto v = corners(best_tri[other]);
          const auto w = nearest_weights(p, pts[v[0]], pts[v[1]], pts[v[2]]);
          const Vec3 q{w[0] * pts[v[0]].x + w[1] * pts[v[1]].x + w[2] * pts[v[2]].x,
                       w[0] * pts[v[0]].y + w[1] * pts[v[1]].y + w[2] * pts[v[2]].y,
                       w[0] * pts[v[0]].z + w[1] * pts[v[1]].z + w[2] * pts[v[2]].z};
          const double distance = std::sqrt(best[other]);
          // Beside the other sheet, not through it: q on its outermost ring of cells or that
          // ring's inner edge, where free edges curl into folds (the side of a point next to a
          // fold is not one triangle's to tell).
          bool beside = false;
          for (int k = 0; k < 3; ++k) beside = beside || (w[k] > 1e-12 && near_border(v[k]));
          const Vec3 normal = cross(sub(pts[v[1]], pts[v[0]]), sub(pts[v[2]], pts[v[0]]));
          const double s = dot(sub(p, q), normal);
          const bool above_at_start = own.layer > sheets[members[other]].layer;
          if (!beside && s != 0 && (s > 0) != above_at_start) {
            crossed = true;
            depth = std::max(depth, distance);
          } else {
            result.min_gap = std::min(result.min_gap, distance);
          }
        }
        if (crossed) {
          ++result.crossed;
          result.max_depth = std::max(result.max_depth, depth);
        }
      }
    }
  }
  return result;
}

}  // namespace drape::bench
