// The substep: its list of stages (world_impl.h, Stage and substep_stages) and each stage,
// from moving the rigid parts through the broad- and narrow phase to the parallel stage.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "terms/terms.h"
#include "world_impl.h"

namespace drape {

// Host stage, first: moving obstacles to their pose at the substep's start, and every
// constrained point's target from the positions at that start (in a group's scope, the
// targets of the constraints on its sheets; groups are not tried while obstacles move).
template <class Real>
void BasicWorld<Real>::Impl::move_rigid_parts(const Scope& sc) {
  const double t = sc.time();
  for (std::uint32_t o : active_obstacles)
    if (obstacle_slots[o].def.motion) detail::place_obstacle(*obstacle_slots[o].obstacle, obstacle_slots[o].def, t);
  if (!constraints.empty())
    constraints.set_targets(t, access(), &sc == &world ? std::span<const std::uint32_t>{} : std::span(sc.active));
}

// Host stage: each sheet's list of obstacles whose reach its bounding box overlaps, so a
// sheet far from every obstacle runs no obstacle term at all.
template <class Real>
void BasicWorld<Real>::Impl::assign_obstacles(const Scope& sc, double h) {
  if (active_obstacles.empty()) return;
  for (std::uint32_t index : sc.active) {
    Sheet<Real>& s = *slots[index].sheet;
    const double lightest = slots[index].lightest_point;
    s.near_obstacles.clear();
    const detail::Aabb box = current_bounds(slots[index]);
    for (std::uint32_t o : active_obstacles) {
      const detail::Obstacle& obstacle = *obstacle_slots[o].obstacle;
      if (!detail::may_touch(obstacle, box)) continue;
      detail::NearObstacle near{.obstacle = &obstacle,
                                .exponent_cap = detail::exponent_cap(obstacle.def, lightest, h),
                                .friction = std::max(s.friction, obstacle.def.friction),
                                .damping = obstacle.def.damping,
                                .dt = h,
                                .gravity = {def.gravity.x, def.gravity.y, def.gravity.z}};
      if (near.friction > 0 || near.damping > 0) detail::set_obstacle_velocity(near, obstacle_slots[o].def, sc.time(), h);
      s.near_obstacles.push_back(near);
    }
  }
}

template <class Real>
bool BasicWorld<Real>::Impl::contacts_possible(const Scope& sc) const {
  if (!(def.contact_strength > 0)) return false;
  return sc.active.size() > 1 ||
         std::any_of(sc.active.begin(), sc.active.end(), [&](auto i) { return slots[i].sheet->self_collision; });
}

template <class Real>
void BasicWorld<Real>::Impl::run_stage(Scope& sc, Stage stage, double h) {
  switch (stage) {
    case Stage::RigidParts: return move_rigid_parts(sc);
    case Stage::Bounds: return contact_bounds(sc);
    case Stage::BroadPhase: return find_pairs(sc);
    case Stage::ContactBoxes: return contact_boxes(sc, h);
    case Stage::NarrowPhase: return narrow_phase(sc, h);
    case Stage::GatherPlan: return plan_gather(sc);
    case Stage::Obstacles: return assign_obstacles(sc, h);
    case Stage::Integrate: return integrate_sheets(sc, step_params(h));
  }
}

// The contact parameters of a substep of length h (friction stops at most one substep's slip).
template <class Real>
detail::ContactParams<Real> BasicWorld<Real>::Impl::contact_params(const Scope& sc, double h) const {
  auto params = detail::ContactParams<Real>::make(def.contact_thickness, def.contact_xi, def.contact_strength,
                                                  def.contact_range);
  params.dt = static_cast<Real>(h);
  params.exact = def.contact_exact;
  params.rims = def.contact_rims;
  params.damping = static_cast<Real>(def.contact_damping);
  params.stamp = sc.steps + 1;
  return params;
}

// For the pair's lightest point, never below 0 (ContactParams::exponent_cap).
template <class Real>
Real BasicWorld<Real>::Impl::pair_exponent_cap(const Scope& sc, std::size_t a, std::size_t b, double h) const {
  const double lightest = std::min(slots[sc.active[a]].lightest_point, slots[sc.active[b]].lightest_point);
  return static_cast<Real>(
      std::max(0.0, detail::stiffness_exponent_cap(def.contact_strength, def.contact_xi, lightest, h)));
}

template <class Real>
void BasicWorld<Real>::Impl::contact_bounds(Scope& sc) {
  const std::size_t count = sc.active.size();
  for (std::size_t k = 0; k < count; ++k) at(sc, k).has_contacts = false;
  sc.contacting = contacts_possible(sc);
  if (!sc.contacting) {
    sc.pairs.clear();
    return;
  }
  active_bounds(sc, sc.bounds);
  grow_for_contact(sc.bounds, sc.grown);
}

template <class Real>
void BasicWorld<Real>::Impl::grow_for_contact(const std::vector<detail::Aabb>& boxes,
                                              std::vector<detail::Aabb>& out) const {
  const double half = 0.5 * double(contact_params(def.dt).range);  // only its range is used here
  out.resize(boxes.size());
  for (std::size_t k = 0; k < boxes.size(); ++k) out[k] = boxes[k].inflated(half);
}

// Worlds of whole sheets below this many points in all update on the calling thread
// (integrate_sheets): at a few nanoseconds a point, less work than a fork and join of the
// arena pays for. A driven world of 333 points (scenes/sewn_box.json), which forks every
// substep, ran twice as long on 2 threads as on 1 while the virtual machine's other core was
// slow to wake.
constexpr std::uint64_t kParallelUpdatePoints = 2048;

// Stale boxes below this many points in all are made on the calling thread: a pass over a
// point's coordinates costs about a nanosecond, a fork and join of the arena microseconds
// (and, on a virtual machine whose other core sleeps, tens of them).
constexpr std::size_t kParallelBoundsPoints = std::size_t(1) << 16;

template <class Real>
void BasicWorld<Real>::Impl::active_bounds(const Scope& sc, std::vector<detail::Aabb>& out) const {
  const std::size_t count = sc.active.size();
  out.resize(count);
  std::size_t stale_points = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const Slot& slot = slots[sc.active[k]];
    if (slot.bounds_fresh)
      out[k] = slot.bounds;
    else
      stale_points += slot.sheet->size();
  }
  auto stale = [&](std::size_t k) {
    const Slot& slot = slots[sc.active[k]];
    if (!slot.bounds_fresh) out[k] = detail::sheet_bounds(*slot.sheet);
  };
  if (stale_points >= kParallelBoundsPoints) return each(sc, count, stale);
  if (stale_points > 0)
    for (std::size_t k = 0; k < count; ++k) stale(k);
}

