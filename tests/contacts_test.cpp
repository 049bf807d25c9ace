// Contacts between sheets against an independent brute-force potential, conservation
// laws and a hand computation.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <random>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "bounds.h"
#include "contacts.h"
#include "damped_rebound.h"
#include "each_target.h"
#include "sheet_data.h"
#include "surface_distance.h"

#include <drape/drape.h>

namespace drape::detail {
namespace {

using test::cross;
using test::dot;
using test::P3;
using test::sub;

struct Potential {
  double h, xi, c, R;
  // E(d) whose −dE/dd is contacts.h's shifted force: zero, with zero slope, at d = R.
  double operator()(double d) const {
    if (d >= R) return 0;
    const double tail = std::exp(-(R - h) / xi);
    return c * (std::exp((h - d) / xi) - tail) + c / xi * tail * (d - R);
  }
};

P3 point(const Sheet<double>& s, std::uint32_t p) { return {s.position.x[p], s.position.y[p], s.position.z[p]}; }

// Σ over points of q of E(distance to the surface of s), the distance a minimum over all
// triangles of s (every cell, no grid): the brute force.
double brute_energy(const Sheet<double>& q, const Sheet<double>& s, const Potential& E) {
  const auto& t = *s.topology;
  double sum = 0;
  for (std::uint32_t p = 0; p < q.size(); ++p)
    sum += E(test::surface_distance(point(q, p), t.m, t.n, [&](std::uint32_t k) { return point(s, k); }));
  return sum;
}

SheetBoxes<double> boxes(const Sheet<double>& s) {
  SheetBoxes<double> out;
  build_boxes(s, out);
  return out;
}

// The points' contacts alone: the brute forces of this file are every point against every
// triangle; the rims (edges against edges) have tests of their own, with kRimParams.
const ContactParams<double> kParams = [] {
  auto p = ContactParams<double>::make(0.005, 0.002, 1e-4, 6.0);
  p.rims = false;
  return p;
}();
const ContactParams<double> kRimParams = [] {
  auto p = kParams;
  p.rims = true;
  return p;
}();
// The same with exact candidate lists between searches (contacts.h, ContactParams::exact).
const ContactParams<double> kExact = [] {
  auto p = kParams;
  p.exact = true;
  return p;
}();

// Two small sheets a few millimetres apart, the upper one rumpled, so most points lie
// within contact range of several triangles of the other sheet.
std::pair<Sheet<double>, Sheet<double>> close_sheets(unsigned seed) {
  SheetDef da;
  da.m = 6;
  da.n = 6;
  da.width = da.height = 0.1;
  SheetDef db = da;
  db.m = 5;
  db.n = 7;
  db.center = {0.01, -0.005, 0.006};
  db.orientation = quat_from_axis_angle({0, 0, 1}, 0.3);
  auto a = build_sheet<double>(da), b = build_sheet<double>(db);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> bump(-0.003, 0.003);
  for (double& z : b.position.z) z += bump(rng);
  for (double& x : a.position.x) x += 0.3 * bump(rng);
  return {std::move(a), std::move(b)};
}

// One pair's forces, from a fresh search.
PairContacts<double> pair_forces(const Sheet<double>& a, const Sheet<double>& b, const ContactParams<double>& prm) {
  PairContacts<double> work;
  ContactScratch<double> scratch;
  pair_contacts(a, boxes(a), b, boxes(b), prm, work, scratch);
  return work;
}

// The pair's forces (the point's in on_a) of a 1 kg point moving at `velocity`, 5 mm (= h)
// above triangle (0,0)(0,1)(1,1) of a static 2×2-cell sheet of 1 m cells and 1 kg, at
// weights (¼, ½, ¼).
PairContacts<double> point_over_surface(Vec3 velocity, double friction, const ContactParams<double>& prm) {
  SheetDef surface;
  surface.m = surface.n = 2;
  surface.width = surface.height = 2.0;
  SheetDef single;
  single.m = single.n = 0;
  single.center = {-1.0 + 0.75, -1.0 + 0.25, 0.005};
  single.initial_velocity = velocity;
  single.friction = friction;
  return pair_forces(build_sheet<double>(single), build_sheet<double>(surface), prm);
}

// close_sheets(seed) with every point moving every which way, up to 0.5 m/s per axis.
std::pair<Sheet<double>, Sheet<double>> jostled_sheets(unsigned seed, unsigned velocity_seed) {
  auto sheets = close_sheets(seed);
  std::mt19937 rng(velocity_seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (auto* s : {&sheets.first, &sheets.second})
    for (std::size_t p = 0; p < s->size(); ++p) {
      s->velocity.x[p] = u(rng);
      s->velocity.y[p] = u(rng);
      s->velocity.z[p] = u(rng);
    }
  return sheets;
}

P3 total(const ContactForces<double>& f) {
  P3 s{0, 0, 0};
  for (std::size_t e = 0; e < f.size(); ++e) s = {s[0] + f.fx[e], s[1] + f.fy[e], s[2] + f.fz[e]};
  return s;
}

// −∂E/∂(coordinate `axis` of point p of s) by central differences (step 1e-7 m), the point
// put back after.
template <class Energy>
double minus_gradient(Sheet<double>& s, std::uint32_t p, int axis, Energy&& energy) {
  constexpr double delta = 1e-7;
  auto& coordinate = axis == 0 ? s.position.x : axis == 1 ? s.position.y : s.position.z;
  const double x0 = coordinate[p];
  coordinate[p] = x0 + delta;
  const double up = energy();
  coordinate[p] = x0 - delta;
  const double down = energy();
  coordinate[p] = x0;
  return -(up - down) / (2 * delta);
}

TEST(Contacts, ForceIsMinusGradientOfBruteForcePotentialOverAllCells) {
  auto sheets = close_sheets(3);  // named, not bound: the energy lambda captures them
  Sheet<double>& a = sheets.first;
  Sheet<double>& b = sheets.second;
  PairContacts<double> work;
  ContactScratch<double> scratch;
  pair_contacts(a, boxes(a), b, boxes(b), kParams, work, scratch);
  ASSERT_GT(work.on_a.size(), 50u);

  const Potential E{kParams.thickness, kParams.xi, kParams.strength, kParams.range};
  auto energy = [&] { return brute_energy(a, b, E) + brute_energy(b, a, E); };
  double fmax = 0;
  for (std::size_t e = 0; e < work.on_a.size(); ++e) fmax = std::max(fmax, std::abs(work.on_a.fz[e]));
  for (auto* side : {&a, &b}) {
    const ContactForces<double>& got = side == &a ? work.on_a : work.on_b;
    for (std::uint32_t p = 0; p < side->size(); p += 3) {
      for (int k = 0; k < 3; ++k) {
        const double expected = minus_gradient(*side, p, k, energy);
        double sum = 0;
        const auto& f = k == 0 ? got.fx : k == 1 ? got.fy : got.fz;
        for (std::size_t e = 0; e < got.size(); ++e)
          if (got.point[e] == p) sum += f[e];
        EXPECT_NEAR(sum, expected, 1e-5 * fmax) << (side == &a ? "a" : "b") << " point " << p << " axis " << k;
      }
    }
  }
}

TEST(Contacts, PairForcesConserveLinearAndAngularMomentum) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    auto [a, b] = close_sheets(seed);
    PairContacts<double> work;
    ContactScratch<double> scratch;
    pair_contacts(a, boxes(a), b, boxes(b), kParams, work, scratch);
    ASSERT_GT(work.on_a.size() + work.on_b.size(), 0u);
    P3 force{0, 0, 0}, torque{0, 0, 0};
    double scale = 0, torque_scale = 0;
    for (const auto& [sheet, f] : {std::pair{&a, &work.on_a}, std::pair{&b, &work.on_b}})
      for (std::size_t e = 0; e < f->size(); ++e) {
        const P3 F{f->fx[e], f->fy[e], f->fz[e]};
        const P3 r = point(*sheet, f->point[e]);
        const P3 t = cross(r, F);
        for (int k = 0; k < 3; ++k) {
          force[k] += F[k];
          torque[k] += t[k];
        }
        scale += std::sqrt(dot(F, F));
        torque_scale += std::sqrt(dot(t, t));
      }
    // A point's force lies along p − q and its reaction acts at q (by weights), so
    // neither the sum of forces nor of torques changes: zero up to rounding.
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(force[k], 0.0, 1e-13 * scale) << "seed " << seed;
      EXPECT_NEAR(torque[k], 0.0, 1e-13 * torque_scale) << "seed " << seed;
    }
  }
}

// Each point's total force from a pair's entries, per axis.
std::vector<P3> dense(const ContactForces<double>& f, std::size_t points) {
  std::vector<P3> out(points, P3{0, 0, 0});
  for (std::size_t e = 0; e < f.size(); ++e) {
    out[f.point[e]][0] += f.fx[e];
    out[f.point[e]][1] += f.fy[e];
    out[f.point[e]][2] += f.fz[e];
  }
  return out;
}

// The rims (contacts.h, edges against edges): the forces they add to the points' are minus
// the gradient of Σ E(distance) over the edge pairs they count, summed by a brute force of
// its own (surface_distance.h, rim_sum: every rim edge against every edge, the common
// perpendicular from a cross product), by central differences at every third point; and,
// each force lying along the line between the two edges' nearest points, they change
// neither the total force nor the total torque.
TEST(Contacts, RimForcesAreMinusTheGradientOfTheRimPotential) {
  for (unsigned seed : {3u, 4u}) {
    auto sheets = close_sheets(seed);
    Sheet<double>& a = sheets.first;
    Sheet<double>& b = sheets.second;
    const PairContacts<double> points = pair_forces(a, b, kParams), all = pair_forces(a, b, kRimParams);
    ASSERT_GT(all.on_a.size() + all.on_b.size(), points.on_a.size() + points.on_b.size() + 20) << "rims in range";
    const Potential E{kParams.thickness, kParams.xi, kParams.strength, kParams.range};
    auto energy = [&] {
      auto at = [](const Sheet<double>& s) { return [&s](std::uint32_t k) { return point(s, k); }; };
      return test::rim_sum(a.topology->m, a.topology->n, at(a), b.topology->m, b.topology->n, at(b), E);
    };
    double fmax = 0;
    P3 force{0, 0, 0}, torque{0, 0, 0};
    double scale = 0;
    std::vector<P3> rim[2];
    for (int k = 0; k < 2; ++k) {
      const Sheet<double>& s = k == 0 ? a : b;
      const auto with = dense(k == 0 ? all.on_a : all.on_b, s.size());
      const auto without = dense(k == 0 ? points.on_a : points.on_b, s.size());
      rim[k].resize(s.size());
      for (std::uint32_t p = 0; p < s.size(); ++p) {
        rim[k][p] = sub(with[p], without[p]);
        const P3 t = cross(point(s, p), rim[k][p]);
        for (int c = 0; c < 3; ++c) {
          force[c] += rim[k][p][c];
          torque[c] += t[c];
          fmax = std::max(fmax, std::abs(rim[k][p][c]));
        }
        scale += std::sqrt(dot(rim[k][p], rim[k][p]));
      }
    }
    ASSERT_GT(fmax, 0.0);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(force[c], 0.0, 1e-12 * scale) << "seed " << seed;
      EXPECT_NEAR(torque[c], 0.0, 1e-12 * scale) << "seed " << seed;
    }
    for (int k = 0; k < 2; ++k) {
      Sheet<double>& side = k == 0 ? a : b;
      for (std::uint32_t p = 0; p < side.size(); p += 3)
        for (int c = 0; c < 3; ++c) {
          EXPECT_NEAR(rim[k][p][c], minus_gradient(side, p, c, energy), 1e-5 * fmax)
              << "seed " << seed << (k == 0 ? " a" : " b") << " point " << p << " axis " << c;
        }
    }
  }
}

