// Many sheets in one World: step throughput against threads, the price of contacts, and
// the broad-phase alone against the number of boxes.
#include <benchmark/benchmark.h>

#include "bench_common.h"
#include <drape/drape.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include "broad_phase.h"

namespace {

using drape::bench::stack_world;  // 48 sheets of 64×64 in 6 columns × 8 layers (bench_common.h)

void report(benchmark::State& state, double points) {
  state.counters["points"] = points;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * double(state.iterations()), benchmark::Counter::kIsRate);
}

// The stack benchmarks below time the same span of a fresh stack in every iteration:
// substeps kStackWarmUp … kStackWarmUp + kStackSpan. A stack's contacts cost what its state
// makes them cost (from about 8 to about 75 ms a substep over its first 0.6 s on one thread,
// counted while it sags into deeper contact), so a world stepped on for as long as the
// benchmark runs timed a span that grew with the build's speed: a faster build ran further,
// into costlier states, and looked slower. The span is 6 frames of frame_substeps, so the
// frame-stepped variants time the same substeps.
constexpr int kStackWarmUp = 10, kStackSpan = 6 * drape::bench::frame_substeps;

// The gap of layers in contact (bench_common.h), as every stacked benchmark below sets it.
constexpr double touching = drape::bench::Stack::contact_gap;

// `per_call` substeps per step() call; the world is made, warmed up and destroyed untimed.
void stack_span(benchmark::State& state, int threads, double layer_gap, drape::bench::StackContact contact = {},
                int per_call = 1) {
  std::optional<drape::World> world;
  std::size_t pairs = 0;
  drape::World::FrameStats frames;
  for (auto _ : state) {
    state.PauseTiming();
    world.emplace(stack_world(threads, layer_gap, contact));  // the last one destroyed first
    world->step(kStackWarmUp);
    state.ResumeTiming();
    for (int k = 0; k < kStackSpan; k += per_call) world->step(std::uint32_t(per_call));
    state.PauseTiming();
    pairs = world->contact_pair_count();
    frames = world->frame_stats();
    state.ResumeTiming();
  }
  world.reset();  // after the loop, untimed
  state.counters["pairs"] = double(pairs);
  state.counters["frames_kept"] = double(frames.kept);  // of the last iteration's frames tried in groups
  state.counters["frames_undone"] = double(frames.undone);
  state.counters["per_call"] = per_call;
  state.counters["warm_up"] = kStackWarmUp;
  drape::bench::set_point_rate(state, 48.0 * 64 * 64, kStackSpan);
}

// Arg: threads. Sheets apart: the host stage finds no pair.
void BM_World48SheetsApart(benchmark::State& state) { stack_span(state, int(state.range(0)), 2.0); }
BENCHMARK(BM_World48SheetsApart)->Arg(1)->Arg(2)->UseRealTime();

// Arg: threads. Same sheets, layers 10 mm apart (issue 13's set-up): every layer touches the
// next, and only the next. 10 mm is nearer than the gap where the default contact force
// carries the layers above, so the layers spring apart at first: in this span their
// contacts thin out towards the pinned corners, and they meet again later in the second.
void BM_World48SheetsInContact(benchmark::State& state) { stack_span(state, int(state.range(0)), touching); }
BENCHMARK(BM_World48SheetsInContact)->Arg(1)->Arg(2)->UseRealTime();

// The same with WorldDef::contact_exact: every point tests every cell within reach each
// substep, the reference the default walk is held to (docs/architecture.md). One thread.
void BM_World48SheetsInContactExact(benchmark::State& state) {
  drape::bench::StackContact exact;
  exact.exact = true;
  stack_span(state, 1, touching, exact);
}
BENCHMARK(BM_World48SheetsInContactExact)->UseRealTime();

// World::contact_energy on the same stack after its warm-up (one thread): the exact search
// of every pair it makes, priced against a substep of BM_World48SheetsInContact/1.
void BM_ContactEnergy(benchmark::State& state) {
  drape::World world = stack_world(1, touching);
  world.step(kStackWarmUp);
  double energy = 0;
  for (auto _ : state) benchmark::DoNotOptimize(energy = world.contact_energy());
  state.counters["energy_J"] = energy;
  state.counters["pairs"] = double(world.contact_pair_count());
}
BENCHMARK(BM_ContactEnergy)->Unit(benchmark::kMillisecond)->UseRealTime();

// World::sheet_crossings on the same stack once it has sagged (400 substeps, 0.4 s; one
// thread): every pair's edges against the other's triangles, what drape run pays for a look
// (it looks within 5 % of a run). Flat layers cost next to nothing (their boxes are apart).
void BM_SheetCrossings(benchmark::State& state) {
  drape::World world = stack_world(1, touching);
  world.step(400);
  std::size_t crossing = 0;
  for (auto _ : state) benchmark::DoNotOptimize(crossing = world.sheet_crossings().size());
  state.counters["crossing_pairs"] = double(crossing);
  state.counters["pairs"] = double(world.contact_pair_count());
}
BENCHMARK(BM_SheetCrossings)->Unit(benchmark::kMillisecond)->UseRealTime();

