// `drape view OUT_DIR`: serves the browser viewer (apps/viewer) and OUT_DIR/run.glb on
// localhost until interrupted. The server is a few lines of our own rather than an exec of
// `python3 -m http.server`: that serves one folder, and the viewer and the run live in two,
// so it would have to copy the viewer into the user's output folder; and drape would need a
// Python at run time for nothing else.
#pragma once

#include <CLI/CLI.hpp>

#include <ostream>
#include <string>

namespace drape::app {

struct ViewArgs {
  std::string out_dir;     // holds run.glb (drape run --format glb)
  int port = 8018;         // 0: any free port
  std::string viewer_dir;  // the built viewer (index.html, viewer.js); empty: the build's
};

CLI::App* add_view_subcommand(CLI::App& app, ViewArgs& args);

// Serves until the process is stopped; prints the address (with the port actually bound) as
// its first line on `log`. Returns an ExitCode (run.h) only when it cannot start.
int view_command(const ViewArgs& args, std::ostream& log);

}  // namespace drape::app
