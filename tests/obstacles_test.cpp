// Obstacles (paper §3, eq 9): implicit functions against finite differences and hand-placed
// points, the direction and size of the repulsion, and points that must not get through.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <numbers>
#include <random>

#include "damped_rebound.h"
#include "each_target.h"
#include "obstacles.h"

namespace {

using drape::ObstacleDef;
using drape::ObstacleShape;
using drape::Vec3;

ObstacleDef shape_def(ObstacleShape shape) {
  ObstacleDef d;
  d.shape = shape;
  d.center = {0.3, -0.2, 0.1};
  d.orientation = drape::quat_from_axis_angle({1, 2, 3}, 0.7);
  switch (shape) {
    case ObstacleShape::Plane: break;
    case ObstacleShape::Sphere: d.size = {0.5, 0, 0}; break;
    case ObstacleShape::Ellipsoid: d.size = {0.6, 0.4, 0.3}; break;
    case ObstacleShape::Torus: d.size = {0.5, 0.2, 0}; break;
    case ObstacleShape::Box: d.size = {0.4, 0.3, 0.2}; break;
  }
  return d;
}

// shape_def's obstacle for the kernel tests: reach 0.64 m, so on the crumpled sheets around
// it most points are in reach, some beyond it, some past the cap.
ObstacleDef kernel_def(ObstacleShape shape, bool full_gradient) {
  ObstacleDef d = shape_def(shape);
  d.c = 0.01;
  d.xi = 0.04;
  d.full_gradient = full_gradient;
  return d;
}

drape::SheetDef grid_def(std::uint32_t m, std::uint32_t n) {
  drape::SheetDef sd;
  sd.m = m;
  sd.n = n;
  return sd;
}

const ObstacleShape all_shapes[] = {ObstacleShape::Plane, ObstacleShape::Sphere, ObstacleShape::Ellipsoid,
                                    ObstacleShape::Torus, ObstacleShape::Box};

double f_at(const drape::detail::Obstacle& o, Vec3 p) {
  const double q[3] = {p.x, p.y, p.z};
  return drape::detail::implicit_at(o, q).f;
}

Vec3 add(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 scaled(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }

void expect_gradient_matches_fd(ObstacleShape shape) {
  const auto o = drape::detail::make_obstacle(shape_def(shape));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 400 && checked < 100; ++trial) {
    const Vec3 p = add(shape_def(shape).center, {u(rng), u(rng), u(rng)});
    const double q[3] = {p.x, p.y, p.z};
    const auto s = drape::detail::implicit_at(o, q);
    const double h = 1e-6;
    double fd[3];
    for (int k = 0; k < 3; ++k) {
      double a[3] = {p.x, p.y, p.z}, b[3] = {p.x, p.y, p.z};
      a[k] += h;
      b[k] -= h;
      fd[k] = (drape::detail::implicit_at(o, a).f - drape::detail::implicit_at(o, b).f) / (2 * h);
    }
    // The box's gradient jumps across the inside planes where two faces are equally near:
    // there one-sided slopes disagree, so skip points whose central difference straddles one.
    if (shape == ObstacleShape::Box && s.f < 0) {
      double sum = 0;
      for (int k = 0; k < 3; ++k) sum += fd[k] * fd[k];
      if (std::abs(sum - 1) > 1e-6) continue;
    }
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.grad[k], fd[k], 1e-6) << "axis " << k << " f " << s.f;
    ++checked;
  }
  EXPECT_GE(checked, 50);
}

TEST(Obstacles, PlaneGradientMatchesFiniteDifference) { expect_gradient_matches_fd(ObstacleShape::Plane); }
TEST(Obstacles, SphereGradientMatchesFiniteDifference) { expect_gradient_matches_fd(ObstacleShape::Sphere); }
TEST(Obstacles, EllipsoidGradientMatchesFiniteDifference) { expect_gradient_matches_fd(ObstacleShape::Ellipsoid); }
TEST(Obstacles, TorusGradientMatchesFiniteDifference) { expect_gradient_matches_fd(ObstacleShape::Torus); }
TEST(Obstacles, BoxGradientMatchesFiniteDifference) { expect_gradient_matches_fd(ObstacleShape::Box); }

// Hand-placed points, in world coordinates, whose f follows from the geometry alone.
TEST(Obstacles, PositionAndOrientationMoveTheSurface) {
  const Vec3 c{1, 2, 3};
  const auto quarter_x = drape::quat_from_axis_angle({1, 0, 0}, std::numbers::pi / 2);  // local z → world −y
  {
    ObstacleDef d;
    d.shape = ObstacleShape::Plane;
    d.center = c;
    d.orientation = quarter_x;
    const auto o = drape::detail::make_obstacle(d);
    EXPECT_NEAR(f_at(o, {5, 2 - 0.25, -7}), 0.25, 1e-12);  // outside is world −y
    EXPECT_NEAR(f_at(o, {0, 2 + 0.5, 0}), -0.5, 1e-12);
  }
  {
    ObstacleDef d;
    d.shape = ObstacleShape::Torus;
    d.center = c;
    d.orientation = quarter_x;
    d.size = {0.5, 0.2, 0};
    const auto o = drape::detail::make_obstacle(d);
    EXPECT_NEAR(f_at(o, c), 0.5 - 0.2, 1e-12);                  // centre of the hole
    EXPECT_NEAR(f_at(o, {1.5, 2, 3}), -0.2, 1e-12);             // on the core circle (world x–z plane)
    EXPECT_NEAR(f_at(o, {1, 2, 3 + 0.5 + 0.2}), 0.0, 1e-12);    // outer rim along world z
    EXPECT_NEAR(f_at(o, {1, 2 + 0.3, 3}), std::hypot(0.5, 0.3) - 0.2, 1e-12);  // on the axis
  }
  {
    ObstacleDef d;
    d.shape = ObstacleShape::Box;
    d.center = c;
    d.orientation = drape::quat_from_axis_angle({0, 0, 1}, std::numbers::pi / 4);
    d.size = {0.4, 0.1, 0.2};
    const auto o = drape::detail::make_obstacle(d);
    const double r = 0.4 / std::sqrt(2.0);
    EXPECT_NEAR(f_at(o, {1 + r, 2 + r, 3}), 0.0, 1e-12);        // end of the long axis, turned 45°
    EXPECT_NEAR(f_at(o, {1 + r + 0.3 / std::sqrt(2.0), 2 + r + 0.3 / std::sqrt(2.0), 3}), 0.3, 1e-12);
    EXPECT_NEAR(f_at(o, c), -0.1, 1e-12);                        // nearest face is the short one
  }
  {
    ObstacleDef d;
    d.shape = ObstacleShape::Ellipsoid;
    d.center = c;
    d.orientation = drape::quat_from_axis_angle({0, 1, 0}, std::numbers::pi / 2);  // local x → world −z
    d.size = {0.6, 0.4, 0.3};
    const auto o = drape::detail::make_obstacle(d);
    EXPECT_NEAR(f_at(o, {1, 2, 3 - 0.6}), 0.0, 1e-12);
    EXPECT_NEAR(f_at(o, {1, 2 + 0.4, 3}), 0.0, 1e-12);
    EXPECT_NEAR(f_at(o, {1 + 0.3, 2, 3}), 0.0, 1e-12);
    EXPECT_NEAR(f_at(o, {1 + 0.5, 2, 3}), 0.2, 1e-12);  // along the smallest axis f is the distance
  }
  {
    ObstacleDef d;
    d.shape = ObstacleShape::Sphere;
    d.center = c;
    d.size = {0.5, 0, 0};
    const auto o = drape::detail::make_obstacle(d);
    EXPECT_NEAR(f_at(o, {1, 2 + 0.3, 3 + 0.4}), 0.0, 1e-12);
    EXPECT_NEAR(f_at(o, c), -0.5, 1e-12);
  }
}