template <class Real>
void BasicWorld<Real>::Impl::find_pairs(Scope& sc) {
  if (!sc.contacting) return;
  const std::size_t count = sc.active.size();
  sc.broad_phase.find_pairs(sc.grown, sc.pairs);
  for (const auto& pair : sc.pairs) {  // they may pass energy
    if (sc.keeps_meets)
      sc.met.emplace_back(sc.active[pair.first], sc.active[pair.second]);
    else
      guard_meet(sc.active[pair.first], sc.active[pair.second]);
  }
  if (std::any_of(sc.active.begin(), sc.active.end(), [&](auto i) { return slots[i].sheet->self_collision; })) {
    for (std::uint32_t k = 0; k < count; ++k)
      if (at(sc, k).self_collision) sc.pairs.push_back({k, k});
    std::sort(sc.pairs.begin(), sc.pairs.end());
  }
}

// Slot q of pair_work serves pairs[q]. A pair keeps its work (its kept contact set,
// contacts.h) while pairs appear and vanish around it: when the list changed, each pair
// takes the work last made for the same two sheets, wherever it sat, and work of pairs
// gone stays behind the list for their return (in the order of their sheets) for
// kGoneSubsteps substeps. Only the pair list and the stamp decide, pair by pair, so the
// result is the same on any thread count, and for sheets stepped in groups (frames.cpp,
// try_frame) as for the whole world at once, down to the order of the work.
template <class Real>
void BasicWorld<Real>::Impl::keep_pair_work(Scope& sc, std::uint64_t stamp) {
  auto same = [&](std::size_t q) { return sc.pair_work[q].a == sc.pairs[q].first && sc.pair_work[q].b == sc.pairs[q].second; };
  auto waited = [&](const detail::PairContacts<Real>& w) { return w.present_at + detail::kGoneSubsteps < stamp; };
  auto key = [](std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; };
  auto by_key = [&](const detail::PairContacts<Real>& x, const detail::PairContacts<Real>& y) {
    return key(x.a, x.b) < key(y.a, y.b);
  };
  std::size_t q = 0;
  while (q < sc.pairs.size() && q < sc.pair_work.size() && same(q)) ++q;
  if (q < sc.pairs.size()) {
    std::vector<std::uint32_t> order;
    for (std::uint32_t r = 0; r < sc.pair_work.size(); ++r)
      if (!waited(sc.pair_work[r])) order.push_back(r);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
      return by_key(sc.pair_work[x], sc.pair_work[y]);
    });
    std::vector<char> taken(sc.pair_work.size(), 0);
    std::vector<detail::PairContacts<Real>> next;
    next.reserve(std::max(sc.pairs.size(), sc.pair_work.size()));
    for (const detail::BoxPair& pair : sc.pairs) {
      const std::uint64_t want = key(pair.first, pair.second);
      auto it = std::lower_bound(order.begin(), order.end(), want, [&](std::uint32_t r, std::uint64_t k) {
        return key(sc.pair_work[r].a, sc.pair_work[r].b) < k;
      });
      while (it != order.end() && key(sc.pair_work[*it].a, sc.pair_work[*it].b) == want && taken[*it]) ++it;
      if (it != order.end() && key(sc.pair_work[*it].a, sc.pair_work[*it].b) == want) {
        taken[*it] = 1;
        next.push_back(std::move(sc.pair_work[*it]));
      } else {
        next.emplace_back();
        next.back().a = pair.first;
        next.back().b = pair.second;
      }
    }
    for (std::uint32_t r : order)
      if (!taken[r]) next.push_back(std::move(sc.pair_work[r]));
    sc.pair_work = std::move(next);
  } else {
    // the list is the same, or lost pairs only at its end: only work that waited its time
    // out goes, and the gone work stays in the order of its sheets (a pair that left from
    // the list's end joins it where it belongs, as it would after any other change)
    const auto gone = sc.pair_work.begin() + std::ptrdiff_t(q);
    sc.pair_work.erase(std::remove_if(gone, sc.pair_work.end(), waited), sc.pair_work.end());
    if (!std::is_sorted(gone, sc.pair_work.end(), by_key)) std::stable_sort(gone, sc.pair_work.end(), by_key);
  }
  for (q = 0; q < sc.pairs.size(); ++q) sc.pair_work[q].present_at = stamp;
}

