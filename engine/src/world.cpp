// The World: a pool of sheets addressed by ids, and the substep that advances them.
#include <drape/world.h>

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "bounds.h"
#include "diagnostics.h"
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
  };

  WorldDef def;
  tbb::task_arena arena;
  std::vector<Slot> slots;
  std::vector<std::uint32_t> free_slots;
  std::vector<std::uint32_t> active;  // live slots in the order sheets were added
  std::vector<std::shared_ptr<const Topology<Real>>> topologies;
  std::uint64_t steps = 0;

  struct ObstacleSlot {
    std::optional<detail::Obstacle> obstacle;
    std::uint32_t generation = 0;
  };
  std::vector<ObstacleSlot> obstacle_slots;
  std::vector<std::uint32_t> free_obstacle_slots;
  std::vector<std::uint32_t> active_obstacles;  // live slots in the order obstacles were added

  explicit Impl(const WorldDef& d)
      : def(d), arena(d.threads > 0 ? d.threads : tbb::task_arena::automatic) {}

  Sheet<Real>& sheet(SheetId id) {
    if (!contains(id)) throw std::invalid_argument("drape: unknown or removed SheetId " + std::to_string(id.index));
    return *slots[id.index].sheet;
  }
  const Sheet<Real>& sheet(SheetId id) const { return const_cast<Impl*>(this)->sheet(id); }
  bool contains(SheetId id) const {
    return id.index < slots.size() && slots[id.index].sheet && slots[id.index].generation == id.generation;
  }

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

  // Parallel stage: every sheet writes only its own buffers, so the result does not
  // depend on how TBB schedules them (bit-identical for any thread count).
  void integrate_sheets(const detail::StepParams<Real>& params) {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, active.size(), 1),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t k = r.begin(); k != r.end(); ++k)
                            detail::integrate(def.integrator, *slots[active[k]].sheet, params);
                        });
    });
  }

  void substep() {
    const detail::StepParams<Real> params{static_cast<Real>(def.dt), static_cast<Real>(def.gravity.x),
                                          static_cast<Real>(def.gravity.y), static_cast<Real>(def.gravity.z)};
    // 1. host stage: bounds, broad-phase and contact work go here
    assign_obstacles();
    // 2. parallel stage: per-sheet forces, then integration
    integrate_sheets(params);
    ++steps;
  }
};

template <class Real>
BasicWorld<Real>::BasicWorld(const WorldDef& def) {
  if (!(def.dt > 0) || !std::isfinite(def.dt)) throw std::invalid_argument("drape: WorldDef.dt must be positive and finite");
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
