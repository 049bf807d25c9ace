// `drape run` and `drape info`: step a loaded scene and write its frames; describe a scene.
// Both are generic over the scene's precision (BasicWorld<double> or BasicWorld<float>).
#pragma once

#include <csignal>
#include <filesystem>
#include <optional>
#include <ostream>
#include <vector>

#include <render/render.h>

#include "scene.h"

namespace drape::app {

// Exit codes of the drape program (docs/cli.md).
enum ExitCode : int {
  exit_ok = 0,
  exit_unstable = 1,    // the simulation became non-finite; frames written before stay valid
  exit_usage = 2,       // bad command line
  exit_bad_scene = 3,   // the scene file is unreadable or invalid; nothing written
  exit_write_failed = 4,  // an output file could not be written
  exit_bad_checkpoint = 5,  // --resume: no usable checkpoint (missing, damaged, other version or scene)
  exit_cases_failed = 6,    // sweep, batch: some runs failed; every other result is written
  exit_failed = 7,          // anything else that stopped the program (out of memory, an engine error)
};

// The checkpoint `drape run --checkpoint-every N` keeps in its output folder (replaced
// atomically each time) and `--resume DIR` reads.
inline constexpr const char* checkpoint_file_name = "checkpoint.drape";
// The whole run as glTF (format glb), written when the run ends.
inline constexpr const char* glb_file_name = "run.glb";

struct RunOptions {
  std::optional<std::filesystem::path> out_dir;      // overrides the scene's output.dir
  std::optional<int> frames;                         // overrides the scene's frame count
  std::optional<std::vector<MeshFormat>> formats;    // overrides the scene's output.formats
  int threads = 0;                                   // 0: all cores
  bool progress_bar = false;                         // true on a terminal: one redrawn line
  int checkpoint_every = 0;                          // frames between checkpoints; 0: none
  // Set (to a signal's number) when the program is asked to stop, e.g. by main's handler of
  // Ctrl-C: the run then ends after the frame it is stepping, as at the end of the scene,
  // with a checkpoint of that frame when it keeps them, and returns 128 + the number.
  const volatile std::sig_atomic_t* stop = nullptr;
  // Continue from DIR/checkpoint.drape, writing the remaining frames into DIR (which
  // replaces out_dir). The checkpoint must come from the same scene (its fingerprint).
  std::optional<std::filesystem::path> resume_dir;
  // The glb format's surface over each sheet's grid, and its samples per cell (gltf.h).
  render::SurfaceKind surface = render::SurfaceKind::Grid;
  int surface_samples = 1;
};

// The scene's world with every sheet and obstacle added; `ids` gets the sheets' ids in the
// scene's order. Stepping it `substeps` at a time gives exactly the frames `drape run` writes.
// Throws SceneError, building nothing, when a constraint names a sheet or obstacle the
// scene lacks (a Scene changed after load_scene checked it).
template <class Real>
BasicWorld<Real> build_world(const Scene& scene, int threads, std::vector<SheetId>& ids);

// Steps the scene and writes frames 0..frames (0 is the initial state), or up to the frame
// it was stepping when options.stop was set. Messages (warnings,
// progress, errors) go to `log`. Returns an ExitCode.
int run_scene(const Scene& scene, const RunOptions& options, std::ostream& log);

// Writes points, springs, memory and the stable step per integrator to `out`.
void describe_scene(const Scene& scene, std::ostream& out);

// Largest stable dt per integrator for one sheet, from the engine's Gershgorin estimate for
// semi-implicit Euler (2/ω_max). Forward Euler grows every undamped oscillation; with
// damping γ = c/m per point it is stable for dt < γ/ω², i.e. γ·dt_se²/4 at ω_max.
struct StableSteps {
  double semi_implicit_euler;
  double forward_euler;  // 0 when the sheet has no damping
};
StableSteps stable_steps(const SheetDef& sheet, double semi_implicit_estimate);

}  // namespace drape::app
