// Surfaces over a control grid (apps/render/surface.h), against independent answers: linear
// precision on a flat grid, a cubic patch whose polynomial is known by hand, a brute-force
// Bernstein sum, and the continuity each scheme promises across its piece boundaries.
#include <gtest/gtest.h>

#include <render/surface.h>

#include <cmath>
#include <random>

namespace {

using namespace drape;
using namespace drape::render;

// Owns the coordinates a SheetMesh points at.
struct Grid {
  std::uint32_t m, n;
  std::vector<double> x, y, z;
  Grid(std::uint32_t m_, std::uint32_t n_) : m(m_), n(n_), x((m + 1) * (n + 1)), y(x.size()), z(x.size()) {}
  SheetMesh mesh() const { return {m, n, x, y, z}; }
  Vec3 at(std::uint32_t i, std::uint32_t j) const {
    const std::size_t k = std::size_t(i) * (n + 1) + j;
    return {x[k], y[k], z[k]};
  }
  void set(std::uint32_t i, std::uint32_t j, Vec3 p) {
    const std::size_t k = std::size_t(i) * (n + 1) + j;
    x[k] = p.x;
    y[k] = p.y;
    z[k] = p.z;
  }
};

Grid random_grid(std::uint32_t m, std::uint32_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> d(-0.3, 0.3);
  Grid g(m, n);
  for (std::uint32_t i = 0; i <= m; ++i)
    for (std::uint32_t j = 0; j <= n; ++j) g.set(i, j, {j + d(rng), i + d(rng), d(rng)});
  return g;
}

double dist(Vec3 a, Vec3 b) { return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z)); }

constexpr SurfaceKind all_kinds[] = {SurfaceKind::Grid, SurfaceKind::Bezier, SurfaceKind::BSpline};

TEST(Surface, EverySchemeReproducesAFlatUniformGridExactly) {
  // P(i, j) = O + i·a + j·b on a tilted plane: every scheme has linear precision, so
  // S(u, v) = O + u·a + v·b, and the normal is b × a normalised.
  const Vec3 o{0.5, -1, 2}, a{0.1, 0.3, 0.2}, b{0.4, -0.05, 0.1};
  for (std::uint32_t m : {1u, 2u, 4u, 7u}) {
    Grid g(m, 5);
    for (std::uint32_t i = 0; i <= m; ++i)
      for (std::uint32_t j = 0; j <= 5; ++j)
        g.set(i, j, {o.x + i * a.x + j * b.x, o.y + i * a.y + j * b.y, o.z + i * a.z + j * b.z});
    const Vec3 c{b.y * a.z - b.z * a.y, b.z * a.x - b.x * a.z, b.x * a.y - b.y * a.x};
    const double len = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
    for (SurfaceKind kind : all_kinds) {
      const SurfaceMesh s = sample_surface(g.mesh(), kind, 3);
      for (std::uint32_t r = 0; r < s.rows; ++r)
        for (std::uint32_t q = 0; q < s.cols; ++q) {
          const double u = r / 3.0, v = q / 3.0;
          const Vec3 expect{o.x + u * a.x + v * b.x, o.y + u * a.y + v * b.y, o.z + u * a.z + v * b.z};
          EXPECT_LT(dist(s.point(r, q), expect), 1e-13) << surface_kind_name(kind) << " m=" << m << " at " << u << "," << v;
          EXPECT_LT(dist(s.normals[r * s.cols + q], {c.x / len, c.y / len, c.z / len}), 1e-12) << surface_kind_name(kind);
        }
    }
  }
}

TEST(Surface, BezierOfACubicGridIsTheKnownPatch) {
  // Degree elevation by hand: u² has cubic Bernstein coefficients (0, 0, 1/3, 1) and v has
  // (0, 1/3, 2/3, 1). With x = v, y = u over the unit square, z(i, j) = c_i·e_j gives the
  // patch z = U²·V, U = u/3, V = v/3 (parameters in grid cells).
  const double c[4] = {0, 0, 1.0 / 3, 1}, e[4] = {0, 1.0 / 3, 2.0 / 3, 1};
  Grid g(3, 3);
  for (std::uint32_t i = 0; i <= 3; ++i)
    for (std::uint32_t j = 0; j <= 3; ++j) g.set(i, j, {j / 3.0, i / 3.0, c[i] * e[j]});
  for (double u : {0.0, 0.4, 1.5, 2.25, 3.0})
    for (double v : {0.0, 0.7, 2.0, 3.0}) {
      const SurfacePoint s = surface_point(g.mesh(), SurfaceKind::Bezier, u, v);
      const double U = u / 3, V = v / 3;
      EXPECT_NEAR(s.p.x, V, 1e-15);
      EXPECT_NEAR(s.p.y, U, 1e-15);
      EXPECT_NEAR(s.p.z, U * U * V, 1e-15);
      EXPECT_NEAR(s.du.z, 2 * U * V / 3, 1e-15);  // ∂z/∂u = 2UV·dU/du
      EXPECT_NEAR(s.dv.z, U * U / 3, 1e-15);
    }
}

