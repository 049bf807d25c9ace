// Many substeps at once: runs of substeps on independent sheets (whole, or as waves in row
// blocks), frames tried ahead and kept only if nothing came near (contact-free, or in groups
// of sheets in contact each stepping the frame alone), and advance().

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "terms/terms.h"
#include "world_impl.h"

namespace drape {

// Blocks of a run of `levels` substeps: whole sheets, and row blocks of the large sheets
// a wave can split (forces.h, sheet_wave): one block per thread, since each block also
// steps `levels` rows beyond each edge (the same arithmetic, done twice), and no block
// shorter than 4·levels rows.
template <class Real>
void BasicWorld<Real>::Impl::plan_wave_blocks(std::uint32_t levels) {
  world.blocks.clear();
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
      world.blocks.push_back({k, 0, rows, 0, false});
      continue;
    }
    push_row_blocks(world, k, rows, count);
  }
}

// `count` substeps of h on independent sheets, in runs of wave_levels substeps: a run
// takes every block (a whole sheet, or the rows of a split one) through all its
// substeps in one task, a sheet that fits the cache budget one whole substep after
// another, a larger one as a wave. Bit-identical to `count` calls of substep(h).
// `swept`, when given, gets each sheet's box over all the substeps' states (in `active`
// order), for try_frame's check.
template <class Real>
void BasicWorld<Real>::Impl::integrate_runs(double h, std::uint64_t count, std::vector<detail::Aabb>* swept) {
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
    if (block_scratch.size() < world.blocks.size()) block_scratch.resize(world.blocks.size());
    if (swept) block_swept.assign(world.blocks.size(), detail::empty_box());
    // every split block copies its halo before any block moves a row
    if (std::any_of(world.blocks.begin(), world.blocks.end(), [](const Block& b) { return b.split; }))
      parallel(world.blocks.size(), [&](std::size_t q) {
        const Block& b = world.blocks[q];
        if (b.split) detail::wave_take_halo(at(b.sheet), levels, b.row_begin, b.row_end, block_scratch[q]);
      });
    parallel(world.blocks.size(), [&](std::size_t q) {
      const Block& b = world.blocks[q];
      Sheet<Real>& s = at(b.sheet);
      detail::Aabb* box = swept ? &block_swept[q] : nullptr;
      if (b.split) {
        detail::integrate_wave(def.integrator, s, params, levels, b.row_begin, b.row_end, block_scratch[q], box);
      } else if (detail::updates_per_point(def.integrator) && detail::wave_ready(s) && !detail::fits_cache_budget(s)) {
        detail::integrate_wave(def.integrator, s, params, levels, 0, s.topology->rows(), wave_scratch.local(), box);
      } else {
        detail::Aabb after;  // the box after each substep, taken as the update moves the points
        for (std::uint32_t k = 0; k < levels; ++k) {
          detail::integrate(def.integrator, s, params, box ? &after : nullptr);
          if (box) detail::include_box(*box, after);
        }
      }
    });
    if (swept)
      for (std::size_t q = 0; q < world.blocks.size(); ++q) detail::include_box((*swept)[world.blocks[q].sheet], block_swept[q]);
    done += levels;
  }
}

// A frame of substeps on sheets that contacts, obstacles or constraints couple, tried in
// groups: the sheets closed under the pairs the frame's first substep would find
// (self-colliding sheets with themselves) and under the constraints' joins, the sheets
// within an obstacle's reach and the sheets a constraint holds, each step the whole frame
// alone, group after group, with every stage of the substep (their pairs, kept contact
// sets, obstacles, their constraints' targets), while the group's state stays in cache. The
// sheets in no group run as independent runs (integrate_runs). The frame is kept only if no
// two groups, and no free sheet with anything, came within contact range over it (their
// boxes swept over the frame, grown by half the range each), and no free sheet within an
// obstacle's reach: then every substep's host stage would have found, for each group, the
// pairs and obstacles the group's own did, and the frame is bit-identical to
// substep-by-substep (a sheet's contacts are gathered in pair order, which a group keeps; a
// pair's work is kept and dropped by a rule of its own, step.cpp). Otherwise the state the
// frame found (each sheet's positions, velocities and travel, each pair's work) is restored
// and the caller steps substep by substep: only a frame in which two groups meet is
// computed twice. Not tried where one group holds every sheet (that is the world's own
// substep), nor for integrators that keep anything between substeps beyond x and v (the
// implicit ones: a kept factor and guess, solver counts, which putting x and v back would
// not undo; detail::remembers_nothing), nor while obstacles move (each substep puts them
// where they are then, for every sheet), nor with a constraint following a motion of the
// caller's (a callback, which is called on the thread that steps, never from two groups at
// once).
template <class Real>
bool BasicWorld<Real>::Impl::frame_may_be_tried() const {
  return detail::remembers_nothing(def.integrator) && !obstacles_move() && !constraints.calls_back();
}

