// Brute-force distances for tests: a point to a triangle (by a different route than the
// narrow phase's Voronoi-region walk) and to the surface of a sheet (every triangle of
// every cell, no grid), so tests can check the engine's contacts independently.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace drape::test {

using P3 = std::array<double, 3>;
inline P3 sub(P3 a, P3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline double dot(P3 a, P3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline P3 cross(P3 a, P3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }

inline double segment_distance(P3 p, P3 a, P3 b) {
  const P3 ab = sub(b, a);
  const double t = std::clamp(dot(sub(p, a), ab) / dot(ab, ab), 0.0, 1.0);
  const P3 q{a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
  return std::sqrt(dot(sub(p, q), sub(p, q)));
}

// The plane distance if p projects inside the triangle, else the nearest of its three edges.
inline double triangle_distance(P3 p, P3 a, P3 b, P3 c) {
  const P3 nrm = cross(sub(b, a), sub(c, a));
  const double h = dot(sub(p, a), nrm) / dot(nrm, nrm);
  const P3 q{p[0] - h * nrm[0], p[1] - h * nrm[1], p[2] - h * nrm[2]};
  const bool inside = dot(cross(sub(b, a), sub(q, a)), nrm) >= 0 && dot(cross(sub(c, b), sub(q, b)), nrm) >= 0 &&
                      dot(cross(sub(a, c), sub(q, c)), nrm) >= 0;
  if (inside) return std::abs(h) * std::sqrt(dot(nrm, nrm));
  return std::min({segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, c, a)});
}

// Distance from p to the surface of a sheet with m×n cells whose point k is at(k), each
// cell (i, j) split into (i,j)(i,j+1)(i+1,j+1) and (i,j)(i+1,j+1)(i+1,j) as the engine does.
template <class At>
double surface_distance(P3 p, std::uint32_t m, std::uint32_t n, At at) {
  const std::uint32_t cols = n + 1;
  double best = INFINITY;
  for (std::uint32_t i = 0; i < m; ++i)
    for (std::uint32_t j = 0; j < n; ++j) {
      const std::uint32_t a = i * cols + j, b = a + 1, c = a + cols, d = c + 1;
      best = std::min({best, triangle_distance(p, at(a), at(b), at(d)), triangle_distance(p, at(a), at(d), at(c))});
    }
  return best;
}

// The edges of a sheet of m×n cells (its surface's: along rows, along columns, and each
// cell's diagonal (i,j)(i+1,j+1)), with whether each lies on the rim (the first or last row
// or column).
struct GridEdge {
  std::uint32_t u, v;
  bool rim;
};
inline std::vector<GridEdge> grid_edges(std::uint32_t m, std::uint32_t n) {
  std::vector<GridEdge> out;
  const std::uint32_t cols = n + 1;
  for (std::uint32_t i = 0; i <= m; ++i)
    for (std::uint32_t j = 0; j <= n; ++j) {
      const std::uint32_t u = i * cols + j;
      if (j < n) out.push_back({u, u + 1, i == 0 || i == m});
      if (i < m) out.push_back({u, u + cols, j == 0 || j == n});
      if (i < m && j < n) out.push_back({u, u + cols + 1, false});
    }
  return out;
}

// The distance between edges pq and ab where they pass each other as the rim contacts count
// them (contacts.h): the lines' common perpendicular, found here from the normal
// n = (q − p) × (b − a) (s = ((a − p) × (b − a))·n / |n|², t = ((a − p) × (q − p))·n / |n|²),
// meeting both edges between 1 % and 99 % of their length, at more than about 6° (|n|² >
// 0.01·|q − p|²·|b − a|²); −1 otherwise.
inline double passing_distance(P3 p, P3 q, P3 a, P3 b) {
  const P3 d1 = sub(q, p), d2 = sub(b, a), n = cross(d1, d2), w = sub(a, p);
  const double nn = dot(n, n);
  if (!(nn > 0.01 * dot(d1, d1) * dot(d2, d2))) return -1;
  const double s = dot(cross(w, d2), n) / nn, t = dot(cross(w, d1), n) / nn;
  if (!(s > 0.01 && s < 0.99 && t > 0.01 && t < 0.99)) return -1;
  const P3 x{p[0] + s * d1[0] - a[0] - t * d2[0], p[1] + s * d1[1] - a[1] - t * d2[1], p[2] + s * d1[2] - a[2] - t * d2[2]};
  return std::sqrt(dot(x, x));
}

// Σ f(distance) over the edge pairs of two sheets that the rim contacts count: every rim edge
// of each against every edge of the other, each pair of rim edges once, every pair passing
// (passing_distance ≥ 0): the brute force of the rims, no boxes.
template <class AtA, class AtB, class F>
double rim_sum(std::uint32_t ma, std::uint32_t na, AtA at_a, std::uint32_t mb, std::uint32_t nb, AtB at_b, F f) {
  const auto ea = grid_edges(ma, na), eb = grid_edges(mb, nb);
  double sum = 0;
  for (const GridEdge& x : ea)
    for (const GridEdge& y : eb) {
      if (!x.rim && !y.rim) continue;
      const double d = passing_distance(at_a(x.u), at_a(x.v), at_b(y.u), at_b(y.v));
      if (d >= 0) sum += f(d);
    }
  return sum;
}

}  // namespace drape::test