// Each pair first decides whether its kept contacts serve this substep (contacts.h,
// pair_needs_boxes); then the boxes of every sheet in a pair that needs them are made
// once here and read by all of its pairs (SheetBoxes). A sheet whose pairs all keep
// their contact sets, or in no pair, makes none.
template <class Real>
void BasicWorld<Real>::Impl::contact_boxes(Scope& sc, double h) {
  if (!sc.contacting) return;
  const auto params = contact_params(sc, h);
  const std::size_t count = sc.active.size();
  keep_pair_work(sc, params.stamp);
  // every sheet in a pair: where it is on its travel scale, for all of its pairs' decisions
  sc.in_pair.assign(count, 0);
  for (const auto& pair : sc.pairs) sc.in_pair[pair.first] = sc.in_pair[pair.second] = 1;
  each(sc, count, [&](std::size_t k) {
    if (sc.in_pair[k]) detail::measure_travel(at(sc, k), params.stamp);
  });
  each(sc, sc.pairs.size(), [&](std::size_t q) {
    auto& w = sc.pair_work[q];
    detail::pair_needs_boxes(at(sc, w.a), at(sc, w.b), params, w, contact_scratch.local());
  });
  // in_pair: 1 the sheet needs its boxes; 2 some pair of it searches or walks its kept set
  // this substep, so its travel (Sheet::travel) goes on. A sheet no entry is tested
  // against skips it: its next pass measures from where it was then (a self-colliding
  // sheet far from everything pays nothing).
  // A pair of two sheets with rims walks its rim candidates every substep, so its travel
  // goes on too.
  sc.in_pair.assign(count, 0);
  for (std::size_t q = 0; q < sc.pairs.size(); ++q) {
    const auto& w = sc.pair_work[q];
    const bool rims = params.rims && w.a != w.b;
    const bool tests = w.decided == 0 || !(w.a_on_b.point.empty() && w.b_on_a.point.empty()) || rims;
    const std::uint8_t mark = (w.decided == 0 || params.exact ? 1 : 0) | (!params.exact && tests ? 2 : 0);
    // the rims' candidates, when due, are made from both sheets' boxes: due by the travel the
    // advance below gives (moved_hi, measured above), as narrow_phase will find it
    auto travel = [&] {
      const bool measured = detail::measured_in(at(sc, w.a), params.stamp) && detail::measured_in(at(sc, w.b), params.stamp);
      return params.exact || !measured ? NAN : at(sc, w.a).moved_hi() + at(sc, w.b).moved_hi();
    };
    const bool rim_boxes = rims && detail::rims_due(w, at(sc, w.a), at(sc, w.b), travel());
    sc.in_pair[sc.pairs[q].first] |= mark | (rim_boxes ? 1 : 0);
    sc.in_pair[sc.pairs[q].second] |= mark | (rim_boxes ? 1 : 0);
  }
  if (sc.sheet_boxes.size() < count) sc.sheet_boxes.resize(count);
  each(sc, count, [&](std::size_t k) {
    if (sc.in_pair[k] & 2) detail::advance_travel(at(sc, k), params.stamp);
    if (sc.in_pair[k] & 1) detail::build_boxes(at(sc, k), sc.sheet_boxes[k]);
  });
}

