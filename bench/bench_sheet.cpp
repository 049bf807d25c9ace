// Fig 13 of the paper: time per step of one sheet against its number of points, for every
// integrator and both precisions. The report fits the log–log slope (linear cost: 1).
#include "bench_common.h"

namespace {

using drape::bench::set_point_rate;

// One sheet stepped a frame of substeps per step() call (`frame` true), as a program
// steps it, or one substep per call.
template <class W>
void sheet_step(benchmark::State& state, drape::Integrator integrator, bool frame) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  drape::WorldDef wd = drape::bench::world_def();
  wd.threads = 1;
  wd.integrator = integrator;
  W world(wd);
  world.add_sheet(drape::bench::square_sheet(side));
  drape::bench::set_stable_dt(world);
  if (frame) {
    drape::bench::step_frames(state, world, double(side) * side);
    return;
  }
  for (auto _ : state) world.step(1);
  set_point_rate(state, double(side) * side);
}

// Names: BM_Fig13/<integrator>/<f64|f32>/<side> (frames), BM_Fig13Single/... (one
// substep per call, semi-implicit Euler only); the report parses them.
const bool registered = [] {
  for (drape::Integrator integrator : drape::bench::all_integrators()) {
    const std::string name = std::string("BM_Fig13/") + std::string(drape::integrator_name(integrator));
    benchmark::RegisterBenchmark((name + "/f64").c_str(), sheet_step<drape::World>, integrator, true)
        ->RangeMultiplier(2)
        ->Range(16, 1024);
    benchmark::RegisterBenchmark((name + "/f32").c_str(), sheet_step<drape::WorldF>, integrator, true)
        ->RangeMultiplier(2)
        ->Range(16, 1024);
  }
  benchmark::RegisterBenchmark("BM_Fig13Single/semi_implicit_euler/f64", sheet_step<drape::World>,
                               drape::Integrator::SemiImplicitEuler, false)
      ->RangeMultiplier(2)
      ->Range(16, 1024);
  return true;
}();

// The paper's headline size: about 1000 points (32×32 = 1024) at interactive rates, one
// substep per step() call (the slower way to call it).
void BM_Paper1000Points(benchmark::State& state) {
  sheet_step<drape::World>(state, drape::Integrator::SemiImplicitEuler, false);
}
BENCHMARK(BM_Paper1000Points)->Arg(32);

}  // namespace