TEST(Contacts, ForceOnAPointLyingOnTheSurfaceIsFiniteAndMatchesTheBound) {
  SheetDef surface;
  surface.m = surface.n = 2;
  surface.width = surface.height = 2.0;  // cells of 1 m: only one triangle within range
  SheetDef single;
  single.m = single.n = 0;
  // Inside triangle (0,0)(0,1)(1,1) of cell (0,0), far from its edges.
  single.center = {-1.0 + 0.75, -1.0 + 0.25, 0.0};  // on the surface: d = 0
  const auto s = build_sheet<double>(surface), q = build_sheet<double>(single);
  PairContacts<double> work;
  ContactScratch<double> scratch;
  pair_contacts(q, boxes(q), s, boxes(s), kParams, work, scratch);
  ASSERT_EQ(work.on_a.size(), 1u);
  const double bound = kParams.strength / kParams.xi * (std::exp(kParams.thickness / kParams.xi) - kParams.tail);
  EXPECT_DOUBLE_EQ(work.on_a.fx[0], 0.0);
  EXPECT_DOUBLE_EQ(work.on_a.fy[0], 0.0);
  EXPECT_NEAR(std::abs(work.on_a.fz[0]), bound, 1e-12 * bound);
  // The reaction goes to the triangle's three corners with weights summing to one.
  const P3 r = total(work.on_b);
  EXPECT_NEAR(r[2], -work.on_a.fz[0], 1e-12 * bound);
}

// Friction (contacts.h) by hand: a 1 kg point 5 mm (= h) above triangle (0,0)(0,1)(1,1) of
// a static sheet of 1 m cells, 9 points of 1/9 kg, at weights (¼, ½, ¼). The load is
// N = (c/ξ)·(1 − tail). Sliding at 1 m/s it meets μ·N against its motion; at 1 µm/s, less
// than μ·N stops it within dt: v / (dt·(1/m_p + Σ w_k²/m_k)) = v / (dt · 4.375 kg⁻¹).
TEST(Contacts, FrictionOnAPointIsMuTimesLoadOrWhatStopsItsSlipWithinTheStep) {
  ContactParams<double> prm = kParams;
  prm.dt = 1e-3;
  const double load = prm.strength / prm.xi * (1 - prm.tail);
  for (double speed : {1.0, 1e-6}) {
    const PairContacts<double> work = point_over_surface({speed, 0, 0}, 0.3, prm);
    ASSERT_EQ(work.on_a.size(), 1u);
    const double expected = speed > 0.5 ? 0.3 * load : speed / (prm.dt * (1.0 + 9.0 * (0.0625 + 0.25 + 0.0625)));
    EXPECT_NEAR(work.on_a.fx[0], -expected, 1e-12 * load) << "speed " << speed;
    EXPECT_NEAR(work.on_a.fy[0], 0.0, 1e-12 * load);
    EXPECT_NEAR(work.on_a.fz[0], load, 1e-12 * load);
    const P3 r = total(work.on_b);  // equal and opposite, shared by the corners
    EXPECT_NEAR(r[0], expected, 1e-12 * load);
    EXPECT_NEAR(r[2], -load, 1e-12 * load);
  }
}

// Friction between two rumpled sheets moving every which way: the pair's forces still sum
// to zero (equal and opposite), each point's friction is tangential and at most μ·N, and
// friction never adds energy: its power Σ F·v over both sheets is ≤ 0.
TEST(Contacts, FrictionBetweenSheetsIsEqualAndOppositeAndOnlyDissipates) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    auto [a, b] = jostled_sheets(seed, seed + 100);
    ContactParams<double> prm = kParams;
    prm.dt = 1e-3;
    const PairContacts<double> plain = pair_forces(a, b, prm);
    b.friction = 0.4;  // the larger of the two coefficients acts
    a.friction = 0.1;
    const PairContacts<double> rubbing = pair_forces(a, b, prm);
    ASSERT_EQ(plain.on_a.size(), rubbing.on_a.size());
    ASSERT_EQ(plain.on_b.size(), rubbing.on_b.size());
    P3 sum{0, 0, 0};
    double scale = 0, power = 0, friction_size = 0;
    for (const auto& [sheet, with, without] : {std::tuple{&a, &rubbing.on_a, &plain.on_a}, std::tuple{&b, &rubbing.on_b, &plain.on_b}})
      for (std::size_t e = 0; e < with->size(); ++e) {
        ASSERT_EQ(with->point[e], without->point[e]);
        const P3 F{with->fx[e], with->fy[e], with->fz[e]}, N{without->fx[e], without->fy[e], without->fz[e]};
        const P3 t = sub(F, N);
        const std::uint32_t p = with->point[e];
        const P3 v{sheet->velocity.x[p], sheet->velocity.y[p], sheet->velocity.z[p]};
        for (int k = 0; k < 3; ++k) sum[k] += F[k];
        scale += std::sqrt(dot(F, F));
        power += dot(t, v);
        friction_size += std::sqrt(dot(t, t));
        // a point's own entry: friction ⟂ its load and at most μ·|load| (reactions are
        // weighted sums of such entries, so they obey the same bound)
        EXPECT_LE(std::sqrt(dot(t, t)), 0.4 * std::sqrt(dot(N, N)) * (1 + 1e-12) + 1e-15);
        EXPECT_NEAR(dot(t, N), 0.0, 1e-12 * dot(N, N) + 1e-18);
      }
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(sum[k], 0.0, 1e-13 * scale) << "seed " << seed;
    EXPECT_GT(friction_size, 0.0);
    EXPECT_LT(power, 0.0) << "seed " << seed;
  }
}

// Hunt–Crossley damping on one point resting at d = h over a surface, by hand: the
// repulsion `load` times (1 − α·ḋ) while uncapped, never below zero, and capped at the
// coefficient ¼·m_eff/dt (m_eff from the weights, as friction's); the reaction is equal and
// opposite.
TEST(Contacts, DampingOnAPointScalesTheLoadByOneMinusAlphaTimesTheGapRate) {
  ContactParams<double> prm = kParams;
  prm.dt = 1e-3;
  const double load = prm.strength / prm.xi * (1 - prm.tail);
  const double inv_mass = 1.0 + 9.0 * (0.0625 + 0.25 + 0.0625);  // the point's 1 kg, the corners' 1/9 kg
  const double cap = 0.25 / (inv_mass * prm.dt);
  struct Case {
    double alpha, gap_rate, expected;
  };
  const Case cases[] = {
      {2.0, -0.3, load * (1 + 2.0 * 0.3)},  // approaching: pressed harder
      {2.0, 0.3, load * (1 - 2.0 * 0.3)},   // parting: weaker
      {2.0, 1.0, 0.0},                      // parting faster than 1/α: no pull
      {1e6, -0.3, load + cap * 0.3},        // a coefficient the substep cannot hold: capped
      {0.0, -0.3, load},                    // off: the repulsion alone
  };
  for (const Case& c : cases) {
    prm.damping = c.alpha;
    const PairContacts<double> work = point_over_surface({0, 0, c.gap_rate}, 0.0, prm);
    ASSERT_EQ(work.on_a.size(), 1u);
    EXPECT_NEAR(work.on_a.fz[0], c.expected, 1e-12 * load) << "alpha " << c.alpha << ", gap rate " << c.gap_rate;
    EXPECT_EQ(work.on_a.fx[0], 0.0);
    EXPECT_EQ(work.on_a.fy[0], 0.0);
    EXPECT_NEAR(total(work.on_b)[2], -c.expected, 1e-12 * load);
  }
}

// Damping (with and without friction) between two rumpled sheets moving every which way:
// the pair's forces still sum to zero, and what damping and friction add to the repulsion
// never adds energy: its power Σ (F − F_repulsion)·v over both sheets is < 0.
TEST(Contacts, DampingBetweenSheetsIsEqualAndOppositeAndOnlyDissipates) {
  for (double mu : {0.0, 0.3})
    for (unsigned seed = 1; seed <= 5; ++seed) {
      auto [a, b] = jostled_sheets(seed, seed + 200);
      ContactParams<double> prm = kParams;
      prm.dt = 1e-3;
      const PairContacts<double> plain = pair_forces(a, b, prm);
      a.friction = mu;
      prm.damping = 3.0;
      const PairContacts<double> damped = pair_forces(a, b, prm);
      ASSERT_EQ(plain.on_a.size(), damped.on_a.size());
      ASSERT_EQ(plain.on_b.size(), damped.on_b.size());
      P3 sum{0, 0, 0};
      double scale = 0, power = 0;
      for (const auto& [sheet, with, without] : {std::tuple{&a, &damped.on_a, &plain.on_a}, std::tuple{&b, &damped.on_b, &plain.on_b}})
        for (std::size_t e = 0; e < with->size(); ++e) {
          ASSERT_EQ(with->point[e], without->point[e]);
          const P3 F{with->fx[e], with->fy[e], with->fz[e]}, N{without->fx[e], without->fy[e], without->fz[e]};
          const std::uint32_t p = with->point[e];
          const P3 v{sheet->velocity.x[p], sheet->velocity.y[p], sheet->velocity.z[p]};
          for (int k = 0; k < 3; ++k) sum[k] += F[k];
          scale += std::sqrt(dot(F, F));
          power += dot(sub(F, N), v);
        }
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(sum[k], 0.0, 1e-13 * scale) << "seed " << seed << ", mu " << mu;
      EXPECT_LT(power, 0.0) << "seed " << seed << ", mu " << mu;
    }
}

// Two equal, aligned 4×4-cell sheets meeting face-on in free space at 1 m/s. Every point
// lies over a grid point of the other sheet, so each is pushed by its own entry and by the
// reaction of the point facing it: 2F each, F the documented force of one entry at the gap d
// (contacts.h) times (1 − α·ḋ). Their gap then follows the 1-D equation
// d̈ = (4/m)·F(d)·(1 − α·ḋ) (m a point's mass), integrated by RK4 (damped_rebound.h) at a hundredth of the
// world's step: the rebound speed of the world must match it, 0 for α = 0 to the step's
// error (energy conserved), and fall with α.
TEST(Contacts, HeadOnSheetsReboundAtTheSpeedOfTheOneDimensionalDampedModel) {
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.dt = 1e-4;
  const double h = wd.contact_thickness, xi = wd.contact_xi, c = wd.contact_strength;
  const double R = h + wd.contact_range * xi, tail = std::exp(-wd.contact_range);
  SheetDef d;
  d.m = d.n = 4;
  d.width = d.height = 0.1;
  d.mass = 0.025;
  const double m = d.mass / 25, approach = 1.0, start = R + 0.003, seconds = 0.05;
  double previous = 2 * approach;
  for (double alpha : {0.0, 0.5, 2.0}) {
    auto accel = [&](double gap, double rate) {
      if (gap >= R) return 0.0;
      const double f = c / xi * (std::exp((h - gap) / xi) - tail);
      return 4.0 / m * std::max(f * (1 - alpha * rate), 0.0);
    };
    const auto [gap, rate] = test::gap_after(accel, start, approach, seconds, wd.dt / 100);
    ASSERT_GT(gap, R) << "the reference has not parted within the run";
    WorldDef w = wd;
    w.contact_damping = alpha;
    World world(w);
    d.center = {0, 0, start / 2};
    d.initial_velocity = {0, 0, -approach / 2};
    const SheetId top = world.add_sheet(d);
    d.center = {0, 0, -start / 2};
    d.initial_velocity = {0, 0, approach / 2};
    const SheetId bottom = world.add_sheet(d);
    ASSERT_TRUE(world.step(std::uint32_t(std::lround(seconds / wd.dt))).ok());
    const auto a = world.view(top), b = world.view(bottom);
    double rebound = 0, spread = 0;
    for (std::size_t p = 0; p < a.size(); ++p) rebound += (a.vz[p] - b.vz[p]) / double(a.size());
    for (std::size_t p = 0; p < a.size(); ++p) spread = std::max(spread, std::abs(a.vz[p] - b.vz[p] - rebound));
    EXPECT_LT(spread, 1e-9) << "the sheets did not stay flat, alpha " << alpha;
    EXPECT_NEAR(rebound, rate, 0.01 * approach) << "alpha " << alpha;
    if (alpha == 0) {
      EXPECT_NEAR(rebound, approach, 0.01 * approach);
    }
    EXPECT_LT(rebound, previous);
    previous = rebound;
  }
}

