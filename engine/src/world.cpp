// The World: a pool of sheets addressed by ids, and the substep that advances them.
#include <drape/world.h>

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "bounds.h"
#include "broad_phase.h"
#include "constraints.h"
#include "contacts.h"
#include "diagnostics.h"
#include "forces.h"
#include "integrate.h"
#include "obstacles.h"
#include "sheet_data.h"
#include "terms/terms.h"

namespace drape {

std::string validate(const WorldDef& d) {
  auto problem = [](const char* field, const char* what, double got) {
    std::ostringstream out;
    out << field << ' ' << what << " (got " << got << ')';
    return out.str();
  };
  const auto finite = [](double v) { return std::isfinite(v); };
  if (!(d.dt > 0) || !finite(d.dt)) return problem("dt", "must be positive and finite", d.dt);
  if (!finite(d.gravity.x) || !finite(d.gravity.y) || !finite(d.gravity.z)) return "gravity must be finite";
  if (!finite(d.wind.velocity.x) || !finite(d.wind.velocity.y) || !finite(d.wind.velocity.z))
    return "wind.velocity must be finite";
  if (!(d.wind.density >= 0) || !finite(d.wind.density))
    return problem("wind.density", "must be non-negative and finite", d.wind.density);
  if (!integrator_from_name(integrator_name(d.integrator))) return problem("integrator", "is not an integrator", double(d.integrator));
  if (d.threads < 0) return problem("threads", "must be 0 (all cores) or positive", d.threads);
  if (!(d.cg_tolerance > 0) || !finite(d.cg_tolerance)) return problem("cg_tolerance", "must be positive and finite", d.cg_tolerance);
  if (d.cg_max_iterations < 1) return problem("cg_max_iterations", "must be at least 1", d.cg_max_iterations);
  if (d.local_global_iterations < 1)
    return problem("local_global_iterations", "must be at least 1", d.local_global_iterations);
  if (d.vertex_block_iterations < 1)
    return problem("vertex_block_iterations", "must be at least 1", d.vertex_block_iterations);
  if (!(d.adaptive_safety > 0 && d.adaptive_safety <= 1)) return problem("adaptive_safety", "must be in (0, 1]", d.adaptive_safety);
  if (!(d.guard_energy_growth > 1) || std::isnan(d.guard_energy_growth))
    return problem("guard_energy_growth", "must be greater than 1", d.guard_energy_growth);
  if (!(d.contact_thickness >= 0) || !finite(d.contact_thickness))
    return problem("contact_thickness", "must be non-negative and finite", d.contact_thickness);
  if (!(d.contact_xi > 0) || !finite(d.contact_xi)) return problem("contact_xi", "must be positive and finite", d.contact_xi);
  if (!(d.contact_strength >= 0) || !finite(d.contact_strength))
    return problem("contact_strength", "must be non-negative and finite", d.contact_strength);
  if (!(d.contact_range > 0) || !finite(d.contact_range))
    return problem("contact_range", "must be positive and finite", d.contact_range);
  if (d.block_points == 0) return problem("block_points", "must be positive", d.block_points);
  return {};
}

std::string describe(const StabilityReport& r) {
  std::ostringstream out;
  out.precision(3);
  if (r.ok()) {
    out << "stable at step " << r.step << " (t = " << r.time << " s), energy growth " << r.energy_growth;
    if (r.unconverged_solves > 0) out << "; " << r.unconverged_solves << " implicit solves stopped before their tolerance";
    return out.str();
  }
  out << "sheet " << r.sheet.index << ": ";
  if (r.status == StabilityStatus::NonFinite)
    out << "positions or velocities are not finite";
  else
    out << "energy grew " << r.energy_growth << "-fold";
  out << " by step " << r.step << " (t = " << r.time << " s) with " << integrator_name(r.integrator) << " at dt = " << r.dt
      << " s; ";
  if (std::isfinite(r.stable_dt) && r.stable_dt > 0)
    out << "stable below dt ~ " << r.stable_dt << " s (estimate), or ";
  out << "use " << integrator_name(r.stable_integrator) << " at this dt";
  if (r.unconverged_solves > 0) out << " (" << r.unconverged_solves << " implicit solves stopped before their tolerance)";
  return out.str();
}

using detail::Sheet;
using detail::Topology;

template <class Real>
struct BasicWorld<Real>::Impl {
  // The stability guard's memory of one sheet (see StabilityReport).
  struct Guard {
    bool has_reference = false;
    double reference_energy = 0;  // E₀
    double scale = 0;             // S: motion energy at the reference, ≥ floor
    double floor = 0;             // work of gravity over the sheet's extent at the reference
  };

  struct Slot {
    std::optional<Sheet<Real>> sheet;
    std::uint32_t generation = 0;
    double omega_max = 0;  // rad/s, Gershgorin bound; fixed by masses and stiffnesses
    Guard guard;
    double lightest_point = 0;  // kg, for the obstacle force bound (obstacles.h, exponent_cap)
    // Moved by a prescribed motion (a path or frame constraint, a moving obstacle): its
    // energy may grow, so the guard halts it only for a state that is not finite.
    bool driven = false;
    // The sheet's box after its last integration, taken while its positions were still in
    // cache; stale after add_sheet, state() or a step that split the sheet into blocks.
    detail::Aabb bounds;
    bool bounds_fresh = false;
  };
  // A unit of the parallel stage: rows [row_begin, row_end) of one sheet. `split` blocks
  // compute forces in the first pass and update in the second; a whole sheet does both
  // in its one task.
  struct Block {
    std::uint32_t sheet;  // position in `active`
    std::uint32_t row_begin, row_end, index;
    bool split;
  };

  WorldDef def;
  std::unique_ptr<tbb::task_arena> arena;
  std::vector<Slot> slots;
  std::vector<std::uint32_t> free_slots;
  std::vector<std::uint32_t> active;  // live slots in the order sheets were added
  std::vector<std::shared_ptr<const Topology<Real>>> topologies;
  std::uint64_t steps = 0;
  // time = time_base + (steps − steps_base)·current_h: exact for runs of equal substeps
  double time_base = 0, current_h = 0;
  std::uint64_t steps_base = 0;
  std::optional<StabilityReport> failure;  // set when the guard halted the world

  void set_def(const WorldDef& d);