// −dE/df by finite differences of the energy, on both sides of the exponent cap.
TEST(Obstacles, ForceScaleIsMinusEnergySlopeAlsoPastTheCap) {
  ObstacleDef d;
  d.c = 0.02;
  d.xi = 0.01;
  d.max_exponent = 6;
  for (double f : {0.05, 0.01, 0.0, -0.03, -0.059, -0.061, -0.2, -3.0}) {
    const double h = 1e-7;
    const double slope = (drape::detail::potential_energy(d, f + h, 6.0) - drape::detail::potential_energy(d, f - h, 6.0)) / (2 * h);
    const double scale = drape::detail::potential_force_scale(d, f, 6.0);
    EXPECT_NEAR(scale, -slope, 1e-5 * std::abs(slope)) << "f " << f;
    EXPECT_LE(scale, d.c / d.xi * std::exp(d.max_exponent) * (1 + 1e-12));
  }
}

// The cut-off (obstacles.h): −dE/df is zero from R = 16 ξ on, and anywhere within
// (c/ξ)·e^−16 of the exact c/ξ·exp(min(−f/ξ, cap)) of eq (9), computed here with std::exp
// (plus 10⁻¹⁴ of it: −f/ξ is rounded, and e^x magnifies that by x ≤ 40).
TEST(Obstacles, CutOffForceStaysWithinItsBoundOfTheExactOne) {
  ObstacleDef d;
  d.c = 0.02;
  d.xi = 0.01;
  const double cap = 6.0, bound = d.c / d.xi * std::exp(-16.0);
  for (double e = -40.0; e <= 12.0; e += 0.01) {  // e = −f/ξ, beyond reach to past the cap
    const double f = -e * d.xi;
    const double exact = d.c / d.xi * std::exp(std::min(e, cap));
    const double cut = drape::detail::potential_force_scale(d, f, cap);
    EXPECT_LE(std::abs(cut - exact), bound * (1 + 1e-12) + 1e-14 * exact) << "f " << f << " excess " << (std::abs(cut - exact) - bound) / exact;
    EXPECT_GE(cut, 0.0) << "f " << f;
    if (f >= 16.0 * d.xi) {
      EXPECT_EQ(cut, 0.0) << "f " << f;
      EXPECT_EQ(drape::detail::potential_energy(d, f, cap), 0.0) << "f " << f;
    }
  }
  // the energy is continuous at the cut and its slope there is zero
  const double r = 16.0 * d.xi, h = 1e-7;
  EXPECT_NEAR(drape::detail::potential_energy(d, r - h, cap), 0.0, 1e-12 * d.c);
  EXPECT_NEAR(drape::detail::potential_force_scale(d, r - h, cap), 0.0, 1e-4 * bound);
}

// The kernel's exp against std::exp (correctly rounded in glibc to within 1 ulp, 2.2·10⁻¹⁶):
// its polynomial is 3·10⁻¹⁶ from e^r (tools/exp_polynomial.py), the evaluation and the
// reduction x − k·ln2 add a few ulp, and the bound, 10⁻¹⁵ of e^x, is what obstacles.h
// promises (the degree-9 polynomial misses it twentyfold). Exact at 0, e^−700 below −700 and e^709 above 709.
TEST(Obstacles, VectorExpStaysWithinItsBoundOfStdExp) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> wide(-700.0, 700.0), used(-17.0, 12.0);  // used: the force's exponents
  double worst = 0, worst_at = 0;
  for (int k = 0; k < 400000; ++k) {
    const double x = k % 4 == 0 ? wide(rng) : used(rng);
    const double want = std::exp(x), error = std::abs(drape::detail::vector_exp(x) - want) / want;
    if (error > worst) worst = error, worst_at = x;
  }
  for (double x = -2.0; x <= 2.0; x += 1.0 / 1024) {  // around the reduction's steps k·ln2/2
    const double want = std::exp(x), error = std::abs(drape::detail::vector_exp(x) - want) / want;
    if (error > worst) worst = error, worst_at = x;
  }
  for (double x = 690.0; x <= 709.0; x += 0.37) {  // up to the top of its range (a contact's uncapped exponent)
    const double want = std::exp(x), error = std::abs(drape::detail::vector_exp(x) - want) / want;
    if (error > worst) worst = error, worst_at = x;
  }
  EXPECT_LE(worst, 1e-15) << "at x = " << worst_at;
  EXPECT_EQ(drape::detail::vector_exp(0.0), 1.0);
  EXPECT_EQ(drape::detail::vector_exp(-800.0), drape::detail::vector_exp(-700.0));
  EXPECT_NEAR(drape::detail::vector_exp(-700.0), std::exp(-700.0), 1e-15 * std::exp(-700.0));
  // clamped above, so a force never overflows: e^709 for anything beyond
  EXPECT_NEAR(drape::detail::vector_exp(709.0), std::exp(709.0), 1e-15 * std::exp(709.0));
  EXPECT_EQ(drape::detail::vector_exp(800.0), drape::detail::vector_exp(709.0));
  EXPECT_EQ(drape::detail::vector_exp(1e300), drape::detail::vector_exp(709.0));
}

// The vectorised kernel against eq (9) point by point, written out here with std::exp, the
// analytic gradient and the normal from the neighbouring points: crumpled sheets of rows
// of 64, 65, 66 and 131 points (whole vectors, and a row's end in a part vector), single
// rows and columns, and every shape, projected and not. Within the cut-off's bound (above)
// plus rounding.
TEST(Obstacles, KernelMatchesEq9PointByPointOnCrumpledSheets) {
  const std::pair<std::uint32_t, std::uint32_t> sizes[] = {{0, 0}, {0, 5}, {4, 0}, {3, 63}, {2, 64}, {5, 65}, {3, 130}};
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  for (ObstacleShape shape : all_shapes)
    for (bool full : {false, true})
      for (auto [m, n] : sizes) {
        const ObstacleDef d = kernel_def(shape, full);
        const auto o = drape::detail::make_obstacle(d);
        auto sheet = drape::detail::build_sheet<double>(grid_def(m, n));
        const std::size_t count = sheet.size();
        for (std::size_t p = 0; p < count; ++p) {
          sheet.position.x[p] = d.center.x + u(rng);
          sheet.position.y[p] = d.center.y + u(rng);
          sheet.position.z[p] = d.center.z + u(rng);
        }
        const double cap = 5.0;
        std::vector<double> fx(count, 0.0), fy(count, 0.0), fz(count, 0.0);
        drape::detail::obstacle_forces<double>(*sheet.topology, drape::detail::NearObstacle{.obstacle = &o, .exponent_cap = cap},
                                               drape::detail::cptr(sheet.position), drape::detail::cptr(sheet.velocity),
                                               sheet.inv_mass.data(), {fx.data(), fy.data(), fz.data()});
        const auto& x = sheet.position;
        const double bound = d.c / d.xi * std::exp(-16.0);
        int beyond = 0, within = 0;
        for (std::uint32_t i = 0; i <= m; ++i)
          for (std::uint32_t j = 0; j <= n; ++j) {
            const std::size_t p = drape::point_index(n, i, j);
            const double q[3] = {x.x[p], x.y[p], x.z[p]};
            const auto s = drape::detail::implicit_at(o, q);
            const double scale = d.c / d.xi * std::exp(std::min(-s.f / d.xi, cap));
            double F[3] = {scale * s.grad[0], scale * s.grad[1], scale * s.grad[2]};
            if (!full) {
              const std::size_t r = drape::point_index(n, i, std::min(j + 1, n)), l = drape::point_index(n, i, j > 0 ? j - 1 : 0);
              const std::size_t up = drape::point_index(n, std::min(i + 1, m), j), dn = drape::point_index(n, i > 0 ? i - 1 : 0, j);
              const double a[3] = {x.x[r] - x.x[l], x.y[r] - x.y[l], x.z[r] - x.z[l]};
              const double b[3] = {x.x[up] - x.x[dn], x.y[up] - x.y[dn], x.z[up] - x.z[dn]};
              const double nv[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
              const double nn = nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2];
              if (nn > 0) {
                const double dot = (F[0] * nv[0] + F[1] * nv[1] + F[2] * nv[2]) / nn;
                for (int k = 0; k < 3; ++k) F[k] = dot * nv[k];
              }
            }
            const double got[3] = {fx[p], fy[p], fz[p]};
            const double size = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
            for (int k = 0; k < 3; ++k)
              EXPECT_NEAR(got[k], F[k], bound + 1e-13 * size)
                  << "shape " << int(shape) << " full " << full << " sheet " << m << "x" << n << " point " << i << "," << j;
            if (s.f >= 16.0 * d.xi) {
              ++beyond;
              EXPECT_EQ(got[0], 0.0);
              EXPECT_EQ(got[1], 0.0);
              EXPECT_EQ(got[2], 0.0);
            } else {
              ++within;
            }
          }
        if (count > 100) {
          EXPECT_GT(within, 0) << "shape " << int(shape);
        }
      }
}

