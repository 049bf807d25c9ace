// drape: the command-line program. Subcommands: run (step a scene, write meshes), render,
// sweep and batch (many runs; across MPI ranks under mpirun) and info (size, memory, stable
// steps). Exit codes are ExitCode in run.h, listed in docs/cli.md.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <sstream>
#include <string_view>

#include <render/surface.h>

#include "batch.h"
#include "cluster.h"
#include "progress.h"
#include "render_command.h"
#include "run.h"
#include "scene.h"
#include "sweep.h"
#include "view_command.h"

namespace {

using namespace drape::app;

// "obj,ply" (CLI11 splits on commas) → formats; one message for an unknown name.
std::optional<std::vector<MeshFormat>> parse_formats(const std::vector<std::string>& names, std::string& error) {
  std::vector<MeshFormat> formats;
  for (const auto& name : names) {
    const auto f = mesh_format_from_name(name);
    if (!f) {
      error = "--format: unknown format \"" + name + "\" (known: obj, ply, vtk, glb)";
      return std::nullopt;
    }
    if (std::find(formats.begin(), formats.end(), *f) == formats.end()) formats.push_back(*f);
  }
  return formats;
}

// The processes this sweep or batch runs on (cluster.h); null after saying why there are none.
std::unique_ptr<Cluster> join_cluster(const char* command) {
  try {
    return std::make_unique<Cluster>();
  } catch (const std::runtime_error& e) {
    std::cerr << "drape " << command << ": " << e.what() << '\n';
    return nullptr;
  }
}

// Ctrl-C (SIGINT) or SIGTERM during drape run: the first asks the run to stop after the
// frame it is stepping (RunOptions::stop), so its output folder holds a whole run, and puts
// the signals back to their default, so a second one stops the program at once.
volatile std::sig_atomic_t stop_signal = 0;

extern "C" void on_stop_signal(int signal_number) {
  stop_signal = signal_number;
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  static const char message[] = "\ndrape: stopping after this frame (again to stop at once)\n";
  [[maybe_unused]] const auto written = ::write(STDERR_FILENO, message, sizeof message - 1);
}

void stop_after_frame_on_signals() {
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  action.sa_flags = SA_RESTART;  // a write or fsync the signal lands in goes on, not EINTR
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

// Ctrl-C (SIGINT) or SIGTERM during drape sweep or batch: the process stops at once, as
// without a handler (a sweep's run is short, a batch's scene is run again whole), after
// saying what is kept: the runs or scenes already finished are in the journal, which the
// same command reads (sweep.h, RunJournal). Only the rank that writes the CSV says it.
char interrupted_message[1024] = {};

extern "C" void on_interrupt(int signal_number) {
  [[maybe_unused]] const auto written = ::write(STDERR_FILENO, interrupted_message, std::strlen(interrupted_message));
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

void say_what_is_kept_on_signals(const Cluster& cluster, const char* command, const std::string& journal,
                                 const char* finished) {
  if (!cluster.is_root()) return;
  std::snprintf(interrupted_message, sizeof interrupted_message,
                "\ndrape %s: interrupted; the %s already finished are kept in %s: the same command again runs only "
                "the others\n",
                command, finished, journal.c_str());
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
}

}  // namespace

int drape_main(int argc, char** argv) {
  CLI::App app{"drape: elastic sheets as mass-spring grids (Gudukbay, Ozguc, Tokad 1997).\n"
               "Exit codes: 0 ok, 1 simulation became unstable, 2 bad command line, 3 bad scene file, "
               "4 output could not be written, 5 checkpoint cannot be resumed, 6 some runs of a sweep or batch failed, 7 any other failure (out of memory, an error of drape's own), 130/143 run stopped by Ctrl-C/SIGTERM after a whole frame."};
  app.require_subcommand(1);

  std::string scene_file;
  std::string out_dir;
  int frames = 0, threads = 0;
  std::vector<std::string> formats;

  CLI::App* run = app.add_subcommand("run", "Step a scene and write its frames as meshes (frame_00000.obj, ...)");
  run->add_option("SCENE", scene_file, "Scene file (JSON, docs/scene-format.md)")->required();
  run->add_option("--out", out_dir, "Output folder (default: the scene's output.dir)");
  run->add_option("--frames", frames, "Frames to write after the initial one (default: the scene's)")
      ->check(CLI::PositiveNumber);
  run->add_option("--threads", threads, "Worker threads (default 0: all cores)")->check(CLI::Range(0, drape::max_threads));
  run->add_option("--format", formats, "Comma-separated mesh formats: obj, ply, vtk (per frame), glb (the whole run in OUT/run.glb) "
                  "(default: the scene's)")
      ->delimiter(',');

  std::string surface = "grid";
  int surface_samples = 0;
  run->add_option("--surface", surface,
                  "glb: the surface exported over each sheet's grid: grid (default), bezier (the paper's Bezier "
                  "surface, bicubic pieces) or bspline (uniform bicubic B-spline)")
      ->check(CLI::IsMember({"grid", "bezier", "bspline"}));
  run->add_option("--surface-samples", surface_samples,
                  "glb: samples per grid cell along each side (default 1 for grid, 4 otherwise)")
      ->check(CLI::Range(1, 64));

  int checkpoint_every = 0;
  std::string resume_dir;
  run->add_option("--checkpoint-every", checkpoint_every,
                  "Write the full state to OUT/checkpoint.drape every N frames (atomically)")
      ->check(CLI::PositiveNumber);
  run->add_option("--resume", resume_dir,
                  "Continue from DIR/checkpoint.drape of the same scene, writing the remaining frames into DIR")
      ->excludes("--out");

  std::vector<std::string> sweep_scenes, sweep_sets;
  std::string sweep_csv;
  int sweep_frames = 0, sweep_threads = 0;
  CLI::App* sweep = app.add_subcommand("sweep", "Run scenes over a grid of parameter values in parallel; one CSV row per run");
  sweep->add_option("SCENES", sweep_scenes, "Scene files (JSON)")->required();
  sweep->add_option("--set", sweep_sets, "PATH=V1,V2,...: values for a scene field, e.g. sheets[*].stiffness=10,100")
      ->take_all()
      ->allow_extra_args(false);
  sweep->add_option("--out", sweep_csv, "CSV file to write (atomically)")->required();
  sweep->add_option("--frames", sweep_frames, "Frames per run (default: each scene's)")->check(CLI::PositiveNumber);
  sweep->add_option("--threads", sweep_threads, "Runs in parallel per process (default 0: all cores, shared by the "
                                                "MPI ranks on a machine)")
      ->check(CLI::Range(0, drape::max_threads));

  std::vector<std::string> batch_scenes, batch_formats;
  std::string batch_out;
  int batch_frames = 0, batch_threads = 0;
  CLI::App* batch = app.add_subcommand("batch", "Run many scenes, each as drape run into OUT/<scene name>, in parallel; "
                                                "OUT/batch.csv says how each went");
  batch->add_option("SCENES", batch_scenes, "Scene files (JSON)")->required();
  batch->add_option("--out", batch_out, "Output folder")->required();
  batch->add_option("--frames", batch_frames, "Frames per scene (default: each scene's)")->check(CLI::PositiveNumber);
  batch->add_option("--threads", batch_threads, "Scenes in parallel per process (default 0: all cores, shared by the "
                                                "MPI ranks on a machine)")
      ->check(CLI::Range(0, drape::max_threads));
  batch->add_option("--format", batch_formats,
                    "Comma-separated mesh formats: obj, ply, vtk (per frame), glb (each scene's whole run in "
                    "OUT/<scene>/run.glb) (default: each scene's)")
      ->delimiter(',');

  CLI::App* info = app.add_subcommand("info", "Print points, springs, memory and the stable step per integrator");
  info->add_option("SCENE", scene_file, "Scene file (JSON)")->required();

  RenderArgs render_args;  // `drape render`: render_command.h
  CLI::App* render = add_render_subcommand(app, render_args);
  ViewArgs view_args;  // `drape view`: view_command.h
  CLI::App* view = add_view_subcommand(app, view_args);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? exit_ok : exit_usage;
  }
  if (render->parsed()) return render_command(render_args, std::cerr);
  if (view->parsed()) return view_command(view_args, std::cerr);

  RunOptions options;
  if (run->parsed()) {
    if (!out_dir.empty()) options.out_dir = out_dir;
    if (frames > 0) options.frames = frames;
    options.threads = threads;
    if (!formats.empty()) {
      std::string error;
      options.formats = parse_formats(formats, error);
      if (!options.formats) {
        std::cerr << "drape run: " << error << '\n';
        return exit_usage;
      }
    }
    options.progress_bar = stderr_is_terminal();
    options.surface = *drape::render::surface_kind_from_name(surface);  // checked by the option
    options.surface_samples = surface_samples > 0 ? surface_samples : (surface == "grid" ? 1 : 4);
    options.checkpoint_every = checkpoint_every;
    if (!resume_dir.empty()) options.resume_dir = resume_dir;
    options.stop = &stop_signal;
    stop_after_frame_on_signals();
  }

  if (sweep->parsed()) {
    SweepOptions sweep_options;
    sweep_options.scenes.assign(sweep_scenes.begin(), sweep_scenes.end());
    for (const auto& text : sweep_sets) {
      auto p = parse_sweep_parameter(text);
      if (!p) {
        std::cerr << "drape sweep: --set " << text << ": expected PATH=V1,V2,... (e.g. sheets[*].stiffness=10,100)\n";
        return exit_usage;
      }
      // twice, the runs took one value and the CSV showed both
      for (const SweepParameter& q : sweep_options.parameters)
        if (q.path == p->path) {
          std::cerr << "drape sweep: --set " << p->path << " is given twice; list all of its values in one --set "
                    << p->path << "=V1,V2,...\n";
          return exit_usage;
        }
      sweep_options.parameters.push_back(std::move(*p));
    }
    if (sweep_frames > 0) sweep_options.frames = sweep_frames;
    sweep_options.threads = sweep_threads;
    sweep_options.progress_bar = stderr_is_terminal();
    const auto joined = join_cluster("sweep");
    if (!joined) return exit_usage;
    const Cluster& cluster = *joined;
    say_what_is_kept_on_signals(cluster, "sweep", sweep_csv + ".journal", "runs");
    return run_sweep(sweep_options, sweep_csv, std::cerr, cluster);
  }

  if (batch->parsed()) {
    BatchOptions batch_options;
    batch_options.scenes.assign(batch_scenes.begin(), batch_scenes.end());
    batch_options.out_dir = batch_out;
    if (batch_frames > 0) batch_options.frames = batch_frames;
    batch_options.threads = batch_threads;
    if (!batch_formats.empty()) {
      std::string error;
      batch_options.formats = parse_formats(batch_formats, error);
      if (!batch_options.formats) {
        std::cerr << "drape batch: " << error << '\n';
        return exit_usage;
      }
    }
    const auto joined = join_cluster("batch");
    if (!joined) return exit_usage;
    const Cluster& cluster = *joined;
    say_what_is_kept_on_signals(cluster, "batch", (batch_options.out_dir / "batch.csv.journal").string(), "scenes");
    return run_batch(batch_options, std::cerr, cluster);
  }

  Scene scene;
  try {
    scene = load_scene(scene_file);
  } catch (const SceneError& e) {
    std::cerr << "drape: " << e.what() << '\n';
    return exit_bad_scene;
  }
  if (info->parsed()) {
    describe_scene(scene, std::cout);
    return exit_ok;
  }
  return run_scene(scene, options, std::cerr);
}

// What the subcommands do not catch themselves (running out of memory, an argument the
// engine refuses that no reader checked) still ends in one line and an exit code, not an
// abort; frames written before stay intact.
int main(int argc, char** argv) {
  try {
    return drape_main(argc, argv);
  } catch (const std::bad_alloc&) {
    std::cerr << "drape: out of memory\n";
  } catch (const std::exception& e) {
    std::string_view what = e.what();
    if (what.starts_with("drape: ")) what.remove_prefix(7);  // the engine's messages name it already
    std::cerr << "drape: " << what << '\n';
  }
  return exit_failed;
}
