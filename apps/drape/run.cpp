// `drape run` / `drape info`: build a world from a scene, step it, write frames.
#include "run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <streambuf>
#include <utility>

#include "checkpoint.h"
#include "export.h"
#include "gltf.h"
#include "progress.h"

namespace drape::app {

template <class Real>
BasicWorld<Real> build_world(const Scene& scene, int threads, std::vector<SheetId>& ids) {
  // Constraints name sheets and obstacles by their index in the scene. load_scene checks
  // them; a Scene changed or made by a program after that is checked here, before anything
  // is built, with the constraint named, rather than read past the lists.
  for (std::size_t k = 0; k < scene.constraints.size(); ++k) {
    const ConstraintDef& c = scene.constraints[k];
    auto check = [&](std::uint32_t index, std::size_t count, const char* what) {
      if (index >= count)
        throw SceneError(scene.file + ": constraints[" + std::to_string(k) + "] names " + what + " " +
                         std::to_string(index) + ", but the scene has " + std::to_string(count));
    };
    check(c.sheet.index, scene.sheets.size(), "sheet");
    if (c.kind == ConstraintKind::PointToPoint) check(c.other_sheet.index, scene.sheets.size(), "other_sheet");
    if (c.carrier) check(c.carrier->index, scene.obstacles.size(), "obstacle");
  }
  WorldDef def = scene.world;
  def.threads = threads;
  BasicWorld<Real> world(def);
  for (const auto& s : scene.sheets) ids.push_back(world.add_sheet(s));
  std::vector<ObstacleId> obstacles;
  for (const auto& o : scene.obstacles) obstacles.push_back(world.add_obstacle(o));
  for (ConstraintDef c : scene.constraints) {  // the file's indices to the world's ids
    c.sheet = ids[c.sheet.index];
    if (c.kind == ConstraintKind::PointToPoint) c.other_sheet = ids[c.other_sheet.index];
    if (c.carrier) c.carrier = obstacles[c.carrier->index];
    world.add_constraint(c);
  }
  return world;
}
template BasicWorld<double> build_world<double>(const Scene&, int, std::vector<SheetId>&);
template BasicWorld<float> build_world<float>(const Scene&, int, std::vector<SheetId>&);

namespace {

std::string frame_name(int frame, std::string_view ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05d.", frame);
  return std::string(buf) + std::string(ext);
}

// A per-frame file's extension: the format's name, but VTK's unstructured grid is .vtu.
std::string_view mesh_extension(MeshFormat f) { return f == MeshFormat::Vtk ? "vtu" : mesh_format_name(f); }

// Counts what is written to it, keeping nothing: a frame's size before any file is made.
class ByteCounter : public std::streambuf {
 public:
  std::uintmax_t bytes() const { return bytes_; }

 protected:
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) ++bytes_;
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char*, std::streamsize count) override {
    bytes_ += std::uintmax_t(count);
    return count;
  }

 private:
  std::uintmax_t bytes_ = 0;
};

// The free space of the file system `dir` is (or would be) on: its nearest existing folder's.
std::optional<std::uintmax_t> free_space(std::filesystem::path dir) {
  std::error_code ec;
  dir = std::filesystem::absolute(dir, ec);
  while (!std::filesystem::exists(dir, ec) && dir.has_parent_path() && dir.parent_path() != dir) dir = dir.parent_path();
  const auto space = std::filesystem::space(dir, ec);
  if (ec) return std::nullopt;
  return space.available;
}

double min_gamma(const SheetDef& s) {
  const std::size_t points = point_count(s.m, s.n);
  double gamma = std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < points; ++p) {
    const double c = s.point_damping.empty() ? s.damping : s.point_damping[p];
    const double m = s.point_masses.empty() ? s.mass / double(points) : s.point_masses[p];
    gamma = std::min(gamma, c / m);
  }
  return gamma;
}

