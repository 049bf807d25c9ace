// The wireframe renderer: PNG files, where lines land (checked against a pinhole projection
// written here from the camera's definition), hidden lines, file errors and camera strings.
#include "render/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using drape::Vec3;
using namespace drape::render;

constexpr std::array<std::uint8_t, 3> white{255, 255, 255};

// The pinhole model of render.h's header comment, from scratch: vertical field of view,
// image y downwards, pixel (px, py) covering [px, px+1) × [py, py+1).
struct Pinhole {
  double ex, ey, ez;     // eye
  double f[3], r[3], u[3];
  double focal, cx, cy;

  Pinhole(const Camera& c, int w, int h) : ex(c.eye.x), ey(c.eye.y), ez(c.eye.z) {
    double fw[3] = {c.target.x - ex, c.target.y - ey, c.target.z - ez};
    const double fl = std::sqrt(fw[0] * fw[0] + fw[1] * fw[1] + fw[2] * fw[2]);
    for (double& v : fw) v /= fl;
    const double up[3] = {c.up.x, c.up.y, c.up.z};
    double rw[3] = {fw[1] * up[2] - fw[2] * up[1], fw[2] * up[0] - fw[0] * up[2], fw[0] * up[1] - fw[1] * up[0]};
    const double rl = std::sqrt(rw[0] * rw[0] + rw[1] * rw[1] + rw[2] * rw[2]);
    for (double& v : rw) v /= rl;
    const double uw[3] = {rw[1] * fw[2] - rw[2] * fw[1], rw[2] * fw[0] - rw[0] * fw[2], rw[0] * fw[1] - rw[1] * fw[0]};
    for (int k = 0; k < 3; ++k) f[k] = fw[k], r[k] = rw[k], u[k] = uw[k];
    focal = (h / 2.0) / std::tan(c.fov_deg / 2 * std::numbers::pi / 180);
    cx = w / 2.0;
    cy = h / 2.0;
  }
  // Continuous image position of a world point in front of the camera.
  std::pair<double, double> project(Vec3 p) const {
    const double d[3] = {p.x - ex, p.y - ey, p.z - ez};
    const double x = d[0] * r[0] + d[1] * r[1] + d[2] * r[2];
    const double y = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
    const double z = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    return {cx + focal * x / z, cy - focal * y / z};
  }
  // Unit direction of the ray from the eye through the centre of pixel (px, py).
  Vec3 direction(int px, int py) const {
    const double x = (px + 0.5 - cx) / focal, y = (cy - (py + 0.5)) / focal;
    double d[3];
    for (int k = 0; k < 3; ++k) d[k] = f[k] + x * r[k] + y * u[k];
    const double dl = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    return {d[0] / dl, d[1] / dl, d[2] / dl};
  }
  // Distance from `c` to the ray through the centre of pixel (px, py).
  double ray_distance(int px, int py, Vec3 c) const {
    const Vec3 d = direction(px, py);
    const double v[3] = {c.x - ex, c.y - ey, c.z - ez};
    const double along = v[0] * d.x + v[1] * d.y + v[2] * d.z;
    const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    return std::sqrt(std::max(0.0, vv - along * along));
  }
};

// A flat sheet of m×n cells spanning [x0, x0+w] × [y0, y0+h] at height z0, tilted about x
// by `tilt` radians around (x0, y0, z0): point (i, j) is row i (along y), column j (along x).
struct TestSheet {
  std::uint32_t m, n;
  std::vector<double> x, y, z;
  TestSheet(std::uint32_t m_, std::uint32_t n_, double x0, double y0, double z0, double w, double h, double tilt)
      : m(m_), n(n_) {
    for (std::uint32_t i = 0; i <= m; ++i)
      for (std::uint32_t j = 0; j <= n; ++j) {
        const double ly = h * i / m;
        x.push_back(x0 + w * j / n);
        y.push_back(y0 + ly * std::cos(tilt));
        z.push_back(z0 + ly * std::sin(tilt));
      }
  }
  Vec3 point(std::uint32_t i, std::uint32_t j) const {
    const std::size_t k = i * (n + 1) + j;
    return {x[k], y[k], z[k]};
  }
  SheetMesh mesh() const { return {m, n, x, y, z}; }
};

bool is_background(const Image& img, int px, int py) { return img.pixel(px, py) == white; }