// groups[0, group_count), group_of and free_sheets for sheets with these boxes, from the
// pairs the host stage would find for them (frame_pairs) and the obstacles within reach.
template <class Real>
void BasicWorld<Real>::Impl::plan_groups(const std::vector<detail::Aabb>& boxes) {
  const auto n = static_cast<std::uint32_t>(active.size());
  frame_pairs.clear();
  if (contacts_possible()) {
    grow_for_contact(boxes, swept_grown);
    broad_phase.find_pairs(swept_grown, frame_pairs);
    for (std::uint32_t k = 0; k < n; ++k)
      if (at(k).self_collision) frame_pairs.push_back({k, k});
  }
  std::vector<std::uint32_t> root(n);  // a forest whose roots are each tree's first sheet
  for (std::uint32_t k = 0; k < n; ++k) root[k] = k;
  auto find = [&](std::uint32_t k) {
    while (root[k] != k) k = root[k] = root[root[k]];
    return k;
  };
  std::vector<char> grouped(n, 0);
  auto join = [&](std::uint32_t first, std::uint32_t second) {
    const std::uint32_t a = find(first), b = find(second);
    root[std::max(a, b)] = std::min(a, b);
    grouped[first] = grouped[second] = 1;
  };
  for (const detail::BoxPair& pair : frame_pairs) join(pair.first, pair.second);
  // a constrained sheet takes its targets in its group's host stage, and a join's two
  // sheets step in one group, wherever they are
  if (!constraints.empty()) {
    std::vector<std::uint32_t> position(slots.size(), kFree);
    for (std::uint32_t k = 0; k < n; ++k) position[active[k]] = k;
    for (const auto& [a, b] : constraints.held_sheets()) join(position[a.index], position[b.index]);
  }
  for (std::uint32_t k = 0; k < n; ++k)
    for (std::uint32_t o : active_obstacles)
      if (!grouped[k] && detail::may_touch(*obstacle_slots[o].obstacle, boxes[k])) grouped[k] = 1;
  group_of.assign(n, kFree);
  free_sheets.clear();
  std::vector<std::vector<std::uint32_t>> members;
  for (std::uint32_t k = 0; k < n; ++k) {
    if (!grouped[k]) {
      free_sheets.push_back(k);
      continue;
    }
    const std::uint32_t r = find(k);  // ≤ k: its group is made
    if (r == k) {
      group_of[k] = static_cast<std::uint32_t>(members.size());
      members.emplace_back();
    } else {
      group_of[k] = group_of[r];
    }
    members[group_of[k]].push_back(k);
  }
  group_count = members.size();
  if (groups.size() < group_count) groups.resize(group_count);
  for (std::size_t g = 0; g < group_count; ++g) {
    Group& group = groups[g];
    Scope& sc = group.scope;
    if (group.members != members[g]) sc.broad_phase.reset();  // its boxes are other sheets'
    group.members = std::move(members[g]);
    sc.active.clear();
    for (std::uint32_t k : group.members) sc.active.push_back(active[k]);
    sc.pairs.clear();
    sc.keeps_meets = true;
    sc.met.clear();
  }
}

// Whether the frame's groups are worth a try: more than one group, or free sheets beside
// one, in a world of at least group_points points whose groups hold an eighth of that each
// on average. A smaller world steps substep by substep about as fast (its state stays in
// cache between substeps), and smaller groups pay more for their own stages than they gain
// (scenes/rain_torus.json, 24 small sheets meeting often, ran 16 % longer in groups).
// Measured on the 48-sheet stack (six columns of eight 64×64 sheets, 1 thread): one column
// alone (33k points) takes 668 us a substep, six together 912 us per column, and in groups
// (a column each) frames of 10 substeps take a tenth to a fifth less than together.
// Groups that cannot meet (no contacts, no obstacles: sheets held by constraints) save
// nothing and are never stepped twice, so only their stages' cost is left against the
// cache: they need a thirty-second of group_points each. Measured on 196,608 points of
// sheets on paths (1 thread): in groups of one sheet 32×32 sheets ran as fast as substep
// by substep, 45×45 to 90×90 a thirtieth to a tenth faster, 16×16 more than twice slower.
template <class Real>
bool BasicWorld<Real>::Impl::groups_pay(bool may_undo) const {
  if (group_count == 1 && free_sheets.empty()) return false;  // the world's own substep
  std::uint64_t points = 0, grouped = 0;
  for (std::size_t k = 0; k < active.size(); ++k) {
    points += at(k).size();
    if (group_of[k] != kFree) grouped += at(k).size();
  }
  const std::uint64_t share = may_undo ? 8 : 32;
  return points >= def.group_points && share * grouped >= std::uint64_t(def.group_points) * group_count;
}

