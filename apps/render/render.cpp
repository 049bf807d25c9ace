// The wireframe rasteriser behind `drape render`.
//
// Pipeline: every sheet and obstacle becomes (a) filled triangles that only write a depth
// buffer and (b) line segments that are drawn where nothing filled is in front of them
// (hidden-line drawing, with a slope-scaled depth offset so a line is never hidden by the
// surface it lies on). Everything is drawn at `supersampling`² samples per pixel and averaged
// down, which anti-aliases the lines. Depth is stored as w = 1/z, which is affine in screen
// space, so interpolating it along lines and over triangles is perspective-correct.
#include "render/render.h"
#include "render/surface.h"

#include <png.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fcntl.h>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <sys/stat.h>
#include <unistd.h>

namespace drape::render {

namespace {

constexpr double pi = std::numbers::pi;

Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double norm(Vec3 a) { return std::sqrt(dot(a, a)); }
Vec3 normalized(Vec3 a) { return (1.0 / norm(a)) * a; }
bool finite(Vec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }

std::string fmt_vec(Vec3 v) {
  std::ostringstream s;
  s << '(' << v.x << ", " << v.y << ", " << v.z << ')';
  return s.str();
}

// Half extents, along the world axes, of a box with local half extents h turned by q.
Vec3 rotated_box_extent(const Quat& q, Vec3 h) {
  const Vec3 a = rotate(q, {1, 0, 0}), b = rotate(q, {0, 1, 0}), c = rotate(q, {0, 0, 1});
  return {std::abs(a.x) * h.x + std::abs(b.x) * h.y + std::abs(c.x) * h.z,
          std::abs(a.y) * h.x + std::abs(b.y) * h.y + std::abs(c.y) * h.z,
          std::abs(a.z) * h.x + std::abs(b.z) * h.y + std::abs(c.z) * h.z};
}

Bounds obstacle_bounds(const ObstacleDef& o) {
  Vec3 h{};
  switch (o.shape) {
    case ObstacleShape::Plane: return {};
    case ObstacleShape::Sphere: h = {o.size.x, o.size.x, o.size.x}; break;
    case ObstacleShape::Ellipsoid: {
      // Exact: the support of an ellipsoid along axis e is sqrt(Σ_j (R_j·e)² s_j²).
      const Vec3 a = rotate(o.orientation, {1, 0, 0}), b = rotate(o.orientation, {0, 1, 0}),
                 c = rotate(o.orientation, {0, 0, 1});
      const Vec3 s = o.size;
      auto ext = [&](double ax, double bx, double cx) {
        return std::sqrt(ax * ax * s.x * s.x + bx * bx * s.y * s.y + cx * cx * s.z * s.z);
      };
      h = {ext(a.x, b.x, c.x), ext(a.y, b.y, c.y), ext(a.z, b.z, c.z)};
      break;
    }
    case ObstacleShape::Torus:
      h = rotated_box_extent(o.orientation, {o.size.x + o.size.y, o.size.x + o.size.y, o.size.y});
      break;
    case ObstacleShape::Box: h = rotated_box_extent(o.orientation, o.size); break;
  }
  Bounds b;
  b.add(o.center - h);
  b.add(o.center + h);
  return b;
}

void check_sheet(const SheetMesh& s, std::size_t index) {
  const std::size_t expected = static_cast<std::size_t>(s.m + 1) * (s.n + 1);
  if (s.x.size() != expected || s.y.size() != expected || s.z.size() != expected) {
    std::ostringstream msg;
    msg << "render: sheet " << index << " is a " << s.m << "x" << s.n << " grid, so it needs " << expected
        << " points, but has " << s.x.size() << "/" << s.y.size() << "/" << s.z.size() << " x/y/z values";
    throw std::invalid_argument(msg.str());
  }
}

Vec3 sheet_point(const SheetMesh& s, std::size_t k) { return {s.x[k], s.y[k], s.z[k]}; }

// ---------------------------------------------------------------------------------------
// The canvas: a supersampled depth buffer for filled surfaces and a colour + depth buffer
// for lines, with the camera transform that maps world points onto it.

class Canvas {
 public:
  Canvas(const Camera& cam, int width, int height, const RenderOptions& opt, const Bounds& content)
      : opt_(opt), ss_(std::max(1, opt.supersampling)), w_(width * ss_), h_(height * ss_) {
    eye_ = cam.eye;
    f_ = normalized(cam.target - cam.eye);
    r_ = normalized(cross(f_, cam.up));
    u_ = cross(r_, f_);
    focal_ = (0.5 * h_) / std::tan(cam.fov_deg * pi / 360.0);
    near_ = 1e-4 * norm(cam.target - cam.eye);
    half_width_ = 0.5 * std::max(opt.line_width, 1e-3) * ss_;
    surface_.assign(static_cast<std::size_t>(w_) * h_, 0.0f);
    line_depth_.assign(static_cast<std::size_t>(w_) * h_, 0.0f);
    line_color_.assign(static_cast<std::size_t>(w_) * h_, opt.background);

    // Depth range of the content, for fading far lines.
    z_near_ = std::numeric_limits<double>::infinity();
    z_far_ = -z_near_;
    if (!content.empty()) {
      for (int k = 0; k < 8; ++k) {
        const Vec3 p{k & 1 ? content.hi.x : content.lo.x, k & 2 ? content.hi.y : content.lo.y,
                     k & 4 ? content.hi.z : content.lo.z};
        const double z = dot(p - eye_, f_);
        z_near_ = std::min(z_near_, z);
        z_far_ = std::max(z_far_, z);
      }
    }
    z_near_ = std::max(z_near_, near_);
    if (!(z_far_ > z_near_)) z_far_ = z_near_ * 2 + 1;
  }