// Two 64×64 sheets (1 kg, k = 100 N/m) hanging from their corners 10 mm apart, as one
// column of issue 13's stack: with the repulsion alone, the points beside the pins rattle
// between their pin and the other sheet far faster than they move on a sheet hanging alone
// (metres per second against a tenth of one, by hand); with contact damping (the default) they move about as
// on the lone sheet. The lone sheet is the reference: the fastest point beside a pin over the
// run's last 0.3 s, within 3 times its speed there.
TEST(Contacts, DampingStopsPointsBesidePinsRattlingAgainstTheNextLayer) {
  auto fastest_beside_pins = [](int layers, double alpha) {
    SheetDef d;  // one of issue 13's stacked sheets
    d.m = d.n = 63;
    d.mass = 1.0;
    d.stiffness = 100;
    d.damping = 1e-3;
    d.pins = corner_points(d.m, d.n);
    WorldDef wd;
    wd.dt = 1e-3;
    wd.threads = 1;
    wd.contact_damping = alpha;
    World world(wd);
    std::vector<SheetId> ids;
    for (int l = 0; l < layers; ++l) {
      d.center = {0, 0, 0.01 * l};
      ids.push_back(world.add_sheet(d));
    }
    const std::uint32_t beside[8] = {1, 64, 62, 127, 63 * 64 + 1, 62 * 64, 63 * 64 + 62, 62 * 64 + 63};
    double fastest = 0;
    for (int step = 0; step < 1000; ++step) {
      EXPECT_TRUE(world.step(1).ok());
      if (step < 700) continue;
      for (SheetId id : ids) {
        const auto v = world.view(id);
        for (std::uint32_t p : beside) fastest = std::max(fastest, std::hypot(v.vx[p], v.vy[p], v.vz[p]));
      }
    }
    return fastest;
  };
  const double alone = fastest_beside_pins(1, 0.0), damped = fastest_beside_pins(2, WorldDef{}.contact_damping);
  EXPECT_GT(alone, 0.0);
  EXPECT_LT(damped, 3.0 * alone) << "alone " << alone;
}

TEST(Contacts, NoForceBeyondTheRange) {
  auto [a, b] = close_sheets(1);
  for (double& z : b.position.z) z += 0.005 + kParams.range;  // every point now beyond R
  PairContacts<double> work;
  ContactScratch<double> scratch;
  pair_contacts(a, boxes(a), b, boxes(b), kParams, work, scratch);
  EXPECT_EQ(work.on_a.size() + work.on_b.size(), 0u);
}

TEST(Contacts, FlatSheetDoesNotRepelItself) {
  SheetDef d;
  d.m = 12;
  d.n = 9;
  d.width = d.height = 0.05;  // spacing well below the contact range: the ring must cover it
  const auto s = build_sheet<double>(d);
  PairContacts<double> work;
  ContactScratch<double> scratch;
  self_contacts(s, boxes(s), kParams, work, scratch);
  EXPECT_EQ(work.on_a.size(), 0u);
}

// A flat sheet of d's cells whose rows above the middle are folded back over the lower
// half, `above` metres above it (row i onto row m − i).
template <class Real = double>
Sheet<Real> folded_sheet(const SheetDef& d, double above) {
  auto s = build_sheet<Real>(d);
  const std::uint32_t cols = d.n + 1;
  for (std::uint32_t i = d.m / 2 + 1; i <= d.m; ++i)
    for (std::uint32_t j = 0; j < cols; ++j) {
      const std::uint32_t p = i * cols + j, mirror = (d.m - i) * cols + j;
      s.position.y[p] = s.position.y[mirror];
      s.position.z[p] = static_cast<Real>(above);
    }
  return s;
}

// Three corner-pinned 0.3 m sheets of `cells` × `cells` cells (k = 50 N/m), each layer
// 8 mm above and 10 mm beside the one below: in contact range from the first substep.
template <class W>
W three_layers(const WorldDef& wd, std::uint32_t cells) {
  W world(wd);
  SheetDef sd;
  sd.m = sd.n = cells;
  sd.width = sd.height = 0.3;
  sd.stiffness = 50;
  sd.damping = 0.05;
  sd.pins = corner_points(sd.m, sd.n);
  for (int layer = 0; layer < 3; ++layer) {
    sd.center = {0.01 * layer, 0.0, 0.008 * layer};
    world.add_sheet(sd);
  }
  return world;
}

// The 20×10-cell, 0.2 × 0.4 m sheet the fold tests fold in half.
SheetDef fold_def() {
  SheetDef d;
  d.m = 20;
  d.n = 10;
  d.width = 0.2;
  d.height = 0.4;
  return d;
}

TEST(Contacts, FoldedSheetPushesItsHalvesApartAndConservesMomentum) {
  const SheetDef d = fold_def();
  const auto s = folded_sheet(d, 0.008);
  const std::uint32_t cols = d.n + 1;
  PairContacts<double> work;
  ContactScratch<double> scratch;
  self_contacts(s, boxes(s), kParams, work, scratch);
  ASSERT_GT(work.on_a.size(), 0u);
  double up = 0, down = 0, scale = 0;
  for (std::size_t e = 0; e < work.on_a.size(); ++e) {
    (work.on_a.point[e] >= 11 * cols ? up : down) += work.on_a.fz[e];
    scale += std::abs(work.on_a.fz[e]);
  }
  EXPECT_GT(up, 0.0);
  EXPECT_LT(down, 0.0);
  EXPECT_NEAR(up + down, 0.0, 1e-13 * scale);
}

// Candidate lists kept across substeps (contacts.h, PairContacts) find exactly what a fresh
// search finds: two rumpled sheets, and a folded sheet against itself, are jostled step by
// step (points moving up to 0.5 mm a step, so the lists outlive a few steps and are then
// remade), and every step's forces with the kept lists equal, bit for bit and entry for
// entry, those of a PairContacts made afresh. It fails if the lists are kept while a point
// has moved more than the skin allows, or if a list misses a cell within R.
void expect_same_forces(const ContactForces<double>& kept, const ContactForces<double>& fresh, int step) {
  ASSERT_EQ(kept.size(), fresh.size()) << "step " << step;
  for (std::size_t e = 0; e < kept.size(); ++e) {
    ASSERT_EQ(kept.point[e], fresh.point[e]) << "step " << step;
    ASSERT_EQ(kept.fx[e], fresh.fx[e]) << "step " << step;
    ASSERT_EQ(kept.fy[e], fresh.fy[e]) << "step " << step;
    ASSERT_EQ(kept.fz[e], fresh.fz[e]) << "step " << step;
  }
}

template <class Real>
void jostle(Sheet<Real>& s, std::mt19937& rng, double amplitude = 0.0003) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  for (std::size_t p = 0; p < s.size(); ++p) {
    s.position.x[p] += static_cast<Real>(u(rng));
    s.position.y[p] += static_cast<Real>(u(rng));
    s.position.z[p] += static_cast<Real>(u(rng));
  }
}

// One step of `kept` and of a fresh PairContacts on the same sheets: the same forces,
// entry for entry, bit for bit. Returns the number of entries on a.
std::size_t kept_matches_fresh(const Sheet<double>& a, const Sheet<double>& b, PairContacts<double>& kept,
                               ContactScratch<double>& scratch, int step) {
  PairContacts<double> fresh;
  pair_contacts(a, boxes(a), b, boxes(b), kExact, kept, scratch);
  pair_contacts(a, boxes(a), b, boxes(b), kExact, fresh, scratch);
  expect_same_forces(kept.on_a, fresh.on_a, step);
  expect_same_forces(kept.on_b, fresh.on_b, step);
  return kept.on_a.size();
}

TEST(Contacts, KeptCandidatesFindWhatAFreshSearchFindsBitForBit) {
  auto [a, b] = close_sheets(4);
  std::mt19937 rng(5);
  PairContacts<double> kept;
  ContactScratch<double> scratch;
  const int steps = 60;
  std::size_t touching = 0;
  for (int step = 0; step < steps; ++step) {
    jostle(a, rng);
    jostle(b, rng);
    touching += kept_matches_fresh(a, b, kept, scratch, step);
  }
  EXPECT_GT(touching, 0u);
  EXPECT_GT(kept.searches, 2u);             // remade when points had moved far enough
  EXPECT_LT(kept.searches, std::uint64_t(steps) / 2);  // and kept in between

  const SheetDef d = fold_def();
  auto s = folded_sheet(d, 0.008);
  PairContacts<double> own;
  for (int step = 0; step < steps; ++step) {
    jostle(s, rng);
    PairContacts<double> fresh;
    self_contacts(s, boxes(s), kExact, own, scratch);
    self_contacts(s, boxes(s), kExact, fresh, scratch);
    expect_same_forces(own.on_a, fresh.on_a, step);
  }
  EXPECT_GT(own.searches, 2u);
  EXPECT_LT(own.searches, std::uint64_t(steps) / 2);
}

// The lists are kept while the sheets move TOGETHER (contacts.h: the relative motion of
// patches decides, not the absolute one): two rumpled sheets carried 2 mm a step along a
// common drift, which varies across the sheets (a slow turn about z, so no single
// translation describes it), with a 20 µm jitter on top. Every step's forces equal a
// fresh search's bit for bit, and the lists are made only a few times, although points
// move more than the whole skin every few steps. Then one sheet alone moves 1.5 mm a step
// towards the other: the lists must be remade, and still match.
TEST(Contacts, KeptCandidatesFollowTheSheetsRelativeMotionNotTheirAbsoluteOne) {
  auto [a, b] = close_sheets(6);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> jitter(-2e-5, 2e-5);
  PairContacts<double> kept;
  ContactScratch<double> scratch;
  auto carry = [&](Sheet<double>& s, double dx, double dz, double turn) {
    for (std::size_t p = 0; p < s.size(); ++p) {
      const double x = s.position.x[p], y = s.position.y[p];
      s.position.x[p] = x * std::cos(turn) - y * std::sin(turn) + dx + jitter(rng);
      s.position.y[p] = x * std::sin(turn) + y * std::cos(turn) + jitter(rng);
      s.position.z[p] += dz + jitter(rng);
    }
  };
  const int steps = 40;
  std::size_t touching = 0;
  for (int step = 0; step < steps; ++step) {
    carry(a, 0.002, 0.0, 0.002);
    carry(b, 0.002, 0.0, 0.002);
    touching += kept_matches_fresh(a, b, kept, scratch, step);
  }
  EXPECT_GT(touching, 0u);
  // 80 mm of common motion: lists kept while each point stayed within 0.45 of the skin
  // (≤ R/2 = 8.5 mm) of where it was would have been made at least 20 times
  EXPECT_LE(kept.searches, 5u);
  const std::uint64_t before = kept.searches;
  for (int step = 0; step < 10; ++step) {
    carry(b, 0.0, -0.0015, 0.0);
    kept_matches_fresh(a, b, kept, scratch, steps + step);
  }
  EXPECT_GE(kept.searches, before + 1);  // 15 mm closer: more than the skin allows
}

// The skin follows how long lists served (contacts.h, PairContacts): exact lists that fail
// their motion test every step narrow to R/16, a kept contact set never below R/2 (its
// entries beyond R only walk, so a narrow skin buys nothing but searches). Two sheets
// jostled by up to 6 mm a step along each axis, so that a patch's points spread by more
// than 0.9 of any skin up to R allows and every step's test fails, the upper one moved
// 6 cm aside first, so both sheets have points far outside the set (open blocks) and the
// set's test fails too.
TEST(Contacts, KeptSetSkinNeverNarrowsBelowHalfTheRangeWhereExactListsDo) {
  auto [a, b] = close_sheets(11);
  for (double& x : b.position.x) x += 0.06;
  std::mt19937 rng(12);
  const double R = kParams.range;
  PairContacts<double> set, exact;
  ContactScratch<double> scratch;
  double least_set = INFINITY, least_exact = INFINITY;
  for (int step = 0; step < 40; ++step) {
    jostle(a, rng, 0.006);
    jostle(b, rng, 0.006);
    const auto ba = boxes(a), bb = boxes(b);
    pair_contacts(a, ba, b, bb, kParams, set, scratch);
    pair_contacts(a, ba, b, bb, kExact, exact, scratch);
    if (step > 0) {  // the first skin is R/4 for both
      least_set = std::min(least_set, set.skin);
      if (exact.skin > 0) least_exact = std::min(least_exact, exact.skin);
    }
  }
  EXPECT_GT(set.searches, 30u);  // the set's test failed most steps
  EXPECT_GE(least_set, R / 2);
  EXPECT_LE(least_exact, R / 8);
}

