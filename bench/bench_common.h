// Scenes and counters shared by the benchmark files. Every figure in docs/BENCHMARKS.md
// is a rate of point-steps per second (points × steps ÷ s), so files stay comparable.
#pragma once

#include <benchmark/benchmark.h>
#include <drape/drape.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "obstacles.h"  // detail::reach_exponent

namespace drape::bench {

// The WorldDef every benchmark starts from. The benchmarks step one substep per
// iteration, but a program runs the stability guard once per step() call (a frame): with it
// on here every substep would pay a frame's guard. It is off, and priced on its own by
// BM_Feature_guard_per_frame.
// Contacts between sheets run the plain repulsion (α = 0, not the default 2 s/m), so that
// the contact figures compare across reports; the damping is priced on its own
// (BM_World48SheetsInContactDissipative).
inline WorldDef world_def(int threads = 0) {
  WorldDef wd;
  wd.threads = threads;
  wd.guard = false;
  wd.contact_damping = 0.0;
  return wd;
}

// The terms a benchmarked sheet carries, to price each one separately.
struct Features {
  bool pins = false;     // four corners hard-pinned (the paper's Figs 5, 7 set-up)
  bool anchors = false;  // four corners held by eq (8) springs instead
  bool damping = false;  // eq (4)'s C
  bool shear = false;    // diagonal springs, k_s = 0.3 k (issue 12)
  bool bending = false;  // quadratic bending, a bending length of 5 cm (issue 12)
  bool air = false;      // pressure and skin friction per cell against the world's wind (issue 12)
};

// A flat side×side-point sheet of cloth, 1 m square, 1 kg, k = 100 N/m: the Fig 13 scene.
inline SheetDef square_sheet(std::uint32_t side, Features f = {true, false, false}, Vec3 center = {}) {
  SheetDef sd;
  sd.m = sd.n = side - 1;
  sd.center = center;
  sd.stiffness = 100.0;
  if (f.pins) sd.pins = corner_points(sd.m, sd.n);
  if (f.anchors) sd.anchors = anchors_at(corner_points(sd.m, sd.n), 1000.0);
  if (f.damping) sd.damping = 1e-3;
  if (f.shear) sd.shear = ShearDef{0.3 * sd.stiffness, std::nullopt};
  if (f.bending) {  // k_b = ρ_A g ℓ³ / h² (docs/scene-format.md), ρ_A = 1 kg/m², ℓ = 5 cm
    const double h = 1.0 / sd.n;
    sd.bending = BendingDef{9.81 * 0.05 * 0.05 * 0.05 / (h * h)};
  }
  if (f.air) sd.air = AirDef{1.2, 0.05};
  return sd;
}

// Half the explicit stability limit, so no run blows up (non-finite or denormal values
// would change the cost being measured).
template <class W>
void set_stable_dt(W& world) {
  world.set_dt(0.5 * world.stable_step_estimate());
}

// `substeps` per iteration: the report divides an iteration's time by it.
inline void set_point_rate(benchmark::State& state, double points_per_step, int substeps = 1) {
  state.counters["points"] = points_per_step;
  state.counters["substeps"] = substeps;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points_per_step * substeps * double(state.iterations()), benchmark::Counter::kIsRate);
}

// Substeps per step() call in the benchmarks that step as a program does: a frame of
// several substeps, so sheets with nothing between their substeps (no contacts, no
// obstacles) run them as waves (docs/architecture.md). About a 30 frame/s frame at the
// default dt of 1 ms.
inline constexpr int frame_substeps = 32;

// Steps `world` a frame per iteration and reports the rate per substep.
template <class W>
void step_frames(benchmark::State& state, W& world, double points) {
  for (auto _ : state) world.step(frame_substeps);
  set_point_rate(state, points, frame_substeps);
}

