// The same Fig 13 scene in an established soft-body engine: Bullet's soft bodies (Debian's
// libbullet-dev, its float64 build), one thread. A side×side patch of nodes joined by
// structural links only, like drape's grid (no diagonals), 1 m square, 1 kg, its four
// corners fixed, gravity, no collisions, at drape's step for the same sheet, stepped a frame
// of frame_substeps fixed substeps per call (stepSimulation with as many internal substeps).
// Bullet solves the links as position constraints (its default: one iteration), drape as
// forces (eq 6): the same scene and step, not the same method. Built only when CMake finds
// Bullet (bench/CMakeLists.txt); tools/bench.sh installs it.
#include <BulletSoftBody/btDefaultSoftBodySolver.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <memory>

#include "bench_common.h"

namespace {

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

  btSoftBodyRigidBodyCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDefaultSoftBodySolver soft_solver;
  btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config, &soft_solver);
  const btVector3 gravity(0, 0, -9.81);
  world.setGravity(gravity);
  btSoftBodyWorldInfo& info = world.getWorldInfo();
  info.m_gravity = gravity;
  info.m_sparsesdf.Initialize();
  const int corners = 1 + 2 + 4 + 8;
  std::unique_ptr<btSoftBody> cloth(btSoftBodyHelpers::CreatePatch(
      info, btVector3(-0.5, -0.5, 0), btVector3(0.5, -0.5, 0), btVector3(-0.5, 0.5, 0), btVector3(0.5, 0.5, 0),
      int(side), int(side), corners, false));
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

}  // namespace