// The nearest point of triangle abc to p and its barycentric weights, by a route of its
// own: the plane's foot if its area coordinates are all non-negative, else the nearest
// point of the three edges (weights 1 − t and t on the edge's ends).
struct Foot {
  double dist;
  P3 q;
  std::array<double, 3> w;
};
Foot nearest_on_triangle(P3 p, P3 a, P3 b, P3 c) {
  const P3 nrm = cross(sub(b, a), sub(c, a));
  const double nn = dot(nrm, nrm);
  const double h = dot(sub(p, a), nrm) / nn;
  const P3 q{p[0] - h * nrm[0], p[1] - h * nrm[1], p[2] - h * nrm[2]};
  const std::array<double, 3> area{dot(cross(sub(c, b), sub(q, b)), nrm) / nn,
                                   dot(cross(sub(a, c), sub(q, c)), nrm) / nn,
                                   dot(cross(sub(b, a), sub(q, a)), nrm) / nn};
  if (area[0] >= 0 && area[1] >= 0 && area[2] >= 0) return {std::sqrt(dot(sub(p, q), sub(p, q))), q, area};
  const P3 corner[3] = {a, b, c};
  Foot best{INFINITY, {}, {}};
  for (int e = 0; e < 3; ++e) {
    const P3 u = corner[e], v = corner[(e + 1) % 3], uv = sub(v, u);
    const double t = std::clamp(dot(sub(p, u), uv) / dot(uv, uv), 0.0, 1.0);
    const P3 f{u[0] + t * uv[0], u[1] + t * uv[1], u[2] + t * uv[2]};
    const double d = std::sqrt(dot(sub(p, f), sub(p, f)));
    if (d < best.dist) {
      best = {d, f, {0, 0, 0}};
      best.w[e] = 1 - t;
      best.w[(e + 1) % 3] = t;
    }
  }
  return best;
}

// Dense per-point forces and the number of force entries, as the narrow phase should
// produce them.
struct Dense {
  std::vector<P3> on_q, on_s;
  std::size_t entries_q = 0, entries_s = 0;
};

// Every point of q against every triangle of s (no grid, no pruning): the nearest one
// within R repels it. `ring` ≥ 0 (q is s): triangles of cells (i, j) with
// i ∈ [pi − ring, pi + ring) and j ∈ [pj − ring, pj + ring) are ignored, (pi, pj) the point.
Dense brute_contacts(const Sheet<double>& q, const Sheet<double>& s, int ring) {
  const auto& t = *s.topology;
  const std::uint32_t cols = t.cols(), qcols = q.topology->cols();
  const double h = kParams.thickness, xi = kParams.xi, c = kParams.strength, R = kParams.range;
  Dense out;
  out.on_q.assign(q.size(), P3{0, 0, 0});
  out.on_s.assign(s.size(), P3{0, 0, 0});
  for (std::uint32_t p = 0; p < q.size(); ++p) {
    const long pi = p / qcols, pj = p % qcols;
    Foot best{INFINITY, {}, {}};
    std::array<std::uint32_t, 3> tri{};
    for (std::uint32_t i = 0; i < t.m; ++i)
      for (std::uint32_t j = 0; j < t.n; ++j) {
        if (ring >= 0 && long(i) >= pi - ring && long(i) < pi + ring && long(j) >= pj - ring && long(j) < pj + ring)
          continue;
        const std::uint32_t k00 = i * cols + j, k01 = k00 + 1, k10 = k00 + cols, k11 = k10 + 1;
        for (const auto& v : {std::array{k00, k01, k11}, std::array{k00, k11, k10}}) {
          const Foot f = nearest_on_triangle(point(q, p), point(s, v[0]), point(s, v[1]), point(s, v[2]));
          if (f.dist < best.dist) {
            best = f;
            tri = v;
          }
        }
      }
    if (!(best.dist < R)) continue;
    const double f = c / xi * (std::exp((h - best.dist) / xi) - std::exp(-(R - h) / xi));
    const P3 dir = sub(point(q, p), best.q);
    for (int k = 0; k < 3; ++k) out.on_q[p][k] += f * dir[k] / best.dist;
    ++out.entries_q;
    for (int v = 0; v < 3; ++v) {
      if (best.w[v] == 0) continue;
      ++out.entries_s;
      for (int k = 0; k < 3; ++k) out.on_s[tri[v]][k] -= best.w[v] * f * dir[k] / best.dist;
    }
  }
  return out;
}


// The brute force's forces of a pair in both directions, summed per sheet: on a (points
// of a against b, and a's corners' share of b's points) and on b.
struct PairForces {
  std::vector<P3> on_a, on_b;
};
PairForces brute_pair(const Dense& ab, const Dense& ba) {
  PairForces out{ab.on_q, ab.on_s};
  for (std::size_t p = 0; p < out.on_a.size(); ++p)
    for (int k = 0; k < 3; ++k) out.on_a[p][k] += ba.on_s[p][k];
  for (std::size_t p = 0; p < out.on_b.size(); ++p)
    for (int k = 0; k < 3; ++k) out.on_b[p][k] += ba.on_q[p][k];
  return out;
}

// The same points feel a force, and the same force to rounding. Reports the first few
// points that differ and how many do.
void expect_same_forces(const std::vector<P3>& got, const std::vector<P3>& want, const std::string& what) {
  double fmax = 0;
  for (const P3& f : want) fmax = std::max({fmax, std::abs(f[0]), std::abs(f[1]), std::abs(f[2])});
  ASSERT_GT(fmax, 0.0) << what;
  const P3 zero{0, 0, 0};
  std::size_t wrong = 0;
  for (std::size_t p = 0; p < want.size(); ++p) {
    bool same = (got[p] == zero) == (want[p] == zero);
    for (int k = 0; k < 3; ++k) same = same && std::abs(got[p][k] - want[p][k]) <= 1e-10 * fmax;
    if (!same && ++wrong <= 3)
      ADD_FAILURE() << what << " point " << p << ": got " << got[p][0] << " " << got[p][1] << " " << got[p][2]
                    << ", want " << want[p][0] << " " << want[p][1] << " " << want[p][2];
  }
  EXPECT_EQ(wrong, 0u) << what << ": points whose force differs";
}

// Two crumpled sheets of different resolutions, tilted against each other, each point
// jittered in every axis by up to a third of the smaller spacing: within range of each
// other almost everywhere, at every angle, with stretched and sheared cells.
template <class Real = double>
std::pair<Sheet<Real>, Sheet<Real>> crumpled_pair(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  SheetDef da;
  da.m = 14 + seed % 5;
  da.n = 17;
  da.width = 0.12;
  da.height = 0.1;
  da.orientation = quat_from_axis_angle({1, 0, 0}, 0.2 * unit(rng));
  SheetDef db;
  db.m = 9;
  db.n = 11 + seed % 3;
  db.width = 0.11;
  db.height = 0.12;
  db.center = {0.01 * unit(rng), 0.01 * unit(rng), 0.007};
  db.orientation = quat_from_axis_angle({0.3, 0.2, 1}, 1.0 + unit(rng));
  auto a = build_sheet<Real>(da), b = build_sheet<Real>(db);
  const double jitter = 0.002;
  for (auto* s : {&a, &b})
    for (std::uint32_t p = 0; p < s->size(); ++p) {
      const double x = s->position.x[p], y = s->position.y[p];
      s->position.x[p] += static_cast<Real>(jitter * unit(rng));
      s->position.y[p] += static_cast<Real>(jitter * unit(rng));
      s->position.z[p] += static_cast<Real>(jitter * unit(rng) + 0.006 * std::sin(40 * x + seed) * std::cos(30 * y));
    }
  return {std::move(a), std::move(b)};
}

TEST(Contacts, PairMatchesEveryPointAgainstEveryTriangle) {
  for (unsigned seed = 1; seed <= 12; ++seed) {
    auto [a, b] = crumpled_pair(seed);
    PairContacts<double> work;
    ContactScratch<double> scratch;  // one scratch for every seed, as a thread reuses it across pairs
    pair_contacts(a, boxes(a), b, boxes(b), kParams, work, scratch);
    const Dense ab = brute_contacts(a, b, -1), ba = brute_contacts(b, a, -1);
    ASSERT_GT(ab.entries_q, a.size() / 4) << "seed " << seed;  // most points in contact
    const auto [on_a, on_b] = brute_pair(ab, ba);
    const std::string tag = "seed " + std::to_string(seed);
    expect_same_forces(dense(work.on_a, a.size()), on_a, tag + " on a");
    expect_same_forces(dense(work.on_b, b.size()), on_b, tag + " on b");
    EXPECT_EQ(work.on_a.size(), ab.entries_q + ba.entries_s) << tag;
    EXPECT_EQ(work.on_b.size(), ab.entries_s + ba.entries_q) << tag;
  }
}

TEST(Contacts, SelfContactMatchesEveryPointAgainstEveryTriangleOutsideTheRing) {
  for (unsigned seed = 1; seed <= 6; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    SheetDef d;
    d.m = 24;
    d.n = 12;
    d.width = 0.12;
    d.height = 0.24;
    // The upper half folded 7 mm above the lower one and shifted, then both crumpled: each
    // half in range of the other and of its own far parts.
    auto s = folded_sheet(d, 0.007);
    for (std::uint32_t p = (d.m / 2 + 1) * (d.n + 1); p < s.size(); ++p) {
      s.position.x[p] += 0.004 * unit(rng);
      s.position.y[p] += 0.003;
    }
    for (std::uint32_t p = 0; p < s.size(); ++p) {
      s.position.x[p] += 0.002 * unit(rng);
      s.position.y[p] += 0.002 * unit(rng);
      s.position.z[p] += 0.002 * unit(rng) + 0.004 * std::sin(50 * s.position.x[p] + seed);
    }
    PairContacts<double> work;
    ContactScratch<double> scratch;
    self_contacts(s, boxes(s), kParams, work, scratch);
    // The ring by its definition in contacts.h, not by calling the engine's function.
    const double spacing = std::min(d.width / d.n, d.height / d.m);
    const int ring = std::min(16, 1 + int(std::ceil(kParams.range / spacing)));
    const Dense want = brute_contacts(s, s, ring);
    ASSERT_GT(want.entries_q, s.size() / 4) << "seed " << seed;
    std::vector<P3> total = want.on_q;
    for (std::size_t p = 0; p < s.size(); ++p)
      for (int k = 0; k < 3; ++k) total[p][k] += want.on_s[p][k];
    expect_same_forces(dense(work.on_a, s.size()), total, "seed " + std::to_string(seed));
    EXPECT_EQ(work.on_a.size(), want.entries_q + want.entries_s) << "seed " << seed;
  }
}