  // Host stage scratch, kept between substeps so a settled scene does not allocate.
  std::vector<detail::Aabb> bounds, grown;
  detail::TrackingBroadPhase broad_phase;  // reset when `active` changes
  std::vector<detail::BoxPair> pairs;
  std::vector<detail::PairContacts<Real>> pair_work;
  tbb::enumerable_thread_specific<detail::ContactGrid<Real>> grids;  // narrow-phase scratch
  std::vector<std::uint32_t> source_start;                  // per sheet, into sources (CSR)
  std::vector<const detail::ContactForces<Real>*> sources;  // per sheet, in pair order
  std::vector<std::uint32_t> source_cursor;                 // while filling sources
  std::vector<Block> blocks;

  explicit Impl(const WorldDef& d) : def(d) { make_arena(); }

  void make_arena() {
    const int concurrency = def.threads > 0 ? def.threads : int(tbb::task_arena::automatic);
    arena = std::make_unique<tbb::task_arena>(concurrency);
  }
  struct ObstacleSlot {
    std::optional<detail::Obstacle> obstacle;  // without its motion; at its pose for this substep
    ObstacleDef def;                           // the caller's definition
    std::uint32_t generation = 0;
  };
  std::vector<ObstacleSlot> obstacle_slots;
  std::vector<std::uint32_t> free_obstacle_slots;
  std::vector<std::uint32_t> active_obstacles;  // live slots in the order obstacles were added

  detail::ConstraintPool<Real> constraints;
  typename detail::ConstraintPool<Real>::Access access() {
    return {[this](SheetId id) { return contains(id) ? &sheet(id) : nullptr; },
            [this](ObstacleId id) { return contains(id) ? &obstacle_slots[id.index].def : nullptr; }};
  }
  // Constraints add anchors (eq 8) to their sheets: the stable step and the guard's
  // energies change with them, and which sheets are driven.
  void constraints_changed() {
    for (std::uint32_t index : active) {
      slots[index].omega_max = 2.0 / detail::sheet_stable_step(*slots[index].sheet);
      slots[index].guard.has_reference = false;
    }
    find_driven();
  }
  // Slot::driven of every sheet: moved by a path or frame (or joined to such a sheet), or
  // in a world with a moving obstacle.
  void find_driven() {
    const std::vector<SheetId> moved = constraints.driven_sheets();
    const bool moving = obstacles_move();
    for (std::uint32_t index : active)
      slots[index].driven =
          moving || std::find(moved.begin(), moved.end(), SheetId{index, slots[index].generation}) != moved.end();
  }
  bool obstacles_move() const {
    return std::any_of(active_obstacles.begin(), active_obstacles.end(),
                       [&](auto o) { return obstacle_slots[o].def.motion.has_value(); });
  }
  // Whether anything moves by itself or couples sheets outside the contact stage: then
  // every substep needs the host stage (no runs of substeps, no contact-free frames).
  bool driven() const { return !constraints.empty() || obstacles_move(); }
  // Host stage, first: moving obstacles to their pose at the substep's start, and every
  // constrained point's target from the positions at that start.
  void move_rigid_parts() {
    const double t = time();
    for (std::uint32_t o : active_obstacles)
      if (obstacle_slots[o].def.motion) detail::place_obstacle(*obstacle_slots[o].obstacle, obstacle_slots[o].def, t);
    if (!constraints.empty()) constraints.set_targets(t, access());
  }


  Sheet<Real>& sheet(SheetId id) {
    if (!contains(id)) throw std::invalid_argument("drape: unknown or removed SheetId " + std::to_string(id.index));
    return *slots[id.index].sheet;
  }
  const Sheet<Real>& sheet(SheetId id) const { return const_cast<Impl*>(this)->sheet(id); }
  bool contains(SheetId id) const {
    return id.index < slots.size() && slots[id.index].sheet && slots[id.index].generation == id.generation;
  }
  Sheet<Real>& at(std::size_t k) { return *slots[active[k]].sheet; }

  detail::Obstacle& obstacle(ObstacleId id) {
    if (!contains(id))
      throw std::invalid_argument("drape: unknown or removed ObstacleId " + std::to_string(id.index));
    return *obstacle_slots[id.index].obstacle;
  }
  bool contains(ObstacleId id) const {
    return id.index < obstacle_slots.size() && obstacle_slots[id.index].obstacle &&
           obstacle_slots[id.index].generation == id.generation;
  }
  // The sheets' obstacle lists point into obstacle_slots: drop them when the pool changes.
  // The guard's energies include the obstacles' potentials, so its references are retaken too.
  void forget_near_obstacles() {
    for (std::uint32_t index : active) {
      slots[index].sheet->near_obstacles.clear();
      slots[index].guard.has_reference = false;
    }
  }

  // Host stage: each sheet's list of obstacles whose reach its bounding box overlaps, so a
  // sheet far from every obstacle runs no obstacle term at all.
  // A sheet's box now: the one its last integration took while the positions were in
  // cache, unless something moved the points since.
  detail::Aabb current_bounds(const Slot& slot) const {
    return slot.bounds_fresh ? slot.bounds : detail::sheet_bounds(*slot.sheet);
  }

  void assign_obstacles(double h) {
    if (active_obstacles.empty()) return;
    for (std::uint32_t index : active) {
      Sheet<Real>& s = *slots[index].sheet;
      const double lightest = slots[index].lightest_point;
      s.near_obstacles.clear();
      const detail::Aabb box = current_bounds(slots[index]);
      for (std::uint32_t o : active_obstacles) {
        const detail::Obstacle& obstacle = *obstacle_slots[o].obstacle;
        if (detail::may_touch(obstacle, box))
          s.near_obstacles.push_back({.obstacle = &obstacle,
                                      .exponent_cap = detail::exponent_cap(obstacle.def, lightest, h),
                                      .friction = std::max(s.friction, obstacle.def.friction),
                                      .dt = h,
                                      .gravity = {def.gravity.x, def.gravity.y, def.gravity.z}});
      }
    }
  }

  // Dozens of identical sheets keep one edge buffer between them.
  void share_topology(Sheet<Real>& s) {
    std::erase_if(topologies, [](const auto& t) { return t.use_count() == 1; });
    for (const auto& t : topologies)
      if (*t == *s.topology) {
        s.topology = t;
        return;
      }
    topologies.push_back(s.topology);
  }