// Eq (9) written out once more, point by point in plain double arithmetic with std::exp,
// for the per-target test below: the cut-off force scale c/ξ·max(e^min(−f/ξ, cap) − e^−16, 0)
// below the reach 16ξ, along ∇f, projected on the sheet normal from the neighbouring points
// (one-sided at the ends), then damping against the rate of leaving the surface and Coulomb
// friction against the slip, both relative to the moving obstacle's surface. f and ∇f of the plane and the torus are written here from the local
// frame (o.rot's columns are the obstacle's axes), not taken from the engine.
struct Eq9Reference {
  const drape::detail::Obstacle& o;
  const drape::detail::NearObstacle& near;

  void implicit(const double p[3], double& f, double g[3]) const {
    double d[3], q[3];
    for (int k = 0; k < 3; ++k) d[k] = p[k] - o.center[k];
    for (int l = 0; l < 3; ++l) q[l] = o.rot[0][l] * d[0] + o.rot[1][l] * d[1] + o.rot[2][l] * d[2];
    double local[3] = {0, 0, 1};
    if (o.def.shape == ObstacleShape::Plane) {
      f = q[2];
    } else {  // torus around local z, major radius size.x, minor size.y
      const double rho = std::hypot(q[0], q[1]), ring = rho - o.def.size.x, len = std::hypot(ring, q[2]);
      f = len - o.def.size.y;
      local[0] = ring / len * q[0] / rho;
      local[1] = ring / len * q[1] / rho;
      local[2] = q[2] / len;
    }
    for (int k = 0; k < 3; ++k) g[k] = o.rot[k][0] * local[0] + o.rot[k][1] * local[1] + o.rot[k][2] * local[2];
  }

  // The force eq (9) adds at point p = (i, j), given the force `before` on it so far.
  void force(const drape::detail::Sheet<double>& s, std::uint32_t i, std::uint32_t j, const double before[3],
             double F[3], double& size) const {
    const std::uint32_t m = s.topology->m, n = s.topology->n;
    const auto at = [&](std::uint32_t a, std::uint32_t b, double q[3]) {
      const std::size_t k = drape::point_index(n, a, b);
      q[0] = s.position.x[k], q[1] = s.position.y[k], q[2] = s.position.z[k];
    };
    const std::size_t p = drape::point_index(n, i, j);
    double x[3], f, g[3];
    at(i, j, x);
    implicit(x, f, g);
    const ObstacleDef& d = o.def;
    const double scale =
        f < 16 * d.xi ? d.c / d.xi * std::max(std::exp(std::min(-f / d.xi, near.exponent_cap)) - std::exp(-16.0), 0.0)
                      : 0.0;
    for (int k = 0; k < 3; ++k) F[k] = scale * g[k];
    if (!d.full_gradient) {
      double l[3], r[3], u[3], w[3];
      at(i, j > 0 ? j - 1 : 0, l);
      at(i, std::min(j + 1, n), r);
      at(i > 0 ? i - 1 : 0, j, w);
      at(std::min(i + 1, m), j, u);
      const double a[3] = {r[0] - l[0], r[1] - l[1], r[2] - l[2]}, b[3] = {u[0] - w[0], u[1] - w[1], u[2] - w[2]};
      const double nv[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
      const double nn = nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2];
      if (nn > 0) {
        const double along = (F[0] * nv[0] + F[1] * nv[1] + F[2] * nv[2]) / nn;
        for (int k = 0; k < 3; ++k) F[k] = along * nv[k];
      }
    }
    size = std::hypot(F[0], F[1], F[2]);
    const double gg = std::hypot(g[0], g[1], g[2]);
    const double inv_mass = s.inv_mass[p], v[3] = {s.velocity.x[p], s.velocity.y[p], s.velocity.z[p]};
    const double* w = near.angular;
    const double r[3] = {x[0] - near.center[0], x[1] - near.center[1], x[2] - near.center[2]};
    const double surface[3] = {near.linear[0] + w[1] * r[2] - w[2] * r[1], near.linear[1] + w[2] * r[0] - w[0] * r[2],
                               near.linear[2] + w[0] * r[1] - w[1] * r[0]};
    if (near.damping > 0 && size > 0) {  // Hunt–Crossley: F·(1 − α·ḋ), its coefficient at most ¼ m/dt
      const double rate = ((v[0] - surface[0]) * g[0] + (v[1] - surface[1]) * g[1] + (v[2] - surface[2]) * g[2]) / gg;
      const double most = inv_mass > 0 ? 0.25 / (inv_mass * near.dt) : std::numeric_limits<double>::infinity();
      const double change = std::max(-std::min(near.damping * size, most) * rate, -size);
      for (int k = 0; k < 3; ++k) F[k] += change / size * F[k];
      size = std::hypot(F[0], F[1], F[2]);
    }
    if (near.friction > 0) {
      const double normal_load = std::max(F[0] * g[0] + F[1] * g[1] + F[2] * g[2], 0.0) / gg;
      double slip[3], wn = 0;
      for (int k = 0; k < 3; ++k) {
        slip[k] = v[k] - surface[k] + near.dt * (inv_mass * (before[k] + F[k]) + near.gravity[k]);
        wn += slip[k] * g[k] / (gg * gg);
      }
      for (int k = 0; k < 3; ++k) slip[k] -= wn * g[k];
      const double speed = std::hypot(slip[0], slip[1], slip[2]);
      const double stop = inv_mass > 0 ? speed / (inv_mass * near.dt) : std::numeric_limits<double>::infinity();
      const double rub = speed > 0 ? std::min(near.friction * normal_load, stop) : 0.0;
      for (int k = 0; k < 3; ++k) F[k] -= speed > 0 ? rub * slip[k] / speed : 0.0;
      size += rub;
    }
  }
};