// The message of the E that f throws; a test failure and "" when it throws nothing.
template <class E, class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception";
  return "";
}
bool mentions(const std::string& message, const std::string& part) { return message.find(part) != std::string::npos; }

fs::path scratch_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("drape_render_test_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(Render, PngWrittenThenReadBackHasSameSizeAndPixels) {
  const fs::path dir = scratch_dir("roundtrip");
  Image img(37, 23);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      img.set_pixel(x, y, {std::uint8_t(7 * x), std::uint8_t(11 * y), std::uint8_t((x * y) % 256)});
  const std::string path = (dir / "a.png").string();
  write_png(img, path);
  const Image back = read_png(path);
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 23);
  EXPECT_EQ(back.rgb, img.rgb);
  // Only the final file is left: the temporary was renamed, not copied.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}), 1);
  fs::remove_all(dir);
}

TEST(Render, SheetPointsAreDrawnWhereThePinholeProjectsThemAndNothingElse) {
  const TestSheet sheet(3, 4, -1.0, -0.6, 0.0, 2.0, 1.5, 0.4);
  Camera cam;
  cam.eye = {0.7, -3.5, 2.2};
  cam.target = {0.1, 0.2, 0.1};
  cam.fov_deg = 40;
  const int w = 320, h = 240;
  const std::vector<SheetMesh> sheets{sheet.mesh()};
  const Image img = render_wireframe(sheets, {}, cam, w, h);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  const Pinhole pin(cam, w, h);

  double lo_x = w, hi_x = 0, lo_y = h, hi_y = 0;
  for (std::uint32_t i = 0; i <= sheet.m; ++i)
    for (std::uint32_t j = 0; j <= sheet.n; ++j) {
      const auto [sx, sy] = pin.project(sheet.point(i, j));
      ASSERT_TRUE(sx >= 0 && sx < w && sy >= 0 && sy < h) << "test set-up: point off the picture";
      EXPECT_FALSE(is_background(img, int(sx), int(sy))) << "grid point (" << i << ", " << j << ") at " << sx << ", " << sy;
      lo_x = std::min(lo_x, sx), hi_x = std::max(hi_x, sx), lo_y = std::min(lo_y, sy), hi_y = std::max(hi_y, sy);
    }
  // The middle of each cell is far from every grid line: background.
  for (std::uint32_t i = 0; i < sheet.m; ++i)
    for (std::uint32_t j = 0; j < sheet.n; ++j) {
      const Vec3 a = sheet.point(i, j), b = sheet.point(i + 1, j + 1);
      const auto [sx, sy] = pin.project({(a.x + b.x) / 2, (a.y + b.y) / 2, (a.z + b.z) / 2});
      EXPECT_TRUE(is_background(img, int(sx), int(sy))) << "cell (" << i << ", " << j << ") centre is drawn";
    }
  // Everything more than two pixels outside the sheet's projected box is background.
  int drawn_outside = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if ((x < lo_x - 2 || x > hi_x + 2 || y < lo_y - 2 || y > hi_y + 2) && !is_background(img, x, y)) ++drawn_outside;
  EXPECT_EQ(drawn_outside, 0);
}

// Renders one obstacle alone and compares it with `hits(origin, direction)`, an independent
// ray test through each pixel's centre: the outline is drawn wherever a hit pixel borders a
// missed one; nothing is drawn two pixels or more outside; all lines have the obstacle colour.
template <class HitTest>
void expect_outline_on_silhouette(const drape::ObstacleDef& obstacle, const Camera& cam, HitTest hits) {
  const int w = 240, h = 200;
  const std::vector<drape::ObstacleDef> obstacles{obstacle};
  const Image img = render_wireframe({}, obstacles, cam, w, h);
  const Pinhole pin(cam, w, h);
  std::vector<char> hit(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) hit[y * w + x] = hits(Vec3{pin.ex, pin.ey, pin.ez}, pin.direction(x, y));
  int boundary_pairs = 0, missed = 0, stray = 0, bluish = 0, drawn = 0;
  std::string first_problem;
  for (int y = 2; y < h - 2; ++y)
    for (int x = 2; x < w - 2; ++x) {
      bool near_hit = false;
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) near_hit |= hit[(y + dy) * w + x + dx] != 0;
      if (!near_hit && !is_background(img, x, y)) {
        if (stray++ == 0) first_problem += "drawn outside at " + std::to_string(x) + "," + std::to_string(y) + "; ";
      }
      for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
        if (hit[y * w + x] == hit[(y + dy) * w + x + dx]) continue;
        ++boundary_pairs;
        if (is_background(img, x, y) && is_background(img, x + dx, y + dy) && missed++ == 0)
          first_problem += "outline missing at " + std::to_string(x) + "," + std::to_string(y) + "; ";
      }
      if (img.pixel(x, y)[0] < 200) {  // well covered by a line, not a faint anti-aliased edge
        ++drawn;
        const auto c = img.pixel(x, y);
        bluish += c[2] > c[0] + 20;
      }
    }
  EXPECT_GT(boundary_pairs, 200) << "test set-up: the obstacle should be large in the picture";
  EXPECT_EQ(missed, 0) << first_problem;
  EXPECT_EQ(stray, 0) << first_problem;
  EXPECT_EQ(bluish, drawn) << "obstacle lines should all be in the obstacle colour";
}

