// `drape batch`: each scene is a whole `drape run` (run_scene) into OUT/<stem>, one thread per
// scene, scenes in parallel; failures become rows of OUT/batch.csv, never a lost batch.
#include "batch.h"

#include <chrono>
#include <cstring>
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

std::string encode(const BatchResult& r) {
  char head[sizeof r.code + sizeof r.frames + sizeof r.wall_seconds];
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
  r.message = bytes.substr(sizeof r.code + sizeof r.frames + sizeof r.wall_seconds);
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
  const auto start = std::chrono::steady_clock::now();
  const std::vector<std::string> results =
      run_spread(cluster, options.scenes.size(), cluster.threads(options.threads), [&](std::size_t k) {
        return encode(run_one(options.scenes[k], options.out_dir / (*folders)[k], options));
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
  const std::filesystem::path csv = options.out_dir / "batch.csv";
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
    log << "drape: " << e.what() << '\n';
    return exit_write_failed;
  }
  log << "drape: " << rows.size() << " scene(s) in " << seconds << " s (" << double(rows.size()) / seconds
      << " scenes/s), " << failed << " did not finish; wrote " << csv.string() << '\n';
  return failed ? exit_cases_failed : exit_ok;
}

}  // namespace drape::app
