// Time integration of eq (4): analytic oscillation period, energy behaviour of the two
// Euler variants, and finiteness with degenerate geometry.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace {

// Two points joined by one spring, stretched and released: the separation oscillates with
// ω² = k/μ, μ = m1·m2/(m1 + m2) the reduced mass.
TEST(Integrators, TwoPointOscillatorPeriodMatchesReducedMass) {
  const double k = 100.0, m1 = 1.0, m2 = 3.0;
  const double mu = m1 * m2 / (m1 + m2);
  const double period = 2 * std::numbers::pi * std::sqrt(mu / k);

  drape::WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.dt = 1e-5;
  wd.integrator = drape::Integrator::SemiImplicitEuler;
  drape::World world(wd);
  drape::SheetDef d;
  d.m = 0;
  d.n = 1;
  d.width = 1.0;
  d.rest_length_h = 0.8;  // released from a stretch of 0.2
  d.point_masses = {m1, m2};
  d.stiffness = k;
  const auto id = world.add_sheet(d);

  // Upward crossings of the rest length, interpolated linearly between steps.
  auto stretch = [&] {
    const auto v = world.view(id);
    return std::hypot(v.x[1] - v.x[0], v.y[1] - v.y[0], v.z[1] - v.z[0]) - 0.8;
  };
  std::vector<double> crossings;
  double prev = stretch();
  const int steps = static_cast<int>(3.5 * period / wd.dt);
  for (int s = 1; s <= steps; ++s) {
    world.step();
    const double now = stretch();
    if (prev < 0 && now >= 0) crossings.push_back((s - 1 + prev / (prev - now)) * wd.dt);
    prev = now;
  }
  ASSERT_GE(crossings.size(), 3u);
  const double measured = (crossings.back() - crossings.front()) / double(crossings.size() - 1);
  EXPECT_NEAR(measured / period, 1.0, 0.005) << "measured " << measured << " s, expected " << period << " s";
}

// An undamped vibrating sheet pinned at its corners: total energy of the whole history.
struct EnergyHistory {
  double initial = 0, min = 0, max = 0, final = 0;
};

EnergyHistory vibrate(drape::Integrator integrator, int steps) {
  drape::WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.integrator = integrator;
  drape::World world(wd);
  drape::SheetDef d;
  d.m = d.n = 8;
  d.mass = 0.2;
  d.stiffness = 50.0;
  d.pins = drape::corner_points(d.m, d.n);
  const auto id = world.add_sheet(d);
  world.set_dt(0.02 * world.stable_step_estimate());
  // a bump in the middle of the sheet, at rest
  auto st = world.state(id);
  for (std::uint32_t i = 0; i <= d.m; ++i)
    for (std::uint32_t j = 0; j <= d.n; ++j)
      st.z[drape::point_index(d.n, i, j)] = 0.05 * std::sin(std::numbers::pi * i / d.m) * std::sin(std::numbers::pi * j / d.n);
  EnergyHistory h;
  h.initial = h.min = h.max = world.energies().total();
  for (int s = 0; s < steps; s += 100) {
    world.step(100);
    const double e = world.energies().total();
    h.min = std::min(h.min, e);
    h.max = std::max(h.max, e);
  }
  h.final = world.energies().total();
  return h;
}

TEST(Integrators, SemiImplicitEulerKeepsEnergyBoundedWhileForwardEulerGains) {
  const auto symplectic = vibrate(drape::Integrator::SemiImplicitEuler, 100000);
  ASSERT_GT(symplectic.initial, 0.0);
  EXPECT_LT((symplectic.max - symplectic.initial) / symplectic.initial, 0.01);
  EXPECT_LT((symplectic.initial - symplectic.min) / symplectic.initial, 0.01);

  const auto forward = vibrate(drape::Integrator::ForwardEuler, 100000);
  // forward Euler multiplies each mode's energy by (1 + ω²dt²) every step
  EXPECT_GT(forward.max, 1.1 * forward.initial);
}

TEST(Integrators, CoincidentPointsStayFinite) {
  for (auto integrator : {drape::Integrator::ForwardEuler, drape::Integrator::SemiImplicitEuler}) {
    drape::WorldDef wd;
    wd.integrator = integrator;
    drape::World world(wd);
    drape::SheetDef d;
    d.m = d.n = 5;
    d.anchors = drape::anchors_at(drape::corner_points(d.m, d.n), 50.0);
    d.pins = {drape::center_point(d.m, d.n)};
    const auto id = world.add_sheet(d);
    auto st = world.state(id);
    for (std::size_t i = 0; i < st.size(); ++i) st.x[i] = st.y[i] = st.z[i] = 0.25;
    world.step(200);
    EXPECT_TRUE(world.all_finite()) << drape::integrator_name(integrator);
    const auto diag = world.diagnostics(id);
    EXPECT_TRUE(diag.finite);
    EXPECT_TRUE(std::isfinite(diag.energy.total()));
  }
}

TEST(Integrators, PinnedPointsNeverMove) {
  drape::World world;
  drape::SheetDef d;
  d.m = d.n = 6;
  d.pins = drape::corner_points(d.m, d.n);
  const auto id = world.add_sheet(d);
  const auto v0 = world.view(id);
  std::vector<double> z0(v0.z.begin(), v0.z.end());
  world.step(500);
  const auto v = world.view(id);
  for (auto p : d.pins) EXPECT_EQ(v.z[p], z0[p]);
  EXPECT_LT(v.z[drape::center_point(d.m, d.n)], z0[drape::center_point(d.m, d.n)]);  // the rest fell
}

TEST(Integrators, FreeFallMatchesKinematics) {
  // With no spring stretched, every point falls as z = −g t²/2 (semi-implicit Euler is
  // off by g·t·dt/2, which the tolerance allows for).
  drape::World world;
  drape::SheetDef d;
  d.m = d.n = 3;
  const auto id = world.add_sheet(d);
  world.step(1000);
  const double t = world.time(), g = 9.81;
  const double expected = -0.5 * g * t * t;
  for (double z : world.view(id).z) EXPECT_NEAR(z, expected, g * t * world.def().dt);
}

}  // namespace