// The rotation that takes world vectors into the obstacle's frame (the inverse quaternion).
Vec3 to_local(const drape::ObstacleDef& o, Vec3 v) {
  return drape::rotate({o.orientation.w, -o.orientation.x, -o.orientation.y, -o.orientation.z}, v);
}

TEST(Render, SphereOutlineIsDrawnOnItsSilhouetteInTheObstacleColour) {
  drape::ObstacleDef sphere;
  sphere.shape = drape::ObstacleShape::Sphere;
  sphere.center = {0.3, -0.2, 0.4};
  sphere.size = {0.6, 0, 0};
  Camera cam;
  cam.eye = {2.5, -3.0, 1.8};
  cam.target = {0.0, 0.0, 0.0};  // the sphere is off the optical axis: its outline is not a circle
  expect_outline_on_silhouette(sphere, cam, [&](Vec3 o, Vec3 d) {
    // Distance from the centre to the ray (d is a unit vector) below the radius.
    const Vec3 v{sphere.center.x - o.x, sphere.center.y - o.y, sphere.center.z - o.z};
    const double along = v.x * d.x + v.y * d.y + v.z * d.z;
    return v.x * v.x + v.y * v.y + v.z * v.z - along * along < sphere.size.x * sphere.size.x;
  });
}

TEST(Render, TurnedEllipsoidOutlineIsDrawnOnItsSilhouette) {
  drape::ObstacleDef ellipsoid;
  ellipsoid.shape = drape::ObstacleShape::Ellipsoid;
  ellipsoid.center = {0.1, 0.2, -0.1};
  ellipsoid.size = {0.9, 0.5, 0.3};
  ellipsoid.orientation = drape::quat_from_axis_angle({1, 2, 3}, 0.7);
  Camera cam;
  cam.eye = {2.0, -3.0, 2.0};
  expect_outline_on_silhouette(ellipsoid, cam, [&](Vec3 o, Vec3 d) {
    // In the frame where the ellipsoid is the unit sphere, the ray meets |o + t·d| = 1.
    const Vec3 s = ellipsoid.size;
    Vec3 lo = to_local(ellipsoid, {o.x - ellipsoid.center.x, o.y - ellipsoid.center.y, o.z - ellipsoid.center.z});
    Vec3 ld = to_local(ellipsoid, d);
    lo = {lo.x / s.x, lo.y / s.y, lo.z / s.z};
    ld = {ld.x / s.x, ld.y / s.y, ld.z / s.z};
    const double a = ld.x * ld.x + ld.y * ld.y + ld.z * ld.z;
    const double b = 2 * (lo.x * ld.x + lo.y * ld.y + lo.z * ld.z);
    const double c = lo.x * lo.x + lo.y * lo.y + lo.z * lo.z - 1;
    return b * b - 4 * a * c > 0;
  });
}