// Issue 13's stacked sheets: 48 sheets of 64×64 points, 1 m wide, 1 kg, k = 100 N/m, corners
// pinned, in 6 columns 1.5 m apart × 8 layers, dt = 1 ms. One description, so drape's world
// (stack_world) and the same scene in another engine (bench_bullet.cpp) cannot drift apart.
struct Stack {
  static constexpr int columns = 6, layers = 8;
  static constexpr std::uint32_t side = 64;  // points per side
  static constexpr double width = 1.0, column_pitch = 1.5;
  static constexpr double mass = 1.0, stiffness = 100.0, damping = 1e-3, dt = 1e-3;
  static constexpr double contact_gap = 0.01;  // m between layers that touch (stack_world)
  // Sheet k of the world is column k / layers, layer k % layers (bottom first).
  static Vec3 center(int column, int layer, double layer_gap) { return {column_pitch * column, 0.0, layer_gap * layer}; }
};

// The gap over an obstacle's surface (its f, eq 9) where the force holds the weight of a point
// of `sheet`: (c/ξ)·(e^(−h/ξ) − e^(−reach)) = m·g. A sheet set down there rests; nearer,
// eq (9) pushes its points with many times their weight and throws the sheet off (the
// benchmarks' floor 5 mm under sheets at rest threw them metres up, where they spent most
// substeps beyond its reach, at next to no cost).
inline double holding_gap(const SheetDef& sheet, double c, double xi) {
  const double weight = sheet.mass / double(point_count(sheet.m, sheet.n)) * -WorldDef{}.gravity.z;
  return -xi * std::log(weight * xi / c + std::exp(-detail::reach_exponent));
}

// A floor (eq 9, c = 0.01 J, ξ = 0.01 m) under sheets lying flat at z = 0, at their holding
// gap: sheets like `sheet` start there at rest and stay, every point within its reach, so
// eq (9) acts on all of them every substep.
inline ObstacleDef floor_holding(const SheetDef& sheet) {
  ObstacleDef floor;
  floor.shape = ObstacleShape::Plane;
  floor.c = 0.01;
  floor.xi = 0.01;
  floor.center = {0.0, 0.0, -holding_gap(sheet, floor.c, floor.xi)};
  return floor;
}

// How the stack's sheets meet. `exact`: WorldDef::contact_exact, the exact nearest triangle
// every substep instead of the walk (the reference, priced beside it). `friction`
// (SheetDef::friction, on every sheet) and `damping` (WorldDef::contact_damping): the
// dissipative contact terms, priced beside the frictionless, undamped contact of world_def().
// `rims`: WorldDef::contact_rims (the rims' edges against the other sheets' edges; off,
// as WorldDef has it, so every stack benchmark prices what a scene pays by default), priced
// by BM_World48SheetsInContactRims against the points' contacts alone.
struct StackContact {
  bool exact = false;
  double friction = 0.0;
  double damping = 0.0;
  bool rims = false;
};

// The stack in drape. `layer_gap` 2 m keeps the sheets apart (no pair within contact range,
// however far they sag and swing); 0.01 m puts each layer in contact with the next (the
// contact range is 0.017 m by default). `guard`: the stability guard after every step()
// call, for runs long enough to blow up.
inline World stack_world(int threads, double layer_gap, StackContact contact = {}, bool guard = false) {
  WorldDef wd = world_def();
  wd.guard = guard;
  wd.dt = Stack::dt;
  wd.threads = threads;
  wd.contact_exact = contact.exact;
  wd.contact_damping = contact.damping;
  wd.contact_rims = contact.rims;
  World world(wd);
  SheetDef sd;
  sd.m = sd.n = Stack::side - 1;
  sd.width = sd.height = Stack::width;
  sd.mass = Stack::mass;
  sd.stiffness = Stack::stiffness;
  sd.damping = Stack::damping;
  sd.friction = contact.friction;
  sd.pins = corner_points(sd.m, sd.n);
  for (int column = 0; column < Stack::columns; ++column)
    for (int layer = 0; layer < Stack::layers; ++layer) {
      sd.center = Stack::center(column, layer, layer_gap);
      world.add_sheet(sd);
    }
  return world;
}

// Every integrator the engine has, from its table: a new integrator is benchmarked as
// soon as it has a row.
inline std::vector<Integrator> all_integrators() {
  const auto all = drape::integrators();
  return {all.begin(), all.end()};
}

}  // namespace drape::bench