  template <class Body>
  void parallel(std::size_t count, Body body) const {
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) body(k);
      });
    });
  }

  bool contacts_possible() const {
    if (!(def.contact_strength > 0)) return false;
    return active.size() > 1 ||
           std::any_of(active.begin(), active.end(), [&](auto i) { return slots[i].sheet->self_collision; });
  }

  // ---- The substep's stages, in the order substep() runs them ----------------------
  //
  // The host stage (serial decisions, parallel work inside), then the parallel stage over
  // sheets and row blocks. The contact stages run only while contacts are possible (more
  // than one sheet, or a self-colliding one, and contact_strength > 0); sheets whose boxes
  // (grown by half the contact range each) do not meet never reach the narrow phase.
  enum class Stage {
    RigidParts,   // moving obstacles posed and constraint targets set for this substep's time
    Bounds,       // every sheet's box, and the box grown by half the contact range
    BroadPhase,   // pairs of sheets whose grown boxes meet, and self-colliding sheets with themselves
    NarrowPhase,  // each pair's contact forces, into buffers only that pair owns (contacts.cpp)
    GatherPlan,   // each sheet's list of the buffers aimed at it, in pair order; has_contacts
    Obstacles,    // each sheet's list of obstacles within reach (assign_obstacles)
    Integrate,    // per sheet or row block: gather contacts, force terms (terms/terms.h), integrator
  };
  static constexpr Stage substep_stages[] = {Stage::RigidParts, Stage::Bounds,    Stage::BroadPhase,
                                             Stage::NarrowPhase, Stage::GatherPlan, Stage::Obstacles,
                                             Stage::Integrate};

  void run_stage(Stage stage, double h) {
    switch (stage) {
      case Stage::RigidParts: return move_rigid_parts();
      case Stage::Bounds: return contact_bounds(h);
      case Stage::BroadPhase: return find_pairs();
      case Stage::NarrowPhase: return narrow_phase(h);
      case Stage::GatherPlan: return plan_gather();
      case Stage::Obstacles: return assign_obstacles(h);
      case Stage::Integrate: return integrate_sheets(step_params(h));
    }
  }

  bool contacting = false;  // this substep's contact stages run (set by contact_bounds)

  // The contact parameters of a substep of length h (friction stops at most one substep's slip).
  detail::ContactParams<Real> contact_params(double h) const {
    auto params = detail::ContactParams<Real>::make(def.contact_thickness, def.contact_xi, def.contact_strength,
                                                    def.contact_range);
    params.dt = static_cast<Real>(h);
    return params;
  }

  void contact_bounds(double h) {
    const std::size_t count = active.size();
    for (std::size_t k = 0; k < count; ++k) at(k).has_contacts = false;
    contacting = contacts_possible();
    if (!contacting) {
      pairs.clear();
      return;
    }
    const auto params = contact_params(h);
    bounds.resize(count);
    grown.resize(count);
    parallel(count, [&](std::size_t k) {
      bounds[k] = current_bounds(slots[active[k]]);
      grown[k] = bounds[k].inflated(0.5 * double(params.range));
    });
  }

  void find_pairs() {
    if (!contacting) return;
    const std::size_t count = active.size();
    broad_phase.find_pairs(grown, pairs);
    if (std::any_of(active.begin(), active.end(), [&](auto i) { return slots[i].sheet->self_collision; })) {
      for (std::uint32_t k = 0; k < count; ++k)
        if (at(k).self_collision) pairs.push_back({k, k});
      std::sort(pairs.begin(), pairs.end());
    }
  }

  void narrow_phase(double h) {
    if (!contacting) return;
    const auto params = contact_params(h);
    if (pair_work.size() < pairs.size()) pair_work.resize(pairs.size());
    parallel(pairs.size(), [&](std::size_t q) {
      auto& w = pair_work[q];
      w.a = pairs[q].first;
      w.b = pairs[q].second;
      auto& grid = grids.local();
      if (w.a == w.b)
        detail::self_contacts(at(w.a), bounds[w.a], params, w, grid);
      else
        detail::pair_contacts(at(w.a), bounds[w.a], at(w.b), bounds[w.b], params, w, grid);
    });
  }

  // Each sheet's sources in pair order: the gather's order, fixed by the boxes alone.
  void plan_gather() {
    if (!contacting) return;
    const std::size_t count = active.size();
    source_start.assign(count + 1, 0);
    for (std::size_t q = 0; q < pairs.size(); ++q) {
      const auto& w = pair_work[q];
      if (w.on_a.size()) ++source_start[w.a + 1];
      if (w.a != w.b && w.on_b.size()) ++source_start[w.b + 1];
    }
    for (std::size_t k = 0; k < count; ++k) source_start[k + 1] += source_start[k];
    sources.resize(source_start[count]);
    source_cursor.assign(source_start.begin(), source_start.end() - 1);
    for (std::size_t q = 0; q < pairs.size(); ++q) {
      const auto& w = pair_work[q];
      if (w.on_a.size()) sources[source_cursor[w.a]++] = &w.on_a;
      if (w.a != w.b && w.on_b.size()) sources[source_cursor[w.b]++] = &w.on_b;
    }
    for (std::size_t k = 0; k < count; ++k) {
      Sheet<Real>& s = at(k);
      s.has_contacts = source_start[k + 1] > source_start[k];
      if (s.has_contacts && s.contact_force.x.size() != s.size()) s.contact_force.resize(s.size());
    }
  }

  // A sheet of at least 2·block_points points is cut into row blocks of about
  // block_points points, so one large sheet among small ones keeps every core busy
  // (with one thread there is no core to keep busy: sheets stay whole).
  void plan_blocks() {
    blocks.clear();
    const bool can_split = detail::updates_per_point(def.integrator) && arena->max_concurrency() > 1;
    for (std::uint32_t k = 0; k < active.size(); ++k) {
      Sheet<Real>& s = at(k);
      const std::uint32_t rows = s.topology->rows(), cols = s.topology->cols();
      const std::uint64_t points = s.size();
      std::uint32_t count = 1;
      // The obstacle term works on whole sheets: a sheet near an obstacle is not split.
      if (can_split && s.near_obstacles.empty() && points >= 2 * std::uint64_t(def.block_points))
        count = static_cast<std::uint32_t>(std::min<std::uint64_t>(rows, points / def.block_points));
      slots[active[k]].bounds_fresh = false;  // set again by a whole sheet's task
      if (count == 1) {
        blocks.push_back({k, 0, rows, 0, false});
        continue;
      }
      if (s.row_scratch.x.size() < std::size_t(count) * cols) s.row_scratch.resize(std::size_t(count) * cols);
      push_row_blocks(k, rows, count);
    }
  }

  // Sheet k's rows cut into `count` blocks of equal size (± 1 row).
  void push_row_blocks(std::uint32_t k, std::uint32_t rows, std::uint64_t count) {
    for (std::uint64_t b = 0; b < count; ++b)
      blocks.push_back({k, std::uint32_t(rows * b / count), std::uint32_t(rows * (b + 1) / count), std::uint32_t(b), true});
  }

  void gather(std::size_t k, std::size_t begin, std::size_t end) {
    Sheet<Real>& s = at(k);
    if (!s.has_contacts) return;
    const std::span<const detail::ContactForces<Real>* const> src(sources.data() + source_start[k],
                                                                   source_start[k + 1] - source_start[k]);
    detail::gather_contacts(src, s.contact_force, begin, end);
  }

  // Parallel stage: every task writes only its own sheet's (or block's) buffers and reads
  // the contact buffers the host stage finished, so the result does not depend on how TBB
  // schedules them (bit-identical for any thread count).
  void integrate_sheets(const detail::StepParams<Real>& params) {
    plan_blocks();
    bool any_split = false;
    const bool keep_bounds = contacts_possible() || !active_obstacles.empty();  // someone reads the box next substep
    parallel(blocks.size(), [&](std::size_t q) {
      const Block& b = blocks[q];
      Slot& slot = slots[active[b.sheet]];
      Sheet<Real>& s = *slot.sheet;
      const std::size_t cols = s.topology->cols();
      gather(b.sheet, b.row_begin * cols, b.row_end * cols);
      if (!b.split) {
        detail::integrate(def.integrator, s, params);
        if (keep_bounds) {  // for the next host stage, while the positions are in cache
          slot.bounds = detail::sheet_bounds(s);
          slot.bounds_fresh = true;
        }
        return;
      }
      auto row = detail::ptr(s.row_scratch);
      const std::size_t off = b.index * cols;
      detail::sheet_forces_rows(s, detail::cptr(s.position), detail::cptr(s.velocity), detail::ptr(s.force),
                                {row.x + off, row.y + off, row.z + off}, b.row_begin, b.row_end);
    });
    for (const Block& b : blocks) any_split = any_split || b.split;
    if (!any_split) return;
    // Second pass, after every block's forces: a block's springs read its neighbours' rows.
    parallel(blocks.size(), [&](std::size_t q) {
      const Block& b = blocks[q];
      if (!b.split) return;
      Sheet<Real>& s = at(b.sheet);
      const std::size_t cols = s.topology->cols();
      detail::update_points(def.integrator, s, params, b.row_begin * cols, b.row_end * cols);
    });
  }

  // One substep: the stages of substep_stages, in order.
  void substep(double h) {
    for (Stage stage : substep_stages) run_stage(stage, h);
    count_substeps(h, 1);
  }

  // Several substeps with nothing between them: no contacts (their forces come from every
  // sheet's positions at each substep) and no obstacles (each substep picks the ones near
  // a sheet). Then sheets are independent for the whole run of substeps, and each task
  // takes its sheet through many substeps while it is in cache.
  bool sheets_independent() const { return !contacts_possible() && active_obstacles.empty(); }

  // Blocks of a run of `levels` substeps: whole sheets, and row blocks of the large sheets
  // a wave can split (forces.h, sheet_wave): one block per thread, since each block also
  // steps `levels` rows beyond each edge (the same arithmetic, done twice), and no block
  // shorter than 4·levels rows.
  void plan_wave_blocks(std::uint32_t levels) {
    blocks.clear();
    const std::uint64_t threads = std::uint64_t(arena->max_concurrency());
    for (std::uint32_t k = 0; k < active.size(); ++k) {
      Sheet<Real>& s = at(k);
      slots[active[k]].bounds_fresh = false;
      const std::uint32_t rows = s.topology->rows();
      const std::uint64_t points = s.size();
      std::uint64_t count = 1;
      if (threads > 1 && detail::updates_per_point(def.integrator) && detail::wave_ready(s) &&
          points >= 2 * std::uint64_t(def.block_points))
        count = std::min({threads, points / def.block_points, std::uint64_t(rows / (4 * levels))});
      if (count <= 1) {
        blocks.push_back({k, 0, rows, 0, false});
        continue;
      }
      push_row_blocks(k, rows, count);
    }
  }

  // `count` substeps of h on independent sheets, in runs of wave_levels substeps: a run
  // takes every block (a whole sheet, or the rows of a split one) through all its
  // substeps in one task, a sheet that fits the cache budget one whole substep after
  // another, a larger one as a wave. Bit-identical to `count` calls of substep(h).
  tbb::enumerable_thread_specific<detail::WaveScratch<Real>> wave_scratch;  // whole sheets
  std::vector<detail::WaveScratch<Real>> block_scratch;                     // per split block, with its halo

  // `swept`, when given, gets each sheet's box over all the substeps' states (in `active`
  // order), for try_frame's check.
  void integrate_runs(double h, std::uint64_t count, std::vector<detail::Aabb>* swept = nullptr) {
    const detail::StepParams<Real> params = step_params(h);
    std::uint32_t widest = 1, reach = 1;
    for (std::size_t k = 0; k < active.size(); ++k) {
      at(k).has_contacts = false;  // contact forces of an earlier substep no longer apply
      at(k).near_obstacles.clear();
      widest = std::max(widest, at(k).topology->cols());
      reach = std::max(reach, detail::force_reach(at(k)));
    }
    const std::uint32_t max_levels = detail::wave_levels(widest, sizeof(Real), reach);
    for (std::uint64_t done = 0; done < count;) {
      const auto levels = static_cast<std::uint32_t>(std::min<std::uint64_t>(max_levels, count - done));
      plan_wave_blocks(levels);
      if (block_scratch.size() < blocks.size()) block_scratch.resize(blocks.size());
      if (swept) block_swept.assign(blocks.size(), detail::empty_box());
      // every split block copies its halo before any block moves a row
      if (std::any_of(blocks.begin(), blocks.end(), [](const Block& b) { return b.split; }))
        parallel(blocks.size(), [&](std::size_t q) {
          const Block& b = blocks[q];
          if (b.split) detail::wave_take_halo(at(b.sheet), levels, b.row_begin, b.row_end, block_scratch[q]);
        });
      parallel(blocks.size(), [&](std::size_t q) {
        const Block& b = blocks[q];
        Sheet<Real>& s = at(b.sheet);
        detail::Aabb* box = swept ? &block_swept[q] : nullptr;
        if (b.split) {
          detail::integrate_wave(def.integrator, s, params, levels, b.row_begin, b.row_end, block_scratch[q], box);
        } else if (detail::updates_per_point(def.integrator) && detail::wave_ready(s) && !detail::fits_cache_budget(s)) {
          detail::integrate_wave(def.integrator, s, params, levels, 0, s.topology->rows(), wave_scratch.local(), box);
        } else {
          for (std::uint32_t k = 0; k < levels; ++k) {
            detail::integrate(def.integrator, s, params);
            if (box) detail::include_box(*box, detail::sheet_bounds(s));
          }
        }
      });
      if (swept)
        for (std::size_t q = 0; q < blocks.size(); ++q) detail::include_box((*swept)[blocks[q].sheet], block_swept[q]);
      done += levels;
    }
  }

  // A frame of substeps on sheets that contacts or obstacles could couple, run as if
  // nothing did, and kept only if nothing did: no two sheets' boxes over the whole frame
  // came within contact range, and no box came within an obstacle's reach. Then the host
  // stage of every substep would have found no pair and no obstacle, and the frame is
  // bit-identical to substep-by-substep; otherwise the state before it is restored and
  // the caller steps substep by substep. For integrators with no memory between substeps
  // beyond x and v (forward and semi-implicit Euler), and no sheet with self-contact
  // (always its own pair). A frame whose sheets are in contact at its start is not tried:
  // only a frame in which a contact begins is computed twice.
  std::vector<detail::Aabb> swept, swept_grown, block_swept;
  detail::TrackingBroadPhase swept_broad_phase;  // over the frames' swept boxes; reset with broad_phase
  std::vector<detail::Vec3Array<Real>> saved;  // positions, then velocities, per sheet

  bool frame_may_be_contact_free() const {
    return detail::updates_per_point(def.integrator) &&
           std::none_of(active.begin(), active.end(), [&](auto i) { return slots[i].sheet->self_collision; });
  }

  // Whether sheets with these boxes are out of each other's contact range and out of
  // every obstacle's reach (what the host stage would find for them).
  bool apart(const std::vector<detail::Aabb>& boxes, detail::TrackingBroadPhase& tracker) {
    if (contacts_possible()) {
      const auto params = contact_params(def.dt);  // only its range is used here
      swept_grown.resize(boxes.size());
      for (std::size_t k = 0; k < boxes.size(); ++k) swept_grown[k] = boxes[k].inflated(0.5 * double(params.range));
      tracker.find_pairs(swept_grown, pairs);
      if (!pairs.empty()) return false;
    }
    for (const detail::Aabb& box : boxes)
      for (std::uint32_t o : active_obstacles)
        if (detail::may_touch(*obstacle_slots[o].obstacle, box)) return false;
    return true;
  }

  bool try_frame(double h, std::uint64_t count) {
    const std::size_t n = active.size();
    swept.resize(n);
    parallel(n, [&](std::size_t k) { swept[k] = current_bounds(slots[active[k]]); });
    // Sheets already in contact, or at an obstacle, would only be undone: no try.
    if (!apart(swept, broad_phase)) return false;
    saved.resize(2 * n);
    parallel(n, [&](std::size_t k) {
      saved[2 * k] = at(k).position;
      saved[2 * k + 1] = at(k).velocity;
    });
    integrate_runs(h, count, &swept);
    if (apart(swept, swept_broad_phase)) return true;
    parallel(n, [&](std::size_t k) {
      Sheet<Real>& s = at(k);
      s.position = saved[2 * k];
      s.velocity = saved[2 * k + 1];
    });
    return false;
  }

  detail::StepParams<Real> step_params(double h) const {
    return {static_cast<Real>(h), static_cast<Real>(def.gravity.x), static_cast<Real>(def.gravity.y),
            static_cast<Real>(def.gravity.z), def.cg_tolerance, def.cg_max_iterations, def.local_global_iterations,
            def.vertex_block_iterations};
  }

  void count_substeps(double h, std::uint64_t count) {
    if (h != current_h) {
      time_base = time();
      steps_base = steps;
      current_h = h;
    }
    steps += count;
  }

  // `count` substeps of h: in runs when the sheets are independent, or when a try shows
  // they stayed apart; else one by one.
  void substeps(double h, std::uint64_t count) {
    if (count > 1 && !driven()) {
      bool ran = false;
      if (sheets_independent()) {
        integrate_runs(h, count);
        ran = true;
      } else if (frame_may_be_contact_free()) {
        ran = try_frame(h, count);
      }
      if (ran) {
        pairs.clear();  // no substep of the run had a pair
        count_substeps(h, count);
        return;
      }
    }
    for (std::uint64_t k = 0; k < count; ++k) substep(h);
  }

  double time() const { return time_base + static_cast<double>(steps - steps_base) * current_h; }

  double omega_max() const {
    double w = 0;
    for (std::uint32_t index : active) w = std::max(w, slots[index].omega_max);
    return w;
  }

  // The longest substep allowed now: dt, or in adaptive mode the explicit integrator's
  // critical step on the stiffest sheet times the safety factor.
  double max_substep() const {
    if (!def.adaptive || !integrator_is_explicit(def.integrator)) return def.dt;
    const double h = def.adaptive_safety * integrator_critical_step(def.integrator, omega_max());
    return std::isfinite(h) ? h : std::numeric_limits<double>::infinity();
  }

  // `seconds` in equal substeps of at most max_substep(), ending exactly at time + seconds.
  void advance(double seconds) {
    const double h_max = max_substep();
    const double count = std::isfinite(h_max) ? std::max(1.0, std::ceil(seconds / h_max * (1 - 1e-12))) : 1.0;
    substeps(seconds / count, static_cast<std::uint64_t>(count));
  }

  // Motion energy: what an unstable step inflates.
  static double motion_energy(const Energies& e) { return e.kinetic + e.spring + e.bending + e.anchor + e.obstacle; }

  // The guard's energy of one sheet: its own terms and every obstacle's potential (as in
  // diagnostics(): not only the near ones, so the value does not depend on the broad-phase).
  Energies guard_energy(const Slot& slot) const {
    Energies e = detail::sheet_energies(*slot.sheet, def.gravity);
    if (!constraints.empty())
      e.anchor -= constraints.join_energy_excess({std::uint32_t(&slot - slots.data()), slot.generation}, *slot.sheet);
    for (std::uint32_t o : active_obstacles) {
      const detail::Obstacle& obstacle = *obstacle_slots[o].obstacle;
      e.obstacle += detail::obstacle_energy(*slot.sheet, obstacle, detail::exponent_cap(obstacle.def, slot.lightest_point, def.dt));
    }
    return e;
  }

  void take_reference(Slot& slot) {
    const auto& s = *slot.sheet;
    const Energies energy = guard_energy(slot);
    const detail::Aabb box = detail::sheet_bounds(s);
    double extent2 = 0, mass = 0;
    for (int k = 0; k < 3; ++k) extent2 += (box.hi[k] - box.lo[k]) * (box.hi[k] - box.lo[k]);
    for (Real m : s.mass) mass += m;
    const double g = std::hypot(def.gravity.x, def.gravity.y, def.gravity.z);
    slot.guard.has_reference = detail::sheet_finite(s) && std::isfinite(energy.total());
    slot.guard.reference_energy = energy.total();
    // The extent counts at least 1 mm so that a sheet collapsed to a point still has a
    // scale under gravity. With no gravity, no stress and no motion the scale would be 0:
    // the smallest normal number keeps the ratio defined (such a sheet cannot move, so
    // E − E₀ stays 0).
    const double extent = std::max(std::sqrt(extent2), 1e-3);
    slot.guard.floor = std::max(mass * g * extent, std::numeric_limits<double>::min());
    slot.guard.scale = std::max(motion_energy(energy), slot.guard.floor);
  }

  void take_references() {
    for (std::uint32_t index : active)
      if (!slots[index].guard.has_reference) take_reference(slots[index]);
  }

  // The guard: one pass over each sheet's points and springs.
  StabilityReport check() const {
    StabilityReport report;
    report.step = steps;
    report.time = time();
    report.integrator = def.integrator;
    report.dt = steps > 0 ? current_h : max_substep();
    double largest_growth = 1;
    bool any = false;
    // Each sheet's energy in parallel (independent passes); the verdict below walks the
    // sheets in order, so the report does not depend on scheduling.
    std::vector<Energies> energies(active.size());
    std::vector<char> finite(active.size());
    parallel(active.size(), [&](std::size_t k) {
      energies[k] = guard_energy(slots[active[k]]);
      finite[k] = detail::sheet_finite(*slots[active[k]].sheet);
    });
    for (std::size_t k = 0; k < active.size(); ++k) {
      const std::uint32_t index = active[k];
      const Slot& slot = slots[index];
      const Energies& energy = energies[k];
      report.unconverged_solves += slot.sheet->last_solve.unconverged_solves;
      StabilityStatus status = StabilityStatus::Stable;
      double growth = 1;
      if (!finite[k] || !std::isfinite(energy.total())) {
        status = StabilityStatus::NonFinite;
        growth = std::numeric_limits<double>::infinity();
      } else if (slot.guard.has_reference) {
        growth = 1 + (energy.total() - slot.guard.reference_energy) / slot.guard.scale;
        // Implicit Euler cannot grow geometrically; its one linearised Newton step can inject
        // energy for a step when a point moves a sizeable part of a spring in one step (the
        // linearisation misses the geometric stiffening), which its damping then removes.
        // That is reported in energy_growth but does not halt it.
        if (growth > def.guard_energy_growth && integrator_is_explicit(def.integrator) && !slot.driven)
          status = StabilityStatus::EnergyGrowth;
      }
      if (status == StabilityStatus::Stable) {
        largest_growth = any ? std::max(largest_growth, growth) : growth;
        any = true;
      } else if (report.ok()) {
        report.status = status;
        report.sheet = {index, slot.generation};
        report.energy_growth = growth;
        report.stable_dt = def.adaptive_safety * integrator_critical_step(def.integrator, slot.omega_max);
        // the cheapest integrator stable at this step; forward Euler is never suggested
        report.stable_integrator = Integrator::ImplicitEuler;
        for (Integrator i : {Integrator::SemiImplicitEuler, Integrator::RK4})
          if (integrator_critical_step(i, slot.omega_max) > report.dt) {
            report.stable_integrator = i;
            break;
          }
      }
    }
    if (report.ok()) report.energy_growth = largest_growth;
    return report;
  }

  StabilityReport finish_step() {
    if (!def.guard) {
      StabilityReport report;
      report.step = steps;
      report.time = time();
      report.integrator = def.integrator;
      report.dt = current_h;
      for (std::uint32_t index : active) report.unconverged_solves += slots[index].sheet->last_solve.unconverged_solves;
      return report;
    }
    StabilityReport report = check();
    if (!report.ok()) failure = report;
    return report;
  }
};