TEST(Render, TiltedTorusOutlineIncludingItsHoleIsDrawnOnItsSilhouette) {
  drape::ObstacleDef torus;
  torus.shape = drape::ObstacleShape::Torus;
  torus.center = {0, 0, 0};
  torus.size = {0.7, 0.25, 0};
  torus.orientation = drape::quat_from_axis_angle({1, 0.3, 0}, 0.5);
  Camera cam;
  cam.eye = {0.8, -1.6, 3.2};  // looking down through the hole
  expect_outline_on_silhouette(torus, cam, [&](Vec3 o, Vec3 d) {
    // Sphere tracing with the torus's exact distance function.
    const Vec3 lo = to_local(torus, o), ld = to_local(torus, d);
    double t = 0;
    for (int it = 0; it < 400 && t < 20; ++it) {
      const Vec3 p{lo.x + t * ld.x, lo.y + t * ld.y, lo.z + t * ld.z};
      const double ring = std::hypot(p.x, p.y) - torus.size.x;
      const double dist = std::hypot(ring, p.z) - torus.size.y;
      if (dist < 1e-7) return true;
      t += dist;
    }
    return false;
  });
}

TEST(Render, BoxCornersFacingTheEyeAreDrawnAndTheHiddenCornerIsNot) {
  drape::ObstacleDef box;
  box.shape = drape::ObstacleShape::Box;
  box.center = {0.1, -0.1, 0.2};
  box.size = {0.6, 0.4, 0.3};
  box.orientation = drape::quat_from_axis_angle({0.3, -0.5, 1}, 0.6);
  Camera cam;
  cam.eye = {2.2, -2.6, 1.9};
  cam.target = box.center;
  const int w = 240, h = 200;
  const std::vector<drape::ObstacleDef> obstacles{box};
  const Image img = render_wireframe({}, obstacles, cam, w, h);
  const Pinhole pin(cam, w, h);
  const Vec3 axes[3] = {drape::rotate(box.orientation, {1, 0, 0}), drape::rotate(box.orientation, {0, 1, 0}),
                        drape::rotate(box.orientation, {0, 0, 1})};
  const double half[3] = {box.size.x, box.size.y, box.size.z};
  int visible = 0, hidden = 0;
  for (int k = 0; k < 8; ++k) {
    Vec3 p = box.center;
    bool faces_eye = false;  // a corner of a convex box is seen iff one of its 3 faces faces the eye
    for (int a = 0; a < 3; ++a) {
      const double sgn = (k >> a) & 1 ? 1.0 : -1.0;
      p = {p.x + sgn * half[a] * axes[a].x, p.y + sgn * half[a] * axes[a].y, p.z + sgn * half[a] * axes[a].z};
    }
    for (int a = 0; a < 3; ++a) {
      const double sgn = (k >> a) & 1 ? 1.0 : -1.0;
      const Vec3 n{sgn * axes[a].x, sgn * axes[a].y, sgn * axes[a].z};
      faces_eye |= n.x * (p.x - cam.eye.x) + n.y * (p.y - cam.eye.y) + n.z * (p.z - cam.eye.z) < 0;
    }
    const auto [sx, sy] = pin.project(p);
    if (faces_eye) {
      EXPECT_FALSE(is_background(img, int(sx), int(sy))) << "visible corner " << k << " not drawn";
      ++visible;
    } else {
      EXPECT_TRUE(is_background(img, int(sx), int(sy))) << "hidden corner " << k << " drawn";
      ++hidden;
    }
  }
  EXPECT_EQ(visible, 7) << "test set-up: a general view of a box shows seven corners";
  EXPECT_EQ(hidden, 1);
}

TEST(Render, ObstacleHidesSheetLinesBehindIt) {
  // A sheet far behind a sphere, seen through the sphere's centre.
  const TestSheet sheet(6, 6, -1.5, 2.0, -1.5, 3.0, 3.0, std::numbers::pi / 2);
  drape::ObstacleDef sphere;
  sphere.shape = drape::ObstacleShape::Sphere;
  sphere.center = {0, 0, 0};
  sphere.size = {0.8, 0, 0};
  Camera cam;
  cam.eye = {0, -5, 0};
  cam.target = {0, 0, 0};
  const int w = 200, h = 200;
  const std::vector<SheetMesh> sheets{sheet.mesh()};
  const std::vector<drape::ObstacleDef> obstacles{sphere};
  RenderOptions flat;
  flat.depth_fade = 0;  // the fade depends on the content's depth range, which the sphere widens
  const Image with = render_wireframe(sheets, obstacles, cam, w, h, flat);
  const Image without = render_wireframe(sheets, {}, cam, w, h, flat);
  const Pinhole pin(cam, w, h);
  auto sheet_grey = [](std::array<std::uint8_t, 3> c) { return c[0] < 200 && std::abs(int(c[0]) - int(c[2])) < 15; };
  // Inside the sphere's disk no sheet line shows; well outside it the sheet is unchanged.
  int grey_inside_without = 0, grey_inside_with = 0, outside = 0, outside_same = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double d = pin.ray_distance(x, y, sphere.center);
      if (d < 0.95 * sphere.size.x) {
        grey_inside_without += sheet_grey(without.pixel(x, y));
        grey_inside_with += sheet_grey(with.pixel(x, y));
      } else if (d > 1.1 * sphere.size.x && !is_background(without, x, y)) {
        ++outside;
        outside_same += with.pixel(x, y) == without.pixel(x, y);
      }
    }
  EXPECT_GT(grey_inside_without, 200) << "test set-up: the sheet should cross the sphere's disk";
  EXPECT_EQ(grey_inside_with, 0) << "sheet lines show through the sphere";
  EXPECT_GT(outside, 500);
  EXPECT_EQ(outside_same, outside) << "the sphere changed sheet lines it does not cover";
}