// The dt to suggest for an estimated stable step `limit`: the step the guard names when a
// run blows up and adaptive steps take (adaptive_safety of the estimate), rounded down to
// two significant digits, so the printed value is never above it.
double suggested_step(const Scene& scene, double limit) {
  const double step = scene.world.adaptive_safety * limit;
  const double unit = std::pow(10.0, std::floor(std::log10(step)) - 1);
  return std::floor(step / unit) * unit;
}

// Two sheets or more, or one colliding with itself, with the contact on: the contact may act.
bool sheets_may_touch(const Scene& scene) {
  return scene.world.contact_strength > 0 &&
         (scene.sheets.size() > 1 ||
          std::any_of(scene.sheets.begin(), scene.sheets.end(), [](const SheetDef& s) { return s.self_collision; }));
}

template <class Real>
int run_world(const Scene& scene, const RunOptions& opt, std::ostream& log) {
  const int frames = opt.frames.value_or(scene.frames);
  const auto formats = opt.formats.value_or(scene.output.formats);
  const std::filesystem::path dir = opt.resume_dir ? *opt.resume_dir : opt.out_dir.value_or(scene.output.dir);

  // A checkpoint holds the step count, not the simulated time; adaptive substeps vary in
  // length, so neither the time nor the frame a checkpoint was written at follows from it.
  if (scene.world.adaptive && (opt.resume_dir || opt.checkpoint_every > 0)) {
    log << "drape: " << scene.file << ": --checkpoint-every and --resume need fixed substeps; the scene sets "
        << "\"adaptive\": true. Nothing was written\n";
    return exit_usage;
  }

  const bool glb = std::find(formats.begin(), formats.end(), MeshFormat::Glb) != formats.end();
  if (glb && opt.resume_dir) {
    log << "drape: --resume " << opt.resume_dir->string() << ": the glb format holds every frame of a run in one file, "
        << "and the frames before the checkpoint are not in memory; resume with --format obj, ply or vtk. Nothing was "
        << "written\n";
    return exit_usage;
  }
  std::optional<GltfRun> gltf;
  if (glb) {
    const GltfOptions options{opt.surface, opt.surface_samples};
    if (const std::uint64_t bytes = GltfRun::frame_bytes(scene, options, std::uint64_t(frames) + 1);
        bytes > GltfRun::max_bytes) {
      log << "drape: " << scene.file << ": " << frames + 1 << " frames make a glb of at least " << (bytes >> 20)
          << " MiB, above glTF's 4 GiB; write fewer frames (--frames) or fewer --surface-samples. Nothing was "
          << "written\n";
      return exit_usage;
    }
    gltf.emplace(scene, options);
  }

  std::vector<SheetId> ids;
  BasicWorld<Real> world = build_world<Real>(scene, opt.threads, ids);

  // Resume: the whole checkpoint is read and checked before anything is written; a refused
  // one leaves the world and the folder as they were.
  int first_frame = 1;
  if (opt.resume_dir) {
    const std::filesystem::path file = *opt.resume_dir / checkpoint_file_name;
    std::error_code exists_ec;
    if (!std::filesystem::is_regular_file(file, exists_ec)) {
      log << "drape: --resume " << opt.resume_dir->string() << ": no checkpoint there (" << file.string()
          << " is missing; write one with --checkpoint-every N)\n";
      return exit_bad_checkpoint;
    }
    try {
      load_checkpoint(file, world, scene.fingerprint);
    } catch (const std::runtime_error& e) {
      log << "drape: cannot resume from " << e.what() << "; nothing was written\n";
      return exit_bad_checkpoint;
    }
    const std::uint64_t steps = world.step_count();
    if (steps % std::uint64_t(scene.substeps) != 0 || world.def().integrator != scene.world.integrator ||
        world.def().dt != scene.world.dt) {
      log << "drape: cannot resume from " << file.string() << ": it was not written by drape run at a frame boundary of "
          << scene.file << "; nothing was written\n";
      return exit_bad_checkpoint;
    }
    first_frame = int(steps / std::uint64_t(scene.substeps)) + 1;
    log << "drape: resuming " << scene.file << " from " << file.string() << " after frame " << first_frame - 1 << '\n';
  }

  // Warn (do not refuse) when dt is above the explicit integrators' estimated critical step.
  const double dt = scene.world.dt;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const StableSteps st = stable_steps(scene.sheets[k], world.stable_step_estimate(ids[k]));
    // forward Euler's damped limit from stable_steps; the others scale the explicit interval
    // 2/ω_max by their own factor (RK4 2√2; implicit Euler +inf: never warned about)
    const double limit = scene.world.integrator == Integrator::ForwardEuler
                             ? st.forward_euler
                             : integrator_critical_step(scene.world.integrator, 2.0 / st.semi_implicit_euler);
    // adaptive: an explicit integrator picks its own stable substep, whatever dt says
    if (dt > limit && !scene.world.adaptive) {
      log << "drape: warning: " << scene.file << ": sheets[" << k << "] (" << scene.sheet_names[k] << "): dt = " << dt
          << " s is above the estimated stable step " << limit << " s of " << integrator_name(scene.world.integrator);
      if (limit > 0)
        log << "; a stable choice is dt = " << std::setprecision(2) << suggested_step(scene, limit) << std::setprecision(6)
            << " s\n";
      else
        log << "; forward_euler needs damping, or use semi_implicit_euler (stable below "
            << st.semi_implicit_euler << " s)\n";
    }
  }
  // ... and above the sheet–sheet contact's, once, for the sheet with the lightest point: no
  // integrator resolves a contact implicitly (World::contact_step_estimate).
  if (sheets_may_touch(scene) && !scene.world.adaptive) {
    std::vector<double> contact_steps;
    for (SheetId id : ids) contact_steps.push_back(world.contact_step_estimate(id));
    const auto lightest = std::size_t(std::min_element(contact_steps.begin(), contact_steps.end()) - contact_steps.begin());
    const double limit = explicit_force_critical_step(scene.world.integrator, 2.0 / contact_steps[lightest]);
    if (dt > limit)
      log << "drape: warning: " << scene.file << ": sheets[" << lightest << "] (" << scene.sheet_names[lightest]
          << "): dt = " << dt << " s is above the estimated stable step " << limit << " s of its contact with "
          << "other sheets (contact_strength / contact_xi² against its lightest point), with any integrator; a stable "
          << "choice is dt = " << std::setprecision(2) << suggested_step(scene, limit) << std::setprecision(6)
          << " s, or a larger contact_xi (a smaller contact_strength softens the contact too, but lowers the barrier "
          << "that keeps fast sheets apart)\n";
  }

  auto sheet_views = [&] {
    std::vector<SheetView<Real>> views;
    for (SheetId id : ids) views.push_back(world.view(id));
    return views;
  };
  // One frame's mesh in a per-frame format (a .glb holds the whole run).
  auto write_mesh = [&](MeshFormat f, std::span<const SheetView<Real>> span, std::ostream& out) {
    switch (f) {
      case MeshFormat::Obj: write_obj<Real>(out, span, scene.sheet_names); break;
      case MeshFormat::Ply: write_ply<Real>(out, span); break;
      case MeshFormat::Vtk: write_vtu<Real>(out, span); break;
      case MeshFormat::Glb: break;
    }
  };
  // Frames that cannot fit the disk are refused before any file is written (--frames 2000000000
  // filled it, a gigabyte every ten seconds): the frames to write × this frame's bytes in each
  // format, a floor (later frames' numbers print longer than the first grid's).
  {
    ByteCounter counter;
    std::ostream count(&counter);
    const std::vector<SheetView<Real>> views = sheet_views();
    for (MeshFormat f : formats) write_mesh(f, views, count);
    const std::uintmax_t to_write = std::uintmax_t(frames - first_frame + 1 + (opt.resume_dir ? 0 : 1));
    const std::uintmax_t bytes = counter.bytes() * to_write;
    const std::optional<std::uintmax_t> available = free_space(dir);
    if (available && bytes > *available) {
      log << "drape: " << to_write << " frames of " << scene.file << " would take at least " << std::fixed
          << std::setprecision(1) << double(bytes) / 1e9 << " GB in " << dir.string() << ", which has "
          << double(*available) / 1e9 << " GB free: write fewer frames (--frames), fewer formats (--format), or to "
          << "another folder (--out); nothing was written\n";
      return exit_write_failed;
    }
  }

  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    log << "drape: cannot create the output folder " << dir.string() << ": " << ec.message() << '\n';
    return exit_write_failed;
  }
  // The scene goes with its frames, so `drape render DIR` finds the sheets' grids, the
  // obstacles and the camera without being told which scene made them.
  try {
    write_atomically(dir / "scene.json", [&](std::ostream& out) { out << scene.source; });
  } catch (const std::runtime_error& e) {
    log << "drape: " << e.what() << '\n';
    return exit_write_failed;
  }
  std::vector<PvdEntry> pvd;
  // frames.pvd is rewritten whole: when its series grew by a tenth since it was last written,
  // and (`all`) at the end, at a checkpoint and when the run goes unstable. Rewritten every
  // frame, a run wrote O(frames²) bytes of it (8,000 frames: over 2 GB of it).
  std::size_t pvd_written = 0;
  auto write_series = [&](bool all) {
    if (pvd.size() == pvd_written || (!all && pvd.size() < pvd_written + std::max<std::size_t>(1, pvd_written / 10)))
      return;
    write_atomically(dir / "frames.pvd", [&](std::ostream& out) { write_pvd(out, pvd); });
    pvd_written = pvd.size();
  };
  // frames written before a resume stay in the .pvd series; time as world.time() computes it
  if (std::find(formats.begin(), formats.end(), MeshFormat::Vtk) != formats.end())
    for (int f = 0; f < first_frame && opt.resume_dir; ++f)
      pvd.push_back({static_cast<double>(std::uint64_t(f) * std::uint64_t(scene.substeps)) * scene.world.dt,
                     frame_name(f, "vtu")});
  auto write_frame = [&](int frame) {
    const std::vector<SheetView<Real>> views = sheet_views();
    const std::span<const SheetView<Real>> span(views);
    for (MeshFormat f : formats) {
      if (f == MeshFormat::Glb) {
        gltf->add_frame<Real>(span, world.time());
        continue;
      }
      write_atomically(dir / frame_name(frame, mesh_extension(f)), [&](std::ostream& out) { write_mesh(f, span, out); });
      if (f == MeshFormat::Vtk) {
        pvd.push_back({world.time(), frame_name(frame, "vtu")});
        write_series(false);
      }
    }
  };
  // The glb holds the frames so far; written once, when the run ends (or goes unstable); the
  // .pvd series then lists every frame.
  auto finish_files = [&] {
    write_series(true);
    if (gltf) write_atomically(dir / glb_file_name, [&](std::ostream& out) { gltf->write(out); });
  };

  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t first_step = world.step_count();
  const double first_time = world.time();
  double points = 0;
  for (SheetId id : world.sheets()) points += double(world.view(id).x.size());
  Progress progress(log, "frame", frames, opt.progress_bar, first_frame - 1);
  // A point inside an obstacle by more than the obstacle's ξ came faster than its potential
  // stops it, or rests on a potential too weak for its weight: said once per sheet and
  // obstacle, the first frame it happens (the run goes on; the frames show it).
  const std::vector<ObstacleId> obstacle_ids = world.obstacles();
  std::set<std::pair<std::size_t, std::size_t>> inside;
  const auto warn_inside = [&](int frame) {
    for (std::size_t k = 0; k < ids.size() && !obstacle_ids.empty(); ++k) {
      const ObstaclePenetration deepest = world.obstacle_penetration(ids[k]);
      const auto o = std::size_t(std::find(obstacle_ids.begin(), obstacle_ids.end(), deepest.obstacle) - obstacle_ids.begin());
      if (o == obstacle_ids.size() || !(deepest.depth > scene.obstacles[o].xi) || !inside.insert({k, o}).second) continue;
      progress.finish();
      log << "drape: warning: " << scene.file << ": frame " << frame << ": sheets[" << k << "] (" << scene.sheet_names[k]
          << ") is " << std::setprecision(3) << deepest.depth << " m inside obstacles[" << o << "] at point "
          << deepest.point << ": it started inside, arrived faster than the obstacle's potential stops it (safe below "
          << "about xi/(2·dt) = " << scene.obstacles[o].xi / (2 * world.substep_dt())
          << " m/s), or weighs more than its c holds; raise the obstacle's xi or c, or lower dt\n"
          << std::setprecision(6);
    }
  };
  // Sheets that pass through each other (or a self-colliding sheet through itself) met
  // faster than the contact stops them, were pressed through, or started so; the contact
  // then holds them crossed. Said once per pair, the first frame it is seen. Looking costs
  // about a contact search of every pair in range (more than the frame itself in a stack of
  // a few substeps a frame), so it is done after the last frame and after any frame whose
  // run since the last look took at least 20 times that look: at most about 5 % of the run.
  std::set<std::pair<std::size_t, std::size_t>> crossed;
  double last_look = 0;  // s the last look took
  auto since_look = std::chrono::steady_clock::now();
  const auto index_of = [&](SheetId id) { return std::size_t(std::find(ids.begin(), ids.end(), id) - ids.begin()); };
  const auto lightest = [&](std::size_t k) {
    const SheetDef& d = scene.sheets[k];
    return d.point_masses.empty() ? d.mass / double(point_count(d.m, d.n))
                                  : *std::min_element(d.point_masses.begin(), d.point_masses.end());
  };
  const auto warn_crossing = [&](int frame) {
    using seconds = std::chrono::duration<double>;
    const auto look = std::chrono::steady_clock::now();
    if (frame < frames && seconds(look - since_look).count() < 20 * last_look) return;
    const std::vector<SheetCrossing> found = world.sheet_crossings();
    since_look = std::chrono::steady_clock::now();
    last_look = seconds(since_look - look).count();
    for (const SheetCrossing& c : found) {
      const std::size_t a = index_of(c.a), b = index_of(c.b);
      if (!crossed.insert({a, b}).second) continue;
      const WorldDef& wd = scene.world;
      // docs/scene-format.md, Safe speeds: half the barrier c·e^(h/ξ) as the lighter point's
      // kinetic energy, and a substep's travel within h/2
      const double safe = std::min(std::sqrt(wd.contact_strength * std::exp(wd.contact_thickness / wd.contact_xi) /
                                             std::min(lightest(a), lightest(b))),
                                   wd.contact_thickness / (2 * world.substep_dt()));
      progress.finish();
      log << "drape: warning: " << scene.file << ": frame " << frame << ": sheets[" << a << "] ("
          << scene.sheet_names[a] << ") ";
      if (a == b)
        log << "passes through itself near its points " << c.point_a << " and " << c.point_b;
      else
        log << "and sheets[" << b << "] (" << scene.sheet_names[b] << ") pass through each other near point "
            << c.point_a << " of the first and point " << c.point_b << " of the second";
      log << " (" << c.edges << " edges across): points met faster than the contact stops them (safe below about "
          << std::setprecision(3) << safe << " m/s closing), were pressed through by more than the contact holds, "
          << (scene.world.contact_rims || a == b ? "or started so" : "an edge cut across a rim, or they started so")
          << "; raise contact_strength or contact_thickness, or lower dt"
          << (scene.world.contact_rims || a == b ? "" : ", or turn contact_rims on (edges against rims)") << "\n"
          << std::setprecision(6);
    }
  };
  try {
    if (!opt.resume_dir) write_frame(0);
    for (int frame = first_frame; frame <= frames; ++frame) {
      if (opt.stop && *opt.stop != 0) {  // asked to stop: what is written stays a whole run up to frame − 1
        progress.finish();
        finish_files();
        const bool keeps = opt.checkpoint_every > 0 && frame - 1 > 0;
        if (keeps) save_checkpoint(world, dir / checkpoint_file_name, scene.fingerprint);
        log << "drape: " << scene.file << ": stopped by a signal after frame " << frame - 1 << " (t = " << world.time()
            << " s): frames 0–" << frame - 1 << " are written to " << dir.string();
        if (keeps) log << "; drape run " << scene.file << " --resume " << dir.string() << " continues";
        log << '\n';
        return 128 + int(*opt.stop);
      }
      const std::uint64_t first = world.step_count() + 1;
      // the engine's stability guard: non-finite state, or energy growing without bound
      drape::StabilityReport report = world.step(scene.substeps);
      if (!report.ok() || !world.all_finite()) {
        if (report.ok()) report = world.check();  // the guard is off: its verdict on the state now
        progress.finish();
        finish_files();
        log << "drape: " << scene.file << ": the simulation became unstable "
            << "during frame " << frame << ", substeps " << first << "–" << world.step_count() << " (t ≤ "
            << world.time() << " s): " << drape::describe(report) << ". Frames 0–" << frame - 1
            << " are written; nothing non-finite was.\n";
        return exit_unstable;
      }
      write_frame(frame);
      warn_inside(frame);
      warn_crossing(frame);
      // after the frame's files: a checkpoint of frame K implies frames 0..K are on disk
      if (opt.checkpoint_every > 0 && frame % opt.checkpoint_every == 0 && frame < frames) {
        write_series(true);
        save_checkpoint(world, dir / checkpoint_file_name, scene.fingerprint);
      }
      std::ostringstream time;
      time << "t = " << world.time() << " s";
      progress.update(frame, time.str());
    }
    finish_files();
  } catch (const std::runtime_error& e) {
    progress.finish();
    log << "drape: " << e.what() << '\n';
    return exit_write_failed;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.finish();
  log << "drape: wrote " << std::max(0, frames + 1 - first_frame + (opt.resume_dir ? 0 : 1)) << " frames to " << dir.string() << " in "
      << std::setprecision(3) << seconds << " s";
  // the run's throughput, output included: what the scene costs on this machine
  const double point_steps = points * double(world.step_count() - first_step);
  if (seconds > 0 && point_steps > 0)
    log << " (" << point_steps / seconds / 1e6 << " M point-steps/s, " << (world.time() - first_time) / seconds
        << " simulated s per wall s)";
  // frames tried ahead and kept if nothing came near (docs/architecture.md, frames of groups):
  // how many had to be stepped again
  const auto tries = world.frame_stats();
  if (tries.undone > 0) log << "; frames tried ahead: " << tries.kept << " kept, " << tries.undone << " stepped again";
  log << '\n';
  return exit_ok;
}

