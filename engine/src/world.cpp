// The World: the public API of BasicWorld, the pools of sheets and obstacles addressed by
// ids, and validate()/describe(). The substep is in step.cpp, runs of substeps in frames.cpp,
// the stability guard in guard.cpp; world_impl.h holds the state they share.
#include <drape/world.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "crossings.h"
#include "diagnostics.h"
#include "world_impl.h"

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
  static_assert(max_threads == 4096, "the message below names it");
  if (d.threads < 0 || d.threads > max_threads)
    return problem("threads", "must be 0 (all cores) or positive, at most drape::max_threads = 4096", d.threads);
  if (!(d.cg_tolerance > 0) || !finite(d.cg_tolerance)) return problem("cg_tolerance", "must be positive and finite", d.cg_tolerance);
  if (d.cg_max_iterations < 1) return problem("cg_max_iterations", "must be at least 1", d.cg_max_iterations);
  if (!preconditioner_from_name(preconditioner_name(d.cg_preconditioner)))
    return problem("cg_preconditioner", "is not a preconditioner", double(d.cg_preconditioner));
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
  if (!(d.contact_damping >= 0) || !finite(d.contact_damping))
    return problem("contact_damping", "must be non-negative and finite", d.contact_damping);
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
  if (r.step_limit == StepLimit::Contact) {
    out << "its contact with other sheets is stiffer than this step holds (contact_strength / contact_xi² against its "
           "lightest point): stable below dt ~ "
        << r.stable_dt << " s (estimate) with any integrator, or a larger contact_xi (a smaller contact_strength "
           "softens the contact too, but lowers the barrier that keeps fast sheets apart)";
  } else if (r.dt > r.stable_dt) {
    if (r.stable_dt > 0) out << "stable below dt ~ " << r.stable_dt << " s (estimate), or ";
    out << "use " << integrator_name(r.stable_integrator) << " at this dt";
  } else {
    // neither the springs nor the contact explain it: say so rather than advise a step in use
    out << "dt is within its stable-step estimate";
    if (std::isfinite(r.stable_dt)) out << " (~" << r.stable_dt << " s)";
    out << ", so its stiffness and damping do not explain this: look for a load too large for the sheet (gravity, wind, "
           "a prescribed motion), state set between steps, or try a smaller dt";
  }
  if (r.unconverged_solves > 0) out << " (" << r.unconverged_solves << " implicit solves stopped before their tolerance)";
  return out.str();
}

template <class Real>
void BasicWorld<Real>::Impl::make_arena() {
  const int concurrency = def.threads > 0 ? def.threads : int(tbb::task_arena::automatic);
  arena = std::make_unique<tbb::task_arena>(concurrency);
}

template <class Real>
typename detail::ConstraintPool<Real>::Access BasicWorld<Real>::Impl::access() {
  return {[this](SheetId id) { return contains(id) ? &sheet(id) : nullptr; },
          [this](ObstacleId id) { return contains(id) ? &obstacle_slots[id.index].def : nullptr; }};
}

// Constraints add anchors (eq 8) to their sheets: the stable step and the guard's
// energies change with them, and which sheets are driven.
template <class Real>
void BasicWorld<Real>::Impl::constraints_changed() {
  for (std::uint32_t index : active) {
    slots[index].omega_max = 2.0 / detail::sheet_stable_step(*slots[index].sheet);
    slots[index].guard.has_reference = false;
  }
  find_driven();
}

// Slot::driven of every sheet: moved by a path or frame (or joined to such a sheet), or
// in a world with a moving obstacle.
template <class Real>
void BasicWorld<Real>::Impl::find_driven() {
  const std::vector<SheetId> moved = constraints.driven_sheets();
  const bool moving = obstacles_move();
  for (std::uint32_t index : active)
    slots[index].driven =
        moving || std::find(moved.begin(), moved.end(), sheet_ids.id(index)) != moved.end();
}

template <class Real>
bool BasicWorld<Real>::Impl::obstacles_move() const {
  return std::any_of(active_obstacles.begin(), active_obstacles.end(),
                     [&](auto o) { return obstacle_slots[o].def.motion.has_value(); });
}

template <class Real>
Sheet<Real>& BasicWorld<Real>::Impl::sheet(SheetId id) {
  if (!contains(id)) throw std::invalid_argument("drape: unknown or removed SheetId " + std::to_string(id.index));
  return *slots[id.index].sheet;
}

