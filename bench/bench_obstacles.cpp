// The price of the obstacle term (eq 9): a sheet lying on an obstacle, per shape, against
// the same sheet with the obstacle out of reach (which pays only the host stage's bounds).
#include <benchmark/benchmark.h>

#include "bench_common.h"
#include <drape/drape.h>

namespace {

// range(0): shape (ObstacleShape as int); range(1): 1 = the sheet touches it, 0 = far away.
// Touching, the sheet is set down flat over the obstacle's top at the gap where eq (9) holds
// its points' weight (bench::holding_gap): its middle rests there and the rest drapes over the
// shape, within reach.
void BM_SheetOnObstacle(benchmark::State& state) {
  const auto shape = static_cast<drape::ObstacleShape>(state.range(0));
  const bool near = state.range(1) != 0;
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-4;
  wd.threads = 1;
  drape::World world(wd);
  drape::ObstacleDef od;
  od.shape = shape;
  od.size = shape == drape::ObstacleShape::Torus ? drape::Vec3{0.3, 0.2, 0} : drape::Vec3{0.5, 0.4, 0.5};
  od.c = 0.01;
  od.xi = 0.01;
  od.center = {0, 0, near ? 0.0 : -10.0};
  world.add_obstacle(od);
  drape::SheetDef sd;
  sd.m = sd.n = 63;
  sd.width = sd.height = 1.0;
  // the obstacle's highest point over its centre (local z up): the plane's surface, the
  // sphere's radius, the ellipsoid's and box's z half extent, the torus's tube radius
  const double top = shape == drape::ObstacleShape::Plane  ? 0.0
                     : shape == drape::ObstacleShape::Sphere ? od.size.x
                     : shape == drape::ObstacleShape::Torus  ? od.size.y
                                                             : od.size.z;
  sd.center = {0, 0, top + drape::bench::holding_gap(sd, od.c, od.xi)};
  world.add_sheet(sd);
  for (auto _ : state) world.step(1);
  const double points = 64.0 * 64.0;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SheetOnObstacle)->ArgsProduct({{0, 1, 2, 3, 4}, {0, 1}});

// Args: threads. One 256×256 sheet lying on a floor that holds it (eq 9 on every point), as
// a large tablecloth on a table, stepped in frames as a program steps it: on two threads its
// rows are cut into blocks (WorldDef::block_points) that the cores step together, obstacle
// term included.
void BM_LargeSheetOnFloor(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-4;
  wd.threads = int(state.range(0));
  drape::World world(wd);
  drape::SheetDef sd;
  sd.m = sd.n = 255;
  sd.width = sd.height = 2.0;
  world.add_obstacle(drape::bench::floor_holding(sd));
  world.add_sheet(sd);
  drape::bench::step_frames(state, world, 256.0 * 256.0);
}
BENCHMARK(BM_LargeSheetOnFloor)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime();

}  // namespace