template <class Real>
BasicWorld<Real>::BasicWorld(const WorldDef& def) {
  if (std::string problem = validate(def); !problem.empty()) throw std::invalid_argument("drape: WorldDef " + problem);
  impl_ = std::make_unique<Impl>(def);
}
template <class Real>
BasicWorld<Real>::~BasicWorld() = default;
template <class Real>
BasicWorld<Real>::BasicWorld(BasicWorld&&) noexcept = default;
template <class Real>
BasicWorld<Real>& BasicWorld<Real>::operator=(BasicWorld&&) noexcept = default;

template <class Real>
SheetId BasicWorld<Real>::add_sheet(const SheetDef& def) {
  if (std::string problem = validate(def); !problem.empty()) throw std::invalid_argument("drape: sheet " + problem);
  Sheet<Real> sheet = detail::build_sheet<Real>(def);
  detail::set_wind(sheet, impl_->def.wind);
  impl_->share_topology(sheet);
  std::uint32_t index;
  if (!impl_->free_slots.empty()) {
    index = impl_->free_slots.back();
    impl_->free_slots.pop_back();
  } else {
    index = static_cast<std::uint32_t>(impl_->slots.size());
    impl_->slots.emplace_back();
  }
  auto& slot = impl_->slots[index];
  slot.lightest_point = *std::min_element(sheet.mass.begin(), sheet.mass.end());
  slot.sheet = std::move(sheet);
  slot.omega_max = 2.0 / detail::sheet_stable_step(*slot.sheet);
  slot.guard = {};
  slot.driven = impl_->obstacles_move();  // constraints come after the sheet
  impl_->take_reference(slot);
  slot.bounds_fresh = false;
  impl_->active.push_back(index);
  impl_->broad_phase.reset();
  impl_->swept_broad_phase.reset();
  return {index, slot.generation};
}