// BM_World48SheetsInContact/1 with WorldDef::contact_rims: the rims' edges against the other
// layers' edges too (docs/architecture.md, sheets through each other). One thread.
void BM_World48SheetsInContactRims(benchmark::State& state) {
  drape::bench::StackContact rims;
  rims.rims = true;
  stack_span(state, 1, touching, rims);
}
BENCHMARK(BM_World48SheetsInContactRims)->UseRealTime();

// Arg: 0 Coulomb friction between the sheets (μ = 0.5), 1 contact damping (α = 2 s/m, the
// default, which stops the layers rattling beside their pins: docs/scene-format.md), 2 both.
// One thread, priced against BM_World48SheetsInContact/1, the frictionless, undamped contact
// (tools/floor_pair.py runs them in alternating rounds).
void BM_World48SheetsInContactDissipative(benchmark::State& state) {
  drape::bench::StackContact contact;
  contact.friction = state.range(0) != 1 ? 0.5 : 0.0;
  contact.damping = state.range(0) != 0 ? 2.0 : 0.0;
  stack_span(state, 1, touching, contact);
}
BENCHMARK(BM_World48SheetsInContactDissipative)->Arg(0)->Arg(1)->Arg(2)->UseRealTime();

// The same two scenes stepped a frame of substeps per call, as a program steps them: the
// sheets apart run contact-free frames (each checked afterwards on its swept boxes); the
// sheets in contact run frames of groups, a column of layers in contact each (kept while no
// two columns come within range: docs/architecture.md, frames of groups).
void BM_World48SheetsApartFrames(benchmark::State& state) {
  stack_span(state, int(state.range(0)), 2.0, {}, drape::bench::frame_substeps);
}
BENCHMARK(BM_World48SheetsApartFrames)->Arg(1)->Arg(2)->UseRealTime();

void BM_World48SheetsInContactFrames(benchmark::State& state) {
  stack_span(state, int(state.range(0)), touching, {}, drape::bench::frame_substeps);
}
BENCHMARK(BM_World48SheetsInContactFrames)->Arg(1)->Arg(2)->UseRealTime();

// Issue 13's set-up, as a user runs it: the same stacks settling for a whole simulated
// second (1,000 substeps of 1 ms, stepped in frames of 10), in contact (layers 10 mm apart)
// or apart (2 m), on 1 or 2 threads. One iteration is the whole second; the `substeps`
// counter turns it into time per substep. The stability guard runs after every frame (about
// 3 % of a bare frame, BM_Feature_guard_per_frame), in contact and apart alike: a stack that
// blows up is reported, not timed (before the contact force's exponent was capped this one
// did, at about 0.4 s, and the benchmark timed the blow-up). Args: in contact (0/1), threads.
void BM_World48SheetsSettling(benchmark::State& state) {
  const bool contact = state.range(0) != 0;
  for (auto _ : state) {
    state.PauseTiming();
    drape::World world = stack_world(int(state.range(1)), contact ? touching : 2.0, {}, /*guard=*/true);
    state.ResumeTiming();
    for (int frame = 0; frame < 100; ++frame) {
      const drape::StabilityReport report = world.step(10);
      if (!report.ok()) {
        state.SkipWithError(("the stack went unstable: " + drape::describe(report)).c_str());
        return;
      }
    }
    state.counters["pairs"] = double(world.contact_pair_count());
  }
  drape::bench::set_point_rate(state, 48.0 * 64 * 64, 1000);
}
BENCHMARK(BM_World48SheetsSettling)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// Self-collision on one 128×128 sheet folded onto itself: its right half turned over its
// left half, 12 mm above it (within contact range), both halves settling under gravity, so
// every point of the fold is in contact range of the other half. Against the same fold
// with self_collision off (the halves then pass through each other unnoticed). Arg:
// self-collision (0/1). One thread, dt = 0.2 ms: points of 61 mg on 100 N/m springs need
// dt < 0.78 ms, and the contact's stiffness at d = 0 (about 3,000 N/m) dt < 0.29 ms.
// Arg 2: self-collision with WorldDef::contact_exact (the reference the walk is held to).
//
// The contact pushes the halves apart: all but a few percent of the points are out of
// range of their mirror point after about 20 substeps, so stepping one world on would
// time a sheet that sprang apart (for how much of the time depends on min_time). Each
// iteration therefore times the same span, substeps 2 … 16 of a fresh fold (made and
// stepped 2 substeps untimed, the first search among them), one step(1) call each, and
// checks that at least
// 90 % of the upper half's points are still within contact range of their mirror point
// below at the end (counter in_range: the smallest share over the iterations).
constexpr int kFoldWarmUp = 2, kFoldSpan = 14;

