// `drape sweep`: plan the grid of runs up front (every scene checked before any runs), run
// them in parallel with one thread each, write one CSV row per run in plan order.
#include "sweep.h"

#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <limits>
#include <numeric>

#include <unistd.h>

#include "checkpoint.h"
#include "export.h"
#include "progress.h"
#include "run.h"

namespace drape::app {

namespace {

template <class Real>
SweepOutcome simulate_in(const Scene& scene, int frames) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<SheetId> ids;
  // one thread: the sweep is parallel over runs; a run's result never depends on threads
  BasicWorld<Real> world = build_world<Real>(scene, 1, ids);
  const WorldDef& def = world.def();
  std::vector<std::vector<Real>> initial_z;
  for (SheetId id : ids) {
    const auto z = world.view(id).z;
    initial_z.emplace_back(z.begin(), z.end());
  }

  // Stable: finite, and no energy from nowhere. Damping only removes energy and anchors,
  // springs, gravity and obstacles are conservative, so E(t) ≤ E(0) up to the integrator's
  // bounded error. Allow a gain of one "energy scale" of the scene (|each term of E(0)| plus
  // each sheet's weight times a drop of its diagonal + 1 m): a run that blows up passes it by
  // orders of magnitude while staying finite for many frames, a sound one never nears it.
  const Energies e0 = world.energies();
  double scale = std::abs(e0.kinetic) + std::abs(e0.spring) + std::abs(e0.bending) + std::abs(e0.gravity) + std::abs(e0.anchor) +
                 std::abs(e0.obstacle) + 1e-9;
  const double g = std::hypot(def.gravity.x, def.gravity.y, def.gravity.z);
  for (const auto& s : scene.sheets) {
    const double mass = s.point_masses.empty() ? s.mass : std::accumulate(s.point_masses.begin(), s.point_masses.end(), 0.0);
    scale += mass * g * (std::hypot(s.width, s.height) + 1.0);
  }
  const double energy_bound = e0.total() + scale;
  auto sound = [&] { return world.all_finite() && world.energies().total() <= energy_bound; };

  SweepOutcome outcome;
  // The run ends early when sound() fails after a frame (that frame was run: not counted),
  // or when the engine's guard halts the world (run_frames stops before that frame's callback).
  outcome.frames_run = world.run_frames(frames, scene.substeps, [&](int) { return sound(); });
  outcome.stable = !world.halted() && sound();
  if (!outcome.stable) {
    if (!world.halted()) --outcome.frames_run;
  } else {
    outcome.max_sag = -std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const auto z = world.view(ids[k]).z;
      for (std::size_t p = 0; p < z.size(); ++p)
        outcome.max_sag = std::max(outcome.max_sag, double(initial_z[k][p]) - double(z[p]));
      outcome.max_strain = std::max(outcome.max_strain, world.diagnostics(ids[k]).max_strain);
    }
    outcome.total_energy = world.energies().total();
  }
  outcome.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return outcome;
}

// The fixed part of an outcome as it travels from a rank to rank 0 (then its error text):
// copied as bytes, so every number arrives with the bits it was computed with.
struct OutcomeBytes {
  double max_sag, max_strain, total_energy, wall_seconds;
  int frames_run;
  bool stable;
};

std::string encode(const SweepOutcome& o) {
  const OutcomeBytes b{o.max_sag, o.max_strain, o.total_energy, o.wall_seconds, o.frames_run, o.stable};
  return std::string(reinterpret_cast<const char*>(&b), sizeof b) + o.error;
}

SweepOutcome decode(const std::string& bytes) {
  OutcomeBytes b;
  std::memcpy(&b, bytes.data(), sizeof b);
  return {b.stable, b.frames_run, b.max_sag, b.max_strain, b.total_energy, b.wall_seconds, bytes.substr(sizeof b)};
}