template <class Real>
void BasicWorld<Real>::remove_sheet(SheetId id) {
  impl_->sheet(id);  // throws on a stale id
  const bool held = impl_->constraints.forget(id, impl_->access());
  auto& slot = impl_->slots[id.index];
  slot.sheet.reset();
  ++slot.generation;
  impl_->free_slots.push_back(id.index);
  std::erase(impl_->active, id.index);
  if (held) impl_->constraints_changed();  // the sheets it was joined to lost anchors
  impl_->broad_phase.reset();
  impl_->swept_broad_phase.reset();
}

template <class Real>
bool BasicWorld<Real>::contains(SheetId id) const { return impl_->contains(id); }
template <class Real>
std::size_t BasicWorld<Real>::sheet_count() const { return impl_->active.size(); }

template <class Real>
std::vector<SheetId> BasicWorld<Real>::sheets() const {
  std::vector<SheetId> ids;
  for (std::uint32_t index : impl_->active) ids.push_back({index, impl_->slots[index].generation});
  return ids;
}

template <class Real>
ObstacleId BasicWorld<Real>::add_obstacle(const ObstacleDef& def) {
  if (std::string problem = validate(def); !problem.empty()) throw std::invalid_argument("drape: obstacle " + problem);
  std::uint32_t index;
  if (!impl_->free_obstacle_slots.empty()) {
    index = impl_->free_obstacle_slots.back();
    impl_->free_obstacle_slots.pop_back();
  } else {
    index = static_cast<std::uint32_t>(impl_->obstacle_slots.size());
    impl_->obstacle_slots.emplace_back();
  }
  impl_->forget_near_obstacles();
  auto& slot = impl_->obstacle_slots[index];
  slot.def = def;
  slot.obstacle = detail::make_obstacle(obstacle_at(def, impl_->time()));
  impl_->active_obstacles.push_back(index);
  if (def.motion) impl_->find_driven();  // a moving obstacle drives every sheet
  return {index, slot.generation};
}