// A sheet standing between the eye and a sphere (the plane y = −2), covering the sphere's
// whole outline.
struct SheetBeforeSphere {
  TestSheet sheet{5, 5, -2.0, -2.0, -2.0, 4.0, 4.0, std::numbers::pi / 2};
  std::vector<SheetMesh> sheets{sheet.mesh()};
  std::vector<drape::ObstacleDef> obstacles;
  Camera cam;
  SheetBeforeSphere() {
    drape::ObstacleDef sphere;
    sphere.shape = drape::ObstacleShape::Sphere;
    sphere.size = {0.7, 0, 0};
    obstacles.push_back(sphere);
    cam.eye = {0.3, -7, 0.4};
    cam.target = {0, 0, 0};
  }
};

TEST(Render, OpaqueSheetHidesObstacleBehindIt) {
  const SheetBeforeSphere set_up;
  const auto& [sheet, sheets, obstacles, cam] = set_up;
  auto bluish_pixels = [&](bool opaque) {
    RenderOptions opt;
    opt.opaque_sheets = opaque;
    const Image img = render_wireframe(sheets, obstacles, cam, 160, 160, opt);
    int count = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const auto c = img.pixel(x, y);
        count += c[2] > c[0] + 20;
      }
    return count;
  };
  EXPECT_GT(bluish_pixels(false), 100) << "test set-up: a see-through sheet shows the sphere";
  EXPECT_EQ(bluish_pixels(true), 0);
}

TEST(Render, PartsBehindTheCameraAreClippedNotMirrored) {
  // A floor sheet 1 m below the eye that runs from behind the camera to far in front of it.
  // Every point of it in front of the eye projects below the horizon (the middle row).
  const TestSheet floor(4, 2, -1.0, -9.0, -1.0, 2.0, 20.0, 0.0);
  Camera cam;
  cam.eye = {0, -5, 0};
  cam.target = {0, 0, 0};
  const int w = 160, h = 120;
  const std::vector<SheetMesh> sheets{floor.mesh()};
  const Image img = render_wireframe(sheets, {}, cam, w, h);
  int below = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (is_background(img, x, y)) continue;
      EXPECT_GE(y, h / 2 - 1) << "drawn above the horizon at " << x << ", " << y;
      ++below;
    }
  EXPECT_GT(below, 100);
}