// fn(k) for every k < count, `threads` at a time (0: all cores).
template <class Fn>
void parallel_runs(std::size_t count, int threads, Fn&& fn) {
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    // grain 1: runs differ a lot in cost (grid size, step count)
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t k = r.begin(); k != r.end(); ++k) fn(k);
    });
  });
}

SweepOutcome run_case(const SweepCase& c, std::optional<int> frames) {
  try {
    return simulate(c.scene, frames);
  } catch (const std::exception& e) {
    SweepOutcome failed;
    failed.stable = false;
    failed.error = e.what();
    return failed;
  }
}

// Equal for the same runs: every case's scene fingerprint (file bytes and overrides), in
// order, and the frame count.
std::uint64_t plan_fingerprint(std::span<const SweepCase> cases, std::optional<int> frames) {
  std::string identity = std::to_string(frames.value_or(0));
  for (const SweepCase& c : cases) identity += ' ' + std::to_string(c.scene.fingerprint);
  return fingerprint_of(identity);
}

}  // namespace

std::string shortest_number(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

RunJournal::RunJournal(std::filesystem::path dir, std::uint64_t plan) : dir_(std::move(dir)) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(plan));
  plan_ = buf;
}

RunJournal::~RunJournal() {
  if (file_) std::fclose(file_);
}

std::map<std::size_t, std::string> RunJournal::read(std::size_t min_bytes) const {
  std::map<std::size_t, std::string> done;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    std::ifstream in(entry.path());
    std::string plan, hex;
    std::size_t k = 0;
    while (in >> plan >> k >> hex) {
      if (plan != plan_ || hex.size() % 2 != 0 || hex.size() / 2 < min_bytes ||
          hex.find_first_not_of("0123456789abcdef") != std::string::npos)
        continue;  // another plan's line, or one cut short by a kill
      std::string bytes;
      for (std::size_t i = 0; i < hex.size(); i += 2) bytes += char(std::stoi(hex.substr(i, 2), nullptr, 16));
      done[k] = std::move(bytes);
    }
  }
  return done;
}

void RunJournal::record(std::size_t k, const std::string& bytes) {
  std::lock_guard lock(mutex_);
  if (!file_) {
    std::error_code ec;
    std::filesystem::create_directories(dir_, ec);
    char host[256] = {};
    ::gethostname(host, sizeof host - 1);
    const auto name = dir_ / ("process-" + std::to_string(::getpid()) + "-" + host + ".log");
    file_ = std::fopen(name.c_str(), "a");
    if (!file_) return;  // the journal is a safety net: without it the runs still run
  }
  std::string line = plan_ + ' ' + std::to_string(k) + ' ';
  static const char* digits = "0123456789abcdef";
  for (unsigned char c : bytes) line += {digits[c >> 4], digits[c & 15]};
  line += '\n';
  std::fputs(line.c_str(), file_);
  std::fflush(file_);
}

void RunJournal::remove() const {
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

std::uint64_t fingerprint_of(const std::string& identity) {
  return fnv1a64(std::span(reinterpret_cast<const unsigned char*>(identity.data()), identity.size()));
}

std::optional<SweepParameter> parse_sweep_parameter(std::string_view text) {
  const auto eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0 || eq + 1 == text.size()) return std::nullopt;
  SweepParameter p;
  p.path = std::string(text.substr(0, eq));
  std::string current;
  int depth = 0;
  bool quoted = false;
  for (char c : text.substr(eq + 1)) {
    if (c == '"') quoted = !quoted;
    if (!quoted && (c == '[' || c == '{')) ++depth;
    if (!quoted && (c == ']' || c == '}')) --depth;
    if (c == ',' && depth == 0 && !quoted) {
      p.values.push_back(current);
      current.clear();
    } else {
      current += c;
    }
  }
  p.values.push_back(current);
  if (depth != 0 || quoted) return std::nullopt;
  for (const auto& v : p.values)
    if (v.empty()) return std::nullopt;
  return p;
}