template <class Real>
void BasicWorld<Real>::remove_obstacle(ObstacleId id) {
  impl_->obstacle(id);  // throws on a stale id
  impl_->forget_near_obstacles();
  const bool carried = impl_->constraints.forget(id, impl_->access());
  auto& slot = impl_->obstacle_slots[id.index];
  const bool moved = slot.def.motion.has_value();
  slot.obstacle.reset();
  slot.def = {};
  ++slot.generation;
  impl_->free_obstacle_slots.push_back(id.index);
  std::erase(impl_->active_obstacles, id.index);
  if (carried)
    impl_->constraints_changed();
  else if (moved)
    impl_->find_driven();
}

template <class Real>
bool BasicWorld<Real>::contains(ObstacleId id) const { return impl_->contains(id); }
template <class Real>
std::size_t BasicWorld<Real>::obstacle_count() const { return impl_->active_obstacles.size(); }

template <class Real>
std::vector<ObstacleId> BasicWorld<Real>::obstacles() const {
  std::vector<ObstacleId> ids;
  for (std::uint32_t index : impl_->active_obstacles) ids.push_back({index, impl_->obstacle_slots[index].generation});
  return ids;
}

template <class Real>
const ObstacleDef& BasicWorld<Real>::obstacle(ObstacleId id) const {
  const_cast<Impl&>(*impl_).obstacle(id);  // throws on a stale id
  return impl_->obstacle_slots[id.index].def;
}