template <class Real>
void BasicWorld<Real>::Impl::narrow_phase(Scope& sc, double h) {
  if (!sc.contacting) return;
  auto params = contact_params(sc, h);
  // Fewer pairs than twice the threads: a pair walks and searches in two parts a direction
  // at once (ContactParams::parts), so that a sheet folding onto itself, or two sheets, use
  // more than one core. The forces are the same either way.
  const int threads = arena->max_concurrency();
  if (threads > 1 && !sc.serial && sc.pairs.size() < 2 * std::size_t(threads)) params.parts = 2;
  each(sc, sc.pairs.size(), [&](std::size_t q) {
    auto& w = sc.pair_work[q];
    auto& scratch = contact_scratch.local();
    auto pair = params;
    pair.exponent_cap = pair_exponent_cap(sc, w.a, w.b, h);
    if (!params.exact) pair.travel = at(sc, w.a).travel + at(sc, w.b).travel;
    if (w.a == w.b)
      detail::self_contacts(at(sc, w.a), sc.sheet_boxes[w.a], pair, w, scratch);
    else
      detail::pair_contacts(at(sc, w.a), sc.sheet_boxes[w.a], at(sc, w.b), sc.sheet_boxes[w.b], pair, w, scratch);
  });
}

// Each sheet's sources in pair order: the gather's order, fixed by the boxes alone.
template <class Real>
void BasicWorld<Real>::Impl::plan_gather(Scope& sc) {
  if (!sc.contacting) return;
  const std::size_t count = sc.active.size();
  sc.source_start.assign(count + 1, 0);
  for (std::size_t q = 0; q < sc.pairs.size(); ++q) {
    const auto& w = sc.pair_work[q];
    if (w.on_a.size()) ++sc.source_start[w.a + 1];
    if (w.a != w.b && w.on_b.size()) ++sc.source_start[w.b + 1];
  }
  for (std::size_t k = 0; k < count; ++k) sc.source_start[k + 1] += sc.source_start[k];
  sc.sources.resize(sc.source_start[count]);
  sc.source_cursor.assign(sc.source_start.begin(), sc.source_start.end() - 1);
  for (std::size_t q = 0; q < sc.pairs.size(); ++q) {
    const auto& w = sc.pair_work[q];
    if (w.on_a.size()) sc.sources[sc.source_cursor[w.a]++] = &w.on_a;
    if (w.a != w.b && w.on_b.size()) sc.sources[sc.source_cursor[w.b]++] = &w.on_b;
  }
  for (std::size_t k = 0; k < count; ++k) {
    Sheet<Real>& s = at(sc, k);
    s.has_contacts = sc.source_start[k + 1] > sc.source_start[k];
    if (s.has_contacts && s.contact_force.x.size() != s.size()) s.contact_force.resize(s.size());
  }
}

