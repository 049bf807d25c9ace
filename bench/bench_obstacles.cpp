// The price of the obstacle term (eq 9): a sheet lying on an obstacle, per shape, against
// the same sheet with the obstacle out of reach (which pays only the host stage's bounds).
#include <benchmark/benchmark.h>

#include "bench_common.h"
#include <drape/drape.h>

namespace {

// range(0): shape (ObstacleShape as int); range(1): 1 = the sheet touches it, 0 = far away.
void BM_SheetOnObstacle(benchmark::State& state) {
  const auto shape = static_cast<drape::ObstacleShape>(state.range(0));
  const bool near = state.range(1) != 0;
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-4;
  wd.threads = 1;
  drape::World world(wd);
  drape::SheetDef sd;
  sd.m = sd.n = 63;
  sd.width = sd.height = 1.0;
  sd.center = {0, 0, 0.52};
  world.add_sheet(sd);
  drape::ObstacleDef od;
  od.shape = shape;
  od.size = shape == drape::ObstacleShape::Torus ? drape::Vec3{0.3, 0.2, 0} : drape::Vec3{0.5, 0.4, 0.5};
  od.c = 0.01;
  od.xi = 0.01;
  od.center = {0, 0, near ? 0.0 : -10.0};
  world.add_obstacle(od);
  for (auto _ : state) world.step(1);
  const double points = 64.0 * 64.0;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SheetOnObstacle)->ArgsProduct({{0, 1, 2, 3, 4}, {0, 1}});

}  // namespace