template <class Real>
ConstraintId BasicWorld<Real>::add_constraint(const ConstraintDef& def) {
  const ConstraintId id = impl_->constraints.add(def, impl_->time(), impl_->access());
  impl_->constraints_changed();
  return id;
}

template <class Real>
void BasicWorld<Real>::remove_constraint(ConstraintId id) {
  impl_->constraints.remove(id, impl_->access());
  impl_->constraints_changed();
}

template <class Real>
bool BasicWorld<Real>::contains(ConstraintId id) const { return impl_->constraints.contains(id); }
template <class Real>
std::size_t BasicWorld<Real>::constraint_count() const { return impl_->constraints.size(); }
template <class Real>
std::vector<ConstraintId> BasicWorld<Real>::constraints() const { return impl_->constraints.ids(); }
template <class Real>
const ConstraintDef& BasicWorld<Real>::constraint(ConstraintId id) const { return impl_->constraints.def(id); }

template <class Real>
SheetView<Real> BasicWorld<Real>::view(SheetId id) const {
  const auto& s = impl_->sheet(id);
  return {s.topology->m, s.topology->n, s.position.x, s.position.y, s.position.z,
          s.velocity.x,  s.velocity.y,  s.velocity.z};
}

template <class Real>
SheetState<Real> BasicWorld<Real>::state(SheetId id) {
  auto& s = impl_->sheet(id);
  impl_->slots[id.index].guard.has_reference = false;  // the caller may write: a new reference
  impl_->slots[id.index].bounds_fresh = false;  // the caller may move points
  return {s.topology->m, s.topology->n, s.position.x, s.position.y, s.position.z,
          s.velocity.x,  s.velocity.y,  s.velocity.z};
}

template <class Real>
StabilityReport BasicWorld<Real>::step(int substeps) {
  if (impl_->failure) return *impl_->failure;
  impl_->take_references();
  if (substeps > 0) {
    if (impl_->def.adaptive && integrator_is_explicit(impl_->def.integrator)) {
      impl_->advance(substeps * impl_->def.dt);
    } else {
      impl_->substeps(impl_->def.dt, static_cast<std::uint64_t>(substeps));
    }
  }
  return impl_->finish_step();
}

template <class Real>
StabilityReport BasicWorld<Real>::advance(double seconds) {
  if (!(seconds >= 0) || !std::isfinite(seconds))
    throw std::invalid_argument("drape: advance() needs a non-negative finite time (got " + std::to_string(seconds) + ")");
  if (impl_->failure) return *impl_->failure;
  impl_->take_references();
  if (seconds > 0) impl_->advance(seconds);
  return impl_->finish_step();
}

template <class Real>
StabilityReport BasicWorld<Real>::check() const { return impl_->check(); }
template <class Real>
bool BasicWorld<Real>::halted() const { return impl_->failure.has_value(); }
template <class Real>
double BasicWorld<Real>::substep_dt() const { return impl_->max_substep(); }