// The search, the walk and the force run on every instruction set the CPU has (contacts.cpp
// is compiled per target, contraction off), and each gives the same forces, entry for entry
// and bit for bit, as the first (the widest): a crumpled pair with friction and a jostled
// fold against itself, over steps that search, keep lists (exact) or walk a kept set, and a
// stack of two equal grids walking with friction, sliding past each other, without and with
// contact damping (the force in lanes where there are vectors, its friction and damping entry
// by entry), in both precisions. It fails if a target's vector gap test or tail rounds
// differently, or finds a different set of cells.
template <class Real>
std::vector<double> contact_forces_over_steps() {
  ContactParams<Real> walked = ContactParams<Real>::make(0.005, 0.002, 1e-4, 6.0);
  walked.rims = true;  // the rims' search and force too
  ContactParams<Real> exact = walked;
  walked.dt = exact.dt = Real(1e-3);
  exact.exact = true;
  ContactParams<Real> damped = walked;  // the stack again with contact damping (α, s/m)
  damped.damping = Real(2);
  std::vector<double> out;
  auto record = [&](const ContactForces<Real>& f) {
    out.push_back(double(f.size()));
    for (std::size_t e = 0; e < f.size(); ++e)
      out.insert(out.end(), {double(f.point[e]), double(f.fx[e]), double(f.fy[e]), double(f.fz[e])});
  };
  auto boxes_of = [](const Sheet<Real>& s) {
    SheetBoxes<Real> out;
    build_boxes(s, out);
    return out;
  };
  std::mt19937 rng(5);
  auto [a, b] = crumpled_pair<Real>(3);
  a.friction = Real(0.4);
  for (std::size_t p = 0; p < a.size(); ++p) a.velocity.x[p] = Real(0.01 * std::sin(double(p)));
  auto s = folded_sheet<Real>(fold_def(), 0.008);
  // Two equal grids stacked, each point over a grid point of the other: walks that end at
  // their first cell's corner (the force in lanes where there are vectors).
  SheetDef layer;
  layer.m = layer.n = 12;
  layer.width = layer.height = 0.12;
  auto lower = build_sheet<Real>(layer);
  layer.center = {0.0, 0.0, 0.006};
  auto upper = build_sheet<Real>(layer);
  upper.friction = Real(0.5);
  for (std::size_t p = 0; p < upper.size(); ++p) {  // some points slip, some are held
    upper.velocity.x[p] = Real(0.02 * std::cos(double(p)));
    lower.velocity.y[p] = Real(p % 3 == 0 ? 0.0 : 0.01 * std::sin(double(p)));
  }
  ContactScratch<Real> scratch;
  PairContacts<Real> pair_walked, pair_exact, fold_walked, fold_exact, stack_walked, stack_damped;
  for (int step = 0; step < 6; ++step) {
    for (Sheet<Real>* sheet : {&a, &b, &s, &lower, &upper}) jostle(*sheet, rng);
    pair_contacts(a, boxes_of(a), b, boxes_of(b), walked, pair_walked, scratch);
    pair_contacts(a, boxes_of(a), b, boxes_of(b), exact, pair_exact, scratch);
    self_contacts(s, boxes_of(s), walked, fold_walked, scratch);
    self_contacts(s, boxes_of(s), exact, fold_exact, scratch);
    for (const auto* w : {&pair_walked, &pair_exact}) {
      record(w->on_a);
      record(w->on_b);
    }
    record(fold_walked.on_a);
    record(fold_exact.on_a);
    pair_contacts(lower, boxes_of(lower), upper, boxes_of(upper), walked, stack_walked, scratch);
    record(stack_walked.on_a);
    record(stack_walked.on_b);
    pair_contacts(lower, boxes_of(lower), upper, boxes_of(upper), damped, stack_damped, scratch);
    record(stack_damped.on_a);
    record(stack_damped.on_b);
  }
  return out;
}

template <class Real>
void expect_every_target_gives_the_same_contact_forces() {
  std::vector<double> first;
  test::for_each_target([&](std::int64_t) {
    const std::vector<double> got = contact_forces_over_steps<Real>();
    if (first.empty()) {
      first = got;
      ASSERT_GT(first.size(), 1000u);  // many contacts, not a vacuous comparison
      return;
    }
    ASSERT_EQ(got.size(), first.size());
    for (std::size_t k = 0; k < got.size(); ++k)  // bits, so −0 and NaN count too
      ASSERT_EQ(std::memcmp(&got[k], &first[k], sizeof(double)), 0) << "value " << k << ": " << got[k] << " vs "
                                                                     << first[k];
  });
}

TEST(Contacts, EveryInstructionSetGivesTheSameForcesBitForBit) {
  expect_every_target_gives_the_same_contact_forces<double>();
}
TEST(Contacts, EveryInstructionSetGivesTheSameForcesBitForBitInFloat) {
  expect_every_target_gives_the_same_contact_forces<float>();
}

TEST(Contacts, GatherAddsSourcesInOrderWithinTheRange) {
  ContactForces<double> first, second;
  first.push(1, 1.0, 2.0, 3.0);
  first.push(3, 0.5, 0.0, 0.0);
  second.push(1, 0.25, 0.0, -1.0);
  const ContactForces<double>* sources[] = {&first, &second};
  Vec3Array<double> out;
  out.resize(4, 9.0);  // stale values must be cleared in the range, kept outside it
  gather_contacts<double>(sources, out, 0, 2);
  EXPECT_EQ(std::vector<double>(out.x.begin(), out.x.end()), (std::vector<double>{0.0, 1.25, 9.0, 9.0}));
  EXPECT_EQ(std::vector<double>(out.z.begin(), out.z.end()), (std::vector<double>{0.0, 2.0, 9.0, 9.0}));
}


// Kept contact sets (contacts.h, KeptContacts: the default between searches) against the
// exact search, on the same positions at every step. Two rumpled sheets carried along a
// common drift that turns slowly, with jitter, then one pressed towards the other; and a
// folded sheet against itself, jostled (0.3 mm a step at random, so it crumples). At each
// step the walked forces of the persistent PairContacts and those of a fresh exact search
// are made dense per point; the summed difference |ΔF| stays within 1e-3 of the summed |F|
// for the pair and 1e-2 for the crumpled fold (a walk that stops on the wrong cell gives a
// force off by its whole size at that point).
double force_gap(const ContactForces<double>& walked, const ContactForces<double>& exact, std::size_t points,
                 double& scale) {
  const auto w = dense(walked, points), e = dense(exact, points);
  double gap = 0;
  for (std::size_t p = 0; p < points; ++p) {
    gap += std::hypot(w[p][0] - e[p][0], w[p][1] - e[p][1], w[p][2] - e[p][2]);
    scale += std::hypot(e[p][0], e[p][1], e[p][2]);
  }
  return gap;
}

TEST(Contacts, WalkedContactSetsStayWithinTheirBoundOfTheExactSearch) {
  auto [a, b] = close_sheets(6);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> jitter(-1e-4, 1e-4);
  auto carry = [&](Sheet<double>& s, double dx, double dz, double turn) {
    for (std::size_t p = 0; p < s.size(); ++p) {
      const double x = s.position.x[p], y = s.position.y[p];
      s.position.x[p] = x * std::cos(turn) - y * std::sin(turn) + dx + jitter(rng);
      s.position.y[p] = x * std::sin(turn) + y * std::cos(turn) + jitter(rng);
      s.position.z[p] += dz + jitter(rng);
    }
  };
  PairContacts<double> walked;
  ContactScratch<double> scratch;
  double gap = 0, scale = 0;
  const int steps = 60;
  for (int step = 0; step < steps; ++step) {
    carry(a, 0.001, 0.0, 0.002);
    carry(b, 0.001, step < 40 ? 0.0 : -1e-4, 0.002);
    PairContacts<double> exact;
    pair_contacts(a, boxes(a), b, boxes(b), kParams, walked, scratch);
    pair_contacts(a, boxes(a), b, boxes(b), kExact, exact, scratch);
    gap += force_gap(walked.on_a, exact.on_a, a.size(), scale);
    gap += force_gap(walked.on_b, exact.on_b, b.size(), scale);
  }
  EXPECT_GT(scale, 0.0);
  EXPECT_LT(walked.searches, std::uint64_t(steps) / 4);  // the walk served most steps
  EXPECT_LE(gap, 1e-3 * scale) << "pair: summed |dF| " << gap << " of " << scale;

  const SheetDef d = fold_def();
  auto s = folded_sheet(d, 0.008);
  PairContacts<double> own;
  double fold_gap = 0, fold_scale = 0;
  for (int step = 0; step < steps; ++step) {
    jostle(s, rng);
    PairContacts<double> exact;
    self_contacts(s, boxes(s), kParams, own, scratch);
    self_contacts(s, boxes(s), kExact, exact, scratch);
    fold_gap += force_gap(own.on_a, exact.on_a, s.size(), fold_scale);
  }
  EXPECT_GT(fold_scale, 0.0);
  EXPECT_LT(own.searches, std::uint64_t(steps) / 4);
  EXPECT_LE(fold_gap, 1e-2 * fold_scale) << "fold: summed |dF| " << fold_gap << " of " << fold_scale;
}

// A walked contact set's forces, most of them computed in lanes where the CPU has vectors
// (the walks that end at their first cell), against every point against every triangle
// with std::exp (brute_contacts). The sheets stay planes: a flat one, and above it the
// same grid tilted against it (about two axes), each point jostled within its sheet's
// plane and the upper sheet carried across the lower one and up and down, step by step.
// The distance to a plane's convex patch has no local minimum but the nearest triangle, so
// the walk ends where the brute force does (a rumpled or jostled mesh has valleys whose
// two sides are both local minima, and there the walk is an approximation; so, measured
// here, are points beyond the edge of a grid shifted or turned against theirs). The same
// points feel a force, and the same force within 10⁻¹⁰ of the largest, on every
// instruction set: it fails if a lane's exp, distance, direction or weights differ from
// repel's beyond rounding. The third pair turns the upper grid half a turn about its
// normal, so its points run over the lower grid's cells in falling order (the lanes' runs
// of falling cells, first_tests), as a fold's do.
TEST(Contacts, WalkedForcesBetweenPlanesMatchEveryPointAgainstEveryTriangle) {
  test::for_each_target([&](std::int64_t) {
    for (int pair = 0; pair < 3; ++pair) {
      SheetDef da;
      da.m = da.n = 16;
      da.width = da.height = 0.16;
      SheetDef db = da;
      db.center = {0.0, 0.0, 0.006};
      db.orientation = pair == 2   ? quat_from_axis_angle(Vec3{0.02, 0.03, 1}, 3.14159265358979)
                       : pair == 0 ? quat_from_axis_angle(Vec3{0.3, 1, 0}, 0.05)
                                   : quat_from_axis_angle(Vec3{1, 0.2, 0}, 0.05);
      auto a = build_sheet<double>(da), b = build_sheet<double>(db);
      // Each sheet's in-plane unit axes, from its first row and column.
      auto axes = [](const Sheet<double>& s) {
        const P3 o = point(s, 0), u = sub(point(s, 1), o), v = sub(point(s, s.topology->cols()), o);
        const double lu = std::sqrt(dot(u, u)), lv = std::sqrt(dot(v, v));
        return std::array<P3, 2>{P3{u[0] / lu, u[1] / lu, u[2] / lu}, P3{v[0] / lv, v[1] / lv, v[2] / lv}};
      };
      const auto along_a = axes(a), along_b = axes(b);
      std::mt19937 rng(3 + pair);
      std::uniform_real_distribution<double> jitter(-3e-4, 3e-4);
      auto move = [&](Sheet<double>& s, const std::array<P3, 2>& along, double du, double dv, double dz) {
        for (std::uint32_t p = 0; p < s.size(); ++p) {
          const double x = du + jitter(rng), y = dv + jitter(rng);
          s.position.x[p] += x * along[0][0] + y * along[1][0];
          s.position.y[p] += x * along[0][1] + y * along[1][1];
          s.position.z[p] += x * along[0][2] + y * along[1][2] + dz;
        }
      };
      PairContacts<double> walked;
      ContactScratch<double> scratch;
      const int steps = 10;
      for (int step = 0; step < steps; ++step) {
        move(a, along_a, 0.0, 0.0, 0.0);
        move(b, along_b, pair != 1 ? 0.0006 : -0.0002, pair != 1 ? 0.0003 : 0.0007, step % 4 < 2 ? -2e-4 : 2e-4);
        pair_contacts(a, boxes(a), b, boxes(b), kParams, walked, scratch);
        const Dense ab = brute_contacts(a, b, -1), ba = brute_contacts(b, a, -1);
        ASSERT_GT(ab.entries_q, a.size() / 2) << "pair " << pair;  // most points in contact
        const auto [on_a, on_b] = brute_pair(ab, ba);
        const std::string tag = "pair " + std::to_string(pair) + " step " + std::to_string(step);
        expect_same_forces(dense(walked.on_a, a.size()), on_a, tag + " on a");
        expect_same_forces(dense(walked.on_b, b.size()), on_b, tag + " on b");
      }
      EXPECT_LE(walked.searches, std::uint64_t(steps) / 2) << "pair " << pair;  // the walk served most steps
    }
  });
}