drape::World folded_sheet(int variant, int threads = 1) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 2e-4;
  wd.threads = threads;
  wd.contact_exact = variant == 2;
  drape::World world(wd);
  drape::SheetDef sd;
  sd.m = sd.n = 127;
  sd.mass = 1.0;
  sd.stiffness = 100.0;
  sd.damping = 1e-3;
  sd.self_collision = variant != 0;
  const drape::SheetId id = world.add_sheet(sd);
  auto s = world.state(id);  // fold: column j > n/2 goes to 2·x_mid − x, 12 mm up
  const double mid = 0.5 * (s.x[64] + s.x[63]);
  for (std::uint32_t i = 0; i <= sd.m; ++i)
    for (std::uint32_t j = 64; j <= sd.n; ++j) {
      const std::uint32_t p = drape::point_index(sd.n, i, j);
      s.x[p] = 2 * mid - s.x[p];
      s.z[p] += 0.012;
    }
  return world;
}

// The share of the upper half's points within `range` of their mirror point below.
double fold_in_range(const drape::World& world, double range) {
  const auto s = world.view(world.sheets()[0]);
  std::size_t near = 0, all = 0;
  for (std::uint32_t i = 0; i <= s.m; ++i)
    for (std::uint32_t j = 64; j <= s.n; ++j, ++all) {
      const std::uint32_t p = drape::point_index(s.n, i, j), q = drape::point_index(s.n, i, s.n - j);
      near += std::hypot(s.x[p] - s.x[q], s.y[p] - s.y[q], s.z[p] - s.z[q]) <= range;
    }
  return double(near) / double(all);
}

void BM_SelfCollisionFold(benchmark::State& state) {
  const int variant = int(state.range(0));
  const drape::WorldDef wd = drape::bench::world_def();
  const double range = wd.contact_thickness + wd.contact_range * wd.contact_xi;
  double in_range = 1;
  std::size_t pairs = 0;
  bool finite = true;
  for (auto _ : state) {
    state.PauseTiming();
    drape::World world = folded_sheet(variant);
    world.step(kFoldWarmUp);
    state.ResumeTiming();
    for (int k = 0; k < kFoldSpan; ++k) world.step(1);
    state.PauseTiming();
    in_range = std::min(in_range, fold_in_range(world, range));
    pairs = world.contact_pair_count();
    finite = finite && world.all_finite();
    state.ResumeTiming();
  }
  state.counters["pairs"] = double(pairs);
  state.counters["in_range"] = in_range;
  if (!finite) state.SkipWithError("the fold blew up; its figures would be meaningless");
  if (variant != 0 && in_range < 0.9) state.SkipWithError("the fold's halves left contact range within the span");
  drape::bench::set_point_rate(state, 128.0 * 128, kFoldSpan);
}
BENCHMARK(BM_SelfCollisionFold)->Arg(0)->Arg(1)->Arg(2)->UseRealTime();

// The same fold with self-collision on 1 and 2 threads (wall time): one sheet is one
// pair, whose kept set a second thread walks in parts (ContactParams::parts).
void BM_SelfCollisionFoldThreads(benchmark::State& state) {
  for (auto _ : state) {
    state.PauseTiming();
    drape::World world = folded_sheet(1, int(state.range(0)));
    world.step(kFoldWarmUp);
    state.ResumeTiming();
    for (int k = 0; k < kFoldSpan; ++k) world.step(1);
  }
  drape::bench::set_point_rate(state, 128.0 * 128, kFoldSpan);
}
BENCHMARK(BM_SelfCollisionFoldThreads)->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime();

// Args: threads, block_points. One 256×256 sheet among eight 32×32 ones: without
// splitting (block_points huge) one core does the large sheet alone.
void BM_WorldOneLargeSheet(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-4;
  wd.threads = int(state.range(0));
  wd.block_points = std::uint32_t(state.range(1));
  drape::World world(wd);
  drape::SheetDef big;
  big.m = big.n = 255;
  big.pins = drape::corner_points(big.m, big.n);
  world.add_sheet(big);
  drape::SheetDef small;
  small.m = small.n = 31;
  small.pins = drape::corner_points(small.m, small.n);
  for (int k = 0; k < 8; ++k) {
    small.center = {2.0 + 1.5 * k, 0.0, 0.0};
    world.add_sheet(small);
  }
  for (auto _ : state) world.step(1);
  report(state, 256.0 * 256 + 8 * 32 * 32);
}
BENCHMARK(BM_WorldOneLargeSheet)
    ->Args({1, 1 << 30})
    ->Args({2, 1 << 30})
    ->Args({2, 8192})
    ->UseRealTime();

