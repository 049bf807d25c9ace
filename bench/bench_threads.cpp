// Thread scaling on this machine: dozens of sheets (parallel over sheets) and one huge
// sheet (split within the sheet), each at 1 and 2 threads, in wall-clock time.
#include "bench_common.h"

namespace {

// 48 sheets of 64×64, four corners pinned, gravity, no contacts (issue 6: contacts off,
// so the sheets are independent between substeps; BM_Feature_contacts_apart prices
// turning them on for sheets that never touch).
template <class W>
void sheets48(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.threads = static_cast<int>(state.range(0));
  wd.contact_strength = 0;
  W world(wd);
  for (int s = 0; s < 48; ++s)
    world.add_sheet(drape::bench::square_sheet(64, {.pins = true}, {1.5 * (s % 8), 1.5 * (s / 8), 0.0}));
  drape::bench::set_stable_dt(world);
  drape::bench::step_frames(state, world, 48.0 * 64 * 64);
}
void BM_Sheets48_f64(benchmark::State& state) { sheets48<drape::World>(state); }
void BM_Sheets48_f32(benchmark::State& state) { sheets48<drape::WorldF>(state); }
BENCHMARK(BM_Sheets48_f64)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime();
BENCHMARK(BM_Sheets48_f32)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime();
// The price of contacts: bench_world.cpp (48 sheets apart and in contact, 1 and 2 threads).

// One 1024×1024 sheet: two threads only help once the world splits a sheet into blocks.
void BM_HugeSheet(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.threads = static_cast<int>(state.range(0));
  drape::World world(wd);
  world.add_sheet(drape::bench::square_sheet(1024));
  drape::bench::set_stable_dt(world);
  drape::bench::step_frames(state, world, 1024.0 * 1024);
}
BENCHMARK(BM_HugeSheet)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime();

}  // namespace