template <class Real>
detail::Obstacle& BasicWorld<Real>::Impl::obstacle(ObstacleId id) {
  if (!contains(id))
    throw std::invalid_argument("drape: unknown or removed ObstacleId " + std::to_string(id.index));
  return *obstacle_slots[id.index].obstacle;
}

// The sheets' obstacle lists point into obstacle_slots: drop them when the pool changes.
// The guard's energies include the obstacles' potentials, so its references are retaken too.
template <class Real>
void BasicWorld<Real>::Impl::forget_near_obstacles() {
  for (std::uint32_t index : active) {
    slots[index].sheet->near_obstacles.clear();
    slots[index].guard.has_reference = false;
  }
}

// Dozens of identical sheets keep one edge buffer between them.
template <class Real>
void BasicWorld<Real>::Impl::share_topology(Sheet<Real>& s) {
  std::erase_if(topologies, [](const auto& t) { return t.use_count() == 1; });
  for (const auto& t : topologies)
    if (*t == *s.topology) {
      s.topology = t;
      return;
    }
  topologies.push_back(s.topology);
}

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
  const std::string problem = std::is_same_v<Real, float> ? validate_float(def) : validate(def);
  if (!problem.empty()) throw std::invalid_argument("drape: sheet " + problem);
  Sheet<Real> sheet = detail::build_sheet<Real>(def);
  detail::set_wind(sheet, impl_->def.wind);
  impl_->share_topology(sheet);
  const std::uint32_t index = impl_->sheet_ids.acquire();
  if (index == impl_->slots.size()) impl_->slots.emplace_back();
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
  impl_->groups.clear();  // their broad phases track other sheets now
  return impl_->sheet_ids.id(index);
}

namespace {
// The read-only spans of a sheet's buffers (view(), and a taken sheet's).
template <class Real>
SheetView<Real> view_of(const detail::Sheet<Real>& s) {
  return {s.topology->m, s.topology->n, s.position.x, s.position.y, s.position.z,
          s.velocity.x,  s.velocity.y,  s.velocity.z};
}
}  // namespace

template <class Real>
void BasicWorld<Real>::remove_sheet(SheetId id) {
  take_sheet(id);  // its buffers freed with the result
}

template <class Real>
RemovedSheet<Real> BasicWorld<Real>::take_sheet(SheetId id) {
  impl_->sheet(id);  // throws on a stale id
  const bool held = impl_->constraints.forget(id, impl_->access());
  // the energy its group passed through it leaves with it: the others start afresh
  impl_->guard_forget_group(id.index);
  auto& slot = impl_->slots[id.index];
  // Moved, not copied: the vectors' storage, which the caller's spans point into, goes along.
  auto taken = std::make_shared<const detail::Sheet<Real>>(std::move(*slot.sheet));
  const SheetView<Real> last = view_of(*taken);
  slot.sheet.reset();
  impl_->sheet_ids.release(id.index);
  // A sheet added into this slot later has the removed one's address, so a pair's kept lists
  // may still pass as made for it (contacts.cpp, made_for); their exact tests compare
  // positions and decide rightly, but their travel bounds (PairContacts::moved_lo_a/b) are
  // on the removed sheet's travel scale, not the new sheet's: forgotten, for every pair.
  for (auto& w : impl_->pair_work)
    w.moved_lo_a = w.moved_lo_b = -std::numeric_limits<double>::infinity();
  // Pairs name sheets by their place in `active`: the removed sheet's go, and those after it
  // move down one, so the work kept for the others still names them (and contact_memory()
  // names only sheets the world has: a checkpoint after a removal resumes).
  const auto gone = std::uint32_t(std::find(impl_->active.begin(), impl_->active.end(), id.index) - impl_->active.begin());
  std::erase_if(impl_->pair_work, [&](const auto& w) { return w.a == gone || w.b == gone; });
  for (auto& w : impl_->pair_work) {
    w.a -= w.a > gone ? 1 : 0;
    w.b -= w.b > gone ? 1 : 0;
  }
  std::erase(impl_->active, id.index);
  if (held) impl_->constraints_changed();  // the sheets it was joined to lost anchors
  impl_->broad_phase.reset();
  impl_->swept_broad_phase.reset();
  impl_->groups.clear();  // their broad phases track other sheets now
  return RemovedSheet<Real>(std::move(taken), last);
}

