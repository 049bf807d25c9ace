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
#include <stdexcept>
#include <string>

#include "bounds.h"
#include "broad_phase.h"
#include "contacts.h"
#include "diagnostics.h"
#include "forces.h"
#include "integrate.h"
#include "obstacles.h"
#include "sheet_data.h"

namespace drape {

using detail::Sheet;
using detail::Topology;

template <class Real>
struct BasicWorld<Real>::Impl {
  struct Slot {
    std::optional<Sheet<Real>> sheet;
    std::uint32_t generation = 0;
    double lightest_point = 0;  // kg, for the obstacle force bound (obstacles.h, exponent_cap)
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

  // Host stage scratch, kept between substeps so a settled scene does not allocate.
  std::vector<detail::Aabb> bounds, grown;
  detail::BroadPhase broad_phase;
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
    std::optional<detail::Obstacle> obstacle;
    std::uint32_t generation = 0;
  };
  std::vector<ObstacleSlot> obstacle_slots;
  std::vector<std::uint32_t> free_obstacle_slots;
  std::vector<std::uint32_t> active_obstacles;  // live slots in the order obstacles were added


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
  void forget_near_obstacles() {
    for (std::uint32_t index : active) slots[index].sheet->near_obstacles.clear();
  }

  // Host stage: each sheet's list of obstacles whose reach its bounding box overlaps, so a
  // sheet far from every obstacle runs no obstacle term at all.
  void assign_obstacles() {
    if (active_obstacles.empty()) return;
    for (std::uint32_t index : active) {
      Sheet<Real>& s = *slots[index].sheet;
      const double lightest = slots[index].lightest_point;
      s.near_obstacles.clear();
      const detail::Aabb box = detail::sheet_bounds(s);
      for (std::uint32_t o : active_obstacles) {
        const detail::Obstacle& obstacle = *obstacle_slots[o].obstacle;
        if (detail::may_touch(obstacle, box))
          s.near_obstacles.push_back({&obstacle, detail::exponent_cap(obstacle.def, lightest, def.dt)});
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
  void parallel(std::size_t count, Body body) {
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

  // Host stage: bounds → broad-phase → contact work per overlapping pair → which forces
  // each sheet gathers. Sheets whose boxes (grown by half the contact range each) do not
  // meet never reach the narrow phase.
  void host_stage() {
    const std::size_t count = active.size();
    for (std::size_t k = 0; k < count; ++k) at(k).has_contacts = false;
    if (!contacts_possible()) {
      pairs.clear();
      return;
    }
    const auto params = detail::ContactParams<Real>::make(def.contact_thickness, def.contact_xi, def.contact_strength,
                                                          def.contact_range);
    bounds.resize(count);
    grown.resize(count);
    parallel(count, [&](std::size_t k) {
      const Slot& slot = slots[active[k]];
      bounds[k] = slot.bounds_fresh ? slot.bounds : detail::sheet_bounds(at(k));
      grown[k] = bounds[k].inflated(0.5 * double(params.range));
    });
    broad_phase.find_pairs(grown, pairs);
    if (std::any_of(active.begin(), active.end(), [&](auto i) { return slots[i].sheet->self_collision; })) {
      for (std::uint32_t k = 0; k < count; ++k)
        if (at(k).self_collision) pairs.push_back({k, k});
      std::sort(pairs.begin(), pairs.end());
    }
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
    // Each sheet's sources in pair order: the gather's order, fixed by the boxes alone.
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
  // block_points points, so one large sheet among small ones keeps every core busy.
  void plan_blocks() {
    blocks.clear();
    const bool can_split = detail::updates_per_point(def.integrator);
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
      for (std::uint32_t b = 0; b < count; ++b)
        blocks.push_back({k, std::uint32_t(std::uint64_t(rows) * b / count), std::uint32_t(std::uint64_t(rows) * (b + 1) / count),
                          b, true});
    }
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
    const bool keep_bounds = contacts_possible();
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

  // One substep, stage by stage.
  void substep() {
    const detail::StepParams<Real> params{static_cast<Real>(def.dt), static_cast<Real>(def.gravity.x),
                                          static_cast<Real>(def.gravity.y), static_cast<Real>(def.gravity.z)};
    host_stage();              // 1. bounds, broad-phase, contact forces per pair; obstacles near each sheet
    assign_obstacles();
    integrate_sheets(params);  // 2. per sheet (or block): gather contacts, forces, integrate
    ++steps;
  }
};

std::string validate(const WorldDef& d) {
  auto bad = [](const char* field, const char* what, double got) {
    return std::string(field) + " " + what + " (got " + std::to_string(got) + ")";
  };
  if (!(d.dt > 0) || !std::isfinite(d.dt)) return bad("dt", "must be positive and finite", d.dt);
  if (d.threads < 0) return bad("threads", "must be >= 0 (0: all cores)", d.threads);
  if (!(d.contact_thickness >= 0) || !std::isfinite(d.contact_thickness))
    return bad("contact_thickness", "must be non-negative and finite", d.contact_thickness);
  if (!(d.contact_xi > 0) || !std::isfinite(d.contact_xi)) return bad("contact_xi", "must be positive and finite", d.contact_xi);
  if (!(d.contact_strength >= 0) || !std::isfinite(d.contact_strength))
    return bad("contact_strength", "must be non-negative and finite", d.contact_strength);
  if (!(d.contact_range > 0) || !std::isfinite(d.contact_range))
    return bad("contact_range", "must be positive and finite", d.contact_range);
  if (d.block_points == 0) return "block_points must be positive";
  return {};
}

template <class Real>
BasicWorld<Real>::BasicWorld(const WorldDef& def) {
  if (std::string problem = validate(def); !problem.empty()) throw std::invalid_argument("drape: WorldDef." + problem);
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
  slot.bounds_fresh = false;
  impl_->active.push_back(index);
  return {index, slot.generation};
}

template <class Real>
void BasicWorld<Real>::remove_sheet(SheetId id) {
  impl_->sheet(id);  // throws on a stale id
  auto& slot = impl_->slots[id.index];
  slot.sheet.reset();
  ++slot.generation;
  impl_->free_slots.push_back(id.index);
  std::erase(impl_->active, id.index);
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
  slot.obstacle = detail::make_obstacle(def);
  impl_->active_obstacles.push_back(index);
  return {index, slot.generation};
}

template <class Real>
void BasicWorld<Real>::remove_obstacle(ObstacleId id) {
  impl_->obstacle(id);  // throws on a stale id
  impl_->forget_near_obstacles();
  auto& slot = impl_->obstacle_slots[id.index];
  slot.obstacle.reset();
  ++slot.generation;
  impl_->free_obstacle_slots.push_back(id.index);
  std::erase(impl_->active_obstacles, id.index);
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
  return const_cast<Impl&>(*impl_).obstacle(id).def;
}

template <class Real>
SheetView<Real> BasicWorld<Real>::view(SheetId id) const {
  const auto& s = impl_->sheet(id);
  return {s.topology->m, s.topology->n, s.position.x, s.position.y, s.position.z,
          s.velocity.x,  s.velocity.y,  s.velocity.z};
}

template <class Real>
SheetState<Real> BasicWorld<Real>::state(SheetId id) {
  auto& s = impl_->sheet(id);
  impl_->slots[id.index].bounds_fresh = false;  // the caller may move points
  return {s.topology->m, s.topology->n, s.position.x, s.position.y, s.position.z,
          s.velocity.x,  s.velocity.y,  s.velocity.z};
}

template <class Real>
void BasicWorld<Real>::step(int substeps) {
  for (int k = 0; k < substeps; ++k) impl_->substep();
}

template <class Real>
const WorldDef& BasicWorld<Real>::def() const { return impl_->def; }
template <class Real>
void BasicWorld<Real>::set_integrator(Integrator integrator) { impl_->def.integrator = integrator; }
template <class Real>
void BasicWorld<Real>::set_dt(double dt) {
  if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument("drape: dt must be positive and finite");
  impl_->def.dt = dt;
}
template <class Real>
void BasicWorld<Real>::set_threads(int threads) {
  if (threads < 0) throw std::invalid_argument("drape: threads must be >= 0 (0: all cores)");
  impl_->def.threads = threads;
  impl_->make_arena();
}
template <class Real>
std::size_t BasicWorld<Real>::contact_pair_count() const { return impl_->pairs.size(); }
template <class Real>
double BasicWorld<Real>::time() const { return static_cast<double>(impl_->steps) * impl_->def.dt; }
template <class Real>
std::uint64_t BasicWorld<Real>::step_count() const { return impl_->steps; }

template <class Real>
void BasicWorld<Real>::set_step_count(std::uint64_t steps) { impl_->steps = steps; }

template <class Real>
void BasicWorld<Real>::set_state(SheetId id, const SheetView<Real>& from) {
  auto& s = impl_->sheet(id);
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
double BasicWorld<Real>::stable_step_estimate() const {
  double dt = std::numeric_limits<double>::infinity();
  for (SheetId id : sheets()) dt = std::min(dt, stable_step_estimate(id));
  return dt;
}

template class BasicWorld<double>;
template class BasicWorld<float>;

}  // namespace drape