// The obstacle term of each instruction set on sheets of rows shorter than a vector, of
// whole vectors and past them, a row wholly beyond reach and points past the cap, projected or
// not, with and without friction and damping against a moving obstacle: the same bits on every target,
// and within rounding of Eq9Reference (1e-12 of the force's size in double, plus the ulp of the sum; in float, the
// sum rounded to float, 2⁻²³ of it).
template <class Real>
std::vector<Real> obstacle_term_on_each_config(std::mt19937& rng) {
  const std::pair<std::uint32_t, std::uint32_t> sizes[] = {{0, 0}, {3, 0}, {2, 1}, {4, 2}, {2, 63}, {3, 70}};
  std::uniform_real_distribution<double> u(-0.8, 0.8), unit(-1, 1), mass(0, 100);
  std::vector<Real> out;
  for (ObstacleShape shape : {ObstacleShape::Plane, ObstacleShape::Torus})
    for (bool full : {false, true})
      for (auto [mu, alpha] : {std::pair{0.0, 0.0}, std::pair{0.4, 0.0}, std::pair{0.0, 3.0}, std::pair{0.4, 3.0}})
        for (auto [m, n] : sizes) {
          const ObstacleDef d = kernel_def(shape, full);
          const auto o = drape::detail::make_obstacle(d);
          auto sheet = drape::detail::build_sheet<Real>(grid_def(m, n));
          auto exact = drape::detail::build_sheet<double>(grid_def(m, n));  // the same values, for the reference
          const std::size_t count = sheet.size();
          std::vector<Real> fx(count), fy(count), fz(count);
          for (std::size_t p = 0; p < count; ++p) {
            const double away = p <= n && m > 1 ? 3.0 : 0.0;  // the first row beyond reach
            const double at[3] = {d.center.x + u(rng) + away * o.rot[0][2], d.center.y + u(rng) + away * o.rot[1][2],
                                  d.center.z + u(rng) + away * o.rot[2][2]};
            sheet.position.x[p] = Real(at[0]), sheet.position.y[p] = Real(at[1]), sheet.position.z[p] = Real(at[2]);
            sheet.velocity.x[p] = Real(unit(rng)), sheet.velocity.y[p] = Real(unit(rng)), sheet.velocity.z[p] = Real(unit(rng));
            sheet.inv_mass[p] = p % 7 == 3 ? Real(0) : Real(mass(rng));  // some pinned
            fx[p] = Real(unit(rng)), fy[p] = Real(unit(rng)), fz[p] = Real(unit(rng));
            exact.position.x[p] = sheet.position.x[p], exact.position.y[p] = sheet.position.y[p];
            exact.position.z[p] = sheet.position.z[p];
            exact.velocity.x[p] = sheet.velocity.x[p], exact.velocity.y[p] = sheet.velocity.y[p];
            exact.velocity.z[p] = sheet.velocity.z[p];
            exact.inv_mass[p] = sheet.inv_mass[p];
          }
          const std::vector<Real> bx = fx, by = fy, bz = fz;
          const drape::detail::NearObstacle near{.obstacle = &o,
                                                 .exponent_cap = 5.0,
                                                 .friction = mu,
                                                 .damping = alpha,
                                                 .dt = 1e-3,
                                                 .gravity = {0, 0, -9.81},
                                                 .linear = {0.1, -0.2, 0.05},
                                                 .angular = {0.3, 0.1, -0.2},
                                                 .center = {o.center[0], o.center[1], o.center[2]}};
          drape::detail::obstacle_forces<Real>(*sheet.topology, near, drape::detail::cptr(sheet.position),
                                               drape::detail::cptr(sheet.velocity), sheet.inv_mass.data(),
                                               {fx.data(), fy.data(), fz.data()});
          const Eq9Reference reference{o, near};
          int within = 0, beyond = 0;
          for (std::uint32_t i = 0; i <= m; ++i)
            for (std::uint32_t j = 0; j <= n; ++j) {
              const std::size_t p = drape::point_index(n, i, j);
              const double before[3] = {double(bx[p]), double(by[p]), double(bz[p])};
              double F[3], size;
              reference.force(exact, i, j, before, F, size);
              (size > 0 ? within : beyond) += 1;
              const double got[3] = {double(fx[p]), double(fy[p]), double(fz[p])};
              for (int k = 0; k < 3; ++k) {
                const double tol = std::is_same_v<Real, float> ? 0x1p-23 * (std::abs(before[k]) + size)
                                                               : 1e-12 * size + 0x1p-52 * std::abs(before[k]);
                EXPECT_NEAR(got[k], before[k] + F[k], tol) << "shape " << int(shape) << " full " << full << " mu " << mu
                                                           << " alpha " << alpha << " sheet " << m << "x" << n << " point " << i << "," << j;
              }
            }
          if (count > 100) {
            EXPECT_GT(within, 0);
            EXPECT_GT(beyond, int(n));
          }
          out.insert(out.end(), fx.begin(), fx.end());
          out.insert(out.end(), fy.begin(), fy.end());
          out.insert(out.end(), fz.begin(), fz.end());
        }
  return out;
}

template <class Real>
void expect_every_target_gives_eq9_bit_for_bit() {
  std::vector<Real> first;
  drape::test::for_each_target([&](std::int64_t) {
    std::mt19937 rng(23);  // the same sheets on every target
    const std::vector<Real> got = obstacle_term_on_each_config<Real>(rng);
    if (first.empty()) {
      first = got;
      return;
    }
    ASSERT_EQ(got.size(), first.size());
    for (std::size_t k = 0; k < got.size(); ++k)  // bits, so −0 and NaN count too
      ASSERT_EQ(std::memcmp(&got[k], &first[k], sizeof(Real)), 0) << "value " << k << ": " << got[k] << " vs " << first[k];
  });
}

TEST(Obstacles, EveryInstructionSetGivesEq9BitForBit) { expect_every_target_gives_eq9_bit_for_bit<double>(); }
TEST(Obstacles, EveryInstructionSetGivesEq9BitForBitInFloat) { expect_every_target_gives_eq9_bit_for_bit<float>(); }

// The obstacle energy (energies(), and the guard after every step() call) runs in vectors on
// each instruction set: it must be the sum over the points of potential_energy (one value at
// a time, through the C library's exp), for every shape, with points within reach, beyond it
// and past the exponent cap, and point counts that leave remainders of every width.
template <class Real>
void expect_obstacle_energy_sums_the_potential() {
  drape::test::for_each_target([&](std::int64_t) {
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> u(-0.8, 0.8);
    const std::pair<std::uint32_t, std::uint32_t> sizes[] = {{0, 0}, {0, 6}, {2, 4}, {3, 70}};
    for (ObstacleShape shape : all_shapes)
      for (auto [m, n] : sizes)
        for (double cap : {2.0, 40.0}) {  // 2: points deep inside are past it; 40: none is
          const ObstacleDef d = kernel_def(shape, false);
          const auto o = drape::detail::make_obstacle(d);
          auto sheet = drape::detail::build_sheet<Real>(grid_def(m, n));
          double expected = 0, scale = 0;
          int within = 0, beyond = 0, past_cap = 0;
          for (std::size_t p = 0; p < sheet.size(); ++p) {
            const double away = p <= n && m > 1 ? 3.0 : 0.0;  // the first row beyond reach
            sheet.position.x[p] = Real(d.center.x + u(rng) + away * o.rot[0][2]);
            sheet.position.y[p] = Real(d.center.y + u(rng) + away * o.rot[1][2]);
            sheet.position.z[p] = Real(d.center.z + u(rng) + away * o.rot[2][2]);
            const double at[3] = {double(sheet.position.x[p]), double(sheet.position.y[p]), double(sheet.position.z[p])};
            const double f = drape::detail::implicit_at(o, at).f;
            const double e = drape::detail::potential_energy(d, f, cap);
            expected += e;
            scale += std::abs(e) + d.c;
            (f < drape::detail::reach_exponent * d.xi ? within : beyond) += 1;
            past_cap += -f / d.xi > cap;
          }
          const double got = drape::detail::obstacle_energy(sheet, o, cap);
          EXPECT_NEAR(got, expected, 1e-12 * scale) << "shape " << int(shape) << " sheet " << m << "x" << n << " cap " << cap;
          if (sheet.size() > 100) {
            EXPECT_GT(within, 0);
            EXPECT_GT(beyond, int(n));
            if (cap == 2.0) {
              EXPECT_GT(past_cap, 0) << "shape " << int(shape);
            }
          }
        }
  });
}

