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
  // scale under gravity. With no gravity, no stress and no motion that would be 0, yet
  // rounding moves such a sheet: its springs' lengths are rounded, so a sheet at rest in
  // free space vibrates at about 1e-16 of its coordinates (double) and that energy, divided
  // by ~0, halted it. So the scale is also at least the energy of the sheet vibrating at its
  // highest frequency ω_max with an amplitude of 100 rounding units of its largest
  // coordinate: far above what rounding does, far below any motion worth seeing.
  const double extent = std::max(std::sqrt(extent2), 1e-3);
  double reach2 = 0;
  for (int k = 0; k < 3; ++k) reach2 += std::max(box.lo[k] * box.lo[k], box.hi[k] * box.hi[k]);
  const double amplitude = 1e2 * std::numeric_limits<Real>::epsilon() * (std::sqrt(reach2) + extent);
  const double rounding = 0.5 * mass * slot.omega_max * slot.omega_max * amplitude * amplitude;
  slot.guard.floor =
      std::max({mass * g * extent, std::isfinite(rounding) ? rounding : 0.0, std::numeric_limits<double>::min()});
  slot.guard.scale = std::max(motion_energy(energy), slot.guard.floor);
}

template <class Real>
std::uint32_t BasicWorld<Real>::Impl::guard_root(std::uint32_t index) const {
  if (index >= guard_group.size()) return index;
  while (guard_group[index] != index) index = guard_group[index];
  return index;
}

template <class Real>
void BasicWorld<Real>::Impl::guard_meet(std::uint32_t a, std::uint32_t b) {
  const std::size_t before = guard_group.size();
  if (before < slots.size()) {
    guard_group.resize(slots.size());
    for (std::size_t k = before; k < slots.size(); ++k) guard_group[k] = std::uint32_t(k);
  }
  auto root = [&](std::uint32_t k) {  // halving the path on the way: the trees stay shallow
    while (guard_group[k] != k) k = guard_group[k] = guard_group[guard_group[k]];
    return k;
  };
  a = root(a);
  b = root(b);
  if (a != b) guard_group[std::max(a, b)] = std::min(a, b);
}

template <class Real>
void BasicWorld<Real>::Impl::guard_forget_group(std::uint32_t index) {
  const std::uint32_t root = guard_root(index);
  std::vector<std::uint32_t> members;
  for (std::uint32_t k = 0; k < guard_group.size(); ++k)
    if (guard_root(k) == root) members.push_back(k);
  for (std::uint32_t k : members) {
    guard_group[k] = k;
    slots[k].guard.has_reference = false;
  }
}

