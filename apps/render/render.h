// drape::render: a small software rasteriser that draws sheets as their grid lines and
// obstacles as wireframes, like the paper's figures, and reads/writes PNG files.
// Everything here is a plain value or a free function; nothing keeps global state.
//
// Camera model (the contract tests rely on): a pinhole at `eye` looking at `target`.
// forward f = normalize(target − eye), right r = normalize(f × up), image-up u = r × f.
// A point p with d = p − eye and depth z = d·f > 0 lands at the continuous image position
//   sx = width/2  + F·(d·r)/z,   sy = height/2 − F·(d·u)/z,   F = (height/2)/tan(fov_deg/2),
// i.e. fov_deg is the vertical field of view, x grows to the right, y grows downwards, and
// pixel (px, py) covers [px, px+1) × [py, py+1).
#pragma once

#include <drape/obstacle.h>
#include <drape/types.h>
#include <drape/world.h>

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace drape::render {

// One sheet's current points, row-major as in eqs (2)–(3): point (i, j) is x[i·(n+1)+j],
// (m+1)·(n+1) points. The spans are only read during render_wireframe().
struct SheetMesh {
  std::uint32_t m = 0, n = 0;
  std::span<const double> x, y, z;
};

// A double-precision world's sheet, without copying (the view must outlive the render).
inline SheetMesh sheet_mesh(const SheetView<double>& v) { return {v.m, v.n, v.x, v.y, v.z}; }

// An axis-aligned box in world coordinates (m). Empty until something is added.
struct Bounds {
  Vec3 lo{1, 1, 1}, hi{-1, -1, -1};
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  void add(Vec3 p);
  void add(const Bounds& b);
};

// What a picture contains: every sheet point and every bounded obstacle. Planes are
// infinite and are left out (they are drawn as a patch under the rest of the content).
Bounds scene_bounds(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles);

// An obstacle as triangles, for shading and export: points with outward unit normals and
// counter-clockwise (seen from outside) index triples. A plane is the square patch the
// wireframe draws under `content` (1.2 content diagonals across); a box has flat faces.
struct TriangleMesh {
  std::vector<Vec3> points, normals;
  std::vector<std::uint32_t> triangles;
};
TriangleMesh obstacle_mesh(const ObstacleDef& obstacle, const Bounds& content);

struct Camera {
  Vec3 eye{3, -4, 2.5};
  Vec3 target{0, 0, 0};
  Vec3 up{0, 0, 1};
  double fov_deg = 35;  // vertical field of view, degrees, in (0, 180)

  // The automatic framing: an oblique view from the front right (azimuth −55° from +x) and
  // above (elevation 28°), z up, like the paper's figures; aimed so the box's eight corners are
  // centred in a picture of the given aspect ratio (width/height) and as close as keeps them
  // inside 92% of it. An empty box frames the unit cube around the origin.
  static Camera looking_at_bounds(const Bounds& box, double aspect = 4.0 / 3.0, double fov_deg = 35);
};

// An empty string when the camera can render; otherwise one message naming the problem,
// e.g. "camera eye and target are the same point (1, 2, 3)".
std::string validate(const Camera& camera);

// Parses a camera description such as "eye=4,-3,2;target=0,0,0;up=0,0,1;fov=35".
// Keys (each at most once, any order, separated by ';'): eye, target, up (x,y,z in m) and
// fov (vertical degrees). Keys not given keep `base`'s values, so "fov=50" only zooms the
// automatic framing. Throws std::invalid_argument with one message naming the key, the text
// and the problem; the result is validated as a whole.
Camera parse_camera(std::string_view spec, const Camera& base = {});

// The camera as a string parse_camera() reads back exactly (shortest round-trip numbers),
// e.g. for a program to print the automatic framing so a user can start from it.
std::string format_camera(const Camera& camera);

// An RGB picture, 8 bits per channel, rows top to bottom, no padding.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;

  Image() = default;
  Image(int w, int h, std::array<std::uint8_t, 3> fill = {255, 255, 255});
  std::array<std::uint8_t, 3> pixel(int px, int py) const;
  void set_pixel(int px, int py, std::array<std::uint8_t, 3> c);
};

// The surface a sheet's control grid defines (surface.h says how each is evaluated).
enum class SurfaceKind { Grid, Bezier, BSpline };

struct RenderOptions {
  std::array<std::uint8_t, 3> background{255, 255, 255};
  std::array<std::uint8_t, 3> sheet_color{25, 25, 30};
  std::array<std::uint8_t, 3> obstacle_color{30, 90, 185};
  double line_width = 1.0;    // output pixels
  int supersampling = 3;      // samples per pixel along each axis (anti-aliasing), 1..8; 1: none.
                              // Lowered for huge pictures so the buffers stay under ~64 M samples.
  double depth_fade = 0.55;   // far lines are blended this much towards the background
  bool opaque_sheets = true;  // sheets hide what is behind them (hidden-line drawing)
  // render_shaded only:
  std::array<std::uint8_t, 3> front_color{226, 139, 58};  // the sheet's +z side (where its quads face)
  std::array<std::uint8_t, 3> back_color{72, 118, 196};
  std::array<std::uint8_t, 3> solid_color{176, 178, 184};  // obstacles
  SurfaceKind surface = SurfaceKind::Grid;
  int surface_samples = 1;  // per grid cell along each direction, 1..64
};

// Draws every sheet as its grid lines and every obstacle as a wireframe (longitude and
// latitude curves and the outline for spheres and ellipsoids, tube rings and the outline for
// the torus, edges for the box, a grid patch for a plane). Obstacles, and sheets when
// options.opaque_sheets, hide the lines behind them. Throws std::invalid_argument for a bad
// camera, size (1..8192 pixels per side) or sheet (span sizes not (m+1)·(n+1)).
Image render_wireframe(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles,
                       const Camera& camera, int width, int height, const RenderOptions& options = {});

// Draws every sheet as its lit surface (options.surface sampled options.surface_samples times
// per cell, smooth normals), the front side and the back side in their two colours (sheet k
// at 1 − 0.14·(k mod 4) of their brightness, so stacked sheets stay apart), and every
// obstacle as a lit solid, with a depth buffer. One light comes from over the camera's left
// shoulder; a face turned away from it keeps an ambient third of its colour. Same errors as
// render_wireframe().
Image render_shaded(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles, const Camera& camera,
                    int width, int height, const RenderOptions& options = {});

// Writes an 8-bit RGB PNG. The data go to a temporary file in the same folder, which is
// renamed to `path` only when complete; on failure the temporary file is removed, `path` is
// untouched, and std::runtime_error says which path and why.
void write_png(const Image& image, const std::string& path);

// Reads any PNG as 8-bit RGB. Throws std::runtime_error naming the path and the reason.
Image read_png(const std::string& path);

}  // namespace drape::render