TEST(Obstacles, EnergyInVectorsSumsThePotentialOfEveryPoint) { expect_obstacle_energy_sums_the_potential<double>(); }
TEST(Obstacles, EnergyInVectorsSumsThePotentialOfEveryPointInFloat) {
  expect_obstacle_energy_sums_the_potential<float>();
}

drape::SheetDef point_def(Vec3 at, double mass = 0.01) {
  drape::SheetDef s;
  s.m = s.n = 0;
  s.mass = mass;
  s.center = at;
  return s;
}

// eq (9) with the physically right sign: the force along +∇f, i.e. out of the obstacle.
TEST(Obstacles, RepulsionPushesOutwardWithMinusEnergyGradient) {
  for (ObstacleShape shape : all_shapes) {
    ObstacleDef d = shape_def(shape);
    d.c = 0.01;
    d.xi = 0.02;
    d.full_gradient = true;
    const auto o = drape::detail::make_obstacle(d);
    // a point just outside, along the obstacle's local +z from a surface point
    const Vec3 base = add(d.center, drape::rotate(d.orientation, {0.05, 0.02, 0.0}));
    const double q[3] = {base.x, base.y, base.z};
    const auto s = drape::detail::implicit_at(o, q);
    const double g = std::sqrt(s.grad[0] * s.grad[0] + s.grad[1] * s.grad[1] + s.grad[2] * s.grad[2]);
    const Vec3 at = add(base, scaled({s.grad[0], s.grad[1], s.grad[2]}, (0.01 - s.f) / (g * g)));

    drape::WorldDef wd;
    wd.gravity = {0, 0, 0};
    wd.dt = 1e-4;
    drape::World world(wd);
    const auto id = world.add_sheet(point_def(at));
    world.add_obstacle(d);
    // −∇E by central differences of the world's own energy report
    const double h = 1e-6;
    double grad_e[3];
    for (int k = 0; k < 3; ++k) {
      auto energy_at = [&](double delta) {
        auto st = world.state(id);
        st.x[0] = at.x + (k == 0) * delta;
        st.y[0] = at.y + (k == 1) * delta;
        st.z[0] = at.z + (k == 2) * delta;
        return world.energies().obstacle;
      };
      grad_e[k] = (energy_at(h) - energy_at(-h)) / (2 * h);
    }
    auto st = world.state(id);
    st.x[0] = at.x, st.y[0] = at.y, st.z[0] = at.z;
    world.step();
    const auto v = world.view(id);
    const double mass = 0.01;
    const double force[3] = {v.vx[0] * mass / wd.dt, v.vy[0] * mass / wd.dt, v.vz[0] * mass / wd.dt};
    double outward = 0;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(force[k], -grad_e[k], 1e-5 * (1 + std::abs(grad_e[k]))) << "shape " << int(shape) << " axis " << k;
      outward += force[k] * s.grad[k];
    }
    EXPECT_GT(outward, 0) << "shape " << int(shape);
  }
}

// A flat sheet facing +z over an obstacle whose gradient is oblique: eq (9) keeps only the
// component along the sheet's normal; full_gradient keeps the sideways part too.
TEST(Obstacles, DefaultForceIsProjectedOnTheSheetNormal) {
  for (bool full : {false, true}) {
    drape::WorldDef wd;
    wd.gravity = {0, 0, 0};
    wd.dt = 1e-4;
    drape::World world(wd);
    drape::SheetDef s;
    s.m = s.n = 2;
    s.width = s.height = 0.2;
    s.center = {0, 0, 0.52};
    const auto id = world.add_sheet(s);
    ObstacleDef d;
    d.shape = ObstacleShape::Sphere;
    d.size = {0.5, 0, 0};
    d.c = 0.01;
    d.xi = 0.05;
    d.full_gradient = full;
    world.add_obstacle(d);
    world.step();
    const auto v = world.view(id);
    const std::uint32_t corner = drape::point_index(2, 2, 2);  // at (+0.1, +0.1)
    EXPECT_GT(v.vz[corner], 0);
    if (full) {
      EXPECT_GT(v.vx[corner], 0);
      EXPECT_NEAR(v.vx[corner] / v.vz[corner], 0.1 / 0.52, 0.05);  // along the sphere's radius
    } else {
      EXPECT_EQ(v.vx[corner], 0.0);  // the sheet is flat, its springs at rest: only the obstacle acts
      EXPECT_EQ(v.vy[corner], 0.0);
    }
  }
}

// A damped point dropped onto the top of each obstacle stops outside it, and comes to rest
// where the potential's force balances gravity: c/ξ·|∇f|·exp(−f/ξ) = m·g.
TEST(Obstacles, DroppedPointDoesNotPassThroughAndRestsWhereForceBalancesGravity) {
  const double g = 9.81, mass = 0.01;
  for (ObstacleShape shape : all_shapes) {
    ObstacleDef d;
    d.shape = shape;
    d.center = {0.1, 0.2, 0.0};
    d.c = 0.01;
    d.xi = 0.01;
    d.full_gradient = true;
    Vec3 top{0.1, 0.2, 0.0};  // highest point of the obstacle under the drop
    switch (shape) {
      case ObstacleShape::Plane: d.orientation = drape::quat_from_axis_angle({1, 0, 0}, 0.0); break;
      case ObstacleShape::Sphere: d.size = {0.3, 0, 0}, top.z = 0.3; break;
      case ObstacleShape::Ellipsoid: d.size = {0.5, 0.4, 0.2}, top.z = 0.2; break;
      case ObstacleShape::Torus: d.size = {0.4, 0.15, 0}, top = {0.5, 0.2, 0.15}; break;
      case ObstacleShape::Box: d.size = {0.3, 0.2, 0.25}, top.z = 0.25; break;
    }
    drape::WorldDef wd;
    wd.dt = 5e-4;
    drape::World world(wd);
    drape::SheetDef p = point_def(add(top, {0, 0, 0.3}), mass);
    p.damping = 0.05;
    const auto id = world.add_sheet(p);
    world.add_obstacle(d);
    const auto o = drape::detail::make_obstacle(d);
    double lowest = 1e9;
    for (int k = 0; k < 6000; ++k) {
      world.step();
      const auto v = world.view(id);
      lowest = std::min(lowest, f_at(o, {v.x[0], v.y[0], v.z[0]}));
    }
    ASSERT_TRUE(world.all_finite());
    // Energy bound: the fall releases at most m·g·0.3 J, which the potential absorbs before
    // c·exp(−f/ξ) exceeds it, so f never drops below −ξ·ln(m·g·0.3/c) (≈ −1.1 ξ).
    EXPECT_GT(lowest, -d.xi * std::log(mass * g * 0.3 / d.c) - 1e-3) << "shape " << int(shape);
    const auto v = world.view(id);
    const double rest = f_at(o, {v.x[0], v.y[0], v.z[0]});
    // |∇f| at the top is 1 for every shape here (the ellipsoid's top is on its smallest axis)
    EXPECT_NEAR(rest, d.xi * std::log(d.c / (d.xi * mass * g)), 0.02 * d.xi) << "shape " << int(shape);
    EXPECT_NEAR(v.x[0], top.x, 1e-9);
    EXPECT_NEAR(v.y[0], top.y, 1e-9);
  }
}

