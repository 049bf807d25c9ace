// What the shipped scenes cost as a user runs them (issue 13: "the many-sheet scenes in
// scenes/ at least 10× faster than today"): each scene file read by the drape program's own
// loader, its world built as `drape run` builds it, then stepped from its first frame for
// `span_seconds` of simulated time (or its whole run if shorter) in the scene's frames, with
// no frames written. One iteration is the whole span, from a fresh world (built outside the
// timed region), repeated until the iterations add up to at least `min_seconds` (CPU time
// on one thread, wall time on two): a scene whose span takes milliseconds is timed over
// hundreds of spans, not one, so its ratio to the baseline is a measurement, not noise.
// Args: threads.
//
// tools/scenes_baseline.py builds this same file against an older commit's engine and
// records its rates in docs/scenes-baseline.json; the report divides today's by them.
// The scenes are read from $DRAPE_SCENES_DIR when set (the baseline script points the old
// build at today's files, so both measure the same scenes), else from this tree's scenes/.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "run.h"
#include "scene.h"

namespace {

// Enough simulated time for the sheets of every scene to meet each other or their obstacle
// (stack_sphere's layers touch from the start, rain_torus's first sheets land on the torus
// within it), short enough that the slowest scene takes seconds, not minutes.
constexpr double span_seconds = 1.0;

// Timed seconds per scene and thread count at least: the slowest scenes' single span is
// longer, and runs once.
constexpr double min_seconds = 1.0;

// The scenes with several sheets, and the one-sheet scenes of issues 12 and 14 that drape a
// sheet over an obstacle or move it along a constraint.
const char* const scene_names[] = {"stack_sphere", "rain_torus", "sewn_box",     "fig05",
                                   "fig06",        "tablecloth", "curtain_rail", "cape_sphere"};

std::filesystem::path scenes_dir() {
  if (const char* dir = std::getenv("DRAPE_SCENES_DIR"); dir && *dir) return dir;
#ifdef DRAPE_SCENES_DIR
  return DRAPE_SCENES_DIR;
#else  // built by an older bench/CMakeLists.txt that does not name it
  return "scenes";
#endif
}

template <class Real>
void step_scene(benchmark::State& state, const drape::app::Scene& scene) {
  const int threads = int(state.range(0));
  const int frames = std::max(1, std::min(scene.frames, int(std::lround(span_seconds / scene.frame_time()))));
  double points = 0;
  for (const drape::SheetDef& sd : scene.sheets) points += double(sd.m + 1) * double(sd.n + 1);
  for (auto _ : state) {
    state.PauseTiming();
    std::vector<drape::SheetId> ids;
    drape::BasicWorld<Real> world = drape::app::build_world<Real>(scene, threads, ids);
    state.ResumeTiming();
    for (int frame = 0; frame < frames; ++frame) world.step(scene.substeps);
    if (!world.all_finite()) {
      state.SkipWithError("the scene became non-finite; its figures would be meaningless");
      return;
    }
  }
  const double substeps = double(frames) * scene.substeps;
  const double simulated = substeps * scene.world.dt;
  state.counters["sheets"] = double(scene.sheets.size());
  state.counters["threads"] = threads;
  state.counters["simulated_s"] = simulated;
  state.counters["simulated_s_per_s"] =
      benchmark::Counter(simulated * double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["s_per_simulated_s"] = benchmark::Counter(
      simulated * double(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["points"] = points;
  state.counters["substeps"] = substeps;
  state.counters["point_steps_per_s"] =
      benchmark::Counter(points * substeps * double(state.iterations()), benchmark::Counter::kIsRate);
}

// Scene file `name` as the drape program reads it, or nothing when it cannot be read (the
// benchmark is then skipped with the loader's message).
std::optional<drape::app::Scene> load(benchmark::State& state, const std::string& name) {
  try {
    return drape::app::load_scene(scenes_dir() / (name + ".json"));
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return std::nullopt;
  }
}

void step_in_its_precision(benchmark::State& state, const drape::app::Scene& scene) {
  if (scene.precision == drape::app::Precision::Float32)
    step_scene<float>(state, scene);
  else
    step_scene<double>(state, scene);
}

void BM_Scene(benchmark::State& state, const std::string& name) {
  if (const auto scene = load(state, name)) step_in_its_precision(state, *scene);
}

// The same scene without what its sheets meet: no contacts (between sheets or of a sheet
// with itself), no obstacles and no constraint riding on one (a carrier); its sheets, their
// terms and other constraints as they are. An explicit substep costs the same whatever the
// sheets' state, so this is the part of the scene's cost that no contact or obstacle work
// removes: the baseline's time over this one is the most × that work could give (the
// report's bound beside issue 13's 10×). One thread.
void BM_SceneSheetsAlone(benchmark::State& state, const std::string& name) {
  auto scene = load(state, name);
  if (!scene) return;
  scene->world.contact_strength = 0;
  scene->obstacles.clear();
  std::erase_if(scene->constraints, [](const drape::ConstraintDef& c) { return c.carrier.has_value(); });
  for (drape::SheetDef& sd : scene->sheets) sd.self_collision = false;
  step_in_its_precision(state, *scene);
}

// One thread in CPU time, the engine's cost as free of other jobs on a shared machine as a
// figure gets; two threads in wall time, which is what two threads buy.
[[maybe_unused]] const bool registered = [] {
  for (const char* name : scene_names) {
    const std::string label = std::string("BM_Scene/") + name;
    benchmark::RegisterBenchmark(label.c_str(), BM_Scene, std::string(name))
        ->Arg(1)
        ->ArgName("threads")
        ->MinTime(min_seconds)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(label.c_str(), BM_Scene, std::string(name))
        ->Arg(2)
        ->ArgName("threads")
        ->MinTime(min_seconds)
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((std::string("BM_SceneSheetsAlone/") + name).c_str(), BM_SceneSheetsAlone,
                                 std::string(name))
        ->Arg(1)
        ->ArgName("threads")
        ->MinTime(min_seconds)
        ->Unit(benchmark::kMillisecond);
  }
  return true;
}();

}  // namespace
