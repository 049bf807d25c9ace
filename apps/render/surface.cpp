// Surfaces over a control grid: each scheme reduces, along u and along v separately, to a few
// weights on grid indices (and their derivatives); the point is the tensor sum of the two.
#include "render/surface.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace drape::render {

namespace {

// Weights of one parameter direction: the surface is Σ_a Σ_b w_u[a]·w_v[b]·P(index_u[a], index_v[b]).
struct Basis {
  int count = 0;
  std::uint32_t index[4] = {};
  double w[4] = {}, dw[4] = {};  // dw: derivative with respect to the global parameter

  void add(std::uint32_t i, double weight, double derivative) {
    for (int k = 0; k < count; ++k)
      if (index[k] == i) {
        w[k] += weight;
        dw[k] += derivative;
        return;
      }
    index[count] = i;
    w[count] = weight;
    dw[count] = derivative;
    ++count;
  }
};

// The grid: linear over cell s (the last cell at u = cells).
Basis grid_basis(std::uint32_t cells, double u) {
  Basis b;
  const std::uint32_t s = std::min(cells - 1, std::uint32_t(u));
  const double t = u - s;
  b.add(s, 1 - t, -1);
  b.add(s + 1, t, 1);
  return b;
}

// Bézier pieces of degree ≤ 3: piece p spans indices 3p..3p+d, d = min(3, cells − 3p);
// Bernstein weights B_k^d(t) at t = (u − 3p)/d.
Basis bezier_basis(std::uint32_t cells, double u) {
  const std::uint32_t pieces = (cells + 2) / 3;
  const std::uint32_t p = std::min(pieces - 1, std::uint32_t(u / 3));
  const std::uint32_t first = 3 * p, d = std::min<std::uint32_t>(3, cells - first);
  const double t = (u - first) / d, s = 1 - t, scale = 1.0 / d;
  Basis b;
  switch (d) {
    case 1:
      b.add(first, s, -scale);
      b.add(first + 1, t, scale);
      break;
    case 2:
      b.add(first, s * s, -2 * s * scale);
      b.add(first + 1, 2 * s * t, 2 * (s - t) * scale);
      b.add(first + 2, t * t, 2 * t * scale);
      break;
    default:
      b.add(first, s * s * s, -3 * s * s * scale);
      b.add(first + 1, 3 * s * s * t, 3 * s * (s - 2 * t) * scale);
      b.add(first + 2, 3 * s * t * t, 3 * t * (2 * s - t) * scale);
      b.add(first + 3, t * t * t, 3 * t * t * scale);
      break;
  }
  return b;
}

// Uniform cubic B-spline over the indices −1..cells+1, one span per cell; the phantom points
// P₋₁ = 2P₀ − P₁ and P_{c+1} = 2P_c − P_{c−1} are folded into weights on real grid points.
Basis bspline_basis(std::uint32_t cells, double u) {
  const std::uint32_t s = std::min(cells - 1, std::uint32_t(u));
  const double t = u - s, r = 1 - t;
  const double w[4] = {r * r * r / 6, (3 * t * t * t - 6 * t * t + 4) / 6, (-3 * t * t * t + 3 * t * t + 3 * t + 1) / 6,
                       t * t * t / 6};
  const double dw[4] = {-r * r / 2, (3 * t * t - 4 * t) / 2, (-3 * t * t + 2 * t + 1) / 2, t * t / 2};
  Basis b;
  for (int k = 0; k < 4; ++k) {
    const long long i = static_cast<long long>(s) + k - 1;
    if (i < 0) {  // P₋₁ = 2P₀ − P₁
      b.add(0, 2 * w[k], 2 * dw[k]);
      b.add(1, -w[k], -dw[k]);
    } else if (i > static_cast<long long>(cells)) {  // P_{c+1} = 2P_c − P_{c−1}
      b.add(cells, 2 * w[k], 2 * dw[k]);
      b.add(cells - 1, -w[k], -dw[k]);
    } else {
      b.add(std::uint32_t(i), w[k], dw[k]);
    }
  }
  return b;
}

Basis basis(SurfaceKind kind, std::uint32_t cells, double u) {
  if (cells == 0) {  // a single row of points: constant along this direction
    Basis b;
    b.add(0, 1, 0);
    return b;
  }
  u = std::clamp(u, 0.0, double(cells));
  switch (kind) {
    case SurfaceKind::Grid: return grid_basis(cells, u);
    case SurfaceKind::Bezier: return bezier_basis(cells, u);
    case SurfaceKind::BSpline: return bspline_basis(cells, u);
  }
  return grid_basis(cells, u);
}

void check_grid(const SheetMesh& g) {
  const std::size_t expected = std::size_t(g.m + 1) * (g.n + 1);
  if (g.x.size() != expected || g.y.size() != expected || g.z.size() != expected)
    throw std::invalid_argument("surface: a " + std::to_string(g.m) + "x" + std::to_string(g.n) + " grid needs " +
                                std::to_string(expected) + " points, got " + std::to_string(g.x.size()));
}

SurfacePoint evaluate(const SheetMesh& g, const Basis& bu, const Basis& bv) {
  SurfacePoint r{};
  const std::size_t cols = g.n + 1;
  for (int a = 0; a < bu.count; ++a)
    for (int b = 0; b < bv.count; ++b) {
      const std::size_t k = bu.index[a] * cols + bv.index[b];
      const Vec3 p{g.x[k], g.y[k], g.z[k]};
      const double w = bu.w[a] * bv.w[b], wu = bu.dw[a] * bv.w[b], wv = bu.w[a] * bv.dw[b];
      r.p = {r.p.x + w * p.x, r.p.y + w * p.y, r.p.z + w * p.z};
      r.du = {r.du.x + wu * p.x, r.du.y + wu * p.y, r.du.z + wu * p.z};
      r.dv = {r.dv.x + wv * p.x, r.dv.y + wv * p.y, r.dv.z + wv * p.z};
    }
  return r;
}

}  // namespace

