// `drape batch`: many scene files, each run as `drape run` would into a folder of its own,
// in parallel (and, under mpirun, dealt out to the ranks, cluster.h), with one summary row
// per scene. A scene that cannot be read or run is reported in its row; the others still run.
#pragma once

#include <filesystem>
#include <optional>
#include <ostream>
#include <vector>

#include "cluster.h"
#include "scene.h"

namespace drape::app {

struct BatchOptions {
  std::vector<std::filesystem::path> scenes;
  std::filesystem::path out_dir;                   // scene k writes into out_dir / its file's stem
  std::optional<int> frames;                       // overrides each scene's frame count
  std::optional<std::vector<MeshFormat>> formats;  // overrides each scene's output.formats
  int threads = 0;                                 // scenes in parallel per rank; 0: all cores
};

// Output folder names, one per scene: the file's stem. Empty optional when two scenes share
// a stem (`error` names them): their frames would land in one folder.
std::optional<std::vector<std::string>> batch_folders(const std::vector<std::filesystem::path>& scenes, std::string& error);

// The whole subcommand: every rank runs its scenes; rank 0 writes OUT/batch.csv (scene,
// output, status, frames, wall_time_s, message) atomically once all have finished. Returns
// exit_ok when every scene ran to its end, exit_cases_failed when some did not (each named in
// its row and on `log`), exit_usage for clashing folder names. Only rank 0 writes to `log`.
int run_batch(const BatchOptions& options, std::ostream& log, const Cluster& cluster);

}  // namespace drape::app
