// Brute-force distances for tests: a point to a triangle (by a different route than the
// narrow phase's Voronoi-region walk) and to the surface of a sheet (every triangle of
// every cell, no grid), so tests can check the engine's contacts independently.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

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

}  // namespace drape::test