template <class Real>
bool BasicWorld<Real>::contains(SheetId id) const { return impl_->contains(id); }
template <class Real>
std::size_t BasicWorld<Real>::sheet_count() const { return impl_->active.size(); }

template <class Real>
std::vector<SheetId> BasicWorld<Real>::sheets() const {
  return impl_->sheet_ids.ids(impl_->active);
}

template <class Real>
ObstacleId BasicWorld<Real>::add_obstacle(const ObstacleDef& def) {
  if (std::string problem = validate(def); !problem.empty()) throw std::invalid_argument("drape: obstacle " + problem);
  // Posed before a slot is taken: a motion callback that throws leaves the pools as they were.
  detail::Obstacle obstacle = detail::make_obstacle(obstacle_at(def, impl_->time()));
  const std::uint32_t index = impl_->obstacle_ids.acquire();
  if (index == impl_->obstacle_slots.size()) impl_->obstacle_slots.emplace_back();
  impl_->forget_near_obstacles();
  auto& slot = impl_->obstacle_slots[index];
  slot.def = def;
  slot.obstacle = std::move(obstacle);
  impl_->active_obstacles.push_back(index);
  if (def.motion) impl_->find_driven();  // a moving obstacle drives every sheet
  return impl_->obstacle_ids.id(index);
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
  impl_->obstacle_ids.release(id.index);
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
  return impl_->obstacle_ids.ids(impl_->active_obstacles);
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
  return view_of(impl_->sheet(id));
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
  if (substeps < 0)
    throw std::invalid_argument("drape: step() needs a non-negative number of substeps (got " + std::to_string(substeps) + ")");
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
void BasicWorld<Real>::set_solver_stats(SheetId id, const SolverStats& stats) {
  impl_->sheet(id).last_solve = {stats.iterations, stats.relative_residual, stats.converged, stats.unconverged_solves};
}

template <class Real>
double BasicWorld<Real>::time() const { return impl_->time(); }

template <class Real>
void BasicWorld<Real>::set_threads(int threads) {
  WorldDef d = impl_->def;
  d.threads = threads;
  impl_->set_def(d);
}
template <class Real>
std::size_t BasicWorld<Real>::contact_pair_count() const { return impl_->pairs.size(); }
template <class Real>
std::uint64_t BasicWorld<Real>::step_count() const { return impl_->steps; }

template <class Real>
typename BasicWorld<Real>::FrameStats BasicWorld<Real>::frame_stats() const { return impl_->frame_stats; }

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
std::vector<std::uint64_t> BasicWorld<Real>::contact_memory() const {
  auto& impl = *impl_;
  std::vector<const detail::Sheet<Real>*> sheets;
  for (std::size_t k = 0; k < impl.active.size(); ++k) sheets.push_back(&impl.at(k));
  return detail::write_contact_memory<Real>(impl.pair_work, sheets);
}

template <class Real>
void BasicWorld<Real>::set_contact_memory(std::span<const std::uint64_t> memory) {
  if (memory.empty()) {
    impl_->pair_work.clear();
    return;
  }
  std::vector<const detail::Sheet<Real>*> sheets;
  for (std::size_t k = 0; k < impl_->active.size(); ++k) sheets.push_back(&impl_->at(k));
  std::vector<detail::SheetTravel<Real>> travel;
  detail::read_contact_memory<Real>(memory, sheets, impl_->pair_work, travel, impl_->steps);
  for (std::size_t k = 0; k < travel.size(); ++k) {
    impl_->at(k).travel = travel[k].travel;
    impl_->at(k).travel_from = std::move(travel[k].from);
  }
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
ObstaclePenetration BasicWorld<Real>::obstacle_penetration(SheetId id) const {
  const auto& sheet = impl_->sheet(id);  // checks the id
  const auto& slot = impl_->slots[id.index];
  const detail::Aabb box = impl_->current_bounds(slot);
  ObstaclePenetration deepest;
  for (std::uint32_t o : impl_->active_obstacles) {
    const detail::Obstacle& obstacle = *impl_->obstacle_slots[o].obstacle;
    if (!detail::may_touch(obstacle, box)) continue;
    for (std::size_t p = 0; p < sheet.position.x.size(); ++p) {
      const double x[3] = {double(sheet.position.x[p]), double(sheet.position.y[p]), double(sheet.position.z[p])};
      const double depth = -detail::implicit_at(obstacle, x).f;
      if (depth > deepest.depth) deepest = {depth, impl_->obstacle_ids.id(o), std::uint32_t(p)};
    }
  }
  return deepest;
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
void BasicWorld<Real>::Impl::pairs_with_boxes(double margin, std::vector<detail::BoxPair>& pairs,
                                              std::vector<detail::SheetBoxes<Real>>& boxes) const {
  const std::size_t count = active.size();
  std::vector<detail::Aabb> grown(count);
  for (std::size_t k = 0; k < count; ++k) grown[k] = detail::sheet_bounds(at(k)).inflated(margin);
  detail::BroadPhase().find_pairs(grown, pairs);
  for (std::uint32_t k = 0; k < count; ++k)
    if (at(k).self_collision) pairs.push_back({k, k});
  std::vector<char> used(count, 0);
  for (const auto& pair : pairs) used[pair.first] = used[pair.second] = 1;
  boxes.assign(count, {});
  parallel(count, [&](std::size_t k) {
    if (used[k]) detail::build_boxes(at(k), boxes[k]);
  });
}

template <class Real>
double BasicWorld<Real>::contact_energy() const {
  if (!impl_->contacts_possible()) return 0;
  const auto params = impl_->contact_params(impl_->def.dt);
  const Impl& impl = *impl_;  // its sheets, read only
  // the pairs the narrow phase would take now: grown boxes that meet, and self-colliding sheets
  std::vector<detail::BoxPair> pairs;
  std::vector<detail::SheetBoxes<Real>> boxes;
  impl_->pairs_with_boxes(0.5 * double(params.range), pairs, boxes);
  // each pair's share computed apart and summed in pair order: the same on any thread count
  std::vector<double> share(pairs.size());
  impl_->parallel(pairs.size(), [&](std::size_t q) {
    const auto [a, b] = pairs[q];
    auto pair = params;
    pair.exponent_cap = impl_->pair_exponent_cap(impl_->world, a, b, impl_->def.dt);
    share[q] = detail::contact_energy(impl.at(a), boxes[a], impl.at(b), boxes[b], pair);
    if (a != b) share[q] += detail::contact_energy(impl.at(b), boxes[b], impl.at(a), boxes[a], pair);
    if (a != b && pair.rims) share[q] += detail::rim_energy(impl.at(a), boxes[a], impl.at(b), boxes[b], pair);
  });
  double energy = 0;
  for (double e : share) energy += e;
  return energy;
}

template <class Real>
std::vector<SheetCrossing> BasicWorld<Real>::sheet_crossings() const {
  std::vector<SheetCrossing> out;
  if (!impl_->contacts_possible()) return out;
  const Impl& impl = *impl_;  // its sheets, read only
  // sheets that pass through each other have boxes that meet (touching counts)
  std::vector<detail::BoxPair> pairs;
  std::vector<detail::SheetBoxes<Real>> boxes;
  impl_->pairs_with_boxes(0, pairs, boxes);
  std::sort(pairs.begin(), pairs.end(), [](const auto& p, const auto& q) {
    return std::pair(p.first, p.second) < std::pair(q.first, q.second);
  });
  std::vector<detail::Crossings> found(pairs.size());
  impl_->parallel(pairs.size(), [&](std::size_t q) {
    const auto [a, b] = pairs[q];
    found[q] = detail::sheet_crossings(impl.at(a), boxes[a], impl.at(b), boxes[b]);
  });
  auto id = [&](std::uint32_t k) { return impl_->sheet_ids.id(impl_->active[k]); };
  for (std::size_t q = 0; q < pairs.size(); ++q)
    if (found[q].count != 0)
      out.push_back({id(pairs[q].first), id(pairs[q].second), found[q].count, found[q].point_a, found[q].point_b});
  return out;
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
double BasicWorld<Real>::contact_step_estimate(SheetId id) const {
  impl_->sheet(id);  // checks the id
  return 2.0 / impl_->contact_omega(impl_->slots[id.index].lightest_point);
}

template <class Real>
double BasicWorld<Real>::stable_step_estimate() const {
  double dt = std::numeric_limits<double>::infinity();
  for (SheetId id : sheets()) dt = std::min(dt, stable_step_estimate(id));
  return dt;
}

// Also instantiates the members of Impl defined in this file.
template class BasicWorld<double>;
template class BasicWorld<float>;

}  // namespace drape