// A sheet of at least 2·block_points points is cut into row blocks of about
// block_points points, so one large sheet among small ones keeps every core busy
// (with one thread there is no core to keep busy: sheets stay whole).
template <class Real>
void BasicWorld<Real>::Impl::plan_blocks(Scope& sc) {
  sc.blocks.clear();
  const bool can_split = detail::updates_per_point(def.integrator) && arena->max_concurrency() > 1 && !sc.serial;
  for (std::uint32_t k = 0; k < sc.active.size(); ++k) {
    Sheet<Real>& s = at(sc, k);
    const std::uint32_t rows = s.topology->rows();
    const std::uint64_t points = s.size();
    std::uint32_t count = 1;
    if (can_split && points >= 2 * std::uint64_t(def.block_points))
      count = static_cast<std::uint32_t>(std::min<std::uint64_t>(rows, points / def.block_points));
    slots[sc.active[k]].bounds_fresh = false;  // set again by the update (integrate_sheets)
    if (count == 1) {
      sc.blocks.push_back({k, 0, rows, 0, false});
      continue;
    }
    const std::size_t scratch = std::size_t(count) * s.topology->scratch_cols();
    if (s.row_scratch.x.size() < scratch) s.row_scratch.resize(scratch);
    push_row_blocks(sc, k, rows, count);
  }
}

// Sheet k's rows cut into `count` blocks of equal size (± 1 row).
template <class Real>
void BasicWorld<Real>::Impl::push_row_blocks(Scope& sc, std::uint32_t k, std::uint32_t rows, std::uint64_t count) {
  for (std::uint64_t b = 0; b < count; ++b)
    sc.blocks.push_back({k, std::uint32_t(rows * b / count), std::uint32_t(rows * (b + 1) / count), std::uint32_t(b), true});
}

template <class Real>
void BasicWorld<Real>::Impl::gather(Scope& sc, std::size_t k, std::size_t begin, std::size_t end) {
  Sheet<Real>& s = at(sc, k);
  if (!s.has_contacts) return;
  const std::span<const detail::ContactForces<Real>* const> src(sc.sources.data() + sc.source_start[k],
                                                                 sc.source_start[k + 1] - sc.source_start[k]);
  detail::gather_contacts(src, s.contact_force, begin, end);
}

// Parallel stage: every task writes only its own sheet's (or block's) buffers and reads
// the contact buffers the host stage finished, so the result does not depend on how TBB
// schedules them (bit-identical for any thread count).
template <class Real>
void BasicWorld<Real>::Impl::integrate_sheets(Scope& sc, const detail::StepParams<Real>& params) {
  plan_blocks(sc);
  bool any_split = false;
  const bool keep_bounds = contacts_possible(sc) || !active_obstacles.empty();  // someone reads the box next substep
  // A first-order explicit integrator spawns no work of its own: with one block or one thread,
  // or whole sheets too small in all to pay for the other threads, its tasks run here, in
  // order, without entering the arena. A small sheet's substep takes a few microseconds, and a
  // parallel_for in the arena costs a sizeable part of that (tens of microseconds on a
  // virtual machine whose other core sleeps). Row blocks (block_points) always go to the arena.
  std::uint64_t points = 0;
  for (std::size_t k = 0; k < sc.active.size(); ++k) points += at(sc, k).size();
  const bool small = points < kParallelUpdatePoints && sc.blocks.size() == sc.active.size();
  const bool here =
      sc.serial || (detail::updates_per_point(def.integrator) && (sc.blocks.size() == 1 || def.threads == 1 || small));
  auto tasks = [&](auto body) {
    if (!here) return parallel(sc.blocks.size(), body);
    for (std::size_t q = 0; q < sc.blocks.size(); ++q) body(q);
  };
  tasks([&](std::size_t q) {
    const Block& b = sc.blocks[q];
    Slot& slot = slots[sc.active[b.sheet]];
    Sheet<Real>& s = *slot.sheet;
    const std::size_t cols = s.topology->cols();
    gather(sc, b.sheet, b.row_begin * cols, b.row_end * cols);
    if (!b.split) {
      // the box for the next host stage, taken as the update moves the points
      detail::integrate(def.integrator, s, params, keep_bounds ? &slot.bounds : nullptr);
      slot.bounds_fresh = keep_bounds;
      return;
    }
    auto row = detail::ptr(s.row_scratch);
    const std::size_t off = b.index * s.topology->scratch_cols();
    detail::sheet_forces_rows(s, detail::cptr(s.position), detail::cptr(s.velocity), detail::ptr(s.force),
                              {row.x + off, row.y + off, row.z + off}, b.row_begin, b.row_end);
  });
  for (const Block& b : sc.blocks) any_split = any_split || b.split;
  if (!any_split) return;
  if (keep_bounds) sc.block_box.assign(sc.blocks.size(), detail::simd::Extent<Real>::none());
  // Second pass, after every block's forces: a block's springs read its neighbours' rows.
  tasks([&](std::size_t q) {
    const Block& b = sc.blocks[q];
    if (!b.split) return;
    Sheet<Real>& s = at(sc, b.sheet);
    const std::size_t cols = s.topology->cols();
    detail::update_points(def.integrator, s, params, b.row_begin * cols, b.row_end * cols,
                          keep_bounds ? &sc.block_box[q] : nullptr);
  });
  if (!keep_bounds) return;
  // A split sheet's box: its blocks' boxes in block order (min and max are exact anyway).
  for (std::size_t q = 0; q < sc.blocks.size(); ++q) {
    const Block& b = sc.blocks[q];
    if (!b.split) continue;
    Slot& slot = slots[sc.active[b.sheet]];
    if (b.index == 0) slot.bounds = detail::empty_box();
    detail::include_extent(slot.bounds, sc.block_box[q]);
    slot.bounds_fresh = true;
  }
}

