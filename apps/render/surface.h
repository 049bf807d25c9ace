// drape::render surfaces: the smooth surface a sheet's control grid defines, evaluated at a
// chosen resolution with normals, for shaded pictures and glTF export. Geometry only: the
// simulated state stays the grid (OBJ, PLY and VTU frames keep it exactly).
//
// Parameters: u ∈ [0, m] runs along the grid's rows i, v ∈ [0, n] along its columns j, so
// (u, v) = (i, j) names grid point (i, j) where a scheme passes through it.
//
//   Grid     the grid itself: bilinear over each cell; passes through every point.
//   Bezier   the paper's Bézier surfaces with the grid as control points (§4), as bicubic
//            pieces: piece (p, q) is the tensor Bézier patch over grid rows 3p..3p+3 and
//            columns 3q..3q+3 (the last piece in a direction has degree m mod 3 or n mod 3 when
//            the grid is not a multiple of 3). Neighbouring pieces share their boundary row of
//            control points, so the surface is continuous (C0) and passes through every third
//            grid point. Why pieces and not one patch of degree m × n: the scenes' grids have
//            10 to 100 cells a side, and one patch of degree 100 lies far from its control
//            points (it keeps only the overall shape: a cloth over a sphere would cut into the
//            sphere) and costs O(m + n) per sample; a grid of up to 3 × 3 cells is one patch.
//   BSpline  the uniform bicubic B-spline of the grid, one piece per cell, C2 everywhere.
//            Its end conditions are phantom points reflected through the border
//            (P₋₁ = 2P₀ − P₁), so the surface reaches the sheet's border and passes through its
//            four corners, and a flat uniform grid stays exactly itself.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "render/render.h"

namespace drape::render {

// SurfaceKind (Grid, Bezier, BSpline) is declared in render.h, whose options name it.
std::string_view surface_kind_name(SurfaceKind kind);                   // "grid", "bezier", "bspline"
std::optional<SurfaceKind> surface_kind_from_name(std::string_view name);

// A point of the surface with its partial derivatives along u and v.
struct SurfacePoint {
  Vec3 p, du, dv;
};

// Evaluates the surface at (u, v), clamped to [0, m] × [0, n]. On a piece boundary the piece
// after it is used (the last piece at u = m). The sheet must have (m+1)·(n+1) points.
SurfacePoint surface_point(const SheetMesh& grid, SurfaceKind kind, double u, double v);

// The surface sampled `per_cell` times along each grid cell: (m·per_cell + 1) × (n·per_cell + 1)
// points, row-major like the grid (sample (a, b) at u = a/per_cell, v = b/per_cell), with unit
// normals dv × du (the side the exported quads face: +z for a sheet as SheetDef lays it out,
// columns j along x and rows i along y; zero where the surface is degenerate). With kind Grid and per_cell 1 the points are the grid's, bit for bit.
struct SurfaceMesh {
  std::uint32_t rows = 0, cols = 0;  // samples along u and v
  std::vector<Vec3> points, normals;
  Vec3 point(std::uint32_t a, std::uint32_t b) const { return points[std::size_t(a) * cols + b]; }
};
SurfaceMesh sample_surface(const SheetMesh& grid, SurfaceKind kind, int per_cell);

}  // namespace drape::render
