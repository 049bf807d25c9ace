// drape sweep's throughput: small scenes run to the end in parallel over runs (one thread
// each), reported as scenes per second, for 1 worker and for every core.
#include <benchmark/benchmark.h>

#include <oneapi/tbb/info.h>

#include "sweep.h"

namespace {

// A 16×16 sheet hung at its corners, 10 frames of 20 substeps: a typical small sweep run.
const char* small_scene = R"({"frames": 10, "dt": 0.001, "substeps": 20, "sheets": [{"grid": [16, 16],
  "size": [1, 1], "stiffness": 100, "mass": 0.3, "damping": 0.02,
  "anchors": [{"at": "corners", "stiffness": 300}]}]})";

void BM_SweepScenes(benchmark::State& state) {
  const int threads = int(state.range(0)) == 0 ? tbb::info::default_concurrency() : int(state.range(0));
  const std::size_t runs = 32;
  std::vector<drape::app::SweepCase> cases(runs);
  for (std::size_t k = 0; k < runs; ++k) {
    const std::string stiffness = std::to_string(50 + 10 * k);
    const drape::app::SceneOverride set[] = {{"sheets[*].stiffness", stiffness}};
    cases[k].values = {stiffness};
    cases[k].scene = drape::app::parse_scene(small_scene, "bench.json", set);
  }
  for (auto _ : state) {
    const auto outcomes = drape::app::run_sweep_cases(cases, std::nullopt, threads);
    benchmark::DoNotOptimize(outcomes.data());
  }
  state.counters["threads"] = threads;
  state.counters["scenes_per_s"] = benchmark::Counter(double(runs * state.iterations()), benchmark::Counter::kIsRate);
}
// 0: every core
BENCHMARK(BM_SweepScenes)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