template <class Real>
const WorldDef& BasicWorld<Real>::def() const { return impl_->def; }
// Changing how the world steps is the caller's answer to a halt: it lifts the halt, and
// the guard takes fresh references at the next step.
template <class Real>
void BasicWorld<Real>::Impl::set_def(const WorldDef& d) {
  if (std::string problem = validate(d); !problem.empty()) throw std::invalid_argument("drape: WorldDef " + problem);
  const bool new_arena = d.threads != def.threads;
  def = d;
  if (new_arena) make_arena();
  failure.reset();
  for (std::uint32_t index : active) {
    slots[index].guard.has_reference = false;
    detail::set_wind(*slots[index].sheet, def.wind);
  }
}

template <class Real>
void BasicWorld<Real>::set_integrator(Integrator integrator) {
  WorldDef d = impl_->def;
  d.integrator = integrator;
  impl_->set_def(d);
}
template <class Real>
void BasicWorld<Real>::set_dt(double dt) {
  WorldDef d = impl_->def;
  d.dt = dt;
  impl_->set_def(d);
}
template <class Real>
void BasicWorld<Real>::set_adaptive(bool adaptive, double safety) {
  WorldDef d = impl_->def;
  d.adaptive = adaptive;
  d.adaptive_safety = safety;
  impl_->set_def(d);
}
template <class Real>
void BasicWorld<Real>::set_cg(double tolerance, int max_iterations) {
  WorldDef d = impl_->def;
  d.cg_tolerance = tolerance;
  d.cg_max_iterations = max_iterations;
  impl_->set_def(d);
}

template <class Real>
typename BasicWorld<Real>::SolverStats BasicWorld<Real>::solver_stats(SheetId id) const {
  const detail::SolveStats& stats = impl_->sheet(id).last_solve;
  return {stats.iterations, stats.relative_residual, stats.converged, stats.unconverged_solves};
}

template <class Real>
double BasicWorld<Real>::time() const { return impl_->time(); }

template <class Real>
void BasicWorld<Real>::set_threads(int threads) {
  if (threads < 0) throw std::invalid_argument("drape: threads must be >= 0 (0: all cores)");
  WorldDef d = impl_->def;
  d.threads = threads;
  impl_->set_def(d);
}
template <class Real>
std::size_t BasicWorld<Real>::contact_pair_count() const { return impl_->pairs.size(); }
template <class Real>
std::uint64_t BasicWorld<Real>::step_count() const { return impl_->steps; }

template <class Real>
void BasicWorld<Real>::set_step_count(std::uint64_t steps) {
  // time() = steps·dt again, as for a world that has taken only steps of dt
  impl_->steps = steps;
  impl_->steps_base = 0;
  impl_->time_base = 0;
  impl_->current_h = impl_->def.dt;
}

template <class Real>
void BasicWorld<Real>::set_state(SheetId id, const SheetView<Real>& from) {
  auto& s = impl_->sheet(id);
  impl_->slots[id.index].guard.has_reference = false;  // new state: the guard takes a new reference
  const std::size_t count = s.size();
  for (std::size_t size : {from.x.size(), from.y.size(), from.z.size(), from.vx.size(), from.vy.size(), from.vz.size()})
    if (size != count)
      throw std::invalid_argument("drape: set_state of sheet " + std::to_string(id.index) + " needs " +
                                  std::to_string(count) + " values per component, got " + std::to_string(size));
  std::copy(from.x.begin(), from.x.end(), s.position.x.begin());
  std::copy(from.y.begin(), from.y.end(), s.position.y.begin());
  std::copy(from.z.begin(), from.z.end(), s.position.z.begin());
  std::copy(from.vx.begin(), from.vx.end(), s.velocity.x.begin());
  std::copy(from.vy.begin(), from.vy.end(), s.velocity.y.begin());
  std::copy(from.vz.begin(), from.vz.end(), s.velocity.z.begin());
  impl_->slots[id.index].bounds_fresh = false;  // the points moved: the cached box is stale
}

template <class Real>
std::span<const Real> BasicWorld<Real>::integrator_memory(SheetId id) const {
  return impl_->sheet(id).integrator_scratch;
}

template <class Real>
void BasicWorld<Real>::set_integrator_memory(SheetId id, std::span<const Real> memory) {
  impl_->sheet(id).integrator_scratch.assign(memory.begin(), memory.end());
}

template <class Real>
SheetDiagnostics BasicWorld<Real>::diagnostics(SheetId id) const {
  const auto& sheet = impl_->sheet(id);
  SheetDiagnostics d = detail::sheet_diagnostics(sheet, impl_->def.gravity);
  d.energy.anchor -= impl_->constraints.join_energy_excess(id, sheet);  // a join's spring counted once
  // every obstacle, not only the near ones: the energy must not depend on the broad-phase
  const double lightest = impl_->slots[id.index].lightest_point;
  for (std::uint32_t o : impl_->active_obstacles) {
    const detail::Obstacle& obstacle = *impl_->obstacle_slots[o].obstacle;
    d.energy.obstacle += detail::obstacle_energy(sheet, obstacle, detail::exponent_cap(obstacle.def, lightest, impl_->def.dt));
  }
  d.finite = d.finite && std::isfinite(d.energy.total());
  return d;
}

template <class Real>
Energies BasicWorld<Real>::energies() const {
  Energies total;
  for (SheetId id : sheets()) {
    const Energies e = diagnostics(id).energy;
    total.kinetic += e.kinetic;
    total.spring += e.spring;
    total.bending += e.bending;
    total.gravity += e.gravity;
    total.anchor += e.anchor;
    total.obstacle += e.obstacle;
  }
  return total;
}

template <class Real>
bool BasicWorld<Real>::all_finite() const {
  return std::all_of(impl_->active.begin(), impl_->active.end(),
                     [&](std::uint32_t index) { return detail::sheet_finite(*impl_->slots[index].sheet); });
}

template <class Real>
double BasicWorld<Real>::stable_step_estimate(SheetId id) const {
  return detail::sheet_stable_step(impl_->sheet(id));
}

template <class Real>
double BasicWorld<Real>::critical_step(Integrator integrator) const {
  return integrator_critical_step(integrator, impl_->omega_max());
}

template <class Real>
double BasicWorld<Real>::stable_step_estimate() const {
  double dt = std::numeric_limits<double>::infinity();
  for (SheetId id : sheets()) dt = std::min(dt, stable_step_estimate(id));
  return dt;
}

template class BasicWorld<double>;
template class BasicWorld<float>;

}  // namespace drape
