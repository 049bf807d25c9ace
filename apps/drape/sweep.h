// `drape sweep`: many independent runs (several scenes, and/or one scene over a grid of
// parameter values), run in parallel, one outcome row each in a CSV. Each run is a whole
// `drape run` without files: the same scene text, overrides and step count give the same
// final state bit for bit, so a row can be checked against a single run. Under mpirun the
// runs are dealt out to the ranks (cluster.h) and rank 0 writes the very same CSV.
#pragma once

#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include "cluster.h"
#include "scene.h"

namespace drape::app {

// `--set PATH=V1,V2,...`: one axis of the grid.
struct SweepParameter {
  std::string path;                 // as in SceneOverride
  std::vector<std::string> values;  // as written, each a SceneOverride value
};
// Splits "PATH=V1,V2" at the first '=' and at commas outside [], {} and quotes, so a value
// may be a JSON array ("gravity=[0,0,-9.81],[0,0,-1.62]"). Empty optional: malformed.
std::optional<SweepParameter> parse_sweep_parameter(std::string_view text);

struct SweepOptions {
  std::vector<std::filesystem::path> scenes;
  std::vector<SweepParameter> parameters;  // the grid is their Cartesian product
  std::optional<int> frames;               // overrides each scene's frame count
  int threads = 0;                         // runs in parallel; 0: all cores
  bool progress_bar = false;               // true on a terminal: one redrawn line (progress.h)
};

// One run of the grid. Row order: scenes in the order given; within a scene the first
// parameter varies slowest and the last fastest (like nested loops in the order given).
struct SweepCase {
  std::size_t scene_index = 0;
  std::vector<std::string> values;  // one per parameter
  Scene scene;                      // the file with the values applied, already checked
};
// Loads every scene with every combination; throws SceneError for the first bad one, so
// nothing runs unless every run can.
std::vector<SweepCase> plan_sweep(const SweepOptions& options);

struct SweepOutcome {
  // Every position and velocity stayed finite and the total energy never rose above its
  // start by more than the scene's energy scale (sweep.cpp): a passive system cannot gain it.
  bool stable = true;
  int frames_run = 0;       // frames completed before the state went unstable
  // Of the final state (empty in the CSV when unstable):
  double max_sag = 0;       // m: max over all points of (initial z − final z)
  double max_strain = 0;    // max over sheets of SheetDiagnostics::max_strain
  double total_energy = 0;  // J: Energies::total() summed over sheets
  double wall_seconds = 0;
  // Why the run could not be made (an exception from the engine, out of memory, ...); empty
  // when it ran. A failed run is reported in its row; every other run keeps its result.
  std::string error;
};
// Steps one scene single-threaded for `frames` (default: its own) frames, checking the state
// is finite after every frame.
SweepOutcome simulate(const Scene& scene, std::optional<int> frames = std::nullopt);
// All cases in parallel (TBB over runs, `threads` workers, 0: all cores); result k is case k.
// `finished`, when given, is called (from a worker thread) after each run.
std::vector<SweepOutcome> run_sweep_cases(std::span<const SweepCase> cases, std::optional<int> frames, int threads,
                                          const std::function<void()>& finished = {});

// The parallel loop of sweeps and batches: run_case(k) for each case k < total of this rank
// (cluster.my_cases), `threads` at a time (0: all cores), each returning its result as bytes.
// Rank 0 gets every case's bytes in case order, the other ranks an empty vector. An exception
// from run_case is not caught here: run_case turns its own failures into results.
// `finished`, when given, is called (from a worker thread) after each of this rank's runs.
std::vector<std::string> run_spread(const Cluster& cluster, std::size_t total, int threads,
                                    const std::function<std::string(std::size_t)>& run_case,
                                    const std::function<void()>& finished = {});

// The results of a plan's runs, kept as they finish in a folder beside the output (one file per
// process, a line per run: the plan's fingerprint, the run's index, its result's bytes in hex),
// so a sweep or batch that is killed, loses a rank or cannot write its table loses nothing
// computed: the same command again reads them back and runs only the rest. The caller removes
// the folder once its output is written.
class RunJournal {
 public:
  RunJournal(std::filesystem::path dir, std::uint64_t plan);
  ~RunJournal();
  RunJournal(const RunJournal&) = delete;
  RunJournal& operator=(const RunJournal&) = delete;
  // Results of this plan any process recorded, by run index; lines of another plan, of fewer
  // than `min_bytes` bytes or cut short by a kill are skipped.
  std::map<std::size_t, std::string> read(std::size_t min_bytes) const;
  // Appends one run's result (from any thread), flushed at once so a kill keeps it.
  void record(std::size_t k, const std::string& bytes);
  void remove() const;

 private:
  std::filesystem::path dir_;
  std::string plan_;
  std::mutex mutex_;
  std::FILE* file_ = nullptr;
};
// FNV-1a 64 of a plan's description: equal descriptions, equal runs.
std::uint64_t fingerprint_of(const std::string& identity);

// CSV helpers shared by the sweep's and the batch's tables: RFC 4180 quoting (a field holding
// a comma, quote or line break), and numbers in shortest round-trip form.
std::string csv_field(const std::string& s);
std::string shortest_number(double v);

// Header: scene, one column per parameter path, stable, frames, max_sag_m, max_strain,
// total_energy_J, wall_time_s, error. Numbers in shortest round-trip form.
void write_sweep_csv(std::ostream& out, const SweepOptions& options, std::span<const SweepCase> cases,
                     std::span<const SweepOutcome> outcomes);

// The whole subcommand: plan, run this rank's cases, gather, and (rank 0) write `csv`
// atomically. Finished runs are kept in `csv`.journal/ until the CSV is written, and an
// earlier attempt's are taken from there instead of being run again. Returns an ExitCode (run.h): unstable runs are outcomes (a row with stable =
// false), not errors; runs that failed make it exit_cases_failed, with every row written.
// Only rank 0 writes to `log`, but for a scene that only another rank cannot read (no shared
// file system there): that rank says so, and every rank stops before running anything.
int run_sweep(const SweepOptions& options, const std::filesystem::path& csv, std::ostream& log, const Cluster& cluster);

}  // namespace drape::app
