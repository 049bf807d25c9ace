// Fig 13 of the paper: time per step of one sheet against its number of points, for every
// integrator and both precisions. The report fits the log–log slope (linear cost: 1).
#include "bench_common.h"

namespace {

using drape::bench::set_point_rate;

template <class W>
void sheet_step(benchmark::State& state, drape::Integrator integrator) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  drape::WorldDef wd = drape::bench::world_def();
  wd.threads = 1;
  wd.integrator = integrator;
  W world(wd);
  world.add_sheet(drape::bench::square_sheet(side));
  drape::bench::set_stable_dt(world);
  for (auto _ : state) world.step(1);
  set_point_rate(state, double(side) * side);
}

// Names: BM_Fig13/<integrator>/<f64|f32>/<side>; the report parses them.
const bool registered = [] {
  for (drape::Integrator integrator : drape::bench::all_integrators()) {
    const std::string name = std::string("BM_Fig13/") + std::string(drape::integrator_name(integrator));
    benchmark::RegisterBenchmark((name + "/f64").c_str(), sheet_step<drape::World>, integrator)
        ->RangeMultiplier(2)
        ->Range(16, 1024);
    benchmark::RegisterBenchmark((name + "/f32").c_str(), sheet_step<drape::WorldF>, integrator)
        ->RangeMultiplier(2)
        ->Range(16, 1024);
  }
  return true;
}();

// The paper's headline size: about 1000 points (32×32 = 1024) at interactive rates.
void BM_Paper1000Points(benchmark::State& state) {
  sheet_step<drape::World>(state, drape::Integrator::SemiImplicitEuler);
}
BENCHMARK(BM_Paper1000Points)->Arg(32);

}  // namespace