// A kept entry beyond R skips its walks while the two sheets have not travelled its slack
// (KeptContacts::until): the forces are those of walking every entry every step, bit for
// bit, on every instruction set. The upper of two tilted 16×16 planes starts 24 mm above
// the lower one and closes 0.6 mm a step while it slides 0.4 mm a step, every point of
// both jittered by up to 0.1 mm a step: entries are made beyond R, skip a few steps, and
// come within R, where a skip one step too long loses the force they then feel. Each
// sheet's travel goes on as the world's does (advance_travel, once a step); the twin's
// travel is unknown, so it walks every entry.
TEST(Contacts, SkippedWalksGiveTheForcesOfWalkingEveryEntry) {
  test::for_each_target([&](std::int64_t) {
    SheetDef da;
    da.m = da.n = 16;
    da.width = da.height = 0.16;
    SheetDef db = da;
    db.center = {0.003, 0.002, 0.024};
    db.orientation = quat_from_axis_angle(Vec3{0.3, 1, 0}, 0.05);
    auto a = build_sheet<double>(da), b = build_sheet<double>(db);
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> jitter(-1e-4, 1e-4);
    PairContacts<double> skipping, walking;
    ContactScratch<double> scratch;
    std::size_t skipped = 0, touching = 0;
    for (int step = 0; step < 30; ++step) {
      for (std::size_t p = 0; p < b.size(); ++p) {
        b.position.x[p] += 0.0004 + jitter(rng);
        b.position.y[p] += jitter(rng);
        b.position.z[p] += -0.0006 + jitter(rng);
        a.position.x[p] += jitter(rng);
        a.position.y[p] += jitter(rng);
        a.position.z[p] += jitter(rng);
      }
      advance_travel(a);
      advance_travel(b);
      ContactParams<double> prm = kParams;
      prm.travel = a.travel + b.travel;
      std::size_t due_to_skip = 0;
      for (const KeptContacts* k : {&skipping.a_on_b, &skipping.b_on_a})
        for (double until : k->until) due_to_skip += prm.travel < until;
      const std::uint64_t searches = skipping.searches;
      pair_contacts(a, boxes(a), b, boxes(b), prm, skipping, scratch);
      pair_contacts(a, boxes(a), b, boxes(b), kParams, walking, scratch);
      if (skipping.searches == searches) skipped += due_to_skip;  // they walked: those skipped
      expect_same_forces(skipping.on_a, walking.on_a, step);
      expect_same_forces(skipping.on_b, walking.on_b, step);
      touching += skipping.on_a.size();
    }
    EXPECT_GT(skipped, a.size());   // entries did skip, over the run
    EXPECT_GT(touching, a.size());  // and the sheets came into range
  });
}

// A pair's kept sets walked and searched in parts (ContactParams::parts, as tasks when the
// world has threads to spare) give the forces of one pass, entry for entry and bit for bit:
// two sheets of 45×45 points, one sliding over the other (both directions walked in halves,
// and searched again in halves of their blocks, partly), and a sheet folded onto itself (one
// set in halves, its forces and reactions in one buffer), jostled for 30 steps, each step
// against a twin that walks and searches in one piece. It fails if the parts' forces are
// appended out of the order one pass pushes them, if a part is left out, or if a set made
// in parts misplaces its blocks (the next partial search walks the wrong entries).
TEST(Contacts, WalkInPartsGivesTheForcesOfOneWalk) {
  test::for_each_target([&](std::int64_t) {
    SheetDef da;
    da.m = da.n = 44;
    da.width = da.height = 0.44;
    SheetDef db = da;
    db.center = {0.15, 0.003, 0.009};  // a third of a beyond reach of b: its blocks there open
    db.orientation = quat_from_axis_angle(Vec3{0.3, 1, 0}, 0.01);
    auto a = build_sheet<double>(da), b = build_sheet<double>(db);
    SheetDef df = fold_def();
    df.m = 60;
    df.n = 40;
    df.width = 0.4;
    df.height = 0.6;
    auto f = folded_sheet(df, 0.008);
    std::mt19937 rng(17);
    PairContacts<double> parts, whole, parts_self, whole_self;
    ContactScratch<double> scratch;
    ContactParams<double> two = kParams;
    two.parts = 2;
    std::size_t walked = 0, partial = 0;
    for (int step = 0; step < 30; ++step) {
      for (auto* s : {&a, &b, &f}) {
        jostle(*s, rng, 0.00005);
        advance_travel(*s);
      }
      for (double& x : b.position.x) x -= 0.0015;  // b slides over a: partial searches
      two.travel = a.travel + b.travel;
      ContactParams<double> one = two;
      one.parts = 1;
      const std::uint64_t searches = parts.searches;
      pair_contacts(a, boxes(a), b, boxes(b), two, parts, scratch);
      pair_contacts(a, boxes(a), b, boxes(b), one, whole, scratch);
      expect_same_forces(parts.on_a, whole.on_a, step);
      expect_same_forces(parts.on_b, whole.on_b, step);
      two.travel = one.travel = 2 * f.travel;
      self_contacts(f, boxes(f), two, parts_self, scratch);
      self_contacts(f, boxes(f), one, whole_self, scratch);
      expect_same_forces(parts_self.on_a, whole_self.on_a, step);
      // the steps that walked (no search) with enough entries to be split, and the partial searches
      walked += parts.searches == searches && parts.a_on_b.point.size() + parts.b_on_a.point.size() >= 2048;
      partial += parts.searches != searches && parts.since_full > 0;
    }
    EXPECT_GT(walked, 5u);
    EXPECT_GT(partial, 3u);
    EXPECT_GE(parts_self.a_on_b.point.size(), 2048u);
  });
}

// The same in a world: on two threads a world with fewer pairs than four walks and
// searches them in parts (one sheet folded onto itself, then two sheets draped over each
// other), and each step's positions equal those of one thread, bit for bit, in double and
// in float.
template <class W>
void expect_few_pairs_in_parts_give_the_bits_of_one() {
  auto run = [](int threads, bool two_sheets) {
    WorldDef wd;
    wd.dt = 2e-4;
    wd.threads = threads;
    W world(wd);
    SheetDef d;
    d.m = d.n = 79;
    d.width = d.height = 0.8;
    d.self_collision = !two_sheets;
    const SheetId id = world.add_sheet(d);
    if (two_sheets) {
      d.center.z = 0.009;
      d.orientation = quat_from_axis_angle(Vec3{0, 0, 1}, 0.02);
      world.add_sheet(d);
    } else {  // columns from 40 on folded over the others, 10 mm up
      auto s = world.state(id);
      const double mid = 0.5 * (s.x[40] + s.x[39]);
      for (std::uint32_t i = 0; i <= d.m; ++i)
        for (std::uint32_t j = 40; j <= d.n; ++j) {
          const std::uint32_t p = point_index(d.n, i, j);
          s.x[p] = 2 * mid - s.x[p];
          s.z[p] += 0.010;
        }
    }
    std::vector<double> out;
    for (int step = 0; step < 25; ++step) {
      world.step(1);
      for (SheetId sheet : world.sheets()) {
        const auto v = world.view(sheet);
        out.insert(out.end(), v.z.begin(), v.z.end());
        out.insert(out.end(), v.x.begin(), v.x.end());
      }
    }
    return out;
  };
  for (bool two_sheets : {false, true}) {
    const auto one = run(1, two_sheets), two = run(2, two_sheets);
    ASSERT_EQ(one.size(), two.size());
    std::size_t differ = 0;
    for (std::size_t k = 0; k < one.size(); ++k) differ += one[k] != two[k];
    EXPECT_EQ(differ, 0u) << (two_sheets ? "two sheets" : "fold");
  }
}
TEST(Contacts, FewPairsWalkedInPartsOnTwoThreadsGiveTheBitsOfOne) { expect_few_pairs_in_parts_give_the_bits_of_one<World>(); }
TEST(Contacts, FewPairsWalkedInPartsOnTwoThreadsGiveTheBitsOfOneInFloat) {
  expect_few_pairs_in_parts_give_the_bits_of_one<WorldF>();
}

// The bound a pair's kept lists take from the sheets' travel (measure_travel): between two
// substeps in which the sheet was measured, no point moved farther than the later moved_hi
// less the earlier moved_lo, whichever substeps advanced the travel between them (some
// measured and advanced, as the world does, some only measured, some only advanced, some
// neither), through jitter, a jump and a stretch, in both precisions.
template <class Real>
void expect_travel_bounds_every_move() {
  SheetDef d;
  d.m = 7;
  d.n = 9;
  auto s = build_sheet<Real>(d);
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  std::uniform_int_distribution<int> what(0, 3);
  struct Seen {
    Vec3Array<Real> at;
    double lo, hi;
  };
  std::vector<Seen> seen;
  int pairs = 0, tight = 0;
  for (std::uint64_t step = 1; step <= 60; ++step) {
    for (std::size_t p = 0; p < s.size(); ++p) {
      // a rigid translation first (there the bound is exact but for its rounding up), then
      // jitter, a jump and a stretch
      const bool rigid = step <= 20;
      const double jump = step == 30 ? 0.05 : 0.0, stretch = step > 45 ? 1e-3 * double(p % 9) : 0.0;
      s.position.x[p] += Real((rigid ? 1e-3 : jitter(rng)) + jump + stretch);
      s.position.y[p] += Real(rigid ? 5e-4 : jitter(rng));
      s.position.z[p] += Real((rigid ? 0 : jitter(rng)) - 2e-4);
    }
    const int w = what(rng);
    if (w == 0 || w == 1) {
      measure_travel(s, step);
      seen.push_back({s.position, s.moved_lo(), s.moved_hi()});
      for (const Seen& then : seen) {  // every earlier measured substep, and this one itself
        double most = 0;
        for (std::size_t p = 0; p < s.size(); ++p) {
          const double dx = double(s.position.x[p]) - then.at.x[p], dy = double(s.position.y[p]) - then.at.y[p],
                       dz = double(s.position.z[p]) - then.at.z[p];
          most = std::max(most, std::sqrt(dx * dx + dy * dy + dz * dz));
        }
        EXPECT_LE(most, s.moved_hi() - then.lo) << "step " << step;
        ++pairs;
        tight += std::isfinite(s.moved_hi() - then.lo) && s.moved_hi() - then.lo < 2 * most + 0.01;
      }
    }
    if (w == 0 || w == 2) advance_travel(s, step);
  }
  EXPECT_GT(pairs, 100);
  EXPECT_GT(tight, 10);  // the bound is finite and not vacuous
}

TEST(Contacts, TravelBoundsEveryMoveBetweenMeasuredSubsteps) { expect_travel_bounds_every_move<double>(); }
TEST(Contacts, TravelBoundsEveryMoveBetweenMeasuredSubstepsInFloat) { expect_travel_bounds_every_move<float>(); }

// The travel bound answering lists_hold's first test for a pair (measure_travel, stamped
// substeps) against the same pair with no stamp, which runs the exact test over its points
// every time: the same forces bit for bit and the same searches, with the bound clearing the
// pair on most substeps. Two 16×16 grids 8 mm apart, the upper one half over the lower one
// (points beyond R: the kept sets have open patches, which the test is for), both jittered
// by up to 20 µm a step, the upper one sliding 0.3 mm a step, so that lists fail and are
// made again every few steps.
TEST(Contacts, TravelBoundDecidesAsTheExactTestDoes) {
  test::for_each_target([&](std::int64_t) {
    SheetDef da;
    da.m = da.n = 16;
    da.width = da.height = 0.16;
    SheetDef db = da;
    db.center = {0.081, 0.002, 0.008};  // half over the lower one: the sets have open patches
    auto a = build_sheet<double>(da), b = build_sheet<double>(db);
    auto a2 = a, b2 = b;
    std::mt19937 rng(37);
    std::uniform_real_distribution<double> jitter(-2e-5, 2e-5);
    PairContacts<double> bounded, exact;
    ContactScratch<double> scratch;
    // the sheets' travel starts here (before it, measure_travel knows no bound: −∞)
    for (auto* s : {&a, &b, &a2, &b2}) advance_travel(*s);
    int cleared = 0;
    for (std::uint64_t step = 1; step <= 60; ++step) {
      for (std::size_t p = 0; p < a.size(); ++p) {
        const double move[6] = {jitter(rng), jitter(rng), jitter(rng), 3e-4 + jitter(rng), jitter(rng), jitter(rng)};
        a.position.x[p] += move[0], a.position.y[p] += move[1], a.position.z[p] += move[2];
        b.position.x[p] += move[3], b.position.y[p] += move[4], b.position.z[p] += move[5];
        a2.position.x[p] = a.position.x[p], a2.position.y[p] = a.position.y[p], a2.position.z[p] = a.position.z[p];
        b2.position.x[p] = b.position.x[p], b2.position.y[p] = b.position.y[p], b2.position.z[p] = b.position.z[p];
      }
      // as the world's contact stage: measured before the pair decides, advanced after
      measure_travel(a, step);
      measure_travel(b, step);
      ContactParams<double> prm = kParams;
      prm.stamp = step;
      if (bounded.skin > 0 && a.moved_hi() - bounded.moved_lo_a <= 0.45 * bounded.skin &&
          b.moved_hi() - bounded.moved_lo_b <= 0.45 * bounded.skin)
        ++cleared;
      pair_contacts(a, boxes(a), b, boxes(b), prm, bounded, scratch);
      pair_contacts(a2, boxes(a2), b2, boxes(b2), kParams, exact, scratch);
      advance_travel(a, step);
      advance_travel(b, step);
      advance_travel(a2);
      advance_travel(b2);
      expect_same_forces(bounded.on_a, exact.on_a, int(step));
      expect_same_forces(bounded.on_b, exact.on_b, int(step));
      EXPECT_EQ(bounded.searches, exact.searches) << "step " << step;
    }
    EXPECT_GT(cleared, 8);  // the bound served, not only the exact test
    EXPECT_GT(bounded.on_a.size(), 0u);  // in contact
  });
}