template <class Real>
void describe_world(const Scene& scene, std::ostream& out) {
  std::vector<SheetId> ids;
  BasicWorld<Real> world = build_world<Real>(scene, 1, ids);
  out << scene.file << ": " << scene.sheets.size() << " sheet(s), " << scene.obstacles.size() << " obstacle(s)\n"
      << "precision " << precision_name(scene.precision) << ", integrator " << integrator_name(scene.world.integrator)
      << ", dt " << scene.world.dt << " s, " << scene.substeps << " substeps per frame, " << scene.frames
      << " frames (" << scene.frames * scene.frame_time() << " s simulated)"
      << (scene.world.adaptive ? ", adaptive substeps" : "") << '\n';
  const WorldDef& w = scene.world;
  if (sheets_may_touch(scene)) {
    out << "contacts between sheets: thickness " << w.contact_thickness << " m, xi " << w.contact_xi << " m, strength "
        << w.contact_strength << " J, range " << w.contact_range << " xi";
    if (w.contact_damping > 0) out << ", damping " << w.contact_damping << " s/m";
    out << (w.contact_rims ? ", rims" : ", points only (contact_rims off)") << '\n';
  }
  if (std::any_of(scene.sheets.begin(), scene.sheets.end(), [](const SheetDef& s) { return s.air.has_value(); }))
    out << "wind: " << w.wind.velocity.x << ", " << w.wind.velocity.y << ", " << w.wind.velocity.z << " m/s, density "
        << w.wind.density << " kg/m^3\n";
  std::uint64_t points = 0, springs = 0;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const auto& s = scene.sheets[k];
    const StableSteps st = stable_steps(s, world.stable_step_estimate(ids[k]));
    points += point_count(s.m, s.n);
    springs += spring_count(s.m, s.n);
    out << "sheets[" << k << "] " << scene.sheet_names[k] << ": " << s.m << "x" << s.n << " cells, "
        << point_count(s.m, s.n) << " points, " << spring_count(s.m, s.n) << " springs, about "
        << estimated_bytes(s, scene.precision) / 1024.0 << " KiB; stable step: semi_implicit_euler "
        << st.semi_implicit_euler << " s, forward_euler " << st.forward_euler << " s"
        << (st.forward_euler == 0 ? " (undamped: unstable at any step)" : "");
    if (sheets_may_touch(scene)) out << ", its contact " << world.contact_step_estimate(ids[k]) << " s";
    out << (s.self_collision ? "; collides with itself" : "") << (s.shear ? "; shear springs" : "")
        << (s.bending ? "; bending" : "") << (s.air ? "; air" : "") << '\n';
  }
  auto motion_text = [](const Motion& m) {
    std::ostringstream text;
    if (m.kind == Motion::Kind::Circle)
      text << "a circle (period " << m.circle.period << " s)";
    else
      text << "keyframes (" << m.keyframes.size() << " knots" << (m.repeat ? ", repeating" : "") << ")";
    return text.str();
  };
  for (std::size_t k = 0; k < scene.obstacles.size(); ++k)
    if (scene.obstacles[k].motion) out << "obstacles[" << k << "] moves: " << motion_text(*scene.obstacles[k].motion) << '\n';
  auto sheet_text = [&](SheetId id) { return "sheets[" + std::to_string(id.index) + "] " + scene.sheet_names[id.index]; };
  for (std::size_t k = 0; k < scene.constraints.size(); ++k) {
    const ConstraintDef& c = scene.constraints[k];
    out << "constraints[" << k << "] " << constraint_kind_name(c.kind) << ": " << c.points.size() << " point(s) of "
        << sheet_text(c.sheet);
    switch (c.kind) {
      case ConstraintKind::PointToPoint:
        out << " joined to " << sheet_text(c.other_sheet) << ", rest length " << c.rest_length << " m";
        break;
      case ConstraintKind::Path: out << " following " << motion_text(c.motion); break;
      case ConstraintKind::Frame:
        if (c.carrier)
          out << " carried by obstacles[" << c.carrier->index << "]";
        else
          out << " carried by " << motion_text(c.motion);
        break;
      case ConstraintKind::Rail: out << " sliding on a rail of " << c.rail.size() << " knots"; break;
    }
    out << ", stiffness " << c.stiffness << " N/m\n";
  }
  if (std::any_of(scene.obstacles.begin(), scene.obstacles.end(), [](const ObstacleDef& o) { return o.motion.has_value(); }))
    out << "moving obstacles: stepped substep by substep (poses and targets set at every substep)\n";
  else if (!scene.constraints.empty())
    out << "constraints: targets set at every substep (a join's sheets step a frame together)\n";
  out << "total: " << points << " points, " << springs << " springs, about " << estimated_bytes(scene) / 1024.0
      << " KiB\n";
}

}  // namespace

StableSteps stable_steps(const SheetDef& sheet, double se) {
  const double gamma = min_gamma(sheet);
  const double fe = std::isinf(se) ? se : (std::isfinite(gamma) ? gamma * se * se / 4 : 0.0);
  return {se, fe};
}

int run_scene(const Scene& scene, const RunOptions& options, std::ostream& log) {
  return scene.precision == Precision::Float32 ? run_world<float>(scene, options, log)
                                               : run_world<double>(scene, options, log);
}

void describe_scene(const Scene& scene, std::ostream& out) {
  if (scene.precision == Precision::Float32)
    describe_world<float>(scene, out);
  else
    describe_world<double>(scene, out);
}

}  // namespace drape::app