// One substep: the stages of substep_stages, in order.
template <class Real>
void BasicWorld<Real>::Impl::substep(Scope& sc, double h) {
  for (Stage stage : substep_stages) run_stage(sc, stage, h);
  count_substeps(sc, h, 1);
}

template <class Real>
detail::StepParams<Real> BasicWorld<Real>::Impl::step_params(double h) const {
  return {static_cast<Real>(h), static_cast<Real>(def.gravity.x), static_cast<Real>(def.gravity.y),
          static_cast<Real>(def.gravity.z), def.cg_tolerance, def.cg_max_iterations, def.local_global_iterations,
          def.vertex_block_iterations, def.cg_preconditioner};
}

template <class Real>
void BasicWorld<Real>::Impl::count_substeps(Scope& sc, double h, std::uint64_t count) {
  if (h != sc.current_h) {
    sc.time_base = sc.time();
    sc.steps_base = sc.steps;
    sc.current_h = h;
  }
  sc.steps += count;
}

// The members defined here, for both precisions (as in frames.cpp).
#define DRAPE_WORLD_STEP(Real)                                                                                  \
  template void BasicWorld<Real>::Impl::move_rigid_parts(const Scope&);                                         \
  template void BasicWorld<Real>::Impl::assign_obstacles(const Scope&, double);                                 \
  template bool BasicWorld<Real>::Impl::contacts_possible(const Scope&) const;                                  \
  template void BasicWorld<Real>::Impl::run_stage(Scope&, Stage, double);                                       \
  template detail::ContactParams<Real> BasicWorld<Real>::Impl::contact_params(const Scope&, double) const;      \
  template Real BasicWorld<Real>::Impl::pair_exponent_cap(const Scope&, std::size_t, std::size_t, double) const; \
  template void BasicWorld<Real>::Impl::contact_bounds(Scope&);                                                 \
  template void BasicWorld<Real>::Impl::grow_for_contact(const std::vector<detail::Aabb>&,                     \
                                                         std::vector<detail::Aabb>&) const;                   \
  template void BasicWorld<Real>::Impl::active_bounds(const Scope&, std::vector<detail::Aabb>&) const;           \
  template void BasicWorld<Real>::Impl::find_pairs(Scope&);                                                     \
  template void BasicWorld<Real>::Impl::keep_pair_work(Scope&, std::uint64_t);                                  \
  template void BasicWorld<Real>::Impl::contact_boxes(Scope&, double);                                          \
  template void BasicWorld<Real>::Impl::narrow_phase(Scope&, double);                                           \
  template void BasicWorld<Real>::Impl::plan_gather(Scope&);                                                    \
  template void BasicWorld<Real>::Impl::plan_blocks(Scope&);                                                    \
  template void BasicWorld<Real>::Impl::push_row_blocks(Scope&, std::uint32_t, std::uint32_t, std::uint64_t);   \
  template void BasicWorld<Real>::Impl::gather(Scope&, std::size_t, std::size_t, std::size_t);                  \
  template void BasicWorld<Real>::Impl::integrate_sheets(Scope&, const detail::StepParams<Real>&);              \
  template void BasicWorld<Real>::Impl::substep(Scope&, double);                                                \
  template detail::StepParams<Real> BasicWorld<Real>::Impl::step_params(double) const;                          \
  template void BasicWorld<Real>::Impl::count_substeps(Scope&, double, std::uint64_t);
DRAPE_WORLD_STEP(double)
DRAPE_WORLD_STEP(float)
#undef DRAPE_WORLD_STEP

}  // namespace drape
