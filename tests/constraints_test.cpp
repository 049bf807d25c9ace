// Constraints (paper §5.2): point-to-point joins, paths, frames, rails and moving rigid
// parts, each checked against an answer found without the engine: a Newton solve of the
// joined sheets' potential energy, statics of a welded seam, the driven oscillator a dragged
// point obeys, and the motion of the centre of mass of a sheet sliding on a rail.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "newton_equilibrium.h"

namespace drape {
namespace {

constexpr double pi = std::numbers::pi;

// ---- Two sheets joined point-to-point, hanging: the static equilibrium by Newton ----------

using testing::newton_equilibrium;
using testing::Spring;

// A hammock of two square sheets side by side, 2 cm apart, joined along their facing edges
// by point-to-point springs of rest length 2 cm; each sheet pinned at its two outer corners.
struct Hammock {
  static constexpr std::uint32_t m = 4, n = 4;
  static constexpr double side = 0.4, gap = 0.02, mass = 0.05, k = 20, seam_k = 50, g = 9.81;
  SheetDef sheet(int which) const {
    SheetDef d;
    d.m = m;
    d.n = n;
    d.width = d.height = side;
    d.mass = mass;
    d.stiffness = k;
    const double cx = (side + gap) / 2;
    d.center = {which == 0 ? -cx : cx, 0, 0};
    const std::uint32_t outer = which == 0 ? 0 : n;
    d.pins = {point_index(n, 0, outer), point_index(n, m, outer)};
    d.damping = 2.0 * mass / point_count(m, n);  // settles as e^(−2t)
    return d;
  }
  ConstraintDef seam(SheetId a, SheetId b) const {
    ConstraintDef c;
    c.kind = ConstraintKind::PointToPoint;
    c.stiffness = seam_k;
    c.rest_length = gap;
    c.sheet = a;
    c.other_sheet = b;
    c.points = column_points(m, n, n);        // a's right edge
    c.other_points = column_points(m, n, 0);  // b's left edge
    return c;
  }
};

// The hammock's equilibrium, points of sheet 0 then sheet 1.
std::vector<double> hammock_equilibrium(const Hammock& h) {
  const std::uint32_t cols = h.n + 1, per = point_count(h.m, h.n);
  std::vector<Spring> springs;
  std::vector<bool> fixed(2 * per, false);
  Eigen::VectorXd x(6 * per);
  const double spacing = h.side / h.n;
  for (std::uint32_t s = 0; s < 2; ++s) {
    const double cx = (s == 0 ? -1 : 1) * (h.side + h.gap) / 2;
    for (std::uint32_t i = 0; i <= h.m; ++i)
      for (std::uint32_t j = 0; j <= h.n; ++j) {
        const std::uint32_t p = s * per + i * cols + j;
        const double px = cx - h.side / 2 + j * spacing, py = -h.side / 2 + i * spacing;
        // a sagging start, so every spring is stretched and the Hessian is definite
        const double u = (px + h.side + h.gap / 2) / (2 * h.side + h.gap);
        x.segment<3>(3 * p) << px, py, -0.1 * std::sin(pi * u) - 0.01 * std::sin(pi * i / h.m);
        if (j < h.n) springs.push_back({p, p + 1, h.k, spacing});
        if (i < h.m) springs.push_back({p, p + cols, h.k, spacing});
      }
    const std::uint32_t outer = s == 0 ? 0 : h.n;
    for (std::uint32_t i : {0u, h.m}) {
      const std::uint32_t p = s * per + i * cols + outer;
      fixed[p] = true;
      x[3 * p + 2] = 0;
    }
  }
  for (std::uint32_t i = 0; i <= h.m; ++i) springs.push_back({i * cols + h.n, per + i * cols, h.seam_k, h.gap});
  const std::vector<double> mass(2 * per, h.mass / per);
  const Eigen::VectorXd eq = newton_equilibrium(x, springs, mass, fixed, h.g);
  return {eq.data(), eq.data() + eq.size()};
}

void expect_hammock_at_rest_at_equilibrium(Integrator integrator, double dt_fraction, double seconds) {
  const Hammock h;
  WorldDef wd;
  wd.gravity = {0, 0, -h.g};
  wd.integrator = integrator;
  World w(wd);
  const SheetId a = w.add_sheet(h.sheet(0)), b = w.add_sheet(h.sheet(1));
  w.add_constraint(h.seam(a, b));
  w.set_dt(dt_fraction * w.stable_step_estimate());
  ASSERT_TRUE(w.step(int(seconds / w.def().dt)).ok());
  const std::vector<double> eq = hammock_equilibrium(h);
  const std::uint32_t per = point_count(h.m, h.n);
  double sag = 0;
  for (std::size_t p = 0; p < 2 * per; ++p) sag = std::max(sag, -eq[3 * p + 2]);
  ASSERT_GT(sag, 0.02);
  EXPECT_LT(w.energies().kinetic, 1e-8 * 2 * h.mass * h.g * sag);
  for (std::uint32_t s = 0; s < 2; ++s) {
    const auto v = w.view(s == 0 ? a : b);
    for (std::uint32_t p = 0; p < per; ++p) {
      const double* e = &eq[3 * (s * per + p)];
      EXPECT_NEAR(v.x[p], e[0], 0.005 * sag) << integrator_name(integrator) << " sheet " << s << " point " << p;
      EXPECT_NEAR(v.y[p], e[1], 0.005 * sag) << integrator_name(integrator) << " sheet " << s << " point " << p;
      EXPECT_NEAR(v.z[p], e[2], 0.005 * sag) << integrator_name(integrator) << " sheet " << s << " point " << p;
    }
  }
}

TEST(Constraints, SheetsJoinedPointToPointHangAtTheNewtonEquilibrium) {
  expect_hammock_at_rest_at_equilibrium(Integrator::SemiImplicitEuler, 0.5, 10.0);
}

// Implicit Euler solves with the joins' anchors in its Jacobian (the far end held for the
// substep): it comes to the same rest at steps past the explicit limit (more slowly: its
// numerical damping holds back the slowest mode, hence the longer run).
TEST(Constraints, ImplicitEulerHangsJoinedSheetsAtTheSameEquilibrium) {
  expect_hammock_at_rest_at_equilibrium(Integrator::ImplicitEuler, 3.0, 24.0);
}

// ---- A welded seam: statics and a bound on how far it opens -------------------------------

// Two vertical panels, the upper pinned along its top edge, the lower welded (rest length 0)
// along its top edge to the upper's bottom edge, released from rest unstressed. The seam's
// springs carry the lower panel: at rest their forces sum to its weight exactly (statics),
// and while it drops no seam spring opens beyond 2·M·g/k, the whole lower panel's weight on
// one spring, doubled for a load applied at once.
TEST(Constraints, WeldedSeamCarriesTheLowerPanelAndNeverOpensBeyondItsBound) {
  constexpr std::uint32_t m = 6, n = 6;
  constexpr double side = 0.3, lower_mass = 0.05, weld_k = 2000, g = 9.81;
  WorldDef wd;
  wd.gravity = {0, 0, -g};
  wd.dt = 2e-4;
  wd.contact_strength = 0;  // welded points coincide: contacts would push the seam apart
  World w(wd);
  SheetDef d;
  d.m = m;
  d.n = n;
  d.width = d.height = side;
  d.stiffness = 200;
  d.mass = 0.05;
  d.orientation = quat_from_axis_angle({1, 0, 0}, pi / 2);  // rows go up along z
  d.center = {0, 0, side / 2};
  d.pins = row_points(m, n, m);
  d.damping = 5.0 * d.mass / point_count(m, n);  // settles as e^(−5t)
  const SheetId upper = w.add_sheet(d);
  d.pins.clear();
  d.mass = lower_mass;
  d.center = {0, 0, -side / 2};
  const SheetId lower = w.add_sheet(d);
  ConstraintDef weld;
  weld.kind = ConstraintKind::PointToPoint;
  weld.stiffness = weld_k;
  weld.sheet = lower;
  weld.other_sheet = upper;
  weld.points = row_points(m, n, m);        // the lower panel's top edge
  weld.other_points = row_points(m, n, 0);  // the upper panel's bottom edge
  w.add_constraint(weld);

  const double bound = 2 * lower_mass * g / weld_k;
  double widest = 0;
  auto seam = [&](double& fz) {
    const auto lo = w.view(lower), up = w.view(upper);
    fz = 0;
    for (std::uint32_t j = 0; j <= n; ++j) {
      const std::uint32_t a = point_index(n, m, j), b = point_index(n, 0, j);
      const double dx = up.x[b] - lo.x[a], dy = up.y[b] - lo.y[a], dz = up.z[b] - lo.z[a];
      widest = std::max(widest, std::sqrt(dx * dx + dy * dy + dz * dz));
      fz += weld_k * dz;
    }
  };
  double fz = 0;
  for (int frame = 0; frame < 400; ++frame) {
    ASSERT_TRUE(w.step(50).ok());
    seam(fz);
  }
  EXPECT_GT(widest, 0.1 * bound);  // the seam did carry the load
  EXPECT_LT(widest, bound) << "the seam opened " << widest << " m";
  EXPECT_NEAR(fz, lower_mass * g, 1e-3 * lower_mass * g) << "at rest the seam carries the lower panel's weight";
}

// ---- A sheet dragged around a circle -------------------------------------------------------

// Every point of a small sheet follows a circle of radius r at angular speed ω (a path
// constraint of stiffness k). The sheet moves rigidly, its springs unstressed, so each point
// is a driven oscillator: e = x − target obeys ë + Ω²e = −T̈ + g with Ω² = k/m, starting at
// e = 0, ė = −ωr. Hence |e| ≤ 2(ω²r/(Ω² − ω²) + g/Ω²) + ωr/Ω, plus ωr·dt because the
// engine takes the target at the start of each substep.
TEST(Constraints, PointsDraggedAlongACircleStayWithinTheDrivenOscillatorBound) {
  constexpr double r = 0.1, period = 1.0, k = 5.0, g = 9.81, dt = 1e-3;
  WorldDef wd;
  wd.dt = dt;
  wd.gravity = {0, 0, -g};
  World w(wd);
  SheetDef d;
  d.m = d.n = 4;
  d.width = d.height = 0.2;
  d.mass = 0.02;
  d.stiffness = 50;
  const SheetId id = w.add_sheet(d);
  const Vec3 start = {-0.1, -0.1, 0};  // the corner point 0
  ConstraintDef drag;
  drag.kind = ConstraintKind::Path;
  drag.stiffness = k;
  drag.sheet = id;
  for (std::uint32_t p = 0; p < point_count(d.m, d.n); ++p) drag.points.push_back(p);
  drag.motion.kind = Motion::Kind::Circle;
  drag.motion.circle = {{-0.1 - r, -0.1, 0}, {0, 0, 1}, start, period};
  drag.motion.pivot = start;
  w.add_constraint(drag);

  const double pm = d.mass / point_count(d.m, d.n), omega = 2 * pi / period, big = std::sqrt(k / pm);
  const double bound = 2 * (omega * omega * r / (big * big - omega * omega) + g / (big * big)) + omega * r / big +
                       omega * r * dt;
  double worst = 0;
  for (int step = 1; step <= 3000; ++step) {
    w.step();
    const double t = step * dt;
    // the corner's target, by hand: on the circle of radius r about (−0.1 − r, −0.1), at angle ωt
    const double tx = -0.1 - r + r * std::cos(omega * t), ty = -0.1 + r * std::sin(omega * t);
    const auto v = w.view(id);
    worst = std::max(worst, std::hypot(v.x[0] - tx, v.y[0] - ty, v.z[0]));
  }
  EXPECT_GT(worst, 0.2 * bound);
  EXPECT_LT(worst, bound) << "worst distance from the target " << worst << " m";
}

// ---- A sheet sliding on a rail -------------------------------------------------------------

// A sheet hangs by one corner from a straight rail inclined at θ. The rail's force is
// perpendicular to it and the springs' forces cancel in the sum, so the sheet's centre of
// mass accelerates along the rail at exactly g·sin θ, whatever the sheet does; and the corner
// stays within 6·M·g/k of the rail (a pendulum released from horizontal pulls at most 3Mg,
// doubled for a load that comes at once).
TEST(Constraints, RailKeepsItsPointAndTheSheetSlidesAtGSinTheta) {
  constexpr double theta = pi / 6, g = 9.81, dt = 1e-3, k = 2000, mass = 0.03;
  WorldDef wd;
  wd.dt = dt;
  wd.gravity = {0, 0, -g};
  World w(wd);
  const Vec3 down{std::cos(theta), 0, -std::sin(theta)};  // along the rail, downhill
  SheetDef d;
  d.m = d.n = 3;
  d.width = d.height = 0.06;
  d.mass = mass;
  d.stiffness = 20;
  d.center = {0.1 * down.x + 0.03, 0.03, 0.1 * down.z};  // corner 0 on the rail, 10 cm down it
  const SheetId id = w.add_sheet(d);
  ConstraintDef rail;
  rail.kind = ConstraintKind::Rail;
  rail.stiffness = k;
  rail.sheet = id;
  rail.points = {0};
  rail.rail = {{-0.5 * down.x, 0, -0.5 * down.z}, {0, 0, 0}, {5 * down.x, 0, 5 * down.z}};
  w.add_constraint(rail);

  auto along_com = [&](double& position, double& velocity) {
    const auto v = w.view(id);
    position = velocity = 0;
    for (std::size_t p = 0; p < v.size(); ++p) {
      position += (v.x[p] * down.x + v.z[p] * down.z) / double(v.size());
      velocity += (v.vx[p] * down.x + v.vz[p] * down.z) / double(v.size());
    }
  };
  double s0, v0;
  along_com(s0, v0);
  const double a = g * std::sin(theta), bound = 6 * mass * g / k;
  double farthest = 0;
  constexpr int steps = 1000;
  for (int step = 1; step <= steps; ++step) {
    w.step();
    const auto v = w.view(id);
    // distance of the corner from the rail's line through the origin
    const double along = v.x[0] * down.x + v.z[0] * down.z;
    farthest = std::max(farthest, std::hypot(v.x[0] - along * down.x, v.y[0], v.z[0] - along * down.z));
  }
  double s, vel;
  along_com(s, vel);
  const double t = steps * dt;
  EXPECT_NEAR(vel, a * t, 1e-9 * a * t);
  EXPECT_NEAR(s - s0, 0.5 * a * t * t, 2.0 / steps * 0.5 * a * t * t);  // O(dt) of semi-implicit Euler
  EXPECT_GT(farthest, 0.05 * bound);
  EXPECT_LT(farthest, bound) << "the corner left the rail by " << farthest << " m";
}

// ---- Conservation, frames, moving rigid parts ----------------------------------------------

// Joins exert equal and opposite forces: two free sheets joined by springs of non-zero rest
// length, thrown at each other without gravity, keep their total momentum.
TEST(Constraints, PointToPointJoinsConserveMomentum) {
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.dt = 5e-4;
  World w(wd);
  SheetDef d;
  d.m = d.n = 5;
  d.width = d.height = 0.2;
  d.mass = 0.04;
  d.initial_velocity = {0.3, 0.1, -0.2};
  const SheetId a = w.add_sheet(d);
  d.center = {0.3, 0.05, 0.1};
  d.mass = 0.07;
  d.initial_velocity = {-0.2, 0, 0.4};
  const SheetId b = w.add_sheet(d);
  ConstraintDef join;
  join.kind = ConstraintKind::PointToPoint;
  join.stiffness = 300;
  join.rest_length = 0.1;
  join.sheet = a;
  join.other_sheet = b;
  join.points = {5, 35, 20};
  join.other_points = {0, 30, 0};
  w.add_constraint(join);
  auto momentum = [&] {
    std::array<double, 3> p{0, 0, 0};
    for (auto [id, mass] : {std::pair{a, 0.04}, std::pair{b, 0.07}}) {
      const auto v = w.view(id);
      for (std::size_t i = 0; i < v.size(); ++i) {
        p[0] += mass / double(v.size()) * v.vx[i];
        p[1] += mass / double(v.size()) * v.vy[i];
        p[2] += mass / double(v.size()) * v.vz[i];
      }
    }
    return p;
  };
  const auto before = momentum();
  w.step(2000);
  const auto after = momentum();
  const auto bv = w.view(b);
  EXPECT_GT(std::abs(bv.vx[0] + 0.2), 0.01);  // the join did act
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(after[c], before[c], 1e-13) << "axis " << c;
}

// The energy of a join is its spring's, ½k(|d| − ℓ)², counted once though it acts at both
// ends; computed here from the positions, by hand.
TEST(Constraints, AJoinsEnergyIsItsSpringCountedOnce) {
  World w;
  SheetDef d;
  d.m = d.n = 2;
  d.width = d.height = 0.2;
  const SheetId a = w.add_sheet(d);
  d.center = {0.3, 0.1, 0.05};
  const SheetId b = w.add_sheet(d);
  const double before = w.energies().anchor;
  ConstraintDef join;
  join.stiffness = 250;
  join.rest_length = 0.07;
  join.sheet = a;
  join.other_sheet = b;
  join.points = {2, 8};
  join.other_points = {0, 6};
  w.add_constraint(join);
  const auto va = w.view(a), vb = w.view(b);
  double expected = 0;
  for (std::size_t k = 0; k < 2; ++k) {
    const auto p = join.points[k], q = join.other_points[k];
    const double len = std::hypot(va.x[p] - vb.x[q], va.y[p] - vb.y[q], va.z[p] - vb.z[q]);
    expected += 0.5 * join.stiffness * (len - join.rest_length) * (len - join.rest_length);
  }
  EXPECT_EQ(before, 0.0);
  EXPECT_NEAR(w.energies().anchor, expected, 1e-12 * expected);
}

// A path does work on the sheet it drags: the guard does not take the energy it pumps in for
// a blow-up, but still halts a state that is not finite.
TEST(Constraints, GuardLetsADrivenSheetGainEnergyButNotGoNonFinite) {
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  World w(wd);
  SheetDef d;
  d.m = d.n = 3;
  d.mass = 0.01;
  const SheetId id = w.add_sheet(d);
  ConstraintDef whirl;
  whirl.kind = ConstraintKind::Path;
  whirl.stiffness = 50;
  whirl.sheet = id;
  whirl.points = {0, 1, 2, 3};
  whirl.motion.kind = Motion::Kind::Circle;
  whirl.motion.circle = {{0, 0, 0}, {0, 0, 1}, {0.5, 0, 0}, 0.5};
  w.add_constraint(whirl);
  const StabilityReport report = w.step(2000);
  EXPECT_TRUE(report.ok()) << describe(report);
  EXPECT_GT(report.energy_growth, wd.guard_energy_growth) << "the whirl pumped energy in";
  w.state(id).x[5] = std::nan("");
  EXPECT_EQ(w.step(1).status, StabilityStatus::NonFinite);
}

// A frame turns a quarter turn about z over one second and then holds: the sheet's edge it
// carries ends turned by 90° about the pivot, within the sag its own weight gives the springs.
TEST(Constraints, FrameTurnsTheEdgeItCarries) {
  WorldDef wd;
  wd.dt = 5e-4;
  World w(wd);
  SheetDef d;
  d.m = d.n = 4;
  d.width = d.height = 0.4;
  d.mass = 0.02;
  d.damping = 0.002;
  const SheetId id = w.add_sheet(d);
  ConstraintDef frame;
  frame.kind = ConstraintKind::Frame;
  frame.stiffness = 5000;
  frame.sheet = id;
  frame.points = row_points(d.m, d.n, 0);  // the edge y = −0.2
  frame.motion.pivot = {0, 0.3, 0};
  frame.motion.keyframes = {{0, {}, {}}, {1, {0, 0, 0.1}, quat_from_axis_angle({0, 0, 1}, pi / 2)}};
  w.add_constraint(frame);
  ASSERT_TRUE(w.step(6000).ok());
  const auto v = w.view(id);
  // by hand: (x, −0.2) about (0, 0.3) turned by 90° is (0.5, 0.3 + x), lifted by 0.1
  const double sag = 3 * d.mass * 9.81 / frame.stiffness;
  for (std::uint32_t j = 0; j <= d.n; ++j) {
    const double x0 = -0.2 + 0.1 * j;
    EXPECT_NEAR(v.x[j], 0.5, sag) << "point " << j;
    EXPECT_NEAR(v.y[j], 0.3 + x0, sag) << "point " << j;
    EXPECT_NEAR(v.z[j], 0.1, sag) << "point " << j;
  }
}

// A sphere moved by keyframes carries a sheet's corner (a frame constraint with the sphere
// as carrier) and pushes the sheets it meets from where it is, not from where it started.
TEST(Constraints, MovingObstacleCarriesItsPointsAndRepelsFromWhereItIs) {
  WorldDef wd;
  wd.dt = 5e-4;
  wd.gravity = {0, 0, 0};
  World w(wd);
  ObstacleDef ball;
  ball.shape = ObstacleShape::Sphere;
  ball.size = {0.1, 0, 0};
  ball.c = 0.01;
  ball.xi = 0.005;
  ball.full_gradient = true;
  Motion move;
  move.keyframes = {{0, {}, {}}, {1, {1, 0, 0}, {}}};
  ball.motion = move;
  const ObstacleId obstacle = w.add_obstacle(ball);
  SheetDef d;
  d.m = d.n = 2;
  d.width = d.height = 0.04;
  d.center = {0.0, 0, 0.14};  // just over the ball, corner 0 to be carried
  const SheetId rider = w.add_sheet(d);
  d.center = {0.6, 0, 0};  // in the ball's way, at its centre height
  const SheetId hit = w.add_sheet(d);
  ConstraintDef carry;
  carry.kind = ConstraintKind::Frame;
  carry.stiffness = 1000;
  carry.sheet = rider;
  carry.points = {0};
  carry.carrier = obstacle;
  w.add_constraint(carry);
  w.step(1000);  // t = 0.5 s: the ball at x = 0.5
  EXPECT_EQ(w.obstacle(obstacle).center.x, 0.0);  // the definition is the caller's
  EXPECT_NEAR(w.view(rider).x[0], 0.5 - 0.02, 0.01);
  EXPECT_GT(w.view(hit).vx[0], 0.0) << "the ball, now 10 cm from the sheet, pushes it";
}

// ---- Motions by hand -----------------------------------------------------------------------

TEST(Motions, KeyframesInterpolateLinearlyAndSlerpAboutThePivot) {
  Motion m;
  m.pivot = {1, 0, 0};
  m.keyframes = {{0, {0, 0, 0}, {}}, {2, {0, 0, 4}, quat_from_axis_angle({0, 0, 1}, pi)}};
  const Pose half = pose_at(m, 1);
  // a quarter turn about z through (1, 0, 0), lifted by 2: the origin goes to (1, −1, 2)
  const Vec3 o = apply(half, {0, 0, 0});
  EXPECT_NEAR(o.x, 1, 1e-12);
  EXPECT_NEAR(o.y, -1, 1e-12);
  EXPECT_NEAR(o.z, 2, 1e-12);
  const Vec3 before = apply(pose_at(m, -1), {3, 0, 0}), after = apply(pose_at(m, 9), {3, 0, 0});
  EXPECT_NEAR(before.x, 3, 1e-12);  // held at the first knot
  EXPECT_NEAR(after.x, -1, 1e-12);  // held at the last: half a turn about x = 1
  EXPECT_NEAR(after.z, 4, 1e-12);
  m.repeat = true;
  const Vec3 again = apply(pose_at(m, 3), {0, 0, 0});
  EXPECT_NEAR(again.x, o.x, 1e-12);
  EXPECT_NEAR(again.y, o.y, 1e-12);
  EXPECT_NEAR(again.z, o.z, 1e-12);
}

TEST(Motions, ComposeAppliesInnerThenOuterAndInverseUndoes) {
  const Pose a{quat_from_axis_angle({0, 0, 1}, pi / 2), {1, 0, 0}}, b{quat_from_axis_angle({1, 0, 0}, pi / 2), {0, 2, 0}};
  // by hand: b takes (0, 1, 0) to (0, 0, 1) + (0, 2, 0) = (0, 2, 1); a turns that to (−2, 0, 1), + (1, 0, 0)
  const Vec3 p = apply(compose(a, b), {0, 1, 0});
  EXPECT_NEAR(p.x, -1, 1e-12);
  EXPECT_NEAR(p.y, 0, 1e-12);
  EXPECT_NEAR(p.z, 1, 1e-12);
  const Vec3 back = apply(inverse(compose(a, b)), p);
  EXPECT_NEAR(back.x, 0, 1e-12);
  EXPECT_NEAR(back.y, 1, 1e-12);
  EXPECT_NEAR(back.z, 0, 1e-12);
}

TEST(Motions, CircleCarriesItsStartAroundTheAxis) {
  Motion m;
  m.kind = Motion::Kind::Circle;
  m.circle = {{1, 2, 3}, {0, 0, 2}, {1.5, 2, 7}, 4.0};
  for (double t : {0.0, 0.5, 1.0, 3.3}) {
    const Vec3 p = apply(pose_at(m, t), m.circle.start);
    const double angle = 2 * pi * t / 4.0;
    EXPECT_NEAR(p.x, 1 + 0.5 * std::cos(angle), 1e-12) << t;
    EXPECT_NEAR(p.y, 2 + 0.5 * std::sin(angle), 1e-12) << t;
    EXPECT_NEAR(p.z, 7, 1e-12) << t;
  }
}

// The API's callback drives a path exactly as the motion it returns the poses of.
TEST(Motions, ACallbackDrivesAPathAsTheMotionItComputes) {
  Motion circle;
  circle.kind = Motion::Kind::Circle;
  circle.circle = {{0, 0, 0}, {0, 1, 1}, {0.3, 0, 0}, 0.7};
  Motion callback;
  callback.kind = Motion::Kind::Callback;
  callback.callback = [circle](double t) { return pose_at(circle, t); };
  std::vector<std::vector<double>> states;
  for (const Motion& motion : {circle, callback}) {
    World w;
    SheetDef d;
    d.m = d.n = 3;
    const SheetId id = w.add_sheet(d);
    ConstraintDef drag;
    drag.kind = ConstraintKind::Path;
    drag.sheet = id;
    drag.points = {0, 15};
    drag.motion = motion;
    w.add_constraint(drag);
    w.step(300);
    const auto v = w.view(id);
    states.emplace_back(v.x.begin(), v.x.end());
    states.back().insert(states.back().end(), v.z.begin(), v.z.end());
  }
  EXPECT_EQ(states[0], states[1]);
  EXPECT_NE(states[0][0], -0.5) << "the corner moved";
}

// Constrained sheets step frames in groups (frames.cpp), each group's task on any thread;
// a callback motion is the caller's code, so a world with one steps substep by substep
// and calls it on the stepping thread only. Two sheets far apart, each on a callback path,
// would otherwise be two groups stepping at once on two threads.
TEST(Motions, ACallbackIsCalledOnTheSteppingThreadOnly) {
  WorldDef wd;
  wd.threads = 2;
  wd.group_points = 0;  // groups in a world this small too
  World w(wd);
  const std::thread::id stepping = std::this_thread::get_id();
  std::atomic<int> elsewhere{0}, calls{0};
  Motion callback;
  callback.kind = Motion::Kind::Callback;
  callback.callback = [&](double t) {
    ++calls;
    if (std::this_thread::get_id() != stepping) ++elsewhere;
    Pose pose;
    pose.translation = {0.1 * t, 0, 0};
    return pose;
  };
  for (int k = 0; k < 2; ++k) {
    SheetDef d;
    d.m = d.n = 30;
    d.center = {5.0 * k, 0, 0};
    ConstraintDef drag;
    drag.kind = ConstraintKind::Path;
    drag.sheet = w.add_sheet(d);
    drag.points = {0, 30};
    drag.motion = callback;
    w.add_constraint(drag);
  }
  for (int frame = 0; frame < 20; ++frame) w.step(10);
  EXPECT_GT(calls.load(), 200);
  EXPECT_EQ(elsewhere.load(), 0);
  EXPECT_EQ(w.frame_stats().kept + w.frame_stats().undone, 0u);
}

TEST(Constraints, RowAndColumnPointsAreTheGridsEdgesInOrder) {
  // a 2×3-cell grid: rows of 4 points, point (i, j) at 4i + j
  EXPECT_EQ(row_points(2, 3, 1), (std::vector<std::uint32_t>{4, 5, 6, 7}));
  EXPECT_EQ(column_points(2, 3, 3), (std::vector<std::uint32_t>{3, 7, 11}));
}

// ---- Bad constraints are refused by name ---------------------------------------------------

std::string refusal(World& w, const ConstraintDef& c) {
  try {
    w.add_constraint(c);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(Constraints, BadConstraintsAreRefusedWithTheField) {
  World w;
  SheetDef d;
  d.m = d.n = 2;  // 9 points
  const SheetId a = w.add_sheet(d), b = w.add_sheet(d);
  ConstraintDef join;
  join.sheet = a;
  join.other_sheet = b;
  join.points = {0, 1};
  join.other_points = {0, 1};
  ConstraintDef c = join;
  c.points[1] = 9;
  EXPECT_NE(refusal(w, c).find("points[1] is not a point of the sheet (got 9; it has 9 points)"), std::string::npos)
      << refusal(w, c);
  c = join;
  c.other_sheet = SheetId{7, 0};
  EXPECT_NE(refusal(w, c).find("other_sheet 7 is not a sheet of the world"), std::string::npos) << refusal(w, c);
  c = join;
  c.other_sheet = a;
  c.other_points = {1, 1};
  EXPECT_NE(refusal(w, c).find("other_points[1] is points[1] (1) of the same sheet"), std::string::npos)
      << refusal(w, c);
  c = join;
  c.other_points = {0};
  EXPECT_NE(refusal(w, c).find("other_points must pair with points one to one"), std::string::npos) << refusal(w, c);
  c = join;
  c.stiffness = 0;
  EXPECT_NE(refusal(w, c).find("stiffness must be positive"), std::string::npos) << refusal(w, c);
  c = join;
  c.kind = ConstraintKind::Rail;
  c.rail = {{0, 0, 0}};
  EXPECT_NE(refusal(w, c).find("rail must have at least two knots (got 1)"), std::string::npos) << refusal(w, c);
  c.kind = ConstraintKind::Path;
  c.motion.keyframes = {{0, {}, {}}};
  EXPECT_NE(refusal(w, c).find("motion.keyframes must have at least two knots (got 1)"), std::string::npos)
      << refusal(w, c);
  c.motion.keyframes = {{0, {}, {}}, {0, {}, {}}};
  EXPECT_NE(refusal(w, c).find("motion.keyframes[1].time must be later"), std::string::npos) << refusal(w, c);
  c.kind = ConstraintKind::Frame;
  c.carrier = ObstacleId{3, 0};
  EXPECT_NE(refusal(w, c).find("carrier 3 is not an obstacle of the world"), std::string::npos) << refusal(w, c);
  c = join;
  w.remove_sheet(b);
  EXPECT_NE(refusal(w, c).find("other_sheet 1 is not a sheet of the world"), std::string::npos) << refusal(w, c);
  EXPECT_EQ(w.constraint_count(), 0u);
}

TEST(Constraints, RemovingASheetRemovesItsConstraintsAndAnchors) {
  World w;
  SheetDef d;
  d.m = d.n = 2;
  d.anchors = anchors_at(std::vector<std::uint32_t>{4}, 10.0);
  const SheetId a = w.add_sheet(d), b = w.add_sheet(d);
  ConstraintDef join;
  join.sheet = a;
  join.other_sheet = b;
  join.points = {0};
  join.other_points = {0};
  const ConstraintId id = w.add_constraint(join);
  EXPECT_TRUE(w.contains(id));
  w.remove_sheet(b);
  EXPECT_FALSE(w.contains(id));
  EXPECT_EQ(w.constraint_count(), 0u);
  // sheet a is back to its own anchor: nothing pulls its point 0
  w.step(10);
  EXPECT_EQ(w.view(a).vx[0], 0.0);
}

// ---- Handles -------------------------------------------------------------------------------

// A motion callback that throws while the obstacle is being added leaves no trace: no
// obstacle, and the next one takes the first slot (a leaked slot would push it to the
// second). A removed obstacle's handle goes stale and its slot is reused with a new
// generation, so the old handle never reaches the new obstacle.
TEST(Handles, AFailedAddLeavesNoSlotBehindAndStaleHandlesStayStale) {
  World w;
  ObstacleDef bad;
  bad.shape = ObstacleShape::Sphere;
  bad.size = {0.1, 0, 0};
  Motion throws;
  throws.kind = Motion::Kind::Callback;
  throws.callback = [](double) -> Pose { throw std::runtime_error("no pose"); };
  bad.motion = throws;
  EXPECT_THROW(w.add_obstacle(bad), std::runtime_error);
  EXPECT_EQ(w.obstacle_count(), 0u);

  ObstacleDef ball = bad;
  ball.motion.reset();
  const ObstacleId first = w.add_obstacle(ball);
  EXPECT_EQ(first.index, 0u);
  w.remove_obstacle(first);
  EXPECT_FALSE(w.contains(first));
  const ObstacleId second = w.add_obstacle(ball);
  EXPECT_EQ(second.index, first.index);
  EXPECT_NE(second.generation, first.generation);
  EXPECT_FALSE(w.contains(first));
  EXPECT_TRUE(w.contains(second));
  EXPECT_THROW(w.remove_obstacle(first), std::invalid_argument);
}

}  // namespace
}  // namespace drape