  // Filled triangle: writes depth only (pushed back by a slope-scaled offset).
  void fill_triangle(Vec3 a, Vec3 b, Vec3 c) {
    if (!finite(a) || !finite(b) || !finite(c)) return;
    // Clip against the near plane in eye space (Sutherland–Hodgman), then fan.
    Vec3 in[3] = {to_eye(a), to_eye(b), to_eye(c)};
    Vec3 poly[4];
    int count = 0;
    for (int i = 0; i < 3; ++i) {
      const Vec3 p = in[i], q = in[(i + 1) % 3];
      const bool p_in = p.z >= near_, q_in = q.z >= near_;
      if (p_in) poly[count++] = p;
      if (p_in != q_in) poly[count++] = p + ((near_ - p.z) / (q.z - p.z)) * (q - p);
    }
    for (int i = 1; i + 1 < count; ++i) raster_triangle(poly[0], poly[i], poly[i + 1]);
  }

  void draw_line(Vec3 a, Vec3 b, std::array<std::uint8_t, 3> color) {
    if (!finite(a) || !finite(b)) return;
    Vec3 p = to_eye(a), q = to_eye(b);
    if (p.z < near_ && q.z < near_) return;
    if (p.z < near_) p = p + ((near_ - p.z) / (q.z - p.z)) * (q - p);
    if (q.z < near_) q = q + ((near_ - q.z) / (p.z - q.z)) * (p - q);
    raster_line(project(p), project(q), color);
  }

  void draw_polyline(std::span<const Vec3> pts, std::array<std::uint8_t, 3> color) {
    for (std::size_t i = 0; i + 1 < pts.size(); ++i) draw_line(pts[i], pts[i + 1], color);
  }

  Image resolve(int width, int height) const {
    Image img(width, height, opt_.background);
    const double inv = 1.0 / (ss_ * ss_);
    for (int py = 0; py < height; ++py) {
      for (int px = 0; px < width; ++px) {
        double acc[3] = {0, 0, 0};
        for (int sy = 0; sy < ss_; ++sy) {
          for (int sx = 0; sx < ss_; ++sx) {
            const std::size_t k = static_cast<std::size_t>(py * ss_ + sy) * w_ + (px * ss_ + sx);
            for (int ch = 0; ch < 3; ++ch) acc[ch] += line_color_[k][ch];
          }
        }
        img.set_pixel(px, py,
                      {static_cast<std::uint8_t>(std::lround(acc[0] * inv)),
                       static_cast<std::uint8_t>(std::lround(acc[1] * inv)),
                       static_cast<std::uint8_t>(std::lround(acc[2] * inv))});
      }
    }
    return img;
  }

  Vec3 eye() const { return eye_; }

 private:
  struct Screen {
    double x, y, w;  // supersampled pixel coordinates, w = 1/z
  };

  Vec3 to_eye(Vec3 p) const {
    const Vec3 d = p - eye_;
    return {dot(d, r_), dot(d, u_), dot(d, f_)};
  }
  Screen project(Vec3 e) const {
    return {0.5 * w_ + focal_ * e.x / e.z, 0.5 * h_ - focal_ * e.y / e.z, 1.0 / e.z};
  }

  void raster_triangle(Vec3 ea, Vec3 eb, Vec3 ec) {
    const Screen a = project(ea), b = project(eb), c = project(ec);
    const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(std::abs(area) > 1e-12)) return;
    const Plane w = plane(a, b, c, a.w, b.w, c.w, area);
    // A line on this surface is sampled up to half a line width plus a sample away from
    // where its depth was computed: push the surface back by that much of its slope.
    const double offset = (std::abs(w.ddx) + std::abs(w.ddy)) * (half_width_ + 1.5);
    scan(a, b, c, area, [&](int x, int y) {
      float& stored = surface_[static_cast<std::size_t>(y) * w_ + x];
      stored = std::max(stored, static_cast<float>(w.at(x + 0.5, y + 0.5) * (1 - 1e-4) - offset));
    });
  }

 public:
  // A triangle of the shaded picture: depth-tested, its colour interpolated from its corners'.
  void shade_triangle(Vec3 pa, Vec3 pb, Vec3 pc, const std::array<double, 3> (&rgb)[3]) {
    if (!finite(pa) || !finite(pb) || !finite(pc)) return;
    const Vec3 ea = to_eye(pa), eb = to_eye(pb), ec = to_eye(pc);
    if (ea.z < near_ || eb.z < near_ || ec.z < near_) return;  // shaded scenes sit in front of the camera
    const Screen a = project(ea), b = project(eb), c = project(ec);
    const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(std::abs(area) > 1e-12)) return;
    const Plane w = plane(a, b, c, a.w, b.w, c.w, area);
    Plane ch[3];
    for (int k = 0; k < 3; ++k) ch[k] = plane(a, b, c, rgb[0][k], rgb[1][k], rgb[2][k], area);
    scan(a, b, c, area, [&](int x, int y) {
      const std::size_t k = static_cast<std::size_t>(y) * w_ + x;
      const double px = x + 0.5, py = y + 0.5;
      const float depth = static_cast<float>(w.at(px, py));
      if (depth <= surface_[k]) return;
      surface_[k] = depth;
      auto channel = [&](int i) { return static_cast<std::uint8_t>(std::lround(std::clamp(ch[i].at(px, py), 0.0, 255.0))); };
      line_color_[k] = {channel(0), channel(1), channel(2)};
    });
  }
  Vec3 right() const { return r_; }
  Vec3 up() const { return u_; }
  Vec3 forward() const { return f_; }

 private:
  // An attribute affine over the screen: value = v0 + ddx·(x − x0) + ddy·(y − y0).
  struct Plane {
    double x0, y0, v0, ddx, ddy;
    double at(double x, double y) const { return v0 + ddx * (x - x0) + ddy * (y - y0); }
  };
  static Plane plane(const Screen& a, const Screen& b, const Screen& c, double va, double vb, double vc, double area) {
    return {a.x, a.y, va, ((vb - va) * (c.y - a.y) - (vc - va) * (b.y - a.y)) / area,
            ((vc - va) * (b.x - a.x) - (vb - va) * (c.x - a.x)) / area};
  }