TEST(Surface, BezierPiecesAreBernsteinSumsOverTheirBlocks) {
  // Brute force: piece (p, q) over rows 3p..3p+d and columns 3q..3q+e is
  // Σ C(d,k) s^(d−k) t^k · C(e,l) … P — the textbook formula, written out with pow().
  const Grid g = random_grid(5, 7, 3);  // pieces of degree 3 and 2 along u; 3, 3 and 1 along v
  auto bern = [](int d, int k, double t) {
    const double binom[4][4] = {{1}, {1, 1}, {1, 2, 1}, {1, 3, 3, 1}};
    return binom[d][k] * std::pow(1 - t, d - k) * std::pow(t, k);
  };
  for (double u : {0.3, 2.9, 3.2, 4.7})
    for (double v : {0.1, 2.5, 4.0, 6.2, 6.9}) {
      const int p0 = u < 3 ? 0 : 3, d = u < 3 ? 3 : 2;
      const int q0 = v < 3 ? 0 : v < 6 ? 3 : 6, e = v < 6 ? 3 : 1;
      const double t = (u - p0) / d, w = (v - q0) / e;
      Vec3 sum{0, 0, 0};
      for (int k = 0; k <= d; ++k)
        for (int l = 0; l <= e; ++l) {
          const double b = bern(d, k, t) * bern(e, l, w);
          const Vec3 p = g.at(p0 + k, q0 + l);
          sum = {sum.x + b * p.x, sum.y + b * p.y, sum.z + b * p.z};
        }
      EXPECT_LT(dist(surface_point(g.mesh(), SurfaceKind::Bezier, u, v).p, sum), 1e-14) << u << "," << v;
    }
}

TEST(Surface, BezierPiecesJoinContinuouslyThroughEveryThirdGridPoint) {
  const Grid g = random_grid(6, 9, 5);
  const SheetMesh mesh = g.mesh();
  for (std::uint32_t i = 0; i <= 6; i += 3)
    for (std::uint32_t j = 0; j <= 9; j += 3)
      EXPECT_LT(dist(surface_point(mesh, SurfaceKind::Bezier, i, j).p, g.at(i, j)), 1e-15);
  // C0 across the boundaries u = 3 and v = 3, 6: the piece before meets the piece after.
  for (double v : {0.0, 1.3, 4.4, 8.9}) {
    const Vec3 before = surface_point(mesh, SurfaceKind::Bezier, std::nextafter(3.0, 0.0), v).p;
    EXPECT_LT(dist(before, surface_point(mesh, SurfaceKind::Bezier, 3.0, v).p), 1e-12);
  }
  for (double knot : {3.0, 6.0})
    for (double u : {0.5, 3.0, 5.5}) {
      const Vec3 before = surface_point(mesh, SurfaceKind::Bezier, u, std::nextafter(knot, 0.0)).p;
      EXPECT_LT(dist(before, surface_point(mesh, SurfaceKind::Bezier, u, knot).p), 1e-12);
    }
}