// Two equal grids, one 8 mm straight above the other, carried together along a drift and a
// turn: every point lies over a vertex of the other sheet, where the triangles around it
// are equally near, and rounding alone (different for each point, through the turn) makes
// one of them nearer by an ulp. The walk stays at its vertex (kWalkTie, contacts.cpp)
// instead of testing the cells around it and moving to whichever rounding favours: no
// kept cell changes after the search. The forces stay the brute force's to 10⁻¹⁰ of the
// largest (double). With the exact vertex test the cells move; a fold moved about a tenth
// of its entries every substep so, and tested three more cells for about half of them.
// Two equal 16×16 grids of 0.16 m, the second 8 mm straight above the first.
template <class Real>
std::pair<Sheet<Real>, Sheet<Real>> aligned_grids() {
  SheetDef da;
  da.m = da.n = 16;
  da.width = da.height = 0.16;
  SheetDef db = da;
  db.center = {0.0, 0.0, 0.008};
  return {build_sheet<Real>(da), build_sheet<Real>(db)};
}

template <class Real>
void expect_walk_stays_at_aligned_vertices() {
  test::for_each_target([&](std::int64_t) {
    auto [a, b] = aligned_grids<Real>();
    const Vec3Array<Real> a0 = a.position, b0 = b.position;
    // The same motion for both, turned about the origin or about (ox, oy) and moved back:
    // equal but for rounding.
    auto carry = [](Sheet<Real>& s, const Vec3Array<Real>& from, int step, double ox, double oy) {
      const Real turn = Real(0.003 * step), c = std::cos(turn), sn = std::sin(turn);
      const Real tx = Real(0.0007 * step) + (c * Real(ox) - sn * Real(oy)) - Real(ox),
                 ty = Real(-0.0004 * step) + (sn * Real(ox) + c * Real(oy)) - Real(oy);
      for (std::size_t p = 0; p < s.size(); ++p) {  // in the sheet's precision, as a step rounds
        const Real x = from.x[p] - Real(ox), y = from.y[p] - Real(oy);
        s.position.x[p] = x * c - y * sn + Real(ox) + tx;
        s.position.y[p] = x * sn + y * c + Real(oy) + ty;
      }
    };
    ContactParams<Real> prm = ContactParams<Real>::make(0.005, 0.002, 1e-4, 6.0);
    PairContacts<Real> walked;
    ContactScratch<Real> scratch;
    std::vector<std::uint32_t> cells_ab, cells_ba;
    for (int step = 0; step < 12; ++step) {
      carry(a, a0, step, 0.0, 0.0);
      carry(b, b0, step, 0.0137, -0.0291);
      SheetBoxes<Real> ba, bb;
      build_boxes(a, ba);
      build_boxes(b, bb);
      pair_contacts(a, ba, b, bb, prm, walked, scratch);
      if (step == 0) {
        cells_ab = walked.a_on_b.cell;
        cells_ba = walked.b_on_a.cell;
        ASSERT_EQ(cells_ab.size(), a.size());  // every point in the set
        continue;
      }
      EXPECT_EQ(walked.a_on_b.cell, cells_ab) << "step " << step;
      EXPECT_EQ(walked.b_on_a.cell, cells_ba) << "step " << step;
      if constexpr (std::is_same_v<Real, double>) {
        const Dense ab = brute_contacts(a, b, -1), ba_ = brute_contacts(b, a, -1);
        const auto [on_a, on_b] = brute_pair(ab, ba_);
        const std::string tag = "step " + std::to_string(step);
        expect_same_forces(dense(walked.on_a, a.size()), on_a, tag + " on a");
        expect_same_forces(dense(walked.on_b, b.size()), on_b, tag + " on b");
      }
    }
    EXPECT_EQ(walked.searches, 1u);  // the walk served every later step
  });
}

TEST(Contacts, WalkOverAnAlignedGridStaysAtItsVertexThroughRounding) {
  expect_walk_stays_at_aligned_vertices<double>();
}
TEST(Contacts, WalkOverAnAlignedGridStaysAtItsVertexThroughRoundingInFloat) {
  expect_walk_stays_at_aligned_vertices<float>();
}

// Within test::for_each_target: the first target's values kept in `first`, every later
// target's `got` the same bit for bit.
template <class Real>
void expect_bits_of_first_target(const std::vector<Real>& got, std::vector<Real>& first) {
  if (first.empty()) {
    first = got;
    return;
  }
  ASSERT_EQ(got.size(), first.size());
  for (std::size_t k = 0; k < got.size(); ++k)
    ASSERT_EQ(std::memcmp(&got[k], &first[k], sizeof(Real)), 0) << "value " << k << ": " << got[k] << " vs " << first[k];
}

// Two equal grids, one 8 mm above the other, searched while flat: every point lies over a
// vertex of the other sheet and its walk starts there. Then some of the lower sheet's
// points rise 0.4 mm (within the skin, so the kept sets serve): the triangles around a
// raised point come nearer to the upper points over its neighbours, so a walk must leave
// its vertex wherever a neighbour rose, along whichever of its six edges that is. The
// lanes take the vertex test of a whole vector of such entries at once, reading the
// vertices' neighbours as runs where they can (first_tests, AVX2 and AVX-512); the scalar
// targets walk one entry at a time and read each neighbour by its index. So every target
// must give the same forces bit for bit, and (for the unshifted grids) the brute force's.
TEST(Contacts, WalkFromAnAlignedVertexFindsTheRaisedNeighboursTriangles) {
  std::vector<double> first;
  test::for_each_target([&](std::int64_t) {
    auto [a, b] = aligned_grids<double>();
    const Vec3Array<double> a0 = a.position, b0 = b.position;
    const auto prm = kParams;  // the points' contacts: the brute force's
    ContactScratch<double> scratch;
    std::mt19937 rng(11);
    std::size_t moved = 0;
    std::vector<double> got;
    for (int trial = 0; trial < 25; ++trial) {
      // The upper grid shifted by 0.1 nm diagonally, one of four ways, or not at all: a
      // search then keeps the cell on that side of each vertex, whose corner the vertex
      // is (and the walk takes a closest point that near a corner as the corner, kWalkTie).
      const int shift = trial % 5;
      b.position = b0;
      if (shift < 4)
        for (std::uint32_t p = 0; p < b.size(); ++p) {
          b.position.x[p] += shift % 2 == 0 ? 1e-10 : -1e-10;
          b.position.y[p] += shift < 2 ? 1e-10 : -1e-10;
        }
      PairContacts<double> walked;
      a.position = a0;
      pair_contacts(a, boxes(a), b, boxes(b), prm, walked, scratch);
      ASSERT_EQ(walked.b_on_a.cell.size(), b.size());  // every point in the set
      const std::vector<std::uint32_t> searched = walked.b_on_a.cell;
      // points of a lattice three apart, each kept or not at random: no vertex has two
      // raised neighbours, whose valleys would leave two local minima for its walk
      const std::uint32_t cols = a.topology->cols(), row0 = rng() % 3, col0 = rng() % 3;
      for (std::uint32_t p = 0; p < a.size(); ++p)
        if ((p / cols) % 3 == row0 && (p % cols) % 3 == col0 && rng() % 2 == 0) a.position.z[p] += 4e-4;
      pair_contacts(a, boxes(a), b, boxes(b), prm, walked, scratch);
      ASSERT_EQ(walked.searches, 1u);  // the walk served the second step
      for (std::size_t e = 0; e < searched.size(); ++e) moved += searched[e] != walked.b_on_a.cell[e];
      const auto on_a = dense(walked.on_a, a.size()), on_b = dense(walked.on_b, b.size());
      for (const auto* forces : {&on_a, &on_b})
        for (const P3& f : *forces) got.insert(got.end(), f.begin(), f.end());
      if (shift == 4) {
        const Dense ab = brute_contacts(a, b, -1), ba = brute_contacts(b, a, -1);
        const auto [brute_a, brute_b] = brute_pair(ab, ba);
        const std::string tag = "trial " + std::to_string(trial);
        expect_same_forces(on_a, brute_a, tag + " on a");
        expect_same_forces(on_b, brute_b, tag + " on b");
      }
    }
    EXPECT_GT(moved, b.size());  // many walks left their vertex
    expect_bits_of_first_target(got, first);
  });
}

// Damping and friction taken in lanes (dissipate_lanes, AVX2 and AVX-512: a vector of
// walked entries at a time, both sides of each choice computed and the lane's kept) against
// dissipate one entry at a time (the other targets): two rumpled 24×24 sheets 3–9 mm apart,
// sliding over each other at speeds from well under to well over what friction stops within
// the step, approaching and parting, their points' masses spread over a factor of 30 (the
// damping coefficient capped at the lighter, not at the heavier), and two patches pinned in
// both sheets (no mass to dissipate), walked for 8 steps: the forces are the same bit for
// bit on every instruction set. (The physics of dissipate itself is tested by hand above.)
template <class Real>
void expect_dissipation_same_on_every_target() {
  std::vector<Real> first;
  test::for_each_target([&](std::int64_t) {
    SheetDef da;
    da.m = da.n = 23;
    da.width = da.height = 0.24;
    SheetDef db = da;
    db.center = {0.004, -0.003, 0.006};
    db.orientation = quat_from_axis_angle({0, 0, 1}, 0.05);
    Sheet<Real> a = build_sheet<Real>(da), b = build_sheet<Real>(db);
    a.friction = 0.4;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> bump(-0.003, 0.003), speed(-0.03, 0.03), scale(1.0, 30.0);
    for (Real& z : b.position.z) z += Real(bump(rng));
    const std::uint32_t cols = da.n + 1;
    for (Sheet<Real>* s : {&a, &b})
      for (std::uint32_t p = 0; p < s->size(); ++p) {
        s->velocity.x[p] = Real(speed(rng));
        s->velocity.y[p] = Real(speed(rng));
        s->velocity.z[p] = Real(0.5 * speed(rng));
        const std::uint32_t i = p / cols, j = p % cols;
        const bool pinned = (i >= 4 && i < 8 && j >= 4 && j < 8) || (i >= 14 && i < 17 && j >= 15 && j < 19);
        s->inv_mass[p] = pinned ? Real(0) : s->inv_mass[p] * Real(scale(rng));
      }
    ContactParams<Real> prm = ContactParams<Real>::make(0.005, 0.002, 1e-4, 6.0);
    prm.rims = false;
    prm.dt = Real(1e-3);
    prm.damping = Real(5);
    PairContacts<Real> work;
    ContactScratch<Real> scratch;
    std::vector<Real> got;
    for (int step = 0; step < 8; ++step) {
      SheetBoxes<Real> ba, bb;
      build_boxes(a, ba);
      build_boxes(b, bb);
      pair_contacts(a, ba, b, bb, prm, work, scratch);
      for (const ContactForces<Real>* f : {&work.on_a, &work.on_b})
        for (std::size_t e = 0; e < f->size(); ++e) got.insert(got.end(), {Real(f->point[e]), f->fx[e], f->fy[e], f->fz[e]});
      for (std::uint32_t p = 0; p < b.size(); ++p) {  // b moves on by its velocity
        b.position.x[p] += prm.dt * b.velocity.x[p];
        b.position.y[p] += prm.dt * b.velocity.y[p];
        b.position.z[p] += prm.dt * b.velocity.z[p];
      }
    }
    EXPECT_EQ(work.searches, 1u);  // the walk served every later step
    ASSERT_GT(got.size(), 4 * a.size());
    expect_bits_of_first_target(got, first);
  });
}