  // Calls fn(x, y) for every sample whose centre the triangle covers.
  template <class F>
  void scan(const Screen& a, const Screen& b, const Screen& c, double area, F&& fn) {
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x, b.x, c.x}))));
    const int x1 = std::min(w_ - 1, static_cast<int>(std::ceil(std::max({a.x, b.x, c.x}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y, b.y, c.y}))));
    const int y1 = std::min(h_ - 1, static_cast<int>(std::ceil(std::max({a.y, b.y, c.y}))));
    const double sign = area > 0 ? 1.0 : -1.0;
    // Edge k is inside where e_k(px, py) = sign·((q.x − p.x)(py − p.y) − (q.y − p.y)(px − p.x)) ≥ 0:
    // linear in px along a row, so each row's covered span is found, not searched for.
    const Screen pts[3] = {a, b, c};
    for (int y = y0; y <= y1; ++y) {
      const double py = y + 0.5;
      double lo = x0 + 0.5, hi = x1 + 0.5;
      for (int k = 0; k < 3; ++k) {
        const Screen& p = pts[k];
        const Screen& q = pts[(k + 1) % 3];
        const double slope = -sign * (q.y - p.y);  // de/dpx
        const double at_p = sign * (q.x - p.x) * (py - p.y);
        if (slope == 0) {
          if (at_p < 0) hi = lo - 1;
        } else if (slope > 0) {
          lo = std::max(lo, p.x - at_p / slope);
        } else {
          hi = std::min(hi, p.x - at_p / slope);
        }
      }
      if (!(hi >= lo)) continue;
      const int first = std::max(x0, static_cast<int>(std::ceil(lo - 0.5)));
      const int last = std::min(x1, static_cast<int>(std::floor(hi - 0.5)));
      for (int x = first; x <= last; ++x) fn(x, y);
    }
  }

  void raster_line(Screen a, Screen b, std::array<std::uint8_t, 3> color) {
    // Clip the parameter range to the canvas (plus the line's half width): Liang–Barsky.
    const double pad = half_width_ + 1;
    double t0 = 0, t1 = 1;
    const double dx = b.x - a.x, dy = b.y - a.y;
    auto clip = [&](double p, double q) {
      if (p == 0) return q >= 0;
      const double t = q / p;
      if (p < 0) {
        if (t > t1) return false;
        t0 = std::max(t0, t);
      } else {
        if (t < t0) return false;
        t1 = std::min(t1, t);
      }
      return true;
    };
    if (!clip(-dx, a.x + pad) || !clip(dx, w_ + pad - a.x) || !clip(-dy, a.y + pad) ||
        !clip(dy, h_ + pad - a.y))
      return;
    const Screen p{a.x + t0 * dx, a.y + t0 * dy, a.w + t0 * (b.w - a.w)};
    const Screen q{a.x + t1 * dx, a.y + t1 * dy, a.w + t1 * (b.w - a.w)};

    const bool x_major = std::abs(dx) >= std::abs(dy);
    const double major0 = x_major ? p.x : p.y, major1 = x_major ? q.x : q.y;
    const double minor0 = x_major ? p.y : p.x, minor1 = x_major ? q.y : q.x;
    const double dmajor = major1 - major0, dminor = minor1 - minor0;
    const double len = std::hypot(dmajor, dminor);
    // Half thickness measured along the minor axis keeps the perpendicular width constant.
    const double half = len > 0 ? half_width_ * len / std::abs(dmajor) : half_width_;
    const int m_first = static_cast<int>(std::floor(std::min(major0, major1)));
    const int m_last = static_cast<int>(std::floor(std::max(major0, major1)));
    const int m_limit = x_major ? w_ : h_, n_limit = x_major ? h_ : w_;
    for (int mj = std::max(0, m_first); mj <= std::min(m_limit - 1, m_last); ++mj) {
      // Position along the segment at this sample column, clamped to the segment.
      double t = dmajor != 0 ? (mj + 0.5 - major0) / dmajor : 0.0;
      t = std::clamp(t, 0.0, 1.0);
      const double mn = minor0 + t * dminor;
      const double w = p.w + t * (q.w - p.w);
      const int n_first = std::max(0, static_cast<int>(std::ceil(mn - half - 0.5)));
      const int n_last = std::min(n_limit - 1, static_cast<int>(std::floor(mn + half - 0.5)));
      for (int nj = n_first; nj <= n_last; ++nj) {
        const int x = x_major ? mj : nj, y = x_major ? nj : mj;
        plot(static_cast<std::size_t>(y) * w_ + x, w, color);
      }
    }
  }

  void plot(std::size_t k, double w, std::array<std::uint8_t, 3> color) {
    const float wf = static_cast<float>(w);
    if (wf < surface_[k] || wf <= line_depth_[k]) return;
    line_depth_[k] = wf;
    // Depth cue: far lines fade towards the background.
    const double t = std::clamp((1.0 / w - z_near_) / (z_far_ - z_near_), 0.0, 1.0) * opt_.depth_fade;
    auto mix = [&](int ch) {
      return static_cast<std::uint8_t>(std::lround(color[ch] + t * (opt_.background[ch] - color[ch])));
    };
    line_color_[k] = {mix(0), mix(1), mix(2)};
  }

  const RenderOptions& opt_;
  int ss_, w_, h_;
  Vec3 eye_{}, r_{}, u_{}, f_{};
  double focal_ = 1, near_ = 1e-6, half_width_ = 1, z_near_ = 0, z_far_ = 1;
  std::vector<float> surface_;
  std::vector<float> line_depth_;  // 0: no line drawn at this sample
  std::vector<std::array<std::uint8_t, 3>> line_color_;  // background where no line
};

// Every hiding surface's depth goes into the canvas before any line is drawn, so each
// drawing function runs twice: once for its surfaces, once for its lines.
enum class Pass { Surfaces, Lines };

