// Constraint prices (issue 14): the feature benchmarks' 48 sheets of 64×64 points on one
// thread, with one kind of constraint on every sheet, stepped one substep per call and a
// frame per call. Each substep's targets come from its own start, so a world with
// constraints takes no runs of substeps; in frames its joined sheets step as groups (a row
// of eight here, frames.cpp), which the frame rows price against the runs of free sheets.
#include "bench_common.h"

namespace {

constexpr int sheet_count = 48;
constexpr std::uint32_t side = 64;
constexpr double spacing = 1.5;  // m between sheet centres (the sheets are 1 m wide)

enum class Kind { None, Joins, Paths, Rails, MovingObstacle };

drape::SheetId add(drape::World& world, int s) {
  return world.add_sheet(drape::bench::square_sheet(side, {false, false, false}, {spacing * (s % 8), spacing * (s / 8), 0.0}));
}

void build(drape::World& world, Kind kind) {
  std::vector<drape::SheetId> ids;
  for (int s = 0; s < sheet_count; ++s) ids.push_back(add(world, s));
  const std::uint32_t n = side - 1;
  for (int s = 0; s < sheet_count; ++s) {
    drape::ConstraintDef c;
    c.stiffness = 1000;
    c.sheet = ids[s];
    switch (kind) {
      case Kind::None:
      case Kind::MovingObstacle: continue;
      case Kind::Joins:  // each sheet's right edge to the next sheet's left edge in its row
        if (s % 8 == 7) continue;
        c.kind = drape::ConstraintKind::PointToPoint;
        c.other_sheet = ids[s + 1];
        c.rest_length = spacing - 1.0;
        c.points = drape::column_points(n, n, n);
        c.other_points = drape::column_points(n, n, 0);
        break;
      case Kind::Paths:  // the four corners carried round a circle
        c.kind = drape::ConstraintKind::Path;
        c.points = drape::corner_points(n, n);
        c.motion.kind = drape::Motion::Kind::Circle;
        c.motion.circle = {{0, 0, 0}, {0, 0, 1}, {0.1, 0, 0}, 2.0};
        break;
      case Kind::Rails:  // the top row on a straight rail
        c.kind = drape::ConstraintKind::Rail;
        c.points = drape::row_points(n, n, n);
        c.rail = {{-10, spacing * (s / 8) + 0.5, 0}, {20, spacing * (s / 8) + 0.5, 0}};
        break;
    }
    world.add_constraint(c);
  }
  if (kind == Kind::MovingObstacle) {  // a floor under every sheet, resting on it, that rises and falls slowly
    drape::ObstacleDef floor = drape::bench::floor_holding(drape::bench::square_sheet(side, {false, false, false}));
    drape::Motion bob;
    bob.repeat = true;
    bob.keyframes = {{0, {}, {}}, {1, {0, 0, 0.002}, {}}, {2, {}, {}}};
    floor.motion = bob;
    world.add_obstacle(floor);
  }
  drape::bench::set_stable_dt(world);
}

void run(benchmark::State& state, Kind kind, int substeps) {
  drape::WorldDef wd = drape::bench::world_def(1);
  wd.contact_strength = 0;  // as the feature benchmarks' "bare"
  drape::World world(wd);
  build(world, kind);
  for (auto _ : state) world.step(substeps);
  if (!world.all_finite()) state.SkipWithError("the scene blew up; its figures would be meaningless");
  drape::bench::set_point_rate(state, double(sheet_count) * side * side, substeps);
}

void BM_Constraint_none(benchmark::State& state) { run(state, Kind::None, 1); }
void BM_Constraint_joins(benchmark::State& state) { run(state, Kind::Joins, 1); }
void BM_Constraint_paths(benchmark::State& state) { run(state, Kind::Paths, 1); }
void BM_Constraint_rails(benchmark::State& state) { run(state, Kind::Rails, 1); }
void BM_Constraint_moving_obstacle(benchmark::State& state) { run(state, Kind::MovingObstacle, 1); }
void BM_Constraint_none_frames(benchmark::State& state) { run(state, Kind::None, drape::bench::frame_substeps); }
void BM_Constraint_joins_frames(benchmark::State& state) { run(state, Kind::Joins, drape::bench::frame_substeps); }
BENCHMARK(BM_Constraint_none);
BENCHMARK(BM_Constraint_joins);
BENCHMARK(BM_Constraint_paths);
BENCHMARK(BM_Constraint_rails);
BENCHMARK(BM_Constraint_moving_obstacle);
BENCHMARK(BM_Constraint_none_frames);
BENCHMARK(BM_Constraint_joins_frames);

}  // namespace
