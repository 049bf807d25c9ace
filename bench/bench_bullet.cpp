// The same Fig 13 scene in an established soft-body engine: Bullet's soft bodies (Debian's
// libbullet-dev, its float64 build), one thread. A side×side patch of nodes joined by
// structural links only, like drape's grid (no diagonals), 1 m square, 1 kg, its four
// corners fixed, gravity, no collisions, at drape's step for the same sheet, stepped a frame
// of frame_substeps fixed substeps per call (stepSimulation with as many internal substeps).
// Bullet solves the links as position constraints (its default: one iteration), drape as
// forces (eq 6): the same scene and step, not the same method. Built only when CMake finds
// Bullet (bench/CMakeLists.txt); tools/bench.sh installs it.
//
// Below it, issue 13's stacked sheets in both engines with contact between sheets on, timed
// in the same run at one thread (Bullet's soft bodies are single-threaded), each with the
// penetration measured the same way (penetration.h).
#include <BulletSoftBody/btDefaultSoftBodySolver.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <vector>

#include "bench_common.h"
#include "penetration.h"

namespace {

// A soft-body world with gravity, as every benchmark here sets it up.
struct BulletWorld {
  static constexpr int corners = 1 + 2 + 4 + 8;  // CreatePatch's flags: fix all four corners
  btSoftBodyRigidBodyCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDefaultSoftBodySolver soft_solver;
  btSoftRigidDynamicsWorld world{&dispatcher, &broadphase, &solver, &config, &soft_solver};
  BulletWorld() {
    const btVector3 gravity(0, 0, -9.81);
    world.setGravity(gravity);
    world.getWorldInfo().m_gravity = gravity;
    world.getWorldInfo().m_sparsesdf.Initialize();
  }
};

// Args: side, step (0: drape's step for this sheet, the Fig 13 rule, half the explicit
// stability limit; else the step in µs). Bullet's cost per substep depends on the step and
// on how the cloth moves (its node and face trees are refitted as nodes move), so every
// run starts from the flat cloth and takes the same 16 frames; it also runs at 1 ms, a
// common step for it. The report prints both.
void BM_BulletCloth(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  drape::World probe(drape::bench::world_def(1));
  probe.add_sheet(drape::bench::square_sheet(side));
  const double dt = state.range(1) == 0 ? 0.5 * probe.stable_step_estimate() : 1e-6 * double(state.range(1));

  BulletWorld bullet;
  btSoftRigidDynamicsWorld& world = bullet.world;
  btSoftBodyWorldInfo& info = world.getWorldInfo();
  std::unique_ptr<btSoftBody> cloth(btSoftBodyHelpers::CreatePatch(
      info, btVector3(-0.5, -0.5, 0), btVector3(0.5, -0.5, 0), btVector3(-0.5, 0.5, 0), btVector3(0.5, 0.5, 0),
      int(side), int(side), BulletWorld::corners, false));
  cloth->setTotalMass(1.0);
  cloth->m_cfg.collisions = 0;
  world.addSoftBody(cloth.get());
  const int frame = drape::bench::frame_substeps;
  for (auto _ : state) world.stepSimulation(frame * dt, frame, dt);
  world.removeSoftBody(cloth.get());
  drape::bench::set_point_rate(state, double(side) * side, frame);
  state.counters["links"] = double(cloth->m_links.size());
  state.counters["dt"] = dt;
}
BENCHMARK(BM_BulletCloth)->ArgsProduct({{16, 32, 64, 128}, {0, 1000}})->Iterations(16);

// Issue 13's stack (bench_common.h's Stack, layers 10 mm apart) stepped from rest in frames
// of 10 substeps, in drape and in Bullet, one thread. A whole second in Bullet takes many
// minutes (one iteration of every repetition), so tools/bench.sh's run takes both engines
// through the first 0.1 s, the start of the fall; DRAPE_BENCH_STACK_SPAN=<seconds> sets
// another span for a run by hand (the counters carry the span). CPU time of the one thread
// that steps (drape's world with threads = 1 works on the caller's thread), so other jobs on
// a shared machine shift both engines' figures alike.
constexpr double stack_default_span = 0.1;  // s
constexpr int stack_frame = 10;             // substeps per step()/stepSimulation call
int stack_frames() {
  double span = stack_default_span;
  if (const char* text = std::getenv("DRAPE_BENCH_STACK_SPAN"); text && *text) span = std::atof(text);
  return std::max(1, int(std::lround(span / (stack_frame * drape::bench::Stack::dt))));
}
constexpr double stack_layer_gap = 0.01;
// Sheets searched around each point by the penetration measure: three layer gaps (its
// cost grows with the cube of it: at 5 cm one measure took as long as 20 of drape's substeps).
constexpr double stack_reach = 0.03;
// Frames between two measurements for the worst penetration over the span (the last frame
// is always measured).
constexpr int stack_measure_every = 5;

struct StackMeasure {
  drape::bench::Penetration end, worst;
  int unmeasured = 0;  // frames whose sheets were torn too far apart to measure
  void take(const std::vector<drape::bench::MeasuredSheet>& sheets, bool last) {
    const auto now = drape::bench::measure_penetration(sheets, drape::bench::Stack::side, stack_reach);
    if (last) end = now;
    if (!now.measured) {
      ++unmeasured;
      return;
    }
    worst.crossed = std::max(worst.crossed, now.crossed);
    worst.max_depth = std::max(worst.max_depth, now.max_depth);
    worst.min_gap = std::min(worst.min_gap, now.min_gap);
  }
  void report(benchmark::State& state) const {
    const double nan = std::numeric_limits<double>::quiet_NaN();  // the last frame could not be measured
    state.counters["crossed_points"] = end.measured ? double(end.crossed) : nan;
    state.counters["max_depth_m"] = end.measured ? end.max_depth : nan;
    state.counters["min_gap_m"] = end.measured ? end.min_gap : nan;
    state.counters["unmeasured_frames"] = unmeasured;
    state.counters["worst_crossed_points"] = double(worst.crossed);
    state.counters["worst_depth_m"] = worst.max_depth;
    state.counters["worst_min_gap_m"] = worst.min_gap;
    state.counters["reach_m"] = stack_reach;
    state.counters["measured_every_s"] = stack_measure_every * stack_frame * drape::bench::Stack::dt;
  }
};

// One iteration's timed loop, shared by both engines: `step` advances a frame, `points`
// reads every sheet's points for the measure (outside the timed region).
template <class Step, class Points>
StackMeasure run_stack(benchmark::State& state, Step&& step, Points&& points) {
  StackMeasure measure;
  const int frames = stack_frames();
  for (int frame = 1; frame <= frames; ++frame) {
    step();
    if (frame % stack_measure_every == 0 || frame == frames) {
      state.PauseTiming();
      measure.take(points(), frame == frames);
      state.ResumeTiming();
    }
  }
  return measure;
}

// The counters of both engines' runs, after the loop (rates need the iteration count).
void report_stack(benchmark::State& state, const StackMeasure& measure) {
  using drape::bench::Stack;
  measure.report(state);
  const double substeps = double(stack_frames()) * stack_frame, simulated = substeps * Stack::dt;
  const double iterations = double(state.iterations());
  state.counters["simulated_s"] = simulated;
  state.counters["simulated_s_per_s"] = benchmark::Counter(simulated * iterations, benchmark::Counter::kIsRate);
  state.counters["s_per_simulated_s"] =
      benchmark::Counter(simulated * iterations, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  drape::bench::set_point_rate(state, double(Stack::columns * Stack::layers) * Stack::side * Stack::side,
                               int(substeps));
}

void BM_StackContact_drape(benchmark::State& state) {
  using drape::bench::Stack;
  StackMeasure measure;
  for (auto _ : state) {
    state.PauseTiming();
    auto world_ptr = std::make_unique<drape::World>(drape::bench::stack_world(1, stack_layer_gap));
    drape::World& world = *world_ptr;
    state.ResumeTiming();
    measure = run_stack(
        state, [&] { world.step(stack_frame); },
        [&] {
          std::vector<drape::bench::MeasuredSheet> sheets;
          int k = 0;
          for (drape::SheetId id : world.sheets()) {
            const auto v = world.view(id);
            drape::bench::MeasuredSheet s{k / Stack::layers, k % Stack::layers, std::vector<drape::Vec3>(v.size())};
            for (std::size_t p = 0; p < v.size(); ++p) s.points[p] = {v.x[p], v.y[p], v.z[p]};
            sheets.push_back(std::move(s));
            ++k;
          }
          return sheets;
        });
    state.PauseTiming();
    if (!world.all_finite()) state.SkipWithError("the stack became non-finite");
    world_ptr.reset();
    state.ResumeTiming();
  }
  report_stack(state, measure);
  state.counters["contact_thickness_m"] = drape::WorldDef{}.contact_thickness;
}
BENCHMARK(BM_StackContact_drape)->Iterations(1)->Unit(benchmark::kMillisecond);

// The same stack in Bullet: each sheet a patch of 64×64 nodes joined by structural links
// (no diagonals), faces two triangles per cell, its four corners fixed, 1 kg. Cloth against
// cloth in Bullet's btSoftRigidDynamicsWorld is fCollision::VF_SS, its nodes against the
// other body's faces (CL_SS collides clusters, convex hulls of groups of nodes made for
// volumes, which a flat sheet does not have; VF_DD belongs to the deformable multibody
// world's solver). Contacts are made where a node is within the two bodies' margins of a
// face; each margin is half drape's contact thickness, so both engines keep sheets apart by
// the same distance. Frictionless, as drape's stack. Links are position constraints solved
// once per substep (Bullet's default one iteration) at the stiffness that one XPBD
// iteration gives a spring of k = 100 N/m at this step: the fraction w/(w + 1/(k dt²)) of
// the error, w the two ends' inverse masses.
struct BulletStack {
  BulletWorld bullet;
  btSoftRigidDynamicsWorld& world = bullet.world;
  std::vector<std::unique_ptr<btSoftBody>> sheets;

  explicit BulletStack(double margin) {
    using drape::bench::Stack;
    btSoftBodyWorldInfo& info = world.getWorldInfo();
    const double half = 0.5 * Stack::width;
    for (int column = 0; column < Stack::columns; ++column)
      for (int layer = 0; layer < Stack::layers; ++layer) {
        const drape::Vec3 c = Stack::center(column, layer, stack_layer_gap);
        std::unique_ptr<btSoftBody> cloth(btSoftBodyHelpers::CreatePatch(
            info, btVector3(c.x - half, c.y - half, c.z), btVector3(c.x + half, c.y - half, c.z),
            btVector3(c.x - half, c.y + half, c.z), btVector3(c.x + half, c.y + half, c.z), int(Stack::side),
            int(Stack::side), BulletWorld::corners, false));
        cloth->setTotalMass(Stack::mass);
        const double node_mass = Stack::mass / (double(Stack::side) * Stack::side);
        const double w = 2.0 / node_mass, alpha = 1.0 / (Stack::stiffness * Stack::dt * Stack::dt);
        cloth->m_materials[0]->m_kLST = w / (w + alpha);
        cloth->m_cfg.piterations = 1;
        cloth->m_cfg.kDF = 0;
        cloth->m_cfg.collisions = btSoftBody::fCollision::VF_SS;
        cloth->getCollisionShape()->setMargin(margin);
        cloth->updateConstants();
        world.addSoftBody(cloth.get());
        sheets.push_back(std::move(cloth));
      }
  }
  ~BulletStack() {
    for (auto& cloth : sheets) world.removeSoftBody(cloth.get());
  }
  BulletStack(const BulletStack&) = delete;
  BulletStack& operator=(const BulletStack&) = delete;
};

void BM_StackContact_Bullet(benchmark::State& state) {
  using drape::bench::Stack;
  const double margin = 0.5 * drape::WorldDef{}.contact_thickness;
  StackMeasure measure;
  for (auto _ : state) {
    state.PauseTiming();
    auto bullet = std::make_unique<BulletStack>(margin);
    state.ResumeTiming();
    measure = run_stack(
        state, [&] { bullet->world.stepSimulation(stack_frame * Stack::dt, stack_frame, Stack::dt); },
        [&] {
          std::vector<drape::bench::MeasuredSheet> measured;
          for (std::size_t k = 0; k < bullet->sheets.size(); ++k) {
            const auto& nodes = bullet->sheets[k]->m_nodes;
            drape::bench::MeasuredSheet s{int(k) / Stack::layers, int(k) % Stack::layers,
                                          std::vector<drape::Vec3>(std::size_t(nodes.size()))};
            for (int p = 0; p < nodes.size(); ++p)
              s.points[std::size_t(p)] = {nodes[p].m_x.x(), nodes[p].m_x.y(), nodes[p].m_x.z()};
            measured.push_back(std::move(s));
          }
          return measured;
        });
    state.PauseTiming();
    bullet.reset();
    state.ResumeTiming();
  }
  report_stack(state, measure);
  state.counters["margin_m"] = margin;
}
BENCHMARK(BM_StackContact_Bullet)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