// ---------------------------------------------------------------------------------------
// Obstacles. Curved ones are parametric surfaces P(u, v) with outward normals N(u, v):
// u ∈ [0, 2π) is periodic; v ∈ [0, π] from pole to pole (sphere, ellipsoid) or periodic
// (torus tube). Each gives a fill mesh, iso-parameter wire curves and its outline.

struct CurvedSurface {
  const ObstacleDef& o;
  bool v_periodic;
  int nu, nv;           // fill-mesh cells
  int wire_u, wire_v;   // a wire curve every this many cells

  double v_max() const { return v_periodic ? 2 * pi : pi; }
  double u_at(int i) const { return 2 * pi * i / nu; }
  double v_at(int j) const { return v_max() * j / nv; }

  Vec3 point(double u, double v) const {
    const Vec3 s = o.size;
    Vec3 local;
    if (o.shape == ObstacleShape::Torus) {
      const double ring = s.x + s.y * std::cos(v);
      local = {ring * std::cos(u), ring * std::sin(u), s.y * std::sin(v)};
    } else {
      const Vec3 axes = o.shape == ObstacleShape::Sphere ? Vec3{s.x, s.x, s.x} : s;
      local = {axes.x * std::cos(u) * std::sin(v), axes.y * std::sin(u) * std::sin(v), axes.z * std::cos(v)};
    }
    return o.center + rotate(o.orientation, local);
  }
  Vec3 normal(double u, double v) const {
    const Vec3 s = o.size;
    Vec3 local;
    if (o.shape == ObstacleShape::Torus) {
      local = {std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v)};
    } else {
      const Vec3 axes = o.shape == ObstacleShape::Sphere ? Vec3{s.x, s.x, s.x} : s;
      local = {std::cos(u) * std::sin(v) / axes.x, std::sin(u) * std::sin(v) / axes.y, std::cos(v) / axes.z};
    }
    return rotate(o.orientation, local);
  }
};

void draw_curved(Canvas& canvas, const CurvedSurface& s, std::array<std::uint8_t, 3> color, Pass pass) {
  const int nu = s.nu, nv = s.nv;
  std::vector<Vec3> grid(static_cast<std::size_t>(nu + 1) * (nv + 1));
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) grid[j * (nu + 1) + i] = s.point(s.u_at(i), s.v_at(j));
  auto at = [&](int i, int j) { return grid[j * (nu + 1) + i]; };
  if (pass == Pass::Surfaces) {
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        canvas.fill_triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1));
        canvas.fill_triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1));
      }
    return;
  }
  // Wire curves: constant u (meridians / tube rings) and constant v (parallels / rings
  // along the tube), drawn through every fill-mesh vertex so they look smooth.
  std::vector<Vec3> curve;
  for (int i = 0; i < nu; i += s.wire_u) {
    curve.clear();
    for (int j = 0; j <= nv; ++j) curve.push_back(at(i, j));
    canvas.draw_polyline(curve, color);
  }
  for (int j = s.v_periodic ? 0 : s.wire_v; j < (s.v_periodic ? nv : nv - s.wire_v + 1); j += s.wire_v) {
    curve.clear();
    for (int i = 0; i <= nu; ++i) curve.push_back(at(i, j));
    canvas.draw_polyline(curve, color);
  }
  // Outline: where the surface turns away from the eye, g(u, v) = N·(P − eye) = 0.
  // Marching squares on the parameter grid; crossing points are evaluated on the exact
  // surface, so the outline is accurate to far below a pixel.
  const Vec3 eye = canvas.eye();
  std::vector<double> g(grid.size());
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i)
      g[j * (nu + 1) + i] = dot(s.normal(s.u_at(i), s.v_at(j)), at(i, j) - eye);
  auto gv = [&](int i, int j) { return g[j * (nu + 1) + i]; };
  auto crossing = [&](int i0, int j0, int i1, int j1) {
    const double g0 = gv(i0, j0), g1 = gv(i1, j1);
    const double t = g0 / (g0 - g1);
    const double u = s.u_at(i0) + t * (s.u_at(i1) - s.u_at(i0));
    const double v = s.v_at(j0) + t * (s.v_at(j1) - s.v_at(j0));
    return s.point(u, v);
  };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      // Cell edges in order: bottom (i,j)-(i+1,j), right, top, left.
      const int ends[4][4] = {{i, j, i + 1, j}, {i + 1, j, i + 1, j + 1}, {i + 1, j + 1, i, j + 1}, {i, j + 1, i, j}};
      Vec3 pts[4];
      int count = 0;
      for (const auto& e : ends) {
        const double g0 = gv(e[0], e[1]), g1 = gv(e[2], e[3]);
        if ((g0 < 0) != (g1 < 0)) pts[count++] = crossing(e[0], e[1], e[2], e[3]);
      }
      if (count >= 2) canvas.draw_line(pts[0], pts[1], color);
      if (count == 4) canvas.draw_line(pts[2], pts[3], color);
    }
  }
}

