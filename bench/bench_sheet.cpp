// One sheet stepped alone: the cost of the spring kernel plus the integrator per point.
#include <benchmark/benchmark.h>
#include <drape/drape.h>

namespace {

void BM_SheetStep(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  drape::WorldDef wd;
  wd.dt = 1e-4;
  wd.threads = 1;
  drape::World world(wd);
  drape::SheetDef sd;
  sd.m = sd.n = side - 1;
  sd.stiffness = 100.0;
  sd.pins = drape::corner_points(sd.m, sd.n);
  world.add_sheet(sd);
  for (auto _ : state) world.step(1);
  const double points = double(side) * side;
  state.counters["points"] = points;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SheetStep)->Arg(16)->Arg(32)->Arg(64)->Arg(128)->Arg(256);

}  // namespace