std::string_view surface_kind_name(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::Grid: return "grid";
    case SurfaceKind::Bezier: return "bezier";
    case SurfaceKind::BSpline: return "bspline";
  }
  return "grid";
}

std::optional<SurfaceKind> surface_kind_from_name(std::string_view name) {
  for (SurfaceKind k : {SurfaceKind::Grid, SurfaceKind::Bezier, SurfaceKind::BSpline})
    if (surface_kind_name(k) == name) return k;
  return std::nullopt;
}

SurfacePoint surface_point(const SheetMesh& grid, SurfaceKind kind, double u, double v) {
  check_grid(grid);
  return evaluate(grid, basis(kind, grid.m, u), basis(kind, grid.n, v));
}

SurfaceMesh sample_surface(const SheetMesh& grid, SurfaceKind kind, int per_cell) {
  check_grid(grid);
  if (per_cell < 1 || per_cell > 64)
    throw std::invalid_argument("surface: samples per cell must be 1..64 (got " + std::to_string(per_cell) + ")");
  SurfaceMesh s;
  s.rows = grid.m * std::uint32_t(per_cell) + 1;
  s.cols = grid.n * std::uint32_t(per_cell) + 1;
  s.points.resize(std::size_t(s.rows) * s.cols);
  s.normals.resize(s.points.size());
  std::vector<Basis> bv(s.cols);
  for (std::uint32_t b = 0; b < s.cols; ++b) bv[b] = basis(kind, grid.n, double(b) / per_cell);
  for (std::uint32_t a = 0; a < s.rows; ++a) {
    const Basis bu = basis(kind, grid.m, double(a) / per_cell);
    for (std::uint32_t b = 0; b < s.cols; ++b) {
      const SurfacePoint sp = evaluate(grid, bu, bv[b]);
      const std::size_t k = std::size_t(a) * s.cols + b;
      s.points[k] = sp.p;
      // On a grid point the grid scheme is the point itself (bit for bit, −0 included).
      if (kind == SurfaceKind::Grid && a % per_cell == 0 && b % per_cell == 0) {
        const std::size_t g = std::size_t(a / per_cell) * (grid.n + 1) + b / per_cell;
        s.points[k] = {grid.x[g], grid.y[g], grid.z[g]};
      }
      // dv × du: the +z side of a sheet whose columns j run along x and rows i along y
      const Vec3 c{sp.dv.y * sp.du.z - sp.dv.z * sp.du.y, sp.dv.z * sp.du.x - sp.dv.x * sp.du.z,
                   sp.dv.x * sp.du.y - sp.dv.y * sp.du.x};
      const double len = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
      s.normals[k] = len > 0 && std::isfinite(len) ? Vec3{c.x / len, c.y / len, c.z / len} : Vec3{0, 0, 0};
    }
  }
  return s;
}

}  // namespace drape::render