// A sheet's reference is taken again with its whole group's (the energy its members
// passed to each other since is in their references), and the group then starts afresh:
// each sheet on its own, with its joins to other sheets (a join passes energy for good).
template <class Real>
void BasicWorld<Real>::Impl::take_references() {
  std::vector<char> retake(slots.size(), 0);  // by the group's root
  bool any = false;
  for (std::uint32_t index : active)
    if (!slots[index].guard.has_reference) {
      retake[guard_root(index)] = 1;
      any = true;
    }
  if (!any) return;
  std::vector<std::uint32_t> retaken;
  for (std::uint32_t index : active)
    if (retake[guard_root(index)]) retaken.push_back(index);
  for (std::uint32_t index : retaken) {
    take_reference(slots[index]);
    if (index < guard_group.size()) guard_group[index] = index;
  }
  for (const auto& [a, b] : constraints.joined_sheets()) guard_meet(a.index, b.index);
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
  std::vector<std::uint32_t> root(active.size());
  for (std::size_t k = 0; k < active.size(); ++k) root[k] = guard_root(active[k]);
  // A coordinate that is not finite leaves the energy not finite: the kinetic and the gravity
  // sums take every coordinate of every point (inf or NaN survives each product and sum, and
  // g·x is NaN for a zero component of g), so only a sheet whose energy is not finite needs
  // the pass over its state (Guard.EveryNonFiniteCoordinateIsReportedByCheck).
  parallel(active.size(), [&](std::size_t k) {
    energies[k] = guard_energy(slots[active[k]]);
    finite[k] = std::isfinite(energies[k].total()) || detail::sheet_finite(*slots[active[k]].sheet);
  });
  // Each group's growth from its members' sums (a group with a driven member: none, as a
  // driven sheet's own): a sheet that took energy from the others halts only when the
  // group's energy grew too. Sheets that never met are each a group of one.
  struct Group {
    double energy = 0, reference = 0, scale = 0;
    bool driven = false;
    std::size_t gained_most = 0;  // the member whose energy grew most, in J
    double gain = -std::numeric_limits<double>::infinity();
    // may the members touch (two or more of them, or one colliding with itself), and the
    // lightest point among them, which the contact stiffness must hold
    bool contact = false;
    std::size_t members = 0;
    double lightest = std::numeric_limits<double>::infinity();
  };
  std::vector<Group> group(slots.size());
  for (std::size_t k = 0; k < active.size(); ++k) {
    const Slot& slot = slots[active[k]];
    Group& g = group[root[k]];
    g.driven = g.driven || slot.driven;
    ++g.members;
    g.contact = g.contact || slot.sheet->self_collision || g.members > 1;
    g.lightest = std::min(g.lightest, slot.lightest_point);
    if (!slot.guard.has_reference || !std::isfinite(energies[k].total())) continue;
    g.energy += energies[k].total();
    g.reference += slot.guard.reference_energy;
    g.scale += slot.guard.scale;
    if (energies[k].total() - slot.guard.reference_energy > g.gain) {
      g.gain = energies[k].total() - slot.guard.reference_energy;
      g.gained_most = k;
    }
  }
  for (std::size_t k = 0; k < active.size(); ++k) {
    std::uint32_t index = active[k];
    const Slot* slot = &slots[index];
    const Energies& energy = energies[k];
    const Group& g = group[root[k]];
    report.unconverged_solves += slot->sheet->last_solve.unconverged_solves;
    StabilityStatus status = StabilityStatus::Stable;
    double growth = 1;
    if (!finite[k] || !std::isfinite(energy.total())) {
      status = StabilityStatus::NonFinite;
      growth = std::numeric_limits<double>::infinity();
    } else if (slot->guard.has_reference) {
      // a sheet that met others: their growth together (alone: its own, the same bits)
      growth = 1 + (g.energy - g.reference) / g.scale;
      // Implicit Euler cannot grow geometrically; its one linearised Newton step can inject
      // energy for a step when a point moves a sizeable part of a spring in one step (the
      // linearisation misses the geometric stiffening), which its damping then removes.
      // That is reported in energy_growth but does not halt it.
      if (growth > def.guard_energy_growth && integrator_is_explicit(def.integrator) && !g.driven) {
        status = StabilityStatus::EnergyGrowth;
        index = active[g.gained_most];  // of a group, the sheet whose energy grew most is named
        slot = &slots[index];
      }
    }
    if (status == StabilityStatus::Stable) {
      largest_growth = any ? std::max(largest_growth, growth) : growth;
      any = true;
    } else if (report.ok()) {
      report.status = status;
      report.sheet = sheet_ids.id(index);
      report.energy_growth = growth;
      report.stable_dt = def.adaptive_safety * integrator_critical_step(def.integrator, slot->omega_max);
      // the cheapest integrator stable at this step; forward Euler is never suggested
      report.stable_integrator = Integrator::ImplicitEuler;
      for (Integrator i : {Integrator::SemiImplicitEuler, Integrator::RK4})
        if (integrator_critical_step(i, slot->omega_max) > report.dt) {
          report.stable_integrator = i;
          break;
        }
      // The contact's stiffness at the thickness, c/ξ², is what the pair's exponent cap
      // cannot bring under m/dt² (pair_exponent_cap): an explicit force in every integrator,
      // bound as semi-implicit Euler's springs are in the implicit ones.
      if (g.contact && def.contact_strength > 0) {
        const double contact_dt =
            def.adaptive_safety * explicit_force_critical_step(def.integrator, contact_omega(g.lightest));
        if (contact_dt < report.stable_dt) {
          report.stable_dt = contact_dt;
          report.stable_integrator = def.integrator;
          report.step_limit = StepLimit::Contact;
        }
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
  template std::uint32_t BasicWorld<Real>::Impl::guard_root(std::uint32_t) const; \
  template void BasicWorld<Real>::Impl::guard_meet(std::uint32_t, std::uint32_t); \
  template void BasicWorld<Real>::Impl::guard_forget_group(std::uint32_t); \
  template StabilityReport BasicWorld<Real>::Impl::check() const;            \
  template StabilityReport BasicWorld<Real>::Impl::finish_step();
DRAPE_WORLD_GUARD(double)
DRAPE_WORLD_GUARD(float)
#undef DRAPE_WORLD_GUARD

}  // namespace drape