void draw_box(Canvas& canvas, const ObstacleDef& o, std::array<std::uint8_t, 3> color, Pass pass) {
  Vec3 c[8];
  for (int k = 0; k < 8; ++k) {
    const Vec3 local{k & 1 ? o.size.x : -o.size.x, k & 2 ? o.size.y : -o.size.y, k & 4 ? o.size.z : -o.size.z};
    c[k] = o.center + rotate(o.orientation, local);
  }
  if (pass == Pass::Surfaces) {
    // Faces as corner-index quads (bit 0: x, bit 1: y, bit 2: z).
    const int faces[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    for (const auto& f : faces) {
      canvas.fill_triangle(c[f[0]], c[f[1]], c[f[2]]);
      canvas.fill_triangle(c[f[0]], c[f[2]], c[f[3]]);
    }
    return;
  }
  for (int a = 0; a < 8; ++a)
    for (int bit = 1; bit < 8; bit <<= 1)
      if (!(a & bit)) canvas.draw_line(c[a], c[a | bit], color);
}

// An infinite plane is drawn as a square grid patch under the rest of the content: centred
// on the content's centre projected onto the plane, 1.2 content diagonals across.
struct PlanePatch {
  Vec3 ex, ey, nz, mid;
  double half;
  Vec3 at(double a, double b) const { return mid + (a * half) * ex + (b * half) * ey; }
};
PlanePatch plane_patch(const ObstacleDef& o, const Bounds& content) {
  PlanePatch p{rotate(o.orientation, {1, 0, 0}), rotate(o.orientation, {0, 1, 0}), rotate(o.orientation, {0, 0, 1}),
               o.center, 1.0};
  if (!content.empty()) {
    const Vec3 cc = 0.5 * (content.lo + content.hi);
    p.mid = cc - dot(cc - o.center, p.nz) * p.nz;
    p.half = std::max(0.6 * norm(content.hi - content.lo), 1e-3);
  }
  return p;
}

void draw_plane(Canvas& canvas, const ObstacleDef& o, const Bounds& content, std::array<std::uint8_t, 3> color,
                Pass pass) {
  const PlanePatch patch = plane_patch(o, content);
  constexpr int cells = 12;
  auto at = [&](double a, double b) { return patch.at(a, b); };
  if (pass == Pass::Surfaces) {
    canvas.fill_triangle(at(-1, -1), at(1, -1), at(1, 1));
    canvas.fill_triangle(at(-1, -1), at(1, 1), at(-1, 1));
    return;
  }
  for (int k = 0; k <= cells; ++k) {
    const double t = -1 + 2.0 * k / cells;
    canvas.draw_line(at(t, -1), at(t, 1), color);
    canvas.draw_line(at(-1, t), at(1, t), color);
  }
}

// The fill-mesh resolution of each curved obstacle, shared by the wireframe and the meshes.
CurvedSurface curved_surface(const ObstacleDef& o) {
  return o.shape == ObstacleShape::Torus ? CurvedSurface{o, true, 144, 48, 6, 12} : CurvedSurface{o, false, 96, 48, 8, 8};
}

void draw_obstacle(Canvas& canvas, const ObstacleDef& o, const Bounds& content, std::array<std::uint8_t, 3> color,
                   Pass pass) {
  switch (o.shape) {
    case ObstacleShape::Plane: draw_plane(canvas, o, content, color, pass); break;
    case ObstacleShape::Sphere:
    case ObstacleShape::Ellipsoid:
    case ObstacleShape::Torus: draw_curved(canvas, curved_surface(o), color, pass); break;
    case ObstacleShape::Box: draw_box(canvas, o, color, pass); break;
  }
}

void draw_sheet(Canvas& canvas, const SheetMesh& s, std::array<std::uint8_t, 3> color, Pass pass) {
  const std::uint32_t cols = s.n + 1;
  auto at = [&](std::uint32_t i, std::uint32_t j) { return sheet_point(s, static_cast<std::size_t>(i) * cols + j); };
  if (pass == Pass::Surfaces) {
    for (std::uint32_t i = 0; i < s.m; ++i)
      for (std::uint32_t j = 0; j < s.n; ++j) {
        canvas.fill_triangle(at(i, j), at(i, j + 1), at(i + 1, j + 1));
        canvas.fill_triangle(at(i, j), at(i + 1, j + 1), at(i + 1, j));
      }
    return;
  }
  // Fig 1: the grid lines are the springs, horizontal (along j) and vertical (along i).
  for (std::uint32_t i = 0; i <= s.m; ++i)
    for (std::uint32_t j = 0; j < s.n; ++j) canvas.draw_line(at(i, j), at(i, j + 1), color);
  for (std::uint32_t i = 0; i < s.m; ++i)
    for (std::uint32_t j = 0; j <= s.n; ++j) canvas.draw_line(at(i, j), at(i + 1, j), color);
}

// ---------------------------------------------------------------------------------------
// Camera string parsing.

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

double parse_number(std::string_view key, std::string_view text) {
  const std::string_view t = trim(text);
  double value = 0;
  const char* first = t.data();
  const char* last = t.data() + t.size();
  if (!t.empty() && *first == '+') ++first;
  const auto [end, ec] = std::from_chars(first, last, value);
  if (t.empty() || ec != std::errc{} || end != last)
    throw std::invalid_argument("camera: " + std::string(key) + ": \"" + std::string(t) + "\" is not a number");
  if (!std::isfinite(value))
    throw std::invalid_argument("camera: " + std::string(key) + ": " + std::string(t) + " is not finite");
  return value;
}

Vec3 parse_vec3(std::string_view key, std::string_view text) {
  double v[3];
  int count = 0;
  std::string_view rest = text;
  while (true) {
    const std::size_t comma = rest.find(',');
    if (count == 3)
      throw std::invalid_argument("camera: " + std::string(key) + " needs three numbers x,y,z, got \"" +
                                  std::string(trim(text)) + "\"");
    v[count++] = parse_number(key, rest.substr(0, comma));
    if (comma == std::string_view::npos) break;
    rest.remove_prefix(comma + 1);
  }
  if (count != 3)
    throw std::invalid_argument("camera: " + std::string(key) + " needs three numbers x,y,z, got \"" +
                                std::string(trim(text)) + "\"");
  return {v[0], v[1], v[2]};
}

std::string errno_text(int e) { return std::strerror(e); }

}  // namespace

// ---------------------------------------------------------------------------------------

void Bounds::add(Vec3 p) {
  if (empty()) {
    lo = hi = p;
    return;
  }
  lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
  hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
}

void Bounds::add(const Bounds& b) {
  if (b.empty()) return;
  add(b.lo);
  add(b.hi);
}

Bounds scene_bounds(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles) {
  Bounds b;
  for (const SheetMesh& s : sheets) {
    const std::size_t count = std::min({s.x.size(), s.y.size(), s.z.size()});
    for (std::size_t k = 0; k < count; ++k) {
      const Vec3 p = sheet_point(s, k);
      if (finite(p)) b.add(p);
    }
  }
  for (const ObstacleDef& o : obstacles) b.add(obstacle_bounds(o));
  return b;
}

