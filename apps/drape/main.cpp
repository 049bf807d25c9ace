// drape: the command-line program. Subcommands: run (step a scene, write meshes) and info
// (size, memory, stable steps). Exit codes are ExitCode in run.h, listed in docs/cli.md.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <sstream>

#include "render_command.h"
#include "run.h"
#include "scene.h"

namespace {

using namespace drape::app;

// "obj,ply" (CLI11 splits on commas) → formats; one message for an unknown name.
std::optional<std::vector<MeshFormat>> parse_formats(const std::vector<std::string>& names, std::string& error) {
  std::vector<MeshFormat> formats;
  for (const auto& name : names) {
    const auto f = mesh_format_from_name(name);
    if (!f) {
      error = "--format: unknown format \"" + name + "\" (known: obj, ply, vtk)";
      return std::nullopt;
    }
    if (std::find(formats.begin(), formats.end(), *f) == formats.end()) formats.push_back(*f);
  }
  return formats;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"drape: elastic sheets as mass-spring grids (Gudukbay, Ozguc, Tokad 1997).\n"
               "Exit codes: 0 ok, 1 simulation became unstable, 2 bad command line, 3 bad scene file, "
               "4 output could not be written."};
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
  run->add_option("--threads", threads, "Worker threads (default 0: all cores)")->check(CLI::NonNegativeNumber);
  run->add_option("--format", formats, "Comma-separated mesh formats: obj, ply, vtk (default: the scene's)")
      ->delimiter(',');

  CLI::App* info = app.add_subcommand("info", "Print points, springs, memory and the stable step per integrator");
  info->add_option("SCENE", scene_file, "Scene file (JSON)")->required();

  RenderArgs render_args;  // `drape render`: render_command.h
  CLI::App* render = add_render_subcommand(app, render_args);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? exit_ok : exit_usage;
  }
  if (render->parsed()) return render_command(render_args, std::cerr);

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
    options.progress_bar = isatty(fileno(stderr)) != 0;
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