// A point meeting a plane face-on at 1 m/s in free space (full gradient): its height x
// above the plane follows m·ẍ = F(x)·(1 − α·ẋ), F the documented cut-off force scale
// (c/ξ)·(e^(−x/ξ) − e^(−16)) below the reach 16ξ, integrated by RK4 at a hundredth of the
// world's step. The world's rebound speed must match it within 1 % for α = 0 (the speed it
// came with: the potential conserves energy), 0.5 and 2 s/m, and fall with α.
TEST(Obstacles, DampedPointReboundsAtTheSpeedOfTheOneDimensionalModel) {
  ObstacleDef d;
  d.shape = ObstacleShape::Plane;
  d.c = 0.01;
  d.xi = 0.01;
  d.full_gradient = true;
  drape::WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.dt = 1e-4;
  const double mass = 0.01, approach = 1.0, start = 16 * d.xi + 0.001, seconds = 1.5;
  double previous = 2 * approach;
  for (double alpha : {0.0, 0.5, 2.0}) {
    const auto accel = [&](double x, double rate) {
      if (x >= 16 * d.xi) return 0.0;
      const double F = d.c / d.xi * (std::exp(-x / d.xi) - std::exp(-16.0));
      return std::max(F * (1 - alpha * rate), 0.0) / mass;
    };
    const auto [x, rate] = drape::test::gap_after(accel, start, approach, seconds, wd.dt / 100);
    ASSERT_GT(x, 16 * d.xi) << "the reference has not left the reach within the run";
    d.damping = alpha;
    drape::World world(wd);
    drape::SheetDef p = point_def({0, 0, start}, mass);
    p.initial_velocity = {0, 0, -approach};
    const auto id = world.add_sheet(p);
    world.add_obstacle(d);
    ASSERT_TRUE(world.step(std::uint32_t(std::lround(seconds / wd.dt))).ok());
    const double rebound = world.view(id).vz[0];
    EXPECT_NEAR(rebound, rate, 0.01 * approach) << "alpha " << alpha;
    if (alpha == 0) {
      EXPECT_NEAR(rebound, approach, 0.01 * approach);
    }
    EXPECT_LT(rebound, previous) << "alpha " << alpha;
    previous = rebound;
  }
}

// Deep inside (f = −25ξ, far past the cap) the force is bounded, so the point is pushed out
// at a finite speed; a point fired at 50 m/s into a plane is stopped and sent back.
TEST(Obstacles, PointStartedInsideOrArrivingFastIsPushedOutWithoutNaN) {
  for (ObstacleShape shape : all_shapes) {
    ObstacleDef d = shape_def(shape);
    d.c = 0.01;
    d.xi = 0.01;
    if (shape == ObstacleShape::Plane) d.size = {};
    drape::WorldDef wd;
    wd.gravity = {0, 0, 0};
    wd.dt = 1e-3;
    drape::World world(wd);
    const auto o = drape::detail::make_obstacle(d);
    // a point inside, deeper than the cap (checked below)
    Vec3 local{0.0, 0.0, -0.1};
    if (shape == ObstacleShape::Torus) local = {0.5, 0.0, 0.0};
    if (shape == ObstacleShape::Box) local = {0.1, 0.1, -0.05};
    const Vec3 at = add(d.center, drape::rotate(d.orientation, local));
    ASSERT_LT(f_at(o, at), -d.xi * d.max_exponent) << "shape " << int(shape);
    drape::SheetDef p = point_def(at);
    p.damping = 0.2;
    const auto id = world.add_sheet(p);
    world.add_obstacle(d);
    for (int k = 0; k < 2000; ++k) {
      world.step();
      ASSERT_TRUE(world.all_finite()) << "shape " << int(shape) << " step " << k;
    }
    const auto v = world.view(id);
    EXPECT_GT(f_at(o, {v.x[0], v.y[0], v.z[0]}), 0) << "shape " << int(shape);
  }
  drape::WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.dt = 1e-3;
  drape::World world(wd);
  drape::SheetDef p = point_def({0, 0, 0.05});
  p.initial_velocity = {0, 0, -50};
  const auto id = world.add_sheet(p);
  ObstacleDef plane;
  plane.shape = ObstacleShape::Plane;
  plane.c = 0.01;
  plane.xi = 0.01;
  world.add_obstacle(plane);
  for (int k = 0; k < 500; ++k) {
    world.step();
    ASSERT_TRUE(world.all_finite()) << "step " << k;
  }
  EXPECT_GT(world.view(id).z[0], 0);
  EXPECT_GT(world.view(id).vz[0], 0);
}

// Deep inside, the force is the bound: (c/ξ)·e^max_exponent for a heavy point, and m·ξ/dt²
// (the potential no stiffer than m/dt²) for a light one, whichever is smaller.
TEST(Obstacles, ForceDeepInsideIsBoundedByCapAndByWhatTheStepResolves) {
  for (double mass : {10.0, 1e-3}) {
    drape::WorldDef wd;
    wd.gravity = {0, 0, 0};
    wd.dt = 1e-3;
    drape::World world(wd);
    const auto id = world.add_sheet(point_def({0, 0, -1.0}, mass));
    ObstacleDef plane;
    plane.shape = ObstacleShape::Plane;
    plane.c = 0.01;
    plane.xi = 0.01;
    world.add_obstacle(plane);
    world.step();
    const double force = world.view(id).vz[0] * mass / wd.dt;
    // less the cut-off's shift (c/ξ)·e^−16 (obstacles.h)
    const double expected = std::min(plane.c / plane.xi * std::exp(plane.max_exponent), mass * plane.xi / (wd.dt * wd.dt)) -
                            plane.c / plane.xi * std::exp(-16.0);
    EXPECT_NEAR(force, expected, 1e-9 * expected) << "mass " << mass;
  }
}

// Only sheets whose bounding box comes within reach (16 ξ) pay for an obstacle.
TEST(Obstacles, OnlyBoxesWithinReachTouch) {
  ObstacleDef d;
  d.shape = ObstacleShape::Sphere;
  d.size = {0.5, 0, 0};
  d.xi = 0.01;
  const auto o = drape::detail::make_obstacle(d);
  drape::detail::Aabb near{{-0.1, -0.1, 0.5 + 0.15}, {0.1, 0.1, 1.0}};
  drape::detail::Aabb far{{-0.1, -0.1, 0.5 + 0.17}, {0.1, 0.1, 1.0}};
  EXPECT_TRUE(drape::detail::may_touch(o, near));
  EXPECT_FALSE(drape::detail::may_touch(o, far));
  ObstacleDef pd;
  pd.shape = ObstacleShape::Plane;
  pd.orientation = drape::quat_from_axis_angle({1, 0, 0}, std::numbers::pi / 4);  // normal (0, −½√2, ½√2)
  pd.xi = 0.01;
  const auto plane = drape::detail::make_obstacle(pd);
  // corner (x, 1, 0.5): f = (0.5 − 1)/√2 < 0 → touches; a box above the plane by 1 m does not
  EXPECT_TRUE(drape::detail::may_touch(plane, {{0, 0, 0.5}, {1, 1, 2}}));
  EXPECT_FALSE(drape::detail::may_touch(plane, {{0, -1, 0.5}, {1, -0.9, 2}}));
}

// A world whose sheets never come near an obstacle steps exactly as one without it.
TEST(Obstacles, FarObstacleLeavesTheSheetBitIdentical) {
  auto run = [](bool with_obstacle) {
    drape::World world;
    drape::SheetDef s;
    s.m = s.n = 6;
    s.pins = drape::corner_points(6, 6);
    const auto id = world.add_sheet(s);
    if (with_obstacle) {
      ObstacleDef d;
      d.center = {0, 0, -5};
      world.add_obstacle(d);
    }
    world.step(200);
    const auto v = world.view(id);
    return std::vector<double>(v.z.begin(), v.z.end());
  };
  EXPECT_EQ(run(false), run(true));
}

// Coulomb friction (obstacles.h): a 3×3 sheet lying on a plane tilted by θ, started at the
// height where eq (9)'s force carries its weight's normal part m·g·cos θ. With tan θ < μ it
// stays put; with tan θ > μ it slides with a = g·(sin θ − μ·cos θ). μ is the larger of the
// sheet's and the obstacle's coefficients, whichever of them holds it.
// The height above a plane at which eq (9)'s cut-off, shifted force carries a normal load
// `load` (N) per point: (c/ξ)·(exp(−f/ξ) − e^−16) = load, solved for f.
double resting_height(const ObstacleDef& plane, double load) {
  return -plane.xi * std::log(load * plane.xi / plane.c + std::exp(-16.0));
}