TEST(Surface, BSplineIsC2AcrossCellBoundaries) {
  const Grid g = random_grid(5, 4, 11);
  const SheetMesh mesh = g.mesh();
  const double h = 1e-4;
  auto second = [&](SurfaceKind kind, double u0, double v, double sign) {  // one-sided ∂²S/∂u²
    const Vec3 a = surface_point(mesh, kind, u0, v).du, b = surface_point(mesh, kind, u0 + sign * h, v).du;
    return Vec3{(b.x - a.x) / (sign * h), (b.y - a.y) / (sign * h), (b.z - a.z) / (sign * h)};
  };
  for (double knot : {1.0, 2.0, 3.0, 4.0})
    for (double v : {0.0, 1.7, 4.0}) {
      const double before = std::nextafter(knot, 0.0);
      const SurfacePoint l = surface_point(mesh, SurfaceKind::BSpline, before, v);
      const SurfacePoint r = surface_point(mesh, SurfaceKind::BSpline, knot, v);
      EXPECT_LT(dist(l.p, r.p), 1e-12);
      EXPECT_LT(dist(l.du, r.du), 1e-12);
      EXPECT_LT(dist(l.dv, r.dv), 1e-12);
      EXPECT_LT(dist(second(SurfaceKind::BSpline, before, v, -1), second(SurfaceKind::BSpline, knot, v, 1)), 1e-2);
    }
  // The same measure sees the kink of the Bézier pieces (C0 only) at u = 3: the check can fail.
  const SurfacePoint l = surface_point(mesh, SurfaceKind::Bezier, std::nextafter(3.0, 0.0), 1.7);
  const SurfacePoint r = surface_point(mesh, SurfaceKind::Bezier, 3.0, 1.7);
  EXPECT_GT(dist(l.du, r.du), 1e-3);
}

TEST(Surface, BSplinePassesThroughTheCornersAndAlongTheBorderPlane) {
  // At a border the phantom point makes S = (P₋₁ + 4P₀ + P₁)/6 = P₀ along the other direction's
  // weights, so the four corners are interpolated.
  const Grid g = random_grid(4, 6, 7);
  const SheetMesh mesh = g.mesh();
  EXPECT_LT(dist(surface_point(mesh, SurfaceKind::BSpline, 0, 0).p, g.at(0, 0)), 1e-15);
  EXPECT_LT(dist(surface_point(mesh, SurfaceKind::BSpline, 4, 0).p, g.at(4, 0)), 1e-14);
  EXPECT_LT(dist(surface_point(mesh, SurfaceKind::BSpline, 0, 6).p, g.at(0, 6)), 1e-14);
  EXPECT_LT(dist(surface_point(mesh, SurfaceKind::BSpline, 4, 6).p, g.at(4, 6)), 1e-14);
}

TEST(Surface, DerivativesMatchFiniteDifferences) {
  const Grid g = random_grid(6, 5, 13);
  const double h = 1e-6;
  for (SurfaceKind kind : all_kinds)
    for (double u : {0.4, 2.6, 4.2})
      for (double v : {0.3, 1.6, 4.5}) {
        const SurfacePoint s = surface_point(g.mesh(), kind, u, v);
        const Vec3 pu = surface_point(g.mesh(), kind, u + h, v).p, mu = surface_point(g.mesh(), kind, u - h, v).p;
        const Vec3 pv = surface_point(g.mesh(), kind, u, v + h).p, mv = surface_point(g.mesh(), kind, u, v - h).p;
        EXPECT_LT(dist(s.du, {(pu.x - mu.x) / (2 * h), (pu.y - mu.y) / (2 * h), (pu.z - mu.z) / (2 * h)}), 1e-7)
            << surface_kind_name(kind);
        EXPECT_LT(dist(s.dv, {(pv.x - mv.x) / (2 * h), (pv.y - mv.y) / (2 * h), (pv.z - mv.z) / (2 * h)}), 1e-7)
            << surface_kind_name(kind);
      }
}

TEST(Surface, GridSampledOncePerCellIsTheGridBitForBit) {
  Grid g = random_grid(3, 4, 17);
  g.x[5] = -0.0;
  const SurfaceMesh s = sample_surface(g.mesh(), SurfaceKind::Grid, 1);
  ASSERT_EQ(s.points.size(), g.x.size());
  for (std::size_t k = 0; k < g.x.size(); ++k) {
    EXPECT_EQ(std::signbit(s.points[k].x), std::signbit(g.x[k]));
    EXPECT_EQ(s.points[k].x, g.x[k]);
    EXPECT_EQ(s.points[k].y, g.y[k]);
    EXPECT_EQ(s.points[k].z, g.z[k]);
  }
}

TEST(Surface, NamesRoundTripAndBadInputIsRefused) {
  for (SurfaceKind kind : all_kinds) EXPECT_EQ(surface_kind_from_name(surface_kind_name(kind)), kind);
  EXPECT_FALSE(surface_kind_from_name("nurbs"));
  Grid g(2, 2);
  SheetMesh bad = g.mesh();
  bad.x = bad.x.subspan(1);
  EXPECT_THROW(sample_surface(bad, SurfaceKind::Bezier, 2), std::invalid_argument);
  EXPECT_THROW(sample_surface(g.mesh(), SurfaceKind::Bezier, 0), std::invalid_argument);
}

}  // namespace