// What a frame saves of a sheet (Impl::Saved), from a sheet or back into it: positions,
// velocities, and its travel with the measurement of it (contacts.h).
namespace {
template <class To, class From>
void copy_frame_state(To& to, const From& from) {
  to.position = from.position;
  to.velocity = from.velocity;
  to.travel_from = from.travel_from;
  to.travel = from.travel;
  to.moved = from.moved;
  to.moved_travel = from.moved_travel;
  to.moved_stamp = from.moved_stamp;
}
}  // namespace

template <class Real>
void BasicWorld<Real>::Impl::save_sheet(std::size_t k) {
  copy_frame_state(saved[k], at(k));
}

template <class Real>
void BasicWorld<Real>::Impl::restore_sheet(std::size_t k) {
  Sheet<Real>& s = at(k);
  copy_frame_state(s, saved[k]);
  s.has_contacts = false;
  s.near_obstacles.clear();
  slots[active[k]].bounds_fresh = false;
}

// `count` substeps of group g alone, with its own scope, from the world's step count and
// clock; first, if the frame may be undone, its sheets' state and its pairs' memory are
// saved and its sheets' boxes after each substep go into swept. Groups step at once: each
// writes only its own sheets, scope and entries of swept and saved.
template <class Real>
void BasicWorld<Real>::Impl::step_group(Group& g, double h, std::uint64_t count, bool may_undo) {
  Scope& sc = g.scope;
  if (may_undo) {
    for (std::uint32_t k : g.members) save_sheet(k);
    // the positions kept lists were made at are shared, not copied
    g.saved_work.resize(sc.pair_work.size());
    for (std::size_t q = 0; q < sc.pair_work.size(); ++q) g.saved_work[q] = sc.pair_work[q];
  }
  sc.steps = steps;
  sc.steps_base = steps_base;
  sc.time_base = time_base;
  sc.current_h = current_h;
  for (std::uint64_t j = 0; j < count; ++j) {
    substep(sc, h);
    if (may_undo)
      for (std::size_t i = 0; i < sc.active.size(); ++i)
        detail::include_box(swept[g.members[i]], current_bounds(slots[sc.active[i]]));
  }
}

// Whether the frame's groups, and its free sheets, stayed as far apart as plan_groups
// found them: no pair across two groups or with a free sheet, no free sheet within an
// obstacle's reach, over the boxes swept over the frame.
template <class Real>
bool BasicWorld<Real>::Impl::groups_stayed_apart() {
  if (contacts_possible()) {
    grow_for_contact(swept, swept_grown);
    swept_broad_phase.find_pairs(swept_grown, frame_pairs);
    for (const detail::BoxPair& pair : frame_pairs)
      if (group_of[pair.first] == kFree || group_of[pair.first] != group_of[pair.second]) return false;
  }
  for (std::size_t k = 0; k < swept.size(); ++k)
    for (std::uint32_t o : active_obstacles)
      if (group_of[k] == kFree && detail::may_touch(*obstacle_slots[o].obstacle, swept[k])) return false;
  return true;
}

// The groups' pairs and work back to the world, in its positions: as they ended the frame
// if it is kept (with its step count and clock, and the pairs met for the guard), else as
// they began it (with every sheet's state the frame found).
template <class Real>
void BasicWorld<Real>::Impl::end_groups(bool kept) {
  pair_work = std::move(aside);
  aside.clear();
  if (kept) pairs.clear();
  for (std::size_t g = 0; g < group_count; ++g) {
    Group& group = groups[g];
    Scope& sc = group.scope;
    if (kept) {
      for (auto& w : sc.pair_work) {
        w.a = group.members[w.a];
        w.b = group.members[w.b];
        pair_work.push_back(std::move(w));
      }
      for (const detail::BoxPair& pair : sc.pairs) pairs.push_back({group.members[pair.first], group.members[pair.second]});
      for (const auto& [a, b] : sc.met) guard_meet(a, b);
    } else {
      for (auto& memory : group.saved_work) {
        detail::PairContacts<Real>& w = pair_work.emplace_back();
        static_cast<detail::PairMemory<Real>&>(w) = std::move(memory);
        w.a = group.members[w.a];
        w.b = group.members[w.b];
      }
    }
    sc.pair_work.clear();
  }
  if (!kept) {
    parallel(active.size(), [&](std::size_t k) { restore_sheet(k); });
    return;
  }
  if (group_count > 0) {  // every group took the same substeps
    const Scope& sc = groups[0].scope;
    steps = sc.steps;
    steps_base = sc.steps_base;
    time_base = sc.time_base;
    current_h = sc.current_h;
  }
  std::sort(pairs.begin(), pairs.end());
  keep_pair_work(world, steps);  // the last substep's stamp: present pairs first, in the pairs' order
}