TriangleMesh obstacle_mesh(const ObstacleDef& o, const Bounds& content) {
  TriangleMesh mesh;
  auto vertex = [&](Vec3 p, Vec3 n) {
    mesh.points.push_back(p);
    mesh.normals.push_back(normalized(n));
    return std::uint32_t(mesh.points.size() - 1);
  };
  // Counter-clockwise seen from outside: the winding follows the normals, whatever the
  // parametrisation's orientation.
  auto triangle = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const Vec3 pa = mesh.points[a], n = mesh.normals[a] + mesh.normals[b] + mesh.normals[c];
    if (dot(cross(mesh.points[b] - pa, mesh.points[c] - pa), n) < 0) std::swap(b, c);
    mesh.triangles.insert(mesh.triangles.end(), {a, b, c});
  };
  auto quad = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    triangle(a, b, c);
    triangle(a, c, d);
  };
  switch (o.shape) {
    case ObstacleShape::Plane: {
      const PlanePatch p = plane_patch(o, content);
      quad(vertex(p.at(-1, -1), p.nz), vertex(p.at(1, -1), p.nz), vertex(p.at(1, 1), p.nz), vertex(p.at(-1, 1), p.nz));
      break;
    }
    case ObstacleShape::Box: {
      for (int axis = 0; axis < 3; ++axis)
        for (double side : {-1.0, 1.0}) {
          Vec3 n{0, 0, 0}, a{0, 0, 0}, b{0, 0, 0};
          (axis == 0 ? n.x : axis == 1 ? n.y : n.z) = side;
          (axis == 0 ? a.y : axis == 1 ? a.z : a.x) = 1;
          (axis == 0 ? b.z : axis == 1 ? b.x : b.y) = 1;
          auto corner = [&](double s, double t) {
            const Vec3 l = n + s * a + t * b;
            return vertex(o.center + rotate(o.orientation, {l.x * o.size.x, l.y * o.size.y, l.z * o.size.z}),
                          rotate(o.orientation, n));
          };
          quad(corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1));
        }
      break;
    }
    case ObstacleShape::Sphere:
    case ObstacleShape::Ellipsoid:
    case ObstacleShape::Torus: {
      const CurvedSurface c = curved_surface(o);
      const std::uint32_t row = std::uint32_t(c.nu + 1);
      for (int j = 0; j <= c.nv; ++j)
        for (int i = 0; i <= c.nu; ++i) vertex(c.point(c.u_at(i), c.v_at(j)), c.normal(c.u_at(i), c.v_at(j)));
      for (std::uint32_t j = 0; j < std::uint32_t(c.nv); ++j)
        for (std::uint32_t i = 0; i < std::uint32_t(c.nu); ++i)
          quad(j * row + i, j * row + i + 1, (j + 1) * row + i + 1, (j + 1) * row + i);
      break;
    }
  }
  return mesh;
}

Camera Camera::looking_at_bounds(const Bounds& box, double aspect, double fov_deg) {
  Bounds b = box;
  if (b.empty()) {
    b.add(Vec3{-0.5, -0.5, -0.5});
    b.add(Vec3{0.5, 0.5, 0.5});
  }
  const Vec3 center = 0.5 * (b.lo + b.hi);
  double radius = 0.5 * norm(b.hi - b.lo);
  if (!(radius > 0)) radius = 0.5;
  if (!(aspect > 0)) aspect = 1.0;
  // From the front right (azimuth −55° from +x) and above (elevation 28°), z up.
  const double az = -55 * pi / 180, el = 28 * pi / 180;
  const Vec3 dir{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
  const Vec3 right = normalized(cross(-1.0 * dir, {0, 0, 1})), up = cross(right, -1.0 * dir);
  const double tan_v = std::tan(fov_deg * pi / 360), tan_h = tan_v * aspect;
  // The bounding sphere fits at this distance. Then, a few times: move in while the box's
  // eight corners still fall inside 92% of the picture (flat scenes are not framed loosely),
  // and shift the aim sideways so the corners' picture is centred.
  const double far = radius / std::sin(std::min(std::atan(tan_v), std::atan(tan_h)));
  Vec3 aim = center;
  auto corner = [&](int k) {
    return Vec3{k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z};
  };
  auto fits = [&](double d) {
    for (int k = 0; k < 8; ++k) {
      const Vec3 rel = corner(k) - (aim + d * dir);
      const double z = -dot(rel, dir);
      if (!(z > 0) || std::abs(dot(rel, right)) > 0.92 * tan_h * z || std::abs(dot(rel, up)) > 0.92 * tan_v * z)
        return false;
    }
    return true;
  };
  double distance = far;
  for (int round = 0; round < 4; ++round) {
    double lo = 0, hi = 2 * far;
    for (int it = 0; it < 50; ++it) {
      const double mid = 0.5 * (lo + hi);
      (fits(mid) ? hi : lo) = mid;
    }
    distance = hi;
    if (round == 3) break;  // the last fit stands
    double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
    for (int k = 0; k < 8; ++k) {
      const Vec3 rel = corner(k) - (aim + distance * dir);
      const double z = -dot(rel, dir);
      x_lo = std::min(x_lo, dot(rel, right) / z), x_hi = std::max(x_hi, dot(rel, right) / z);
      y_lo = std::min(y_lo, dot(rel, up) / z), y_hi = std::max(y_hi, dot(rel, up) / z);
    }
    aim = aim + (0.5 * (x_lo + x_hi) * distance) * right + (0.5 * (y_lo + y_hi) * distance) * up;
  }
  Camera cam;
  cam.target = aim;
  cam.eye = aim + distance * dir;
  cam.up = {0, 0, 1};
  cam.fov_deg = fov_deg;
  return cam;
}

std::string validate(const Camera& c) {
  if (!finite(c.eye)) return "camera eye " + fmt_vec(c.eye) + " is not finite";
  if (!finite(c.target)) return "camera target " + fmt_vec(c.target) + " is not finite";
  if (!finite(c.up)) return "camera up " + fmt_vec(c.up) + " is not finite";
  if (!(c.fov_deg > 0 && c.fov_deg < 180))
    return "camera fov must be between 0 and 180 degrees (got " + std::to_string(c.fov_deg) + ")";
  const Vec3 view = c.target - c.eye;
  if (!(norm(view) > 0)) return "camera eye and target are the same point " + fmt_vec(c.eye);
  if (!(norm(c.up) > 0)) return "camera up must not be the zero vector";
  if (norm(cross(view, c.up)) <= 1e-9 * norm(view) * norm(c.up))
    return "camera up " + fmt_vec(c.up) + " is parallel to the viewing direction " + fmt_vec(view);
  return {};
}

Camera parse_camera(std::string_view spec, const Camera& base) {
  Camera cam = base;
  bool seen[4] = {false, false, false, false};
  static constexpr std::string_view keys[4] = {"eye", "target", "up", "fov"};
  std::string_view rest = spec;
  while (!rest.empty()) {
    const std::size_t semi = rest.find(';');
    const std::string_view item = trim(rest.substr(0, semi));
    rest = semi == std::string_view::npos ? std::string_view{} : rest.substr(semi + 1);
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos)
      throw std::invalid_argument("camera: \"" + std::string(item) +
                                  "\" is not key=value (keys: eye, target, up, fov; e.g. eye=4,-3,2;fov=35)");
    const std::string_view key = trim(item.substr(0, eq));
    const std::string_view value = item.substr(eq + 1);
    const auto it = std::find(std::begin(keys), std::end(keys), key);
    if (it == std::end(keys))
      throw std::invalid_argument("camera: unknown key \"" + std::string(key) + "\" (keys: eye, target, up, fov)");
    const auto index = static_cast<std::size_t>(it - std::begin(keys));
    if (seen[index]) throw std::invalid_argument("camera: key \"" + std::string(key) + "\" is given twice");
    seen[index] = true;
    switch (index) {
      case 0: cam.eye = parse_vec3(key, value); break;
      case 1: cam.target = parse_vec3(key, value); break;
      case 2: cam.up = parse_vec3(key, value); break;
      default: cam.fov_deg = parse_number(key, value); break;
    }
  }
  if (std::string problem = validate(cam); !problem.empty()) throw std::invalid_argument(problem);
  return cam;
}