std::vector<SweepCase> plan_sweep(const SweepOptions& options) {
  std::vector<SweepCase> cases;
  const std::size_t axes = options.parameters.size();
  for (std::size_t s = 0; s < options.scenes.size(); ++s) {
    std::vector<std::size_t> index(axes, 0);  // an odometer over the grid, last axis fastest
    while (true) {
      SweepCase c;
      c.scene_index = s;
      std::vector<SceneOverride> overrides;
      for (std::size_t a = 0; a < axes; ++a) {
        c.values.push_back(options.parameters[a].values[index[a]]);
        overrides.push_back({options.parameters[a].path, c.values.back()});
      }
      c.scene = load_scene(options.scenes[s], overrides);
      cases.push_back(std::move(c));
      std::size_t a = axes;
      while (a > 0 && ++index[a - 1] == options.parameters[a - 1].values.size()) index[--a] = 0;
      if (a == 0) break;
    }
  }
  return cases;
}

SweepOutcome simulate(const Scene& scene, std::optional<int> frames) {
  const int n = frames.value_or(scene.frames);
  return scene.precision == Precision::Float32 ? simulate_in<float>(scene, n) : simulate_in<double>(scene, n);
}

std::vector<std::string> run_spread(const Cluster& cluster, std::size_t total, int threads,
                                    const std::function<std::string(std::size_t)>& run_case,
                                    const std::function<void()>& finished) {
  const std::vector<std::size_t> mine = cluster.my_cases(total);
  std::vector<std::string> results(mine.size());
  parallel_runs(mine.size(), threads, [&](std::size_t k) {
    results[k] = run_case(mine[k]);
    if (finished) finished();
  });
  return cluster.gather(total, results);
}

std::vector<SweepOutcome> run_sweep_cases(std::span<const SweepCase> cases, std::optional<int> frames, int threads,
                                          const std::function<void()>& finished) {
  std::vector<SweepOutcome> outcomes(cases.size());
  parallel_runs(cases.size(), threads, [&](std::size_t k) {
    outcomes[k] = run_case(cases[k], frames);
    if (finished) finished();
  });
  return outcomes;
}

void write_sweep_csv(std::ostream& out, const SweepOptions& options, std::span<const SweepCase> cases,
                     std::span<const SweepOutcome> outcomes) {
  out << "scene";
  for (const auto& p : options.parameters) out << ',' << csv_field(p.path);
  out << ",stable,frames,max_sag_m,max_strain,total_energy_J,wall_time_s,error\n";
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const SweepCase& c = cases[k];
    const SweepOutcome& o = outcomes[k];
    out << csv_field(options.scenes[c.scene_index].string());
    for (const auto& v : c.values) out << ',' << csv_field(v);
    out << ',' << (o.stable ? "true" : "false") << ',' << o.frames_run;
    if (o.stable)
      out << ',' << shortest_number(o.max_sag) << ',' << shortest_number(o.max_strain) << ','
          << shortest_number(o.total_energy);
    else
      out << ",,,";
    out << ',' << shortest_number(o.wall_seconds) << ',' << csv_field(o.error) << '\n';
  }
}

