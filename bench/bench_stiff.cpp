// Stiff sheets at large steps (issue 16). Every iteration steps one simulated second, so
// the report reads simulated seconds per wall second (sim_s_per_wall_s: above 1 is faster
// than real time) beside the largest spring stretch the run reached (max_stretch, over the
// ends of its frames of 1/60 s).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "bench_common.h"
#include <drape/drape.h>

namespace {

using drape::Integrator;

// A step and budget of one integrator; dt ≤ 0 means −dt × the explicit critical step.
struct Stepping {
  Integrator integrator;
  double dt;
  int iterations;  // local_global_iterations or vertex_block_iterations
  std::string label;
};

const Stepping steppings[] = {
    {Integrator::SemiImplicitEuler, -0.8, 1, "semi_implicit_euler/0.8_critical"},
    {Integrator::ImplicitEuler, 1.0 / 60, 1, "implicit_euler/dt_1_60"},
    {Integrator::LocalGlobal, 1.0 / 60, 2, "local_global/dt_1_60/it_2"},
    {Integrator::LocalGlobal, 1.0 / 60, 5, "local_global/dt_1_60/it_5"},
    {Integrator::LocalGlobal, 1.0 / 60, 10, "local_global/dt_1_60/it_10"},
    {Integrator::LocalGlobal, 1.0 / 30, 2, "local_global/dt_1_30/it_2"},
    {Integrator::VertexBlockDescent, 1.0 / 60, 2, "vertex_block_descent/dt_1_60/it_2"},
    {Integrator::VertexBlockDescent, 1.0 / 60, 5, "vertex_block_descent/dt_1_60/it_5"},
    {Integrator::VertexBlockDescent, 1.0 / 60, 10, "vertex_block_descent/dt_1_60/it_10"},
    {Integrator::VertexBlockDescent, 1.0 / 30, 2, "vertex_block_descent/dt_1_30/it_2"},
};

// 64×64 points (by default), 1 m square, 1 kg, corners pinned: the sheet.
drape::SheetDef stiff_sheet(double stiffness, drape::Vec3 center = {}, std::uint32_t side = 64) {
  drape::SheetDef sd = drape::bench::square_sheet(side, {true, false, false}, center);
  sd.mass = 1.0;
  sd.stiffness = stiffness;
  return sd;
}

// One simulated second per iteration of `world` (its sheets already added), in frames of
// 1/60 s; the stretch is read at the end of every frame, outside the timing.
void run_seconds(benchmark::State& state, drape::World& world, const Stepping& s, double points) {
  world.set_dt(s.dt > 0 ? s.dt : -s.dt * world.stable_step_estimate());
  const double dt = world.def().dt;
  const int per_frame = std::max(1, int(std::lround(1.0 / 60 / dt)));
  const int frames = std::max(1, int(std::lround(1.0 / (per_frame * dt))));
  double stretch = 0;
  std::uint64_t unconverged = 0;
  for (auto _ : state) {
    for (int f = 0; f < frames; ++f) {
      world.step(per_frame);
      state.PauseTiming();
      for (drape::SheetId id : world.sheets()) {
        stretch = std::max(stretch, world.diagnostics(id).max_strain);
        unconverged = std::max(unconverged, world.solver_stats(id).unconverged_solves);
      }
      state.ResumeTiming();
    }
  }
  const double simulated = frames * per_frame * dt;
  state.counters["sim_s_per_wall_s"] = benchmark::Counter(simulated * double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["max_stretch"] = stretch;
  state.counters["dt"] = dt;
  state.counters["unconverged_solves"] = double(unconverged);
  drape::bench::set_point_rate(state, points, frames * per_frame);
}

// The sheet at k = 1e5 N/m on one core: how many times faster than real time each
// integrator runs it (its error against a converged reference is in docs/accuracy.md).
void BM_StiffSheet(benchmark::State& state, Stepping s) {
  drape::WorldDef wd = drape::bench::world_def(1);
  wd.integrator = s.integrator;
  wd.local_global_iterations = s.iterations;
  wd.vertex_block_iterations = s.iterations;
  drape::World world(wd);
  world.add_sheet(stiff_sheet(1e5));
  run_seconds(state, world, s, 64.0 * 64.0);
}

// The equal-stiffness comparison: the 48 sheets of 64×64 (corners pinned, 1 kg each) at
// k = 3e4 N/m, stiff enough that semi-implicit Euler's largest stretch stays under 5 %
// over the first second (it does not at 1e4), stepped one simulated second, at 1 and 2
// threads. The report picks the cheapest stepping whose max_stretch is at most 5 %.
constexpr double equal_stiffness = 3e4;

void BM_EqualStiffness48(benchmark::State& state, Stepping s) {
  drape::WorldDef wd = drape::bench::world_def(int(state.range(0)));
  wd.integrator = s.integrator;
  wd.local_global_iterations = s.iterations;
  wd.vertex_block_iterations = s.iterations;
  wd.contact_strength = 0;  // apart, as in BM_Sheets48
  drape::World world(wd);
  for (int k = 0; k < 48; ++k) world.add_sheet(stiff_sheet(equal_stiffness, {2.0 * (k % 8), 2.0 * (k / 8), 0}));
  run_seconds(state, world, s, 48 * 64.0 * 64.0);
}

// Implicit Euler per step on the sheet (64×64, 1 kg, corners pinned, dt = 1/60 s) at
// k = 1e4, 1e5, 1e6 N/m (the target), 1e8, and 10 to 1e3 (where auto's threshold
// between the two lies), and on 128×128 (the factor grows faster with the sheet than an
// iteration does), with each preconditioner measured in the same run: block Jacobi at the
// default cap (200 iterations, the path before issue 16) and the Cholesky factor. Each
// iteration is one step of a sheet falling from flat (30 steps, the same trajectory for
// both up to the solves' tolerance; the first step also pays for the factor's analysis);
// the counters say how many CG iterations a step took and whether every solve converged.
void BM_ImplicitEulerStep(benchmark::State& state, drape::Preconditioner preconditioner) {
  drape::WorldDef wd = drape::bench::world_def(1);
  wd.integrator = Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_preconditioner = preconditioner;
  drape::World world(wd);
  const auto side = std::uint32_t(state.range(0));
  const drape::SheetId id = world.add_sheet(stiff_sheet(double(state.range(1)), {}, side));
  // Settled: the timed steps follow this many untimed ones (a sheet hanging after its fall,
  // where a kept Cholesky factor serves step after step; from flat, each step's matrix
  // differs too much from the last one's).
  world.step(std::uint32_t(state.range(2)));
  const double unconverged_before = double(world.solver_stats(id).unconverged_solves);
  double iterations = 0;
  for (auto _ : state) {
    world.step(1);
    state.PauseTiming();
    iterations += world.solver_stats(id).iterations;
    state.ResumeTiming();
  }
  state.counters["cg_iterations"] = iterations / double(state.iterations());
  state.counters["unconverged_solves"] = double(world.solver_stats(id).unconverged_solves) - unconverged_before;
  state.counters["dt_omega_max"] = wd.dt * 2.0 / world.stable_step_estimate(id);
  drape::bench::set_point_rate(state, double(side) * side, 1);
}

// One stiff sheet falling from flat (k = 1e5 N/m, Cholesky) on one and two threads, wall
// time: the sheet is one task, so a second thread helps only where the step itself splits,
// the factor's two groups of subtrees (supernodal.h).
void BM_ImplicitEulerThreads(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def(int(state.range(1)));
  wd.integrator = Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_preconditioner = drape::Preconditioner::Cholesky;
  drape::World world(wd);
  const auto side = std::uint32_t(state.range(0));
  world.add_sheet(stiff_sheet(1e5, {}, side));
  for (auto _ : state) world.step(1);
  drape::bench::set_point_rate(state, double(side) * side, 1);
}
BENCHMARK(BM_ImplicitEulerThreads)
    ->ArgNames({"side", "threads"})
    ->ArgsProduct({{64, 128}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(30)
    ->UseRealTime();

const int registered = [] {
  for (auto preconditioner : {drape::Preconditioner::BlockJacobi, drape::Preconditioner::Cholesky})
    benchmark::RegisterBenchmark(("BM_ImplicitEulerStep/" + std::string(drape::preconditioner_name(preconditioner))).c_str(),
                                 BM_ImplicitEulerStep, preconditioner)
        ->ArgNames({"side", "k", "settled"})
        ->ArgsProduct({{64}, {10, 100, 1000, 10000, 100000, 1000000, 100000000}, {0}})
        ->ArgsProduct({{64}, {10000, 100000, 100000000}, {300}})
        ->ArgsProduct({{128}, {10, 100, 1000, 100000}, {0}})
        ->Unit(benchmark::kMillisecond)
        ->Iterations(30);
  for (const Stepping& s : steppings) {
    benchmark::RegisterBenchmark(("BM_StiffSheet/" + s.label).c_str(), BM_StiffSheet, s)
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);
    if (s.integrator == Integrator::ImplicitEuler || s.iterations == 10) continue;  // the slow ones: once above
    benchmark::RegisterBenchmark(("BM_EqualStiffness48/" + s.label).c_str(), BM_EqualStiffness48, s)
        ->Arg(1)
        ->Arg(2)
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1)
        ->UseRealTime();
  }
  return 0;
}();

}  // namespace
