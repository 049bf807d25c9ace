// Feature prices: the same 48 sheets of 64×64 points on one thread, adding one term at a
// time to the bare spring kernel + integrator. The report prints each as a rate and as a
// cost relative to "bare".
#include "bench_common.h"

namespace {

using drape::bench::Features;

constexpr int sheet_count = 48;
constexpr std::uint32_t side = 64;

// Sheets side by side, 1.5 m apart, so a later contact stage finds no pairs among them.
template <class W>
void add_sheets(W& world, Features f) {
  for (int s = 0; s < sheet_count; ++s)
    world.add_sheet(drape::bench::square_sheet(side, f, {1.5 * (s % 8), 1.5 * (s / 8), 0.0}));
  drape::bench::set_stable_dt(world);
}

drape::WorldDef one_thread() {
  drape::WorldDef wd;
  wd.threads = 1;
  return wd;
}

void run(benchmark::State& state, Features f, bool finite_check) {
  drape::World world(one_thread());
  add_sheets(world, f);
  for (auto _ : state) {
    world.step(1);
    if (finite_check) benchmark::DoNotOptimize(world.all_finite());  // the guard a program runs per frame
  }
  drape::bench::set_point_rate(state, double(sheet_count) * side * side);
}

void BM_Feature_bare(benchmark::State& state) { run(state, {false, false, false}, false); }
void BM_Feature_pins(benchmark::State& state) { run(state, {true, false, false}, false); }
void BM_Feature_anchors(benchmark::State& state) { run(state, {false, true, false}, false); }
void BM_Feature_damping(benchmark::State& state) { run(state, {false, false, true}, false); }
void BM_Feature_finite_check(benchmark::State& state) { run(state, {false, false, false}, true); }
void BM_Feature_all(benchmark::State& state) { run(state, {true, true, true}, true); }
BENCHMARK(BM_Feature_bare);
BENCHMARK(BM_Feature_pins);
BENCHMARK(BM_Feature_anchors);
BENCHMARK(BM_Feature_damping);
BENCHMARK(BM_Feature_finite_check);
BENCHMARK(BM_Feature_all);
// TODO(obstacles merge): BM_Feature_obstacle — the bare scene plus one torus under the
// sheets (world.add_obstacle), to price the eq (9) term.
// TODO(contacts merge): BM_Feature_contacts — the bare scene with sheets stacked so the
// host stage finds pairs, to price the contact term.

}  // namespace