std::string format_camera(const Camera& c) {
  auto num = [](double v) {
    char buf[32];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
    return ec == std::errc{} ? std::string(buf, end) : std::string("nan");
  };
  auto vec = [&](Vec3 v) { return num(v.x) + "," + num(v.y) + "," + num(v.z); };
  return "eye=" + vec(c.eye) + ";target=" + vec(c.target) + ";up=" + vec(c.up) + ";fov=" + num(c.fov_deg);
}

Image::Image(int w, int h, std::array<std::uint8_t, 3> fill) : width(w), height(h) {
  if (w < 0 || h < 0) throw std::invalid_argument("image size must not be negative");
  rgb.resize(static_cast<std::size_t>(w) * h * 3);
  for (std::size_t k = 0; k < rgb.size(); k += 3) std::copy(fill.begin(), fill.end(), rgb.begin() + k);
}

std::array<std::uint8_t, 3> Image::pixel(int px, int py) const {
  const std::size_t k = (static_cast<std::size_t>(py) * width + px) * 3;
  return {rgb[k], rgb[k + 1], rgb[k + 2]};
}

void Image::set_pixel(int px, int py, std::array<std::uint8_t, 3> c) {
  const std::size_t k = (static_cast<std::size_t>(py) * width + px) * 3;
  std::copy(c.begin(), c.end(), rgb.begin() + k);
}

namespace {

void check_render_arguments(std::span<const SheetMesh> sheets, const Camera& camera, int width, int height,
                            const RenderOptions& options) {
  if (std::string problem = validate(camera); !problem.empty()) throw std::invalid_argument("render: " + problem);
  constexpr int max_side = 8192;
  if (width < 1 || height < 1 || width > max_side || height > max_side)
    throw std::invalid_argument("render: image size " + std::to_string(width) + "x" + std::to_string(height) +
                                " is outside 1..8192 pixels per side");
  if (options.supersampling < 1 || options.supersampling > 8)
    throw std::invalid_argument("render: supersampling must be 1..8 (got " + std::to_string(options.supersampling) +
                                ")");
  for (std::size_t k = 0; k < sheets.size(); ++k) check_sheet(sheets[k], k);
}

// About 11 bytes per sample: keep the buffers under ~64 M samples by supersampling less.
RenderOptions fitted(const RenderOptions& options, int width, int height) {
  RenderOptions opt = options;
  const double pixels = double(width) * height;
  while (opt.supersampling > 1 && pixels * opt.supersampling * opt.supersampling > 64e6) --opt.supersampling;
  return opt;
}

}  // namespace

Image render_wireframe(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles,
                       const Camera& camera, int width, int height, const RenderOptions& options) {
  check_render_arguments(sheets, camera, width, height, options);
  const RenderOptions opt = fitted(options, width, height);
  const Bounds content = scene_bounds(sheets, obstacles);
  Canvas canvas(camera, width, height, opt, content);
  for (const ObstacleDef& o : obstacles) draw_obstacle(canvas, o, content, options.obstacle_color, Pass::Surfaces);
  if (options.opaque_sheets)
    for (const SheetMesh& s : sheets) draw_sheet(canvas, s, options.sheet_color, Pass::Surfaces);
  for (const ObstacleDef& o : obstacles) draw_obstacle(canvas, o, content, options.obstacle_color, Pass::Lines);
  for (const SheetMesh& s : sheets) draw_sheet(canvas, s, options.sheet_color, Pass::Lines);
  return canvas.resolve(width, height);
}