TEST(Render, DefaultCameraFramesAllContent) {
  const TestSheet sheet(10, 10, -0.5, -0.5, 1.2, 1.0, 1.0, 0.0);
  drape::ObstacleDef torus;
  torus.shape = drape::ObstacleShape::Torus;
  torus.center = {0.2, 0.1, 0.3};
  torus.size = {0.6, 0.15, 0};
  const std::vector<SheetMesh> sheets{sheet.mesh()};
  const std::vector<drape::ObstacleDef> obstacles{torus};
  const Bounds box = scene_bounds(sheets, obstacles);
  // Hand-computed box: the torus reaches 0.75 around its centre in x, y and 0.15 in z.
  EXPECT_DOUBLE_EQ(box.lo.x, -0.55);
  EXPECT_DOUBLE_EQ(box.hi.x, 0.95);
  EXPECT_DOUBLE_EQ(box.lo.y, -0.65);
  EXPECT_DOUBLE_EQ(box.hi.y, 0.85);
  EXPECT_DOUBLE_EQ(box.lo.z, 0.15);
  EXPECT_DOUBLE_EQ(box.hi.z, 1.2);
  const int w = 400, h = 300;
  const Camera cam = Camera::looking_at_bounds(box, double(w) / h);
  EXPECT_EQ(validate(cam), "");
  EXPECT_GT(cam.eye.z, cam.target.z) << "the default view looks down on the scene";
  const Pinhole pin(cam, w, h);
  double x_lo = w, x_hi = 0, y_lo = h, y_hi = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3 p{k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z};
    const auto [sx, sy] = pin.project(p);
    EXPECT_TRUE(sx > 0 && sx < w && sy > 0 && sy < h) << "box corner " << k << " at " << sx << ", " << sy;
    x_lo = std::min(x_lo, sx), x_hi = std::max(x_hi, sx), y_lo = std::min(y_lo, sy), y_hi = std::max(y_hi, sy);
  }
  // Tight and centred: the box spans most of the picture one way, with equal margins.
  EXPECT_TRUE(x_hi - x_lo > 0.85 * w || y_hi - y_lo > 0.85 * h) << x_lo << ".." << x_hi << ", " << y_lo << ".." << y_hi;
  EXPECT_NEAR(x_lo, w - x_hi, 2.0);
  EXPECT_NEAR(y_lo, h - y_hi, 2.0);
}

TEST(Render, WritePngIntoMissingFolderThrowsNamingThePathAndWritesNothing) {
  const fs::path dir = scratch_dir("missing");
  const std::string path = (dir / "no_such_folder" / "out.png").string();
  const std::string msg = error_of<std::runtime_error>([&] { write_png(Image(4, 4), path); });
  EXPECT_TRUE(mentions(msg, path)) << msg;
  EXPECT_TRUE(mentions(msg, "No such file or directory")) << msg;
  EXPECT_FALSE(fs::exists(dir / "no_such_folder"));
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(Render, WritePngOntoADirectoryThrowsAndLeavesNoFile) {
  const fs::path dir = scratch_dir("isdir");
  fs::create_directory(dir / "target.png");
  const std::string path = (dir / "target.png").string();
  const std::string msg = error_of<std::runtime_error>([&] { write_png(Image(4, 4), path); });
  EXPECT_TRUE(mentions(msg, path)) << msg;
  EXPECT_TRUE(mentions(msg, "is a directory")) << msg;
  EXPECT_TRUE(fs::is_directory(dir / "target.png"));
  EXPECT_TRUE(fs::is_empty(dir / "target.png"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}), 1) << "a temporary file was left";
  fs::remove_all(dir);
}

TEST(Render, ReadPngOfANonPngThrowsNamingThePath) {
  const fs::path dir = scratch_dir("notpng");
  const std::string path = (dir / "x.png").string();
  { std::FILE* f = std::fopen(path.c_str(), "w"); std::fputs("not a png", f); std::fclose(f); }
  const std::string msg = error_of<std::runtime_error>([&] { (void)read_png(path); });
  EXPECT_TRUE(mentions(msg, path)) << msg;
  const std::string absent = (dir / "absent.png").string();
  const std::string msg2 = error_of<std::runtime_error>([&] { (void)read_png(absent); });
  EXPECT_TRUE(mentions(msg2, absent)) << msg2;
  fs::remove_all(dir);
}

TEST(Render, CameraStringSetsGivenKeysAndKeepsTheOthers) {
  Camera base;
  base.eye = {9, 9, 9};
  base.target = {1, 1, 1};
  const Camera c = parse_camera(" eye=4,-3.5,2 ; fov=50;", base);
  EXPECT_EQ(c.eye, (Vec3{4, -3.5, 2}));
  EXPECT_EQ(c.target, (Vec3{1, 1, 1}));
  EXPECT_EQ(c.up, (Vec3{0, 0, 1}));
  EXPECT_EQ(c.fov_deg, 50);
  const Camera d = parse_camera("target=0,0,1;up=0,1,0;eye=0,0,5e0", base);
  EXPECT_EQ(d.eye, (Vec3{0, 0, 5}));
  EXPECT_EQ(d.up, (Vec3{0, 1, 0}));
  EXPECT_EQ(parse_camera("", base).eye, base.eye);
}