template <class Real>
typename BasicWorld<Real>::Impl::Try BasicWorld<Real>::Impl::try_frame(double h, std::uint64_t count) {
  const std::size_t n = active.size();
  active_bounds(swept);
  plan_groups(swept);
  // Without contacts and obstacles (groups of constrained sheets only), no two groups can
  // meet: nothing is saved or swept, and the frame is kept.
  const bool may_undo = !sheets_independent();
  if (group_count > 0 && !groups_pay(may_undo)) return Try::NotTried;
  // Each pair's work to its group, in the group's positions; aside if its two sheets are
  // not in one group (the pair is gone, and stays gone in a frame that is kept).
  std::vector<std::uint32_t> local(n);
  for (std::size_t g = 0; g < group_count; ++g)
    for (std::uint32_t i = 0; i < groups[g].members.size(); ++i) local[groups[g].members[i]] = i;
  aside.clear();
  for (auto& w : pair_work) {
    const std::uint32_t g = w.a < n && w.b < n ? group_of[w.a] : kFree;
    if (g == kFree || g != group_of[w.b]) {
      aside.push_back(std::move(w));
      continue;
    }
    w.a = local[w.a];
    w.b = local[w.b];
    groups[g].scope.pair_work.push_back(std::move(w));
  }
  pair_work.clear();
  if (may_undo) saved.resize(n);
  // The free sheets as independent runs, with the world's list of sheets theirs meanwhile.
  if (!free_sheets.empty()) {
    if (may_undo) parallel(free_sheets.size(), [&](std::size_t i) { save_sheet(free_sheets[i]); });
    std::vector<std::uint32_t> slots_of(free_sheets.size());
    free_swept.resize(free_sheets.size());
    for (std::size_t i = 0; i < free_sheets.size(); ++i) {
      slots_of[i] = active[free_sheets[i]];
      free_swept[i] = swept[free_sheets[i]];
    }
    std::swap(active, slots_of);
    integrate_runs(h, count, may_undo ? &free_swept : nullptr);
    std::swap(active, slots_of);
    for (std::size_t i = 0; i < free_sheets.size(); ++i) swept[free_sheets[i]] = free_swept[i];
  }
  // The groups at once, each a task; a thread waiting inside one group's stages takes only
  // that group's work meanwhile (isolate), never a whole other group. With a group for every
  // thread, each group's stages run in order on its own thread (Scope::serial).
  const bool serial = group_count >= std::size_t(arena->max_concurrency());
  for (std::size_t g = 0; g < group_count; ++g) groups[g].scope.serial = serial;
  parallel(group_count, [&](std::size_t g) {
    tbb::this_task_arena::isolate([&] { step_group(groups[g], h, count, may_undo); });
  });
  const bool kept = !may_undo || groups_stayed_apart();
  ++(kept ? frame_stats.kept : frame_stats.undone);
  if (kept && group_count == 0) count_substeps(h, count);  // else each group counted its substeps
  end_groups(kept);
  return kept ? Try::Kept : Try::Undone;
}

// Substeps a try of try_frame takes at most: enough to step a group while its state is in
// cache, few enough that a try undone (two groups met) costs little to step again.
constexpr std::uint64_t kFrameTry = 32;

// `count` substeps of h: in runs when the sheets are independent; else in tries of at most
// kFrameTry substeps each (try_frame), each stepped substep by substep if it is undone. After
// an undone try the next ones are skipped, twice as many after each undone try in a row (up
// to 8), so that a scene whose groups keep meeting does not pay for every try twice.
template <class Real>
void BasicWorld<Real>::Impl::substeps(double h, std::uint64_t count) {
  if (count > 1 && !driven() && sheets_independent()) {
    integrate_runs(h, count);
    pairs.clear();  // no substep of the run had a pair
    count_substeps(h, count);
    return;
  }
  const bool may_try = count > 1 && frame_may_be_tried();
  while (count > 0) {
    const std::uint64_t part = std::min(count, kFrameTry);
    count -= part;
    if (may_try && part > 1 && tries_to_skip == 0) {
      const Try tried = try_frame(h, part);
      if (tried == Try::Kept) {
        try_backoff = 0;
        continue;
      }
      if (tried == Try::Undone) {
        try_backoff = std::min<std::uint32_t>(8, std::max<std::uint32_t>(1, 2 * try_backoff));
        tries_to_skip = try_backoff;
      }
    } else if (may_try && part > 1) {
      --tries_to_skip;
    }
    for (std::uint64_t k = 0; k < part; ++k) substep(h);
  }
}

