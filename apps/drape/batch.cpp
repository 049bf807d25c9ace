// `drape batch`: each scene is a whole `drape run` (run_scene) into OUT/<stem>, one thread per
// scene, scenes in parallel; failures become rows of OUT/batch.csv, never a lost batch.
#include "batch.h"

#include <chrono>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include "export.h"
#include "run.h"
#include "sweep.h"

namespace drape::app {

namespace {

// What one scene's run came to, as it travels from its rank to rank 0.
struct BatchResult {
  int code = exit_ok;     // run_scene's ExitCode; exit_bad_scene when the file did not load
  int frames = 0;         // frames the scene asked for (0 when it did not load)
  double wall_seconds = 0;
  std::string message;    // the run's last line of log when it did not succeed
};

constexpr std::size_t result_head = sizeof(BatchResult::code) + sizeof(BatchResult::frames) +
                                    sizeof(BatchResult::wall_seconds);

std::string encode(const BatchResult& r) {
  char head[result_head];
  std::memcpy(head, &r.code, sizeof r.code);
  std::memcpy(head + sizeof r.code, &r.frames, sizeof r.frames);
  std::memcpy(head + sizeof r.code + sizeof r.frames, &r.wall_seconds, sizeof r.wall_seconds);
  return std::string(head, sizeof head) + r.message;
}

BatchResult decode(const std::string& bytes) {
  BatchResult r;
  std::memcpy(&r.code, bytes.data(), sizeof r.code);
  std::memcpy(&r.frames, bytes.data() + sizeof r.code, sizeof r.frames);
  std::memcpy(&r.wall_seconds, bytes.data() + sizeof r.code + sizeof r.frames, sizeof r.wall_seconds);
  r.message = bytes.substr(result_head);
  return r;
}

std::string_view status_name(int code) {
  switch (code) {
    case exit_ok: return "ok";
    case exit_unstable: return "unstable";
    case exit_bad_scene: return "bad_scene";
    case exit_write_failed: return "write_failed";
    default: return "failed";
  }
}

// The last non-empty line of a run's log, without the "drape: " every line starts with.
std::string last_line(const std::string& log) {
  std::istringstream in(log);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last.rfind("drape: ", 0) == 0 ? last.substr(7) : last;
}

BatchResult run_one(const std::filesystem::path& file, const std::filesystem::path& dir, const BatchOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  BatchResult r;
  std::ostringstream log;
  try {
    const Scene scene = load_scene(file);
    r.frames = options.frames.value_or(scene.frames);
    RunOptions run;
    run.out_dir = dir;
    run.frames = options.frames;
    run.formats = options.formats;
    run.threads = 1;  // the batch is parallel over scenes; a run's frames never depend on threads
    r.code = run_scene(scene, run, log);
    if (r.code != exit_ok) r.message = last_line(log.str());
  } catch (const SceneError& e) {
    r.code = exit_bad_scene;
    r.message = e.what();
  } catch (const std::exception& e) {
    r.code = -1;
    r.message = e.what();
  }
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

// Equal for the same batch: the scene files (paths and bytes), --frames and --format.
std::uint64_t batch_fingerprint(const BatchOptions& options) {
  std::string identity = std::to_string(options.frames.value_or(0));
  for (MeshFormat f : options.formats.value_or(std::vector<MeshFormat>{})) identity += mesh_format_name(f);
  for (const auto& scene : options.scenes) {
    std::ifstream in(scene, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    identity += '\n' + scene.string() + '\n' + std::to_string(fingerprint_of(bytes.str()));
  }
  return fingerprint_of(identity);
}

// A result worth keeping: the scene ran to its end or went unstable, or its file was bad
// (each would be the same again); a write failure or an exception is tried again.
bool final_result(int code) { return code == exit_ok || code == exit_unstable || code == exit_bad_scene; }

}  // namespace

std::optional<std::vector<std::string>> batch_folders(const std::vector<std::filesystem::path>& scenes, std::string& error) {
  std::vector<std::string> names;
  std::set<std::string> seen;
  for (const auto& s : scenes) {
    names.push_back(s.stem().string());
    if (!seen.insert(names.back()).second) {
      error = "two scenes are named " + names.back() + " (" + s.string() + " and an earlier one): their frames " +
              "would land in one folder; rename one";
      return std::nullopt;
    }
  }
  return names;
}

int run_batch(const BatchOptions& options, std::ostream& log, const Cluster& cluster) {
  std::string error;
  const auto folders = batch_folders(options.scenes, error);
  if (!folders) {
    if (cluster.is_root()) log << "drape batch: " << error << '\n';
    return exit_usage;
  }
  if (cluster.is_root()) {
    log << "drape: batch of " << options.scenes.size() << " scene(s)";
    if (cluster.size() > 1) log << " on " << cluster.size() << " MPI ranks";
    log << " into " << options.out_dir.string() << '\n';
  }
  const std::filesystem::path csv = options.out_dir / "batch.csv";
  RunJournal journal(csv.string() + ".journal", batch_fingerprint(options));
  const std::map<std::size_t, std::string> done = journal.read(result_head);
  if (cluster.is_root() && !done.empty())
    log << "drape: " << done.size() << " scene(s) already done by an earlier attempt (" << csv.string()
        << ".journal), not run again\n";
  const auto start = std::chrono::steady_clock::now();
  const std::vector<std::string> results =
      run_spread(cluster, options.scenes.size(), cluster.threads(options.threads), [&](std::size_t k) {
        if (const auto it = done.find(k); it != done.end()) return it->second;
        const BatchResult r = run_one(options.scenes[k], options.out_dir / (*folders)[k], options);
        std::string bytes = encode(r);
        if (final_result(r.code)) journal.record(k, bytes);
        return bytes;
      });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!cluster.is_root()) return exit_ok;

  std::size_t failed = 0;
  std::vector<BatchResult> rows;
  for (std::size_t k = 0; k < results.size(); ++k) {
    rows.push_back(decode(results[k]));
    if (rows.back().code == exit_ok) continue;
    ++failed;
    log << "drape: " << options.scenes[k].string() << ": " << status_name(rows.back().code) << ": "
        << rows.back().message << '\n';
  }
  try {
    std::error_code ec;
    std::filesystem::create_directories(options.out_dir, ec);
    if (ec) throw std::runtime_error("cannot create the folder " + options.out_dir.string() + ": " + ec.message());
    write_atomically(csv, [&](std::ostream& out) {
      out << "scene,output,status,frames,wall_time_s,message\n";
      for (std::size_t k = 0; k < rows.size(); ++k)
        out << csv_field(options.scenes[k].string()) << ',' << csv_field((*folders)[k]) << ','
            << status_name(rows[k].code) << ',' << rows[k].frames << ',' << shortest_number(rows[k].wall_seconds)
            << ',' << csv_field(rows[k].message) << '\n';
    });
  } catch (const std::runtime_error& e) {
    log << "drape: " << e.what() << "; the finished scenes are kept in " << csv.string()
        << ".journal: the same command again does not run them\n";
    return exit_write_failed;
  }
  journal.remove();
  log << "drape: " << rows.size() << " scene(s) in " << seconds << " s (" << double(rows.size()) / seconds
      << " scenes/s), " << failed << " did not finish; wrote " << csv.string() << '\n';
  return failed ? exit_cases_failed : exit_ok;
}

}  // namespace drape::app