TEST(Render, SheetMeshOfAWorldSheetSharesItsPoints) {
  drape::World world;
  drape::SheetDef def;
  def.m = 3;
  def.n = 5;
  const drape::SheetId id = world.add_sheet(def);
  const drape::SheetView<double> view = world.view(id);
  const SheetMesh mesh = sheet_mesh(view);
  EXPECT_EQ(mesh.m, 3u);
  EXPECT_EQ(mesh.n, 5u);
  EXPECT_EQ(mesh.x.data(), view.x.data());
  EXPECT_EQ(mesh.z.size(), 24u);
}

TEST(Render, FormattedCameraParsesBackExactly) {
  Camera c;
  c.eye = {0.1, -1.0 / 3.0, 2e-7};
  c.target = {-4.25, 1e10, 0};
  c.up = {0.2, 0.3, 0.9};
  c.fov_deg = 33.333333333333336;
  const std::string text = format_camera(c);
  const Camera back = parse_camera(text, Camera{});
  EXPECT_EQ(back.eye, c.eye) << text;
  EXPECT_EQ(back.target, c.target) << text;
  EXPECT_EQ(back.up, c.up) << text;
  EXPECT_EQ(back.fov_deg, c.fov_deg) << text;
}

TEST(Render, CameraStringErrorsNameTheProblem) {
  const std::pair<const char*, const char*> cases[] = {
      {"eye=1,2", "three numbers"},
      {"eye=1,2,3,4", "three numbers"},
      {"eye=1,x,3", "\"x\" is not a number"},
      {"eye=1,,3", "is not a number"},
      {"fov=nan", "not finite"},
      {"fov=200", "between 0 and 180"},
      {"fov=0", "between 0 and 180"},
      {"zoom=3", "unknown key \"zoom\""},
      {"eye 1,2,3", "is not key=value"},
      {"fov=30;fov=40", "given twice"},
      {"eye=1,1,1;target=1,1,1", "same point"},
      {"eye=0,0,5;target=0,0,0;up=0,0,1", "parallel"},
      {"up=0,0,0", "zero vector"},
  };
  for (const auto& [spec, expected] : cases) {
    const std::string msg = error_of<std::invalid_argument>([&] { (void)parse_camera(spec); });
    EXPECT_TRUE(mentions(msg, expected)) << "\"" << spec << "\" gave: " << msg;
  }
}

TEST(Render, RejectsBadSizeAndMismatchedSheet) {
  const TestSheet sheet(2, 2, 0, 0, 0, 1, 1, 0);
  const std::vector<SheetMesh> good{sheet.mesh()};
  EXPECT_THROW(render_wireframe(good, {}, Camera{}, 0, 10), std::invalid_argument);
  EXPECT_THROW(render_wireframe(good, {}, Camera{}, 10, 9000), std::invalid_argument);
  SheetMesh bad = sheet.mesh();
  bad.m = 3;
  const std::vector<SheetMesh> bads{bad};
  const std::string msg = error_of<std::invalid_argument>([&] { render_wireframe(bads, {}, Camera{}, 10, 10); });
  EXPECT_TRUE(mentions(msg, "sheet 0")) << msg;
}

}  // namespace

namespace {

// render.h's light, computed here: over the camera's left shoulder, fixed to the view,
// L = normalize(−0.45·r + 0.65·u − f); a side lit at angle θ shows (0.33 + 0.67·max(0, cos θ))
// of its colour.
std::array<double, 3> expected_shade(const Pinhole& p, Vec3 normal, std::array<std::uint8_t, 3> color) {
  double l[3];
  for (int k = 0; k < 3; ++k) l[k] = -0.45 * p.r[k] + 0.65 * p.u[k] - p.f[k];
  const double ll = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  const double c = std::max(0.0, (normal.x * l[0] + normal.y * l[1] + normal.z * l[2]) / ll);
  const double k = 0.33 + 0.67 * c;
  return {k * color[0], k * color[1], k * color[2]};
}

TEST(RenderShaded, AFlatSheetShowsItsLitFrontFromAboveAndItsBackFromBelow) {
  const TestSheet sheet(4, 4, -1, -1, 0, 2, 2, 0);  // z = 0, its quads face +z
  const std::vector<SheetMesh> sheets{sheet.mesh()};
  const RenderOptions opt;
  for (double side : {1.0, -1.0}) {
    Camera cam;
    cam.eye = {0.2, -0.3, 4 * side};
    cam.target = {0, 0, 0};
    cam.up = {0, 1, 0};
    const Image img = render_shaded(sheets, {}, cam, 120, 90, opt);
    const Pinhole p(cam, 120, 90);
    // the side seen is lit with the normal turned towards the eye
    const auto expect = expected_shade(p, {0, 0, side}, side > 0 ? opt.front_color : opt.back_color);
    const auto c = img.pixel(60, 45);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c[ch], expect[ch], 1.0) << "side " << side << " channel " << ch;
    EXPECT_EQ(img.pixel(2, 2), white) << "outside the sheet's projection stays background";
  }
}

