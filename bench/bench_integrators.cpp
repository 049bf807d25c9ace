// The price of each integrator per substep, and of the stability guard per frame.
#include <benchmark/benchmark.h>

#include "bench_common.h"
#include <drape/drape.h>

namespace {

drape::World make_world(drape::Integrator integrator, std::uint32_t side) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-4;
  wd.threads = 1;
  wd.integrator = integrator;
  wd.guard = false;  // measured on its own below
  drape::World world(wd);
  drape::SheetDef sd;
  sd.m = sd.n = side - 1;
  sd.stiffness = 100.0;
  sd.pins = drape::corner_points(sd.m, sd.n);
  world.add_sheet(sd);
  return world;
}

void BM_IntegratorStep(benchmark::State& state) {
  const auto integrator = static_cast<drape::Integrator>(state.range(0));
  const auto side = static_cast<std::uint32_t>(state.range(1));
  auto world = make_world(integrator, side);
  for (auto _ : state) world.step(1);
  state.SetLabel(std::string(drape::integrator_name(integrator)));
  const double points = double(side) * side;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IntegratorStep)->ArgsProduct({{0, 1, 2, 3, 4}, {32, 128}});

// World::check(): one pass over points and springs, run once per step() call (a frame).
// Compare with BM_IntegratorStep × substeps per frame.
// on_floor: the sheet rests on a floor (eq 9 acts on every point), whose potential the guard
// adds to the energy.
void BM_GuardCheck(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  auto world = make_world(drape::Integrator::SemiImplicitEuler, side);
  if (state.range(1) != 0) {
    drape::SheetDef sd;
    sd.m = sd.n = side - 1;
    world.add_obstacle(drape::bench::floor_holding(sd));
  }
  for (auto _ : state) benchmark::DoNotOptimize(world.check());
  state.counters["points"] = double(side) * side;
}
BENCHMARK(BM_GuardCheck)->ArgNames({"side", "on_floor"})->ArgsProduct({{32, 128}, {0, 1}});

}  // namespace
