// The stability guard: each sheet's reference energy and scale, and the check after a step.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "diagnostics.h"
#include "world_impl.h"

namespace drape {

// The guard's energy of one sheet: its own terms and every obstacle's potential (as in
// diagnostics(): not only the near ones, so the value does not depend on the broad-phase).
template <class Real>
Energies BasicWorld<Real>::Impl::guard_energy(const Slot& slot) const {
  Energies e = detail::sheet_energies(*slot.sheet, def.gravity);
  if (!constraints.empty())
    e.anchor -= constraints.join_energy_excess(sheet_ids.id(std::uint32_t(&slot - slots.data())), *slot.sheet);
  for (std::uint32_t o : active_obstacles) {
    const detail::Obstacle& obstacle = *obstacle_slots[o].obstacle;
    e.obstacle += detail::obstacle_energy(*slot.sheet, obstacle, detail::exponent_cap(obstacle.def, slot.lightest_point, def.dt));
  }
  return e;
}

template <class Real>
void BasicWorld<Real>::Impl::take_reference(Slot& slot) {
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

template <class Real>
void BasicWorld<Real>::Impl::take_references() {
  for (std::uint32_t index : active)
    if (!slots[index].guard.has_reference) take_reference(slots[index]);
}

// The guard: one pass over each sheet's points and springs.
template <class Real>
StabilityReport BasicWorld<Real>::Impl::check() const {
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
  // A coordinate that is not finite leaves the energy not finite: the kinetic and the gravity
  // sums take every coordinate of every point (inf or NaN survives each product and sum, and
  // g·x is NaN for a zero component of g), so only a sheet whose energy is not finite needs
  // the pass over its state (Guard.EveryNonFiniteCoordinateIsReportedByCheck).
  parallel(active.size(), [&](std::size_t k) {
    energies[k] = guard_energy(slots[active[k]]);
    finite[k] = std::isfinite(energies[k].total()) || detail::sheet_finite(*slots[active[k]].sheet);
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
      report.sheet = sheet_ids.id(index);
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

template <class Real>
StabilityReport BasicWorld<Real>::Impl::finish_step() {
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

// The members defined here, for both precisions (as in frames.cpp).
#define DRAPE_WORLD_GUARD(Real)                                              \
  template Energies BasicWorld<Real>::Impl::guard_energy(const Slot&) const; \
  template void BasicWorld<Real>::Impl::take_reference(Slot&);               \
  template void BasicWorld<Real>::Impl::take_references();                   \
  template StabilityReport BasicWorld<Real>::Impl::check() const;            \
  template StabilityReport BasicWorld<Real>::Impl::finish_step();
DRAPE_WORLD_GUARD(double)
DRAPE_WORLD_GUARD(float)
#undef DRAPE_WORLD_GUARD

}  // namespace drape