Image render_shaded(std::span<const SheetMesh> sheets, std::span<const ObstacleDef> obstacles, const Camera& camera,
                    int width, int height, const RenderOptions& options) {
  check_render_arguments(sheets, camera, width, height, options);
  const RenderOptions opt = fitted(options, width, height);
  std::vector<SurfaceMesh> surfaces;
  for (const SheetMesh& s : sheets) surfaces.push_back(sample_surface(s, options.surface, options.surface_samples));

  const Bounds content = scene_bounds(sheets, obstacles);
  Canvas canvas(camera, width, height, opt, content);
  // The light comes from over the camera's left shoulder, fixed to the view.
  const Vec3 light = normalized(-0.45 * canvas.right() + 0.65 * canvas.up() - 1.0 * canvas.forward());
  const Vec3 eye = camera.eye;
  auto lit = [&](std::array<std::uint8_t, 3> color, Vec3 n) {
    const double k = 0.33 + 0.67 * std::max(0.0, dot(n, light));
    return std::array<double, 3>{k * color[0], k * color[1], k * color[2]};
  };
  // front: the triangle's corners wind counter-clockwise seen from the eye; n then faces it
  auto shade = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 na, Vec3 nb, Vec3 nc, std::array<std::uint8_t, 3> front,
                   std::array<std::uint8_t, 3> back) {
    const Vec3 g = cross(b - a, c - a);
    const bool facing = dot(g, eye - a) >= 0;
    const double sign = facing ? 1 : -1;
    const auto color = facing ? front : back;
    const std::array<double, 3> rgb[3] = {lit(color, sign * na), lit(color, sign * nb), lit(color, sign * nc)};
    canvas.shade_triangle(a, b, c, rgb);
  };
  for (const ObstacleDef& o : obstacles) {
    const TriangleMesh mesh = obstacle_mesh(o, content);
    for (std::size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
      const std::uint32_t a = mesh.triangles[t], b = mesh.triangles[t + 1], c = mesh.triangles[t + 2];
      shade(mesh.points[a], mesh.points[b], mesh.points[c], mesh.normals[a], mesh.normals[b], mesh.normals[c],
            options.solid_color, options.solid_color);
    }
  }
  for (std::size_t index = 0; index < surfaces.size(); ++index) {
    const SurfaceMesh& s = surfaces[index];
    // sheet k's colours at (1 − 0.14·(k mod 4)) of their brightness: stacked sheets stay apart
    const double tint = 1 - 0.14 * double(index % 4);
    auto tinted = [&](std::array<std::uint8_t, 3> c) {
      return std::array<std::uint8_t, 3>{std::uint8_t(std::lround(tint * c[0])), std::uint8_t(std::lround(tint * c[1])),
                                         std::uint8_t(std::lround(tint * c[2]))};
    };
    const auto front = tinted(options.front_color), back = tinted(options.back_color);
    for (std::uint32_t i = 0; i + 1 < s.rows; ++i)
      for (std::uint32_t j = 0; j + 1 < s.cols; ++j) {
        // the exported quads' winding: (i, j), (i, j+1), (i+1, j+1), (i+1, j) faces the normals' side
        const std::size_t k[4] = {std::size_t(i) * s.cols + j, std::size_t(i) * s.cols + j + 1,
                                  std::size_t(i + 1) * s.cols + j + 1, std::size_t(i + 1) * s.cols + j};
        for (int tri = 0; tri < 2; ++tri) {
          const std::size_t a = k[0], b = k[1 + tri], c = k[2 + tri];
          shade(s.points[a], s.points[b], s.points[c], s.normals[a], s.normals[b], s.normals[c], front, back);
        }
      }
  }
  return canvas.resolve(width, height);
}

// ---------------------------------------------------------------------------------------
// PNG files, through libpng's simplified API (no setjmp/longjmp across C++ frames).

void write_png(const Image& image, const std::string& path) {
  namespace fs = std::filesystem;
  auto fail = [&](const std::string& why) { throw std::runtime_error("cannot write PNG \"" + path + "\": " + why); };
  if (image.width < 1 || image.height < 1 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * image.height * 3)
    fail("the image is empty or its pixel buffer does not match its size");
  std::error_code ec;
  if (fs::is_directory(path, ec)) fail("it is a directory");

  // Temporary file in the target's folder, so the final rename stays on one file system.
  static std::atomic<unsigned> counter{0};
  std::string temp;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    temp = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) {
      const fs::path parent = fs::path(path).parent_path();
      fail("cannot create a file in \"" + (parent.empty() ? std::string(".") : parent.string()) +
           "\": " + errno_text(errno));
    }
  }
  if (fd < 0) fail("cannot find a free temporary name next to it");
  FILE* file = ::fdopen(fd, "wb");
  if (!file) {
    const int e = errno;
    ::close(fd);
    ::unlink(temp.c_str());
    fail(errno_text(e));
  }
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGB;
  const bool wrote = png_image_write_to_stdio(&png, file, 0, image.rgb.data(), image.width * 3, nullptr) != 0;
  const std::string png_message = png.message;
  png_image_free(&png);
  const bool flushed = std::fflush(file) == 0 && ::fsync(::fileno(file)) == 0;
  const int flush_errno = errno;
  const bool closed = std::fclose(file) == 0;
  if (!wrote || !flushed || !closed) {
    ::unlink(temp.c_str());
    fail(!wrote ? "libpng: " + png_message : errno_text(flushed ? errno : flush_errno));
  }
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(temp.c_str());
    fail(errno_text(e));
  }
}

Image read_png(const std::string& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) {
    const std::string why = png.message;
    png_image_free(&png);
    throw std::runtime_error("cannot read PNG \"" + path + "\": " + why);
  }
  png.format = PNG_FORMAT_RGB;
  Image image;
  image.width = static_cast<int>(png.width);
  image.height = static_cast<int>(png.height);
  image.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, image.rgb.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    throw std::runtime_error("cannot read PNG \"" + path + "\": " + why);
  }
  return image;
}

}  // namespace drape::render
