// The force terms beyond the paper (issue 12: shear, bending, air) against independent
// answers: linear elasticity of a sheared cell, Euler–Bernoulli beam theory, the drag law,
// and finite differences of each term's energy and force.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "diagnostics.h"
#include "forces.h"
#include "integrate.h"
#include "sheet_data.h"
#include "terms/terms.h"

namespace {

using drape::SheetDef;
using drape::detail::Sheet;

// Total force on every point through the engine's sweep (all of the sheet's terms).
void forces(Sheet<double>& s) {
  drape::detail::sheet_forces(s, cptr(s.position), cptr(s.velocity), ptr(s.force));
}

// A flat sheet sheared in its plane: every row i moved by gamma·(its height) along x, so
// each cell is sheared by gamma. The x-force on the top row, summed, is what a shear test
// measures on the loaded edge.
double top_row_shear_force(const SheetDef& d, double gamma) {
  Sheet<double> s = drape::detail::build_sheet<double>(d);
  const std::uint32_t cols = d.n + 1;
  const double y0 = s.position.y[0];
  for (std::size_t p = 0; p < s.size(); ++p) s.position.x[p] += gamma * (s.position.y[p] - y0);
  forces(s);
  double fx = 0;
  for (std::uint32_t j = 0; j < cols; ++j) fx += s.force.x[d.m * cols + j];
  return fx;
}

SheetDef square_grid(std::uint32_t cells, double size) {
  SheetDef d;
  d.m = d.n = cells;
  d.width = d.height = size;
  d.stiffness = 500;
  return d;
}

// Linear elasticity of one cell with diagonals of stiffness k_s at 45°: a shear gamma
// lengthens one diagonal by gamma·h/√2 and shortens the other as much, each pulling with
// k_s·gamma·h/√2 along its direction, whose x-part is 1/√2 of it: k_s·gamma·h per cell in
// all, against the shear. The top row of an n-cell-wide sheet carries n cells' worth.
TEST(Shear, InPlaneShearResistsWithExpectedForce) {
  const double size = 0.5, gamma = 1e-5, ks = 80;
  SheetDef d = square_grid(6, size);
  d.shear = drape::ShearDef{ks, std::nullopt};
  const double h = size / 6;
  const double expected = -6 * ks * gamma * h;
  EXPECT_NEAR(top_row_shear_force(d, gamma), expected, 1e-4 * std::abs(expected));
}

// The paper's grid alone: the vertical springs only turn, their length changes by
// (gamma·h)²/(2h), so the resisting force is third order in gamma: nothing at first order.
TEST(Shear, GridWithoutShearSpringsDoesNotResistShear) {
  const double size = 0.5, gamma = 1e-5, ks = 80;
  SheetDef d = square_grid(6, size);
  const double with_shear_scale = 6 * ks * gamma * size / 6;
  EXPECT_LT(std::abs(top_row_shear_force(d, gamma)), 1e-6 * with_shear_scale);
}

// A strip clamped at one end (two columns pinned, so the slope between them is zero: the
// beam's clamp sits half-way between them, h/2 from the end) sags under
// its own weight. Each grid line of spacing h stores ½ k_b Σ |x_a − 2x_b + x_c|² ≈
// ½ (k_b h³) ∫ κ² ds, a beam of EI = k_b h³; the strip has two such lines. Euler–Bernoulli:
// a cantilever of length L under a uniform load q per length deflects at the tip by
// δ = q L⁴ / (8 EI). Implicit Euler at a step about 100 times the explicit limit of this
// bending stiffness: without the term's Jacobian in its matrix the run blows up.
TEST(Bending, CantileverTipDeflectionMatchesBeamTheory) {
  const std::uint32_t n = 40;
  const double h = 0.025, mass_point = 2.5e-3, g = 9.81;
  SheetDef d;
  d.m = 1;
  d.n = n;
  d.width = n * h;
  d.height = 0.02;
  d.stiffness = 2e4;  // stiff in stretch: the strip bends, it does not stretch
  d.bending = drape::BendingDef{1e6};
  d.point_masses.assign(2 * (n + 1), mass_point);
  d.point_masses[n] = d.point_masses[2 * n + 1] = mass_point / 2;  // the free end carries half a cell
  d.damping = 0.25;  // about critical for the first bending mode
  d.pins = {0, 1, n + 1, n + 2};
  drape::WorldDef wd;
  wd.integrator = drape::Integrator::ImplicitEuler;
  wd.dt = 2e-3;
  wd.cg_max_iterations = 1000;
  wd.cg_tolerance = 1e-10;
  drape::World w(wd);
  const auto id = w.add_sheet(d);
  const double z0 = w.view(id).z[n];
  w.step(1500);
  const auto v = w.view(id);
  EXPECT_LT(std::abs(v.vz[n]), 1e-6);  // at rest
  const double sag = z0 - 0.5 * (v.z[n] + v.z[2 * n + 1]);
  const double L = (n - 0.5) * h;             // from the clamp to the tip
  const double q = 2 * mass_point * g / h;    // two rows of points, one every h
  const double EI = 2 * 1e6 * h * h * h;      // two lines
  const double beam = q * L * L * L * L / (8 * EI);
  EXPECT_LT(beam / L, 0.02);  // a small load: linear theory applies
  EXPECT_NEAR(sag, beam, 0.01 * beam);
}

// A sheet falling flat, face down, with air: m g = ½ ρ C_n A v², so it settles at
// v = √(2 m g / (ρ C_n A)) whatever its size in cells. Each point carries the mass of its
// share of the cells around it, as it carries their drag, so the sheet falls flat.
TEST(Air, FallingSheetReachesTheDragLawTerminalVelocity) {
  SheetDef d;
  d.m = d.n = 8;
  d.width = d.height = 0.5;
  d.stiffness = 50;
  for (std::uint32_t i = 0; i <= d.m; ++i)
    for (std::uint32_t j = 0; j <= d.n; ++j) {
      const double cells = (i == 0 || i == d.m ? 1 : 2) * (j == 0 || j == d.n ? 1 : 2);  // quarters of cells
      d.point_masses.push_back(0.01 / 64 * cells / 4);
    }
  d.air = drape::AirDef{1.3, 0.0};
  drape::WorldDef wd;
  wd.dt = 1e-3;
  wd.wind.density = 1.2;
  drape::World w(wd);
  const auto id = w.add_sheet(d);
  w.step(1500);  // about 20 time constants v/g
  const double terminal = std::sqrt(2 * 0.01 * 9.81 / (1.2 * 1.3 * 0.25));
  const auto v = w.view(id);
  for (std::size_t p = 0; p < v.size(); ++p) EXPECT_NEAR(-v.vz[p], terminal, 1e-3 * terminal) << "point " << p;
}

// Wind blowing up through a sheet at rest gives the same force as the sheet falling
// through still air at that speed: only the relative velocity counts.
TEST(Air, OnlyTheVelocityRelativeToTheWindCounts) {
  SheetDef d;
  d.m = d.n = 3;
  d.air = drape::AirDef{1.0, 0.3};
  Sheet<double> still = drape::detail::build_sheet<double>(d), windy = still;
  drape::detail::set_wind(still, drape::Wind{{0, 0, 0}, 1.2});
  drape::detail::set_wind(windy, drape::Wind{{0.5, 0, 2}, 1.2});
  for (std::size_t p = 0; p < still.size(); ++p) {
    still.velocity.x[p] = -0.5;
    still.velocity.z[p] = -2;
    still.position.z[p] += 0.01 * std::sin(double(p));  // cells at various tilts
    windy.position.z[p] = still.position.z[p];
  }
  forces(still);
  forces(windy);
  double up = 0;
  for (std::size_t p = 0; p < still.size(); ++p) {
    EXPECT_NEAR(still.force.x[p], windy.force.x[p], 1e-12);
    EXPECT_NEAR(still.force.z[p], windy.force.z[p], 1e-12);
    up += windy.force.z[p];
  }
  EXPECT_GT(up, 0);  // pushed along the wind
}

// Sheets with every conservative term, crumpled at random, for the checks below.
Sheet<double> crumpled(bool shear, bool bending) {
  SheetDef d;
  d.m = 4;
  d.n = 5;
  d.width = 0.5;
  d.height = 0.4;
  d.stiffness = 70;
  if (shear) d.shear = drape::ShearDef{30, 0.1};
  if (bending) d.bending = drape::BendingDef{12};
  Sheet<double> s = drape::detail::build_sheet<double>(d);
  for (std::size_t p = 0; p < s.size(); ++p) {
    s.position.x[p] += 0.03 * std::sin(1.3 * double(p));
    s.position.y[p] += 0.03 * std::cos(2.1 * double(p));
    s.position.z[p] += 0.05 * std::sin(0.7 * double(p) + 1);
  }
  return s;
}

double potential(const Sheet<double>& s) {
  const drape::Energies e = drape::detail::sheet_energies(s, drape::Vec3{0, 0, 0});
  return e.spring + e.bending;
}

// f = −∇E by central differences, for each term on its own (grid springs are always there:
// the difference between sheets with and without the term is checked through the total).
TEST(Terms, EachForceIsMinusTheGradientOfItsEnergy) {
  for (auto [shear, bending] : {std::pair{false, false}, std::pair{true, false}, std::pair{false, true},
                                std::pair{true, true}}) {
    Sheet<double> s = crumpled(shear, bending);
    forces(s);
    const double eps = 1e-6;
    for (std::size_t p = 0; p < s.size(); ++p)
      for (auto* axis : {&s.position.x, &s.position.y, &s.position.z}) {
        const double keep = (*axis)[p];
        (*axis)[p] = keep + eps;
        const double up = potential(s);
        (*axis)[p] = keep - eps;
        const double down = potential(s);
        (*axis)[p] = keep;
        const double* f = axis == &s.position.x ? s.force.x.data() : axis == &s.position.y ? s.force.y.data()
                                                                                           : s.force.z.data();
        EXPECT_NEAR(f[p], -(up - down) / (2 * eps), 1e-6) << "shear " << shear << " bending " << bending << " point " << p;
      }
  }
}

// Implicit Euler's blocks: J·dx against the change of the force for a small dx. Stretched
// state, where the clamp of compressed springs (spring_stiffness) does not act, so the
// blocks are the exact Jacobian.
TEST(Terms, JacobianBlocksMatchFiniteDifferencesOfTheForce) {
  Sheet<double> s = crumpled(true, true);
  for (std::size_t p = 0; p < s.size(); ++p) {  // every diagonal longer than its rest length
    s.position.x[p] *= 1.5;
    s.position.y[p] *= 1.5;
  }
  // the grid springs' own force is taken out by differencing against a sheet without the terms
  Sheet<double> bare = crumpled(false, false);
  bare.position = s.position;
  auto term_force = [&](std::vector<double>& out) {
    forces(s);
    forces(bare);
    out.resize(3 * s.size());
    for (std::size_t p = 0; p < s.size(); ++p) {
      out[3 * p] = s.force.x[p] - bare.force.x[p];
      out[3 * p + 1] = s.force.y[p] - bare.force.y[p];
      out[3 * p + 2] = s.force.z[p] - bare.force.z[p];
    }
  };
  drape::detail::Vec3Array<double> dx, jdx;
  dx.resize(s.size());
  jdx.resize(s.size());
  for (std::size_t p = 0; p < s.size(); ++p) {
    dx.x[p] = std::sin(3.1 * double(p));
    dx.y[p] = std::cos(1.7 * double(p));
    dx.z[p] = std::sin(0.9 * double(p) + 2);
  }
  drape::detail::term_jvp(s, cptr(s.position), cptr(dx), ptr(jdx));
  const double eps = 1e-6;
  std::vector<double> plus, minus;
  auto shift = [&](double by) {
    for (std::size_t p = 0; p < s.size(); ++p) {
      s.position.x[p] += by * dx.x[p];
      s.position.y[p] += by * dx.y[p];
      s.position.z[p] += by * dx.z[p];
    }
    bare.position = s.position;
  };
  shift(eps);
  term_force(plus);
  shift(-2 * eps);
  term_force(minus);
  for (std::size_t p = 0; p < s.size(); ++p) {
    EXPECT_NEAR(jdx.x[p], (plus[3 * p] - minus[3 * p]) / (2 * eps), 1e-5) << p;
    EXPECT_NEAR(jdx.y[p], (plus[3 * p + 1] - minus[3 * p + 1]) / (2 * eps), 1e-5) << p;
    EXPECT_NEAR(jdx.z[p], (plus[3 * p + 2] - minus[3 * p + 2]) / (2 * eps), 1e-5) << p;
  }
}

// Every term's forces are internal: they sum to zero over the sheet (air excepted: the air
// is outside). Momentum is conserved whatever the shape.
TEST(Terms, InternalForcesSumToZero) {
  Sheet<double> s = crumpled(true, true);
  forces(s);
  double fx = 0, fy = 0, fz = 0;
  for (std::size_t p = 0; p < s.size(); ++p) {
    fx += s.force.x[p];
    fy += s.force.y[p];
    fz += s.force.z[p];
  }
  EXPECT_NEAR(fx, 0, 1e-12);
  EXPECT_NEAR(fy, 0, 1e-12);
  EXPECT_NEAR(fz, 0, 1e-12);
}

TEST(Terms, BadTermSettingsAreRejectedByName) {
  SheetDef d;
  d.shear = drape::ShearDef{-1, std::nullopt};
  EXPECT_NE(drape::validate(d).find("shear.stiffness"), std::string::npos);
  d.shear = drape::ShearDef{1, -0.5};
  EXPECT_NE(drape::validate(d).find("shear.rest_length"), std::string::npos);
  d.shear.reset();
  d.bending = drape::BendingDef{0};
  EXPECT_NE(drape::validate(d).find("bending.stiffness"), std::string::npos);
  d.bending.reset();
  d.air = drape::AirDef{std::nan(""), 0};
  EXPECT_NE(drape::validate(d).find("air.drag"), std::string::npos);
  d.air = drape::AirDef{1, -1};
  EXPECT_NE(drape::validate(d).find("air.friction"), std::string::npos);
  drape::WorldDef wd;
  wd.wind.density = -1;
  EXPECT_NE(drape::validate(wd).find("wind.density"), std::string::npos);
  wd.wind = {{0, INFINITY, 0}, 1.2};
  EXPECT_NE(drape::validate(wd).find("wind.velocity"), std::string::npos);
}

// The stable-step estimate counts the new terms' stiffness: a stiff bending term must lower it.
TEST(Terms, StableStepEstimateCountsShearAndBending) {
  Sheet<double> bare = crumpled(false, false), cloth = crumpled(true, true);
  EXPECT_LT(drape::detail::sheet_stable_step(cloth), drape::detail::sheet_stable_step(bare));
}

}  // namespace