struct Incline {
  double along = 0, speed = 0;  // mean displacement and velocity down the slope
};

Incline slide_down(double theta, double mu_sheet, double mu_obstacle, double seconds) {
  const double g = 9.81, point_mass = 0.01;
  const drape::Quat tilt = drape::quat_from_axis_angle({1, 0, 0}, theta);
  const Vec3 normal = drape::rotate(tilt, {0, 0, 1}), down = drape::rotate(tilt, {0, -1, 0});
  ObstacleDef plane;
  plane.shape = ObstacleShape::Plane;
  plane.orientation = tilt;
  plane.c = 0.01;
  plane.xi = 0.01;
  plane.friction = mu_obstacle;
  const double rest = resting_height(plane, point_mass * g * std::cos(theta));
  drape::WorldDef wd;
  wd.dt = 1e-3;
  drape::World world(wd);
  drape::SheetDef s;
  s.m = s.n = 2;
  s.width = s.height = 0.1;
  s.mass = 9 * point_mass;
  s.orientation = tilt;
  s.center = scaled(normal, rest);
  s.friction = mu_sheet;
  const auto id = world.add_sheet(s);
  world.add_obstacle(plane);
  const auto before = world.view(id);
  std::vector<double> start;
  for (std::size_t p = 0; p < 9; ++p) start.push_back(before.x[p] * down.x + before.y[p] * down.y + before.z[p] * down.z);
  world.step(std::uint64_t(std::lround(seconds / wd.dt)));
  EXPECT_TRUE(world.all_finite());
  const auto v = world.view(id);
  Incline r;
  for (std::size_t p = 0; p < 9; ++p) {
    r.along += (v.x[p] * down.x + v.y[p] * down.y + v.z[p] * down.z - start[p]) / 9;
    r.speed += (v.vx[p] * down.x + v.vy[p] * down.y + v.vz[p] * down.z) / 9;
  }
  return r;
}

TEST(Obstacles, FrictionHoldsASheetOnAnInclineFlatterThanItsAngle) {
  const double theta = 20 * std::numbers::pi / 180;  // tan θ = 0.36
  for (auto [sheet, obstacle] : {std::pair{0.5, 0.0}, std::pair{0.0, 0.5}, std::pair{0.5, 0.3}}) {
    const Incline r = slide_down(theta, sheet, obstacle, 1.0);
    EXPECT_LT(std::abs(r.along), 1e-6) << "mu " << sheet << ", " << obstacle;  // less than 1 µm in 1 s
    EXPECT_LT(std::abs(r.speed), 1e-6) << "mu " << sheet << ", " << obstacle;
  }
  // without friction the same sheet slides with g·sin θ (0.1 % over half a second)
  const Incline free = slide_down(theta, 0.0, 0.0, 0.5);
  EXPECT_NEAR(free.speed, 9.81 * std::sin(theta) * 0.5, 1e-3 * 9.81 * std::sin(theta) * 0.5);
}

TEST(Obstacles, FrictionSlowsASlidingSheetToGTimesSinMinusMuCos) {
  const double theta = 30 * std::numbers::pi / 180, mu = 0.2, t = 0.5;  // tan θ = 0.58 > μ
  const double a = 9.81 * (std::sin(theta) - mu * std::cos(theta));
  for (auto [sheet, obstacle] : {std::pair{mu, 0.0}, std::pair{0.0, mu}, std::pair{mu, 0.1}}) {
    const Incline r = slide_down(theta, sheet, obstacle, t);
    EXPECT_NEAR(r.speed, a * t, 5e-3 * a * t) << "mu " << sheet << ", " << obstacle;
    EXPECT_NEAR(r.along, 0.5 * a * t * t, 1e-2 * 0.5 * a * t * t) << "mu " << sheet << ", " << obstacle;
  }
}

// Friction acts against the slip relative to a moving obstacle's surface (eq (9)'s
// obstacle posed by its motion): a 4×4-cell sheet lying on a horizontal plane that moves
// along x by `platform(t)`, started at rest at the height where eq (9) carries its weight.
// Returns the sheet's mean velocity along x after `seconds`.
double carried_along(const std::function<double(double)>& platform, double mu, double seconds) {
  const double g = 9.81, point_mass = 0.01;
  ObstacleDef plane;
  plane.shape = ObstacleShape::Plane;
  plane.c = 0.01;
  plane.xi = 0.01;
  plane.friction = mu;
  plane.motion = drape::Motion{};
  plane.motion->kind = drape::Motion::Kind::Callback;
  plane.motion->callback = [platform](double t) { return drape::Pose{{}, {platform(t), 0, 0}}; };
  const double rest = resting_height(plane, point_mass * g);
  drape::WorldDef wd;
  wd.dt = 1e-3;
  drape::World world(wd);
  drape::SheetDef s;
  s.m = s.n = 4;
  s.width = s.height = 0.1;
  s.mass = 25 * point_mass;
  s.center = {0, 0, rest};
  const auto id = world.add_sheet(s);
  world.add_obstacle(plane);
  world.step(std::uint64_t(std::lround(seconds / wd.dt)));
  EXPECT_TRUE(world.all_finite());
  const auto v = world.view(id);
  double vx = 0;
  for (std::size_t p = 0; p < v.size(); ++p) vx += v.vx[p] / double(v.size());
  return vx;
}

TEST(Obstacles, FrictionCarriesASheetAlongWithAPlatformMovingAtConstantSpeed) {
  const double u = 0.5;
  const auto platform = [u](double t) { return u * t; };
  // μ·g = 9.8 m/s² brings it to u within about 0.05 s; at 0.5 s it moves with the platform
  EXPECT_NEAR(carried_along(platform, 1.0, 0.5), u, 1e-3 * u);
  // without friction the platform slides away beneath it
  EXPECT_LT(std::abs(carried_along(platform, 0.0, 0.5)), 1e-9);
}

TEST(Obstacles, AcceleratingPlatformCarriesASheetBelowMuGAndDragsItAtMuGAbove) {
  const double g = 9.81, mu = 0.4, t = 0.5;
  // a < μ·g: no slip, the sheet keeps the platform's velocity a·t
  const double slow = 0.5 * mu * g;
  EXPECT_NEAR(carried_along([slow](double s) { return 0.5 * slow * s * s; }, mu, t), slow * t, 5e-3 * slow * t);
  // a > μ·g: it slips, and kinetic friction gives it μ·g
  const double fast = 2 * mu * g;
  EXPECT_NEAR(carried_along([fast](double s) { return 0.5 * fast * s * s; }, mu, t), mu * g * t, 5e-3 * mu * g * t);
}

// A turntable: a horizontal plane turning about the z axis at ω. With friction the sheet
// laid on it off the axis ends turning with it, each point at ω ẑ × x (the centripetal
// ω²·r = 0.8 m/s² is well below μ·g); friction sees the rotation, not only a translation.
TEST(Obstacles, FrictionTurnsASheetWithATurningPlatform) {
  const double g = 9.81, point_mass = 0.01, omega = 2, r = 0.2;
  ObstacleDef plane;
  plane.shape = ObstacleShape::Plane;
  plane.c = 0.01;
  plane.xi = 0.01;
  plane.friction = 1.0;
  plane.motion = drape::Motion{};
  plane.motion->kind = drape::Motion::Kind::Callback;
  plane.motion->callback = [omega](double t) {
    return drape::Pose{drape::quat_from_axis_angle({0, 0, 1}, omega * t), {}};
  };
  drape::WorldDef wd;
  wd.dt = 1e-3;
  drape::World world(wd);
  drape::SheetDef s;
  s.m = s.n = 4;
  s.width = s.height = 0.1;
  s.mass = 25 * point_mass;
  s.center = {r, 0, resting_height(plane, point_mass * g)};
  const auto id = world.add_sheet(s);
  world.add_obstacle(plane);
  world.step(500);
  const auto v = world.view(id);
  for (std::size_t p = 0; p < v.size(); ++p) {
    EXPECT_NEAR(v.vx[p], -omega * v.y[p], 1e-2 * omega * r) << "point " << p;
    EXPECT_NEAR(v.vy[p], omega * v.x[p], 1e-2 * omega * r) << "point " << p;
  }
}

