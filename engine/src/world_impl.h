// The World's private state, BasicWorld<Real>::Impl: the pools, the scratch of the host
// stage and of frames, and the stability guard's references. Its member functions live
// by concept: world.cpp (the pools and ids behind the public API), step.cpp (the
// substep's stages, in order), frames.cpp (runs of substeps, contact-free frames, waves),
// guard.cpp (the stability guard). Each of them instantiates the members it defines, one
// by one (an explicit instantiation of Impl itself may appear only once in a program).
#pragma once

#include <drape/world.h>

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "bounds.h"
#include "broad_phase.h"
#include "constraints.h"
#include "contacts.h"
#include "forces.h"
#include "id_pool.h"
#include "integrate.h"
#include "obstacles.h"
#include "sheet_data.h"

namespace drape {

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
    std::uint32_t sheet;  // position in its scope's `active`
    std::uint32_t row_begin, row_end, index;
    bool split;
  };

  // What a substep's stages (step.cpp) read and write besides the sheets themselves: the
  // sheets they step, the step count and clock, the pairs found and each pair's work, and
  // the host stage's scratch, kept between substeps so a settled scene does not allocate.
  // The world steps with `world`; in a frame of groups each group steps with a scope of its
  // own (frames.cpp), so that groups step at once on different threads.
  struct Scope {
    std::vector<std::uint32_t> active;  // slots of the sheets stepped, in the order they were added
    std::uint64_t steps = 0;
    // time = time_base + (steps − steps_base)·current_h: exact for runs of equal substeps
    double time_base = 0, current_h = 0;
    std::uint64_t steps_base = 0;
    std::vector<detail::Aabb> bounds, grown;
    detail::TrackingBroadPhase broad_phase;  // reset when `active` changes
    std::vector<detail::BoxPair> pairs;
    std::vector<std::uint8_t> in_pair;                  // per sheet: needs its boxes (1), in a pair (2)
    std::vector<detail::SheetBoxes<Real>> sheet_boxes;  // per sheet in a pair, shared by its pairs
    std::vector<detail::PairContacts<Real>> pair_work;
    std::vector<std::uint32_t> source_start;                  // per sheet, into sources (CSR)
    std::vector<const detail::ContactForces<Real>*> sources;  // per sheet, in pair order
    std::vector<std::uint32_t> source_cursor;                 // while filling sources
    std::vector<Block> blocks;
    std::vector<detail::simd::Extent<Real>> block_box;  // a split block's box after its update
    bool contacting = false;  // this substep's contact stages run (set by contact_bounds)
    // A group stepping beside at least as many others as there are threads: its stages'
    // loops run in order on the thread that steps it (each), without forking.
    bool serial = false;
    // A group's scope keeps the slots of the pairs it met for the guard (guard_meet), which
    // the world's takes once the frame is kept; the world's meets them at once.
    bool keeps_meets = false;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> met;
    double time() const { return time_base + static_cast<double>(steps - steps_base) * current_h; }
  };

  WorldDef def;
  std::unique_ptr<tbb::task_arena> arena;
  std::vector<Slot> slots;
  detail::IdPool<SheetTag> sheet_ids;  // handles to `slots`
  Scope world;
  // The world's scope by the names the pools, the guard and frames use.
  std::vector<std::uint32_t>& active = world.active;  // live slots in the order sheets were added
  std::uint64_t& steps = world.steps;
  double& time_base = world.time_base;
  double& current_h = world.current_h;
  std::uint64_t& steps_base = world.steps_base;
  detail::TrackingBroadPhase& broad_phase = world.broad_phase;
  std::vector<detail::BoxPair>& pairs = world.pairs;
  std::vector<detail::PairContacts<Real>>& pair_work = world.pair_work;
  std::vector<std::shared_ptr<const Topology<Real>>> topologies;
  std::optional<StabilityReport> failure;  // set when the guard halted the world
  tbb::enumerable_thread_specific<detail::ContactScratch<Real>> contact_scratch;  // narrow phase

  explicit Impl(const WorldDef& d) : def(d) { make_arena(); }

  struct ObstacleSlot {
    std::optional<detail::Obstacle> obstacle;  // without its motion; at its pose for this substep
    ObstacleDef def;                           // the caller's definition
  };
  std::vector<ObstacleSlot> obstacle_slots;
  detail::IdPool<ObstacleTag> obstacle_ids;  // handles to `obstacle_slots`
  std::vector<std::uint32_t> active_obstacles;  // live slots in the order obstacles were added

  detail::ConstraintPool<Real> constraints;

  // integrate_runs' scratch (frames.cpp)
  tbb::enumerable_thread_specific<detail::WaveScratch<Real>> wave_scratch;  // whole sheets
  std::vector<detail::WaveScratch<Real>> block_scratch;                     // per split block, with its halo
  // try_frame's scratch (frames.cpp)
  std::vector<detail::Aabb> swept, swept_grown, block_swept;
  detail::TrackingBroadPhase swept_broad_phase;  // over the frames' swept boxes; reset with broad_phase
  // A frame's groups: sheets closed under the pairs at the frame's start and the
  // constraints' joins, with those near an obstacle or held by a constraint; each steps the
  // frame alone, substep by substep, with the world's stages.
  struct Group {
    std::vector<std::uint32_t> members;  // positions in the world's `active`, ascending
    Scope scope;                         // its sheets' slots, its pairs and their work (in its positions)
    std::vector<detail::PairMemory<Real>> saved_work;  // its pairs' work as the frame found it
  };
  std::vector<Group> groups;
  std::size_t group_count = 0;           // groups[0, group_count) serve this frame
  std::vector<std::uint32_t> group_of;    // per position in `active`: its group, or kFree
  static constexpr std::uint32_t kFree = ~std::uint32_t(0);
  std::vector<std::uint32_t> free_sheets;  // positions of the sheets in no group: independent runs
  std::vector<detail::Aabb> free_swept;
  std::vector<detail::PairContacts<Real>> aside;  // gone pairs' work of sheets in two groups
  std::vector<detail::BoxPair> frame_pairs;
  // Per sheet, as the frame found it: positions, velocities, and its travel (Sheet::travel
  // and the measurement of it, contacts.h), the contact stage's state of the sheet.
  struct Saved {
    detail::Vec3Array<Real> position, velocity, travel_from;
    double travel = 0, moved = 0, moved_travel = 0;
    std::uint64_t moved_stamp = 0;
  };
  std::vector<Saved> saved;
  FrameStats frame_stats;
  std::uint32_t try_backoff = 0, tries_to_skip = 0;  // substeps(): tries skipped after one undone

  // ---- The pools and ids behind the public API (world.cpp) --------------------------

  void make_arena();
  void set_def(const WorldDef& d);
  typename detail::ConstraintPool<Real>::Access access();
  void constraints_changed();
  void find_driven();
  bool obstacles_move() const;
  // Whether anything moves by itself or couples sheets outside the contact stage: then
  // every substep needs the host stage (no runs of substeps, no contact-free frames).
  bool driven() const { return !constraints.empty() || obstacles_move(); }
  Sheet<Real>& sheet(SheetId id);
  const Sheet<Real>& sheet(SheetId id) const { return const_cast<Impl*>(this)->sheet(id); }
  bool contains(SheetId id) const { return sheet_ids.contains(id); }
  Sheet<Real>& at(std::size_t k) { return *slots[active[k]].sheet; }
  const Sheet<Real>& at(std::size_t k) const { return *slots[active[k]].sheet; }
  detail::Obstacle& obstacle(ObstacleId id);
  bool contains(ObstacleId id) const { return obstacle_ids.contains(id); }
  void forget_near_obstacles();
  void share_topology(Sheet<Real>& s);

  template <class Body>
  void parallel(std::size_t count, Body body) const {
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) body(k);
      });
    });
  }

  double time() const { return world.time(); }
  // A stage's loop over count items: across the threads (parallel), or in order in a serial scope.
  template <class Body>
  void each(const Scope& sc, std::size_t count, Body body) const {
    if (!sc.serial) return parallel(count, body);
    for (std::size_t k = 0; k < count; ++k) body(k);
  }

  // ---- The substep's stages, in the order substep() runs them (step.cpp) ------------
  //
  // The host stage (serial decisions, parallel work inside), then the parallel stage over
  // sheets and row blocks. The contact stages run only while contacts are possible (more
  // than one sheet, or a self-colliding one, and contact_strength > 0); sheets whose boxes
  // (grown by half the contact range each) do not meet never reach the narrow phase.
  enum class Stage {
    RigidParts,   // moving obstacles posed and constraint targets set for this substep's time
    Bounds,       // every sheet's box, and the box grown by half the contact range
    BroadPhase,   // pairs of sheets whose grown boxes meet, and self-colliding sheets with themselves
    ContactBoxes, // each sheet in a pair: its cells' and patches' boxes, made once for all its pairs
    NarrowPhase,  // each pair's contact forces, into buffers only that pair owns (contacts.cpp)
    GatherPlan,   // each sheet's list of the buffers aimed at it, in pair order; has_contacts
    Obstacles,    // each sheet's list of obstacles within reach (assign_obstacles)
    Integrate,    // per sheet or row block: gather contacts, force terms (terms/terms.h), integrator
  };
  static constexpr Stage substep_stages[] = {Stage::RigidParts,  Stage::Bounds,     Stage::BroadPhase,
                                             Stage::ContactBoxes, Stage::NarrowPhase, Stage::GatherPlan,
                                             Stage::Obstacles,   Stage::Integrate};

  Sheet<Real>& at(const Scope& sc, std::size_t k) { return *slots[sc.active[k]].sheet; }
  const Sheet<Real>& at(const Scope& sc, std::size_t k) const { return *slots[sc.active[k]].sheet; }
  bool contacts_possible(const Scope& sc) const;
  bool contacts_possible() const { return contacts_possible(world); }
  void move_rigid_parts(const Scope& sc);
  // A sheet's box now: the one its last integration took (from the update's registers, or
  // a pass while the positions were in cache), unless something moved the points since.
  detail::Aabb current_bounds(const Slot& slot) const {
    return slot.bounds_fresh ? slot.bounds : detail::sheet_bounds(*slot.sheet);
  }
  // Every active sheet's current_bounds, into out[k]. Most are fresh (a read); the stale
  // ones take a pass over their points each, across the threads only when they hold enough
  // points to pay for waking them: a small world's host stage then forks no work for
  // nothing. The boxes are the same either way.
  void active_bounds(const Scope& sc, std::vector<detail::Aabb>& out) const;
  void active_bounds(std::vector<detail::Aabb>& out) const { active_bounds(world, out); }
  // For a search of the sheets now (contact_energy, sheet_crossings): the pairs of active
  // sheets (positions in `active`) whose boxes, grown by `margin`, meet, sorted, then every
  // self-colliding sheet with itself; and the boxes (build_boxes) of each sheet in a pair.
  void pairs_with_boxes(double margin, std::vector<detail::BoxPair>& pairs,
                        std::vector<detail::SheetBoxes<Real>>& boxes) const;
  void assign_obstacles(const Scope& sc, double h);
  void run_stage(Scope& sc, Stage stage, double h);
  detail::ContactParams<Real> contact_params(const Scope& sc, double h) const;
  detail::ContactParams<Real> contact_params(double h) const { return contact_params(world, h); }
  // The exponent cap (contacts.h) of the pair of sheets a, b (positions in sc.active) at the substep h.
  Real pair_exponent_cap(const Scope& sc, std::size_t a, std::size_t b, double h) const;
  void contact_bounds(Scope& sc);
  // `boxes` grown by half the contact range each, into `out`: two of them meet where the
  // broad phase pairs their sheets.
  void grow_for_contact(const std::vector<detail::Aabb>& boxes, std::vector<detail::Aabb>& out) const;
  void find_pairs(Scope& sc);
  // sc.pair_work in the order of sc.pairs (a pair's work kept across changes of the list)
  void keep_pair_work(Scope& sc, std::uint64_t stamp);
  void contact_boxes(Scope& sc, double h);
  void narrow_phase(Scope& sc, double h);
  void plan_gather(Scope& sc);
  void plan_blocks(Scope& sc);
  void push_row_blocks(Scope& sc, std::uint32_t k, std::uint32_t rows, std::uint64_t count);
  void gather(Scope& sc, std::size_t k, std::size_t begin, std::size_t end);
  void integrate_sheets(Scope& sc, const detail::StepParams<Real>& params);
  void substep(Scope& sc, double h);
  void substep(double h) { substep(world, h); }
  detail::StepParams<Real> step_params(double h) const;
  void count_substeps(Scope& sc, double h, std::uint64_t count);
  void count_substeps(double h, std::uint64_t count) { count_substeps(world, h, count); }

  // ---- Runs of substeps, frames tried ahead (contact-free, in groups), waves (frames.cpp)

  // Several substeps with nothing between them: no contacts (their forces come from every
  // sheet's positions at each substep) and no obstacles (each substep picks the ones near
  // a sheet). Then sheets are independent for the whole run of substeps, and each task
  // takes its sheet through many substeps while it is in cache.
  bool sheets_independent() const { return !contacts_possible() && active_obstacles.empty(); }
  void plan_wave_blocks(std::uint32_t levels);
  void integrate_runs(double h, std::uint64_t count, std::vector<detail::Aabb>* swept = nullptr);
  bool frame_may_be_tried() const;
  void plan_groups(const std::vector<detail::Aabb>& boxes);
  bool groups_pay(bool may_undo) const;
  void save_sheet(std::size_t k);
  void restore_sheet(std::size_t k);
  void step_group(Group& g, double h, std::uint64_t count, bool may_undo);
  bool groups_stayed_apart();
  void end_groups(bool kept);
  // A frame tried: kept, undone (then the caller steps it substep by substep), or not tried
  // (sheets in groups that do not pay, groups_pay).
  enum class Try { Kept, Undone, NotTried };
  Try try_frame(double h, std::uint64_t count);
  void substeps(double h, std::uint64_t count);
  double omega_max() const;
  // ω of the sheet–sheet contact for a point of mass `lightest`: √(c/m)/ξ (0 when c = 0),
  // what contact_step_estimate, the adaptive step and the guard's report use.
  double contact_omega(double lightest) const;
  double max_substep() const;
  void advance(double seconds);

  // ---- The stability guard (guard.cpp) ---------------------------------------------

  // Motion energy: what an unstable step inflates.
  static double motion_energy(const Energies& e) { return e.kinetic + e.spring + e.bending + e.anchor + e.obstacle; }
  Energies guard_energy(const Slot& slot) const;
  void take_reference(Slot& slot);
  void take_references();
  StabilityReport check() const;
  // Contacts and joins pass energy between sheets, so the guard judges sheets that met
  // since their references together (check): guard_group[slot] is a slot of the same group
  // (a forest of slots; a root is its own), and guard_meet puts two slots in one group.
  std::vector<std::uint32_t> guard_group;
  std::uint32_t guard_root(std::uint32_t index) const;
  void guard_meet(std::uint32_t a, std::uint32_t b);
  // The slot's group has its references retaken at the next step (remove_sheet).
  void guard_forget_group(std::uint32_t index);
  StabilityReport finish_step();
};

}  // namespace drape