TEST(Contacts, DampingAndFrictionInLanesGiveTheBitsOfOneEntryAtATime) { expect_dissipation_same_on_every_target<double>(); }
TEST(Contacts, DampingAndFrictionInLanesGiveTheBitsOfOneEntryAtATimeInFloat) {
  expect_dissipation_same_on_every_target<float>();
}

// The same over whole runs of a World, where a different force changes the trajectory:
// a stack of three pinned sheets dropped 8 mm onto each other, and a sheet folded onto
// itself with self-collision, each stepped for 0.3 s (60 ms for the fold) with walked
// contact sets and with WorldDef::contact_exact. Their positions stay within 0.2 of the
// contact thickness h of each other at every frame. The stack bounces: the gap between
// the runs grows from rounding (1e-7 m after a frame) to about 0.1 h by 0.3 s.
template <class Setup>
double largest_position_gap(Setup setup, int frames, int substeps) {
  World walk = setup(false), exact = setup(true);
  double most = 0;
  for (int f = 0; f < frames; ++f) {
    walk.step(substeps);
    exact.step(substeps);
    for (SheetId id : walk.sheets()) {
      const auto x = walk.state(id), y = exact.state(id);
      for (std::size_t p = 0; p < x.x.size(); ++p)
        most = std::max(most, std::hypot(x.x[p] - y.x[p], x.y[p] - y.y[p], x.z[p] - y.z[p]));
    }
  }
  return most;
}

TEST(Contacts, WalkedContactSetsKeepStackAndFoldRunsWithinTheirBoundOfTheExactSearch) {
  auto stack = [](bool exact) {
    return three_layers<World>(WorldDef{.dt = 1e-3, .threads = 1, .contact_exact = exact}, 15);
  };
  const double h = WorldDef{}.contact_thickness;
  const double stack_gap = largest_position_gap(stack, 30, 10);
  EXPECT_LE(stack_gap, 0.2 * h);
  auto fold = [](bool exact) {
    WorldDef wd;
    wd.dt = 2e-4;
    wd.threads = 1;
    wd.contact_exact = exact;
    World world(wd);
    SheetDef sd;
    sd.m = 31;
    sd.n = 15;
    sd.width = 0.25;
    sd.height = 0.5;
    sd.mass = 0.1;
    sd.stiffness = 50;
    sd.damping = 1e-3;
    sd.self_collision = true;
    const SheetId id = world.add_sheet(sd);
    auto s = world.state(id);
    for (std::uint32_t i = 16; i <= sd.m; ++i)
      for (std::uint32_t j = 0; j <= sd.n; ++j) {
        const std::uint32_t p = point_index(sd.n, i, j), mirror = point_index(sd.n, sd.m - i, j);
        s.y[p] = s.y[mirror];
        s.z[p] = 0.012;
      }
    return world;
  };
  const double fold_gap = largest_position_gap(fold, 30, 10);
  EXPECT_LE(fold_gap, 0.2 * h);
}

// The contact memory packs indices and flags two to a word (layout 2) and still reads the
// one-entry-a-word layout 1 of older checkpoints: both, read back, give pairs that write
// the same layout-2 words, and layout 2 is shorter than layout 1 by half of each index or
// flag list (rounded down), counted here from the pairs themselves.
// Six jostled steps of sheets a and b as pair 0 of a world's list; with `travel`, each
// sheet's travel going on as the world's does, so entries beyond R skip.
std::vector<PairContacts<double>> jostled_pair(Sheet<double>& a, Sheet<double>& b, bool travel) {
  std::mt19937 rng(8);
  ContactScratch<double> scratch;
  std::vector<PairContacts<double>> pairs(1);
  pairs[0].a = 0;
  pairs[0].b = 1;
  for (int step = 0; step < 6; ++step) {
    jostle(a, rng);
    jostle(b, rng);
    ContactParams<double> prm = kParams;
    if (travel) {
      advance_travel(a);
      advance_travel(b);
      prm.travel = a.travel + b.travel;
    }
    pair_contacts(a, boxes(a), b, boxes(b), prm, pairs[0], scratch);
  }
  return pairs;
}

TEST(ContactMemory, PackedAndOneEntryAWordLayoutsReadBackTheSamePairs) {
  auto [a, b] = close_sheets(7);
  const std::vector<PairContacts<double>> pairs = jostled_pair(a, b, false);
  const PairContacts<double>& p = pairs[0];
  ASSERT_FALSE(p.a_on_b.point.empty());
  const std::array<const Sheet<double>*, 2> sheets{&a, &b};
  const auto packed = write_contact_memory<double>(pairs, sheets, 2);
  const auto loose = write_contact_memory<double>(pairs, sheets, 1);
  std::size_t halved = 0;
  for (const auto* list : {&p.a_near_b.begin, &p.a_near_b.count, &p.a_near_b.cell, &p.b_near_a.begin,
                           &p.b_near_a.count, &p.b_near_a.cell, &p.a_on_b.point, &p.a_on_b.cell,
                           &p.a_on_b.block_begin, &p.b_on_a.point, &p.b_on_a.cell, &p.b_on_a.block_begin,
                           &p.last_a, &p.last_b})
    halved += list->size() / 2;
  halved += p.a_on_b.open.size() / 2 + p.b_on_a.open.size() / 2;
  EXPECT_EQ(loose.size() - packed.size(), halved);

  std::vector<SheetTravel<double>> travel;
  for (const auto* words : {&packed, &loose}) {
    std::vector<PairContacts<double>> read;
    read_contact_memory<double>(*words, sheets, read, travel);
    EXPECT_EQ(write_contact_memory<double>(read, sheets, 2), packed);
    EXPECT_TRUE(travel.empty());  // layouts before 3 hold none
  }

  // A packed flag that is neither 0 nor 1, or bits after a list's last entry, are refused.
  ASSERT_EQ(p.a_on_b.open.size() % 2, 1u) << "the test wants an odd number of blocks";
  std::vector<PairContacts<double>> marked = pairs;
  marked[0].a_on_b.open.back() = 0xAB;  // written as it is, so it can be found
  const auto bad_flag = write_contact_memory<double>(marked, sheets, 2);
  std::vector<PairContacts<double>> untouched = pairs;
  EXPECT_THROW(read_contact_memory<double>(bad_flag, sheets, untouched, travel), std::invalid_argument);
  std::size_t at = 0;
  while (at < bad_flag.size() && bad_flag[at] != 0xAB) ++at;
  ASSERT_LT(at, bad_flag.size());
  auto past_end = packed;
  ASSERT_EQ(past_end[at] >> 32, 0u);
  past_end[at] |= std::uint64_t(1) << 32;
  EXPECT_THROW(read_contact_memory<double>(past_end, sheets, untouched, travel), std::invalid_argument);
  EXPECT_EQ(write_contact_memory<double>(untouched, sheets, 2), packed);  // left as it was
}

// Layout 3, the one written by default, adds each kept set's skips (KeptContacts::until)
// and every sheet's travel: read back, they are the pair's and the sheets' own, and the
// words written again are the same; the same words cut short are refused, leaving the
// pairs and travel as they were.
TEST(ContactMemory, LayoutFourCarriesTheSkipsEverySheetsTravelAndWhenEachPairWasPresent) {
  auto [a, b] = close_sheets(7);
  for (double& z : b.position.z) z += 0.012;  // most points beyond R: their entries skip
  std::vector<PairContacts<double>> pairs = jostled_pair(a, b, true);
  pairs[0].present_at = 5;
  const PairContacts<double>& p = pairs[0];
  ASSERT_GT(a.travel, 0.0);
  const auto skips = std::count_if(p.a_on_b.until.begin(), p.a_on_b.until.end(),
                                   [&](double u) { return u > a.travel + b.travel; });
  ASSERT_GT(skips, 0);
  const std::array<const Sheet<double>*, 2> sheets{&a, &b};
  const auto words = write_contact_memory<double>(pairs, sheets);
  ASSERT_EQ(words.front(), 4u);
  std::vector<PairContacts<double>> read;
  std::vector<SheetTravel<double>> travel;
  read_contact_memory<double>(words, sheets, read, travel);
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].present_at, 5u);
  EXPECT_EQ(read[0].a_on_b.until, p.a_on_b.until);
  EXPECT_EQ(read[0].b_on_a.until, p.b_on_a.until);
  ASSERT_EQ(travel.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const Sheet<double>& s = k == 0 ? a : b;
    EXPECT_EQ(travel[k].travel, s.travel);
    EXPECT_EQ(travel[k].from.x, s.travel_from.x);
    EXPECT_EQ(travel[k].from.y, s.travel_from.y);
    EXPECT_EQ(travel[k].from.z, s.travel_from.z);
  }
  EXPECT_EQ(write_contact_memory<double>(read, sheets), words);
  auto cut = words;
  cut.pop_back();
  std::vector<PairContacts<double>> untouched = pairs;
  std::vector<SheetTravel<double>> kept_travel = travel;
  EXPECT_THROW(read_contact_memory<double>(cut, sheets, untouched, kept_travel), std::invalid_argument);
  EXPECT_EQ(write_contact_memory<double>(untouched, sheets), words);
  EXPECT_EQ(kept_travel.size(), 2u);
  // Layout 3 has no substep a pair was last present: its pairs read as present at the one given.
  const auto three = write_contact_memory<double>(pairs, sheets, 3);
  EXPECT_EQ(three.size() + 1, words.size());
  read_contact_memory<double>(three, sheets, read, travel, 9);
  EXPECT_EQ(read[0].present_at, 9u);
  EXPECT_EQ(read[0].a_on_b.until, p.a_on_b.until);
}

// In float, lists of positions pack two to a word as well: a WorldF stack in contact takes
// back the memory it wrote (the same words again), and a twin that forgot its memory and
// took those words instead runs on bit for bit with it, where one that forgot it (searches
// afresh) ends elsewhere; the same words cut short are refused.
TEST(ContactMemory, FloatWorldTakesItsPackedMemoryBackAndRunsOnBitForBit) {
  const auto stack = [] { return three_layers<WorldF>(WorldDef{.dt = 1e-3, .threads = 1}, 12); };
  WorldF world = stack(), twin = stack(), forgot = stack();
  world.step(50);
  twin.step(50);
  forgot.step(50);
  forgot.set_contact_memory({});
  const std::vector<std::uint64_t> words = world.contact_memory();
  ASSERT_GT(words.size(), 8u);
  world.set_contact_memory(words);
  EXPECT_EQ(world.contact_memory(), words);
  twin.set_contact_memory({});
  twin.set_contact_memory(words);
  auto cut = words;
  cut.pop_back();
  EXPECT_THROW(twin.set_contact_memory(cut), std::invalid_argument);
  world.step(250);
  twin.step(250);
  forgot.step(250);
  const auto same = [&](const WorldF& other) {
    for (SheetId id : world.sheets()) {
      const auto a = world.view(id), b = other.view(id);
      for (std::size_t p = 0; p < a.x.size(); ++p)
        if (!(a.x[p] == b.x[p] && a.y[p] == b.y[p] && a.z[p] == b.z[p])) return false;
    }
    return true;
  };
  EXPECT_TRUE(same(twin));
  EXPECT_FALSE(same(forgot));  // the memory is what makes them equal
}

}  // namespace
}  // namespace drape::detail
