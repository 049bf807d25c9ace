// `drape render`: a wireframe or shaded PNG of one frame — or a strip of several, left to right, like the
// paper's animation figures — from a scene file (simulated up to that frame) or from a folder
// `drape run` wrote (the frame's mesh read back, exactly as it was written).
#pragma once

#include <CLI/CLI.hpp>

#include <ostream>
#include <string>
#include <vector>

namespace drape::app {

struct RenderArgs {
  std::string input;             // scene file, or output folder of `drape run`
  std::vector<int> frames;       // one panel each, left to right; empty: the last frame
  std::string camera;            // parse_camera() overrides of the scene's or automatic camera
  std::string size = "800x600";  // WxH pixels of one panel
  bool see_through = false;      // sheets do not hide what is behind them
  std::string style = "wireframe";  // or "shaded"
  std::string surface = "grid";     // shaded: grid, bezier or bspline (render/surface.h)
  int surface_samples = 0;          // shaded: samples per grid cell; 0: 1 for grid, 4 otherwise
  std::string output;            // the PNG
};

// Adds the subcommand and its options (bound to `args`) to the program.
CLI::App* add_render_subcommand(CLI::App& app, RenderArgs& args);

// Renders and writes the PNG; messages go to `log`. Returns an ExitCode (run.h). On any
// error nothing is written.
int render_command(const RenderArgs& args, std::ostream& log);

}  // namespace drape::app