TEST(RenderShaded, ASphereIsLitBrightestWhereItsNormalMeetsTheLight) {
  drape::ObstacleDef sphere;
  sphere.shape = drape::ObstacleShape::Sphere;
  sphere.size = {1, 0, 0};
  Camera cam;
  cam.eye = {0, -6, 0};
  cam.target = {0, 0, 0};
  const std::vector<drape::ObstacleDef> obstacles{sphere};
  const RenderOptions opt;
  const Image img = render_shaded({}, obstacles, cam, 160, 160, opt);
  const Pinhole p(cam, 160, 160);
  // the sphere's point facing the light straight: normal = L (seen from the front hemisphere)
  double l[3];
  for (int k = 0; k < 3; ++k) l[k] = -0.45 * p.r[k] + 0.65 * p.u[k] - p.f[k];
  const double ll = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  const Vec3 n{l[0] / ll, l[1] / ll, l[2] / ll};
  const auto [sx, sy] = p.project(n);
  const auto c = img.pixel(int(sx), int(sy));
  EXPECT_NEAR(c[0], opt.solid_color[0], 3.0);  // full light: the colour itself (meshed normals)
  // the silhouette, seen edge-on, falls to the ambient third or a little more
  const auto [ex, ey] = p.project({0.97, 0, -0.2});
  EXPECT_LT(img.pixel(int(ex), int(ey))[0], 0.6 * opt.solid_color[0]);
}

TEST(RenderShaded, ANearerSheetHidesTheSphereBehindIt) {
  const SheetBeforeSphere set_up;
  const auto& [sheet, sheets, obstacles, cam] = set_up;
  const RenderOptions opt;
  const Image both = render_shaded(sheets, obstacles, cam, 100, 100, opt);
  const Image sheet_only = render_shaded(sheets, {}, cam, 100, 100, opt);
  EXPECT_EQ(both.rgb, sheet_only.rgb);
  const Image sphere_only = render_shaded({}, obstacles, cam, 100, 100, opt);
  EXPECT_NE(sphere_only.rgb, sheet_only.rgb) << "test set-up: the sphere alone is visible";
}

}  // namespace

namespace {

TEST(RenderShaded, EachOfFourSheetsInARowIsDarkerThanTheOneBefore) {
  // Four flat sheets side by side seen from straight above: the same light on each, the
  // brightness 1, 0.86, 0.72, 0.58 of the front colour (render.h), so a stack shows its layers.
  std::vector<TestSheet> owned;
  for (int k = 0; k < 4; ++k) owned.emplace_back(2, 2, -2.0 + k, -0.4, 0.0, 0.8, 0.8, 0.0);
  std::vector<SheetMesh> sheets;
  for (const auto& t : owned) sheets.push_back(t.mesh());
  Camera cam;
  cam.eye = {0, 0, 6};
  cam.target = {0, 0, 0};
  cam.up = {0, 1, 0};
  const RenderOptions opt;
  const Image img = render_shaded(sheets, {}, cam, 400, 200, opt);
  const Pinhole p(cam, 400, 200);
  const auto lit = expected_shade(p, {0, 0, 1}, opt.front_color);
  for (int k = 0; k < 4; ++k) {
    const auto [sx, sy] = p.project({-1.6 + k, 0, 0});
    const double tint = 1 - 0.14 * k;
    // the tinted colour is rounded before lighting: allow that rounding and the pixel's
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(img.pixel(int(sx), int(sy))[ch], tint * lit[ch], 1.5) << "sheet " << k;
  }
}

}  // namespace