// Sheet-sized boxes (1 m at most) scattered in a cube whose volume grows with the count,
// so each box overlaps a few others at every size.
std::vector<drape::detail::Aabb> scattered_boxes(std::size_t count, double side, std::mt19937& rng) {
  std::uniform_real_distribution<double> pos(0.0, side), ext(0.2, 1.0);
  std::vector<drape::detail::Aabb> boxes(count);
  for (auto& b : boxes)
    for (int k = 0; k < 3; ++k) {
      b.lo[k] = pos(rng);
      b.hi[k] = b.lo[k] + ext(rng);
    }
  return boxes;
}

void report_boxes(benchmark::State& state, std::size_t pairs) {
  state.counters["pairs"] = double(pairs);
  state.counters["boxes_per_s"] =
      benchmark::Counter(double(state.range(0)) * double(state.iterations()), benchmark::Counter::kIsRate);
  state.SetComplexityN(state.range(0));
}

// Arg: number of boxes. The tree built from scratch on every call.
void BM_BroadPhase(benchmark::State& state) {
  const auto count = std::size_t(state.range(0));
  std::mt19937 rng(42);
  const auto boxes = scattered_boxes(count, 2.0 * std::cbrt(double(count)), rng);
  drape::detail::BroadPhase bp;
  std::vector<drape::detail::BoxPair> pairs;
  for (auto _ : state) {
    bp.find_pairs(boxes, pairs);
    benchmark::DoNotOptimize(pairs.data());
  }
  report_boxes(state, pairs.size());
}
BENCHMARK(BM_BroadPhase)->RangeMultiplier(10)->Range(10, 10000)->Complexity(benchmark::oNLogN);

// Arg: number of boxes. The broad-phase as the world pays it per substep: the same boxes,
// each moving every call by its own velocity × dt (dt = 1 ms, speeds 0–3 m/s in random
// directions, like falling sheets; bouncing off the cube's walls so the density stays),
// into the tracking broad-phase.
void BM_BroadPhaseTracking(benchmark::State& state) {
  const auto count = std::size_t(state.range(0));
  std::mt19937 rng(42);
  const double side = 2.0 * std::cbrt(double(count)), dt = 1e-3;
  auto boxes = scattered_boxes(count, side, rng);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> speed(0.0, 3.0);
  std::vector<std::array<double, 3>> velocity(count);
  for (auto& v : velocity) {
    double d[3] = {normal(rng), normal(rng), normal(rng)};
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double s = speed(rng) / (norm > 0 ? norm : 1.0);
    v = {s * d[0], s * d[1], s * d[2]};
  }
  drape::detail::TrackingBroadPhase bp;
  std::vector<drape::detail::BoxPair> pairs;
  for (auto _ : state) {
    for (std::size_t i = 0; i < count; ++i)
      for (int k = 0; k < 3; ++k) {
        auto& b = boxes[i];
        if ((b.lo[k] < 0 && velocity[i][k] < 0) || (b.hi[k] > side && velocity[i][k] > 0))
          velocity[i][k] = -velocity[i][k];
        b.lo[k] += velocity[i][k] * dt;
        b.hi[k] += velocity[i][k] * dt;
      }
    bp.find_pairs(boxes, pairs);
    benchmark::DoNotOptimize(pairs.data());
  }
  report_boxes(state, pairs.size());
}
BENCHMARK(BM_BroadPhaseTracking)->RangeMultiplier(10)->Range(10, 10000)->Complexity(benchmark::oN);

// The world step the broad-phase is a part of, at 10,000 sheets: small sheets (8×8 points,
// 0.3 m) scattered like BM_BroadPhase's boxes, a few in contact range of each other. The
// report prints BM_BroadPhaseTracking/10000 as a share of this.
void BM_WorldStep10kSheets(benchmark::State& state) {
  drape::WorldDef wd = drape::bench::world_def();
  wd.dt = 1e-3;
  wd.threads = int(state.range(0));
  drape::World world(wd);
  std::mt19937 rng(42);
  const std::size_t count = 10000;
  const double side = 2.0 * std::cbrt(double(count));
  std::uniform_real_distribution<double> pos(0.0, side);
  drape::SheetDef sd;
  sd.m = sd.n = 7;
  sd.width = sd.height = 0.3;
  sd.mass = 0.05;
  sd.stiffness = 50.0;
  for (std::size_t k = 0; k < count; ++k) {
    sd.center = {pos(rng), pos(rng), pos(rng)};
    world.add_sheet(sd);
  }
  world.step(1);
  for (auto _ : state) world.step(1);
  state.counters["pairs"] = double(world.contact_pair_count());
  report(state, double(count) * 64);
}
BENCHMARK(BM_WorldStep10kSheets)->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