// No tunnelling at the speeds docs/scene-format.md calls safe for obstacles: a sheet thrown
// at a plane, a sphere and a box at v = √(c/m) (½·m·v² is half the potential c at f = 0)
// with v·dt ≤ ξ/2, square on and at a slant, with and without friction. A point stops where
// c·exp(−f/ξ) ≈ ½·m·v², near f = ξ·ln 2; every point is held, at every substep, farther
// than a tenth of ξ outside the surface, and the sheet as a whole comes back out.
TEST(Obstacles, SheetsThrownAtTheSafeSpeedStopOutside) {
  for (ObstacleShape shape : {ObstacleShape::Plane, ObstacleShape::Sphere, ObstacleShape::Box})
    for (double tilt : {0.0, 0.4})
      for (double friction : {0.0, 0.5}) {
        ObstacleDef d;
        d.shape = shape;
        d.size = {0.3, 0.3, 0.3};
        d.c = 0.01;
        d.xi = 0.01;
        d.friction = friction;
        const double top = shape == ObstacleShape::Plane ? 0.0 : 0.3;
        drape::SheetDef s;
        s.m = s.n = 10;
        s.width = s.height = 0.2;
        s.mass = 0.05;
        const double m = s.mass / drape::point_count(s.m, s.n), v = std::sqrt(d.c / m);
        drape::WorldDef wd;
        wd.gravity = {0, 0, 0};
        wd.dt = std::min(2e-4, 0.5 * d.xi / v);
        drape::World world(wd);
        s.center = {0.02, -0.01, top + 0.2};
        s.orientation = drape::quat_from_axis_angle({1, 1, 0}, tilt);
        s.initial_velocity = {0, 0, -v};
        const auto id = world.add_sheet(s);
        world.add_obstacle(d);
        const auto o = drape::detail::make_obstacle(d);
        double closest = 1e9;
        for (int k = 0; k < int(0.4 / v / wd.dt); ++k) {
          world.step();
          const auto p = world.view(id);
          for (std::size_t q = 0; q < p.size(); ++q) closest = std::min(closest, f_at(o, {p.x[q], p.y[q], p.z[q]}));
        }
        EXPECT_GT(closest, 0.1 * d.xi) << "shape " << int(shape) << " tilt " << tilt << " friction " << friction;
        EXPECT_LT(closest, 2 * d.xi) << "shape " << int(shape) << ": the sheet never came near";
        const auto p = world.view(id);
        double rebound = 0;  // the sheet's momentum along z: it flaps, but as a whole it moves away
        for (std::size_t q = 0; q < p.size(); ++q) rebound += p.vz[q];
        EXPECT_GT(rebound, 0.0) << "shape " << int(shape) << " tilt " << tilt;
      }
}

// obstacle_penetration against depths computed here from the shapes' geometry: a sphere's
// r − |p − c|, a turned box's smallest (half extent − |local coordinate|), a plane's height
// below it; of every point and obstacle the deepest, and 0 with no obstacle for a sheet
// outside all of them.
TEST(Obstacles, PenetrationIsTheDeepestPointsDistanceInsideTheSurface) {
  drape::World world;
  ObstacleDef sphere;
  sphere.center = {0.1, 0.05, 0};
  sphere.size = {0.3, 0, 0};
  ObstacleDef box;
  box.shape = ObstacleShape::Box;
  box.center = {2, 0, 0};
  box.size = {0.35, 0.4, 0.5};
  const double turn = 0.3;
  box.orientation = drape::quat_from_axis_angle({0, 0, 1}, turn);
  ObstacleDef plane;  // outside is +z, above z = −0.2
  plane.shape = ObstacleShape::Plane;
  plane.center = {0, 0, -0.2};
  const drape::ObstacleId ids[3] = {world.add_obstacle(sphere), world.add_obstacle(box), world.add_obstacle(plane)};
  const auto depths = [&](Vec3 p) {
    const double lx = std::cos(turn) * (p.x - 2) + std::sin(turn) * p.y, ly = -std::sin(turn) * (p.x - 2) + std::cos(turn) * p.y;
    const double inside_box = std::min({0.35 - std::abs(lx), 0.4 - std::abs(ly), 0.5 - std::abs(p.z)});
    return std::array<double, 3>{0.3 - std::hypot(p.x - 0.1, p.y - 0.05, p.z), inside_box, -0.2 - p.z};
  };
  drape::SheetDef s;
  s.m = s.n = 8;
  s.orientation = drape::quat_from_axis_angle({1, 0, 0}, 0.2);  // points at several heights
  for (Vec3 center : {Vec3{0, 0, 0}, Vec3{2, 0.05, 0.1}, Vec3{-3, 0, -0.3}, Vec3{5, 5, 1}}) {
    s.center = center;
    const auto id = world.add_sheet(s);
    const auto v = world.view(id);
    drape::ObstaclePenetration expected;
    for (std::uint32_t p = 0; p < v.size(); ++p) {
      const auto d = depths({v.x[p], v.y[p], v.z[p]});
      for (int o = 0; o < 3; ++o)
        if (d[o] > expected.depth) expected = {d[o], ids[o], p};
    }
    const drape::ObstaclePenetration got = world.obstacle_penetration(id);
    EXPECT_NEAR(got.depth, expected.depth, 1e-12) << "sheet at x = " << center.x;
    EXPECT_EQ(got.obstacle, expected.obstacle) << "sheet at x = " << center.x;
    EXPECT_EQ(got.point, expected.point) << "sheet at x = " << center.x;
    if (center.x == 5) {
      EXPECT_EQ(got.depth, 0.0) << "a sheet outside every obstacle";
    } else {
      EXPECT_GT(got.depth, 0.05) << "each of the others is inside one";
    }
  }
}

TEST(Obstacles, RemovedObstacleNoLongerActsAndItsIdIsStale) {
  drape::WorldDef wd;
  drape::World world(wd);
  const auto id = world.add_sheet(point_def({0, 0, 0.05}));
  ObstacleDef plane;
  plane.shape = ObstacleShape::Plane;
  plane.c = 0.01;
  plane.xi = 0.01;
  const auto oid = world.add_obstacle(plane);
  world.step(10);
  world.remove_obstacle(oid);
  EXPECT_FALSE(world.contains(oid));
  EXPECT_THROW(world.remove_obstacle(oid), std::invalid_argument);
  const double vz = world.view(id).vz[0];
  world.step();
  EXPECT_NEAR(world.view(id).vz[0] - vz, -9.81 * wd.dt, 1e-12);  // free fall only
}

TEST(Obstacles, BadDefinitionIsRejectedWithItsField) {
  drape::World world;
  ObstacleDef d;
  d.xi = 0;
  try {
    world.add_obstacle(d);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("xi"), std::string::npos);
  }
  d = ObstacleDef{};
  d.shape = ObstacleShape::Torus;
  d.size = {0.5, -1, 0};
  EXPECT_NE(drape::validate(d).find("minor radius"), std::string::npos);
  d = ObstacleDef{};
  d.damping = -2;
  EXPECT_EQ(drape::validate(d), "damping must be non-negative and finite (got -2)");
}

}  // namespace