template <class Real>
double BasicWorld<Real>::Impl::omega_max() const {
  double w = 0;
  for (std::uint32_t index : active) w = std::max(w, slots[index].omega_max);
  return w;
}

template <class Real>
double BasicWorld<Real>::Impl::contact_omega(double lightest) const {
  return std::sqrt(def.contact_strength / lightest) / def.contact_xi;
}

// The longest substep allowed now: dt, or in adaptive mode the explicit integrator's
// critical step on the stiffest sheet, or on the sheet–sheet contact of the lightest point
// where sheets may touch, times the safety factor.
template <class Real>
double BasicWorld<Real>::Impl::max_substep() const {
  if (!def.adaptive || !integrator_is_explicit(def.integrator)) return def.dt;
  double omega = omega_max();
  if (contacts_possible()) {
    double lightest = std::numeric_limits<double>::infinity();
    for (std::uint32_t index : active) lightest = std::min(lightest, slots[index].lightest_point);
    omega = std::max(omega, contact_omega(lightest));
  }
  const double h = def.adaptive_safety * integrator_critical_step(def.integrator, omega);
  return std::isfinite(h) ? h : std::numeric_limits<double>::infinity();
}

// `seconds` in equal substeps of at most max_substep(), ending exactly at time + seconds.
template <class Real>
void BasicWorld<Real>::Impl::advance(double seconds) {
  const double h_max = max_substep();
  const double count = std::isfinite(h_max) ? std::max(1.0, std::ceil(seconds / h_max * (1 - 1e-12))) : 1.0;
  // a count past 2^53 is not even a whole number in double (nor, past 2^64, a uint64_t: the
  // cast would be undefined); no run could take that many substeps anyway
  if (!(count <= 0x1p53)) {
    std::ostringstream out;
    out << "drape: advance(" << seconds << ") needs " << count << " substeps of at most " << h_max
        << " s, more than 2^53: advance a shorter time";
    throw std::invalid_argument(out.str());
  }
  substeps(seconds / count, static_cast<std::uint64_t>(count));
}

// The members defined here, for both precisions: one explicit instantiation of Impl as a
// whole in each of the files that define its members would instantiate it more than once.
#define DRAPE_WORLD_FRAMES(Real)                                                                              \
  template void BasicWorld<Real>::Impl::plan_wave_blocks(std::uint32_t);                                      \
  template void BasicWorld<Real>::Impl::integrate_runs(double, std::uint64_t, std::vector<detail::Aabb>*);    \
  template bool BasicWorld<Real>::Impl::frame_may_be_tried() const;                                           \
  template void BasicWorld<Real>::Impl::plan_groups(const std::vector<detail::Aabb>&);                        \
  template bool BasicWorld<Real>::Impl::groups_pay(bool) const;                                               \
  template void BasicWorld<Real>::Impl::save_sheet(std::size_t);                                              \
  template void BasicWorld<Real>::Impl::restore_sheet(std::size_t);                                           \
  template void BasicWorld<Real>::Impl::step_group(Group&, double, std::uint64_t, bool);                      \
  template bool BasicWorld<Real>::Impl::groups_stayed_apart();                                                \
  template void BasicWorld<Real>::Impl::end_groups(bool);                                                     \
  template typename BasicWorld<Real>::Impl::Try BasicWorld<Real>::Impl::try_frame(double, std::uint64_t);                                     \
  template void BasicWorld<Real>::Impl::substeps(double, std::uint64_t);                                      \
  template double BasicWorld<Real>::Impl::omega_max() const;                                                  \
  template double BasicWorld<Real>::Impl::contact_omega(double) const;                                        \
  template double BasicWorld<Real>::Impl::max_substep() const;                                                \
  template void BasicWorld<Real>::Impl::advance(double);
DRAPE_WORLD_FRAMES(double)
DRAPE_WORLD_FRAMES(float)
#undef DRAPE_WORLD_FRAMES

}  // namespace drape