int run_sweep(const SweepOptions& options, const std::filesystem::path& csv, std::ostream& log, const Cluster& cluster) {
  // Every rank plans the whole grid (it is cheap and the same everywhere), so a bad value
  // stops every rank before anything runs, and only rank 0 says so.
  // The ranks agree on the plan's verdict before going on: a rank that cannot read a file
  // another one can (no shared file system there) must not leave the others waiting.
  // Rank 0 says what is wrong; another rank only when rank 0 found nothing wrong.
  std::vector<SweepCase> cases;
  std::string problem;
  try {
    cases = plan_sweep(options);
  } catch (const SceneError& e) {
    problem = e.what();
  }
  const int verdict = cluster.max_over_ranks(problem.empty() ? 0 : cluster.is_root() ? 2 : 1);
  if (verdict != 0) {
    if (!problem.empty() && (cluster.is_root() || verdict == 1))
      log << "drape: " << (cluster.is_root() ? "" : "rank " + std::to_string(cluster.rank()) + ": ") << problem << '\n';
    return exit_bad_scene;
  }
  if (cluster.is_root()) {
    log << "drape: sweep of " << cases.size() << " run(s)";
    if (cluster.size() > 1) log << " on " << cluster.size() << " MPI ranks";
    log << '\n';
  }
  RunJournal journal(csv.string() + ".journal", plan_fingerprint(cases, options.frames));
  const std::map<std::size_t, std::string> done = journal.read(sizeof(OutcomeBytes));
  if (cluster.is_root() && !done.empty())
    log << "drape: " << done.size() << " run(s) already done by an earlier attempt (" << csv.string()
        << ".journal), not run again\n";
  const auto start = std::chrono::steady_clock::now();
  // Progress of this rank's runs, shown by rank 0 only (its share is about 1/R of the sweep).
  std::optional<Progress> progress;
  if (cluster.is_root()) progress.emplace(log, "run", std::int64_t(cluster.my_cases(cases.size()).size()), options.progress_bar);
  std::atomic<std::int64_t> finished{0};
  // with several ranks, the lines say whose runs they count ("run 2/2" of a sweep of 3 read as done)
  const std::string share = cluster.size() > 1 ? "rank 0's share of the " + std::to_string(cases.size()) + " runs on " +
                                                     std::to_string(cluster.size()) + " ranks"
                                               : std::string();
  const std::vector<std::string> results = run_spread(
      cluster, cases.size(), cluster.threads(options.threads),
      [&](std::size_t k) {
        if (const auto it = done.find(k); it != done.end()) return it->second;
        const SweepOutcome outcome = run_case(cases[k], options.frames);
        std::string bytes = encode(outcome);
        if (outcome.error.empty()) journal.record(k, bytes);  // a failure is tried again next time
        return bytes;
      },
      [&] {
        if (progress) progress->update(++finished, share);
      });
  if (progress) progress->finish();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!cluster.is_root()) return exit_ok;

  std::vector<SweepOutcome> outcomes;
  for (const std::string& r : results) outcomes.push_back(decode(r));
  std::size_t failed = 0;
  for (std::size_t k = 0; k < cases.size(); ++k) {
    if (outcomes[k].error.empty()) continue;
    ++failed;
    log << "drape: run " << k + 1 << " (" << options.scenes[cases[k].scene_index].string();
    for (std::size_t a = 0; a < options.parameters.size(); ++a)
      log << ", " << options.parameters[a].path << "=" << cases[k].values[a];
    log << ") failed: " << outcomes[k].error << '\n';
  }
  try {
    if (csv.has_parent_path()) {
      std::error_code ec;
      std::filesystem::create_directories(csv.parent_path(), ec);
      if (ec) throw std::runtime_error("cannot create the folder " + csv.parent_path().string() + ": " + ec.message());
    }
    write_atomically(csv, [&](std::ostream& out) { write_sweep_csv(out, options, cases, outcomes); });
  } catch (const std::runtime_error& e) {
    log << "drape: " << e.what() << "; the runs are kept in " << csv.string()
        << ".journal: the same command again writes the CSV without running them\n";
    return exit_write_failed;
  }
  journal.remove();
  const auto unstable = std::count_if(outcomes.begin(), outcomes.end(),
                                      [](const SweepOutcome& o) { return !o.stable && o.error.empty(); });
  // the rate of the runs made now, not of those taken from the journal
  log << "drape: " << cases.size() << " run(s) in " << seconds << " s ("
      << double(cases.size() - done.size()) / seconds << " runs/s), ";
  if (!done.empty()) log << done.size() << " of them from the journal, ";
  log << unstable << " unstable";
  if (failed) log << ", " << failed << " failed";
  log << "; wrote " << csv.string() << '\n';
  return failed ? exit_cases_failed : exit_ok;
}

}  // namespace drape::app
