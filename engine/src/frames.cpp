// Many substeps at once: runs of substeps on independent sheets (whole, or as waves in row
// blocks), contact-free frames that are kept only if nothing came near, and advance().

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
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
        detail::Aabb after;  // the box after each substep, taken as the update moves the points
        for (std::uint32_t k = 0; k < levels; ++k) {
          detail::integrate(def.integrator, s, params, box ? &after : nullptr);
          if (box) detail::include_box(*box, after);
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
template <class Real>
bool BasicWorld<Real>::Impl::frame_may_be_contact_free() const {
  return detail::updates_per_point(def.integrator) &&
         std::none_of(active.begin(), active.end(), [&](auto i) { return slots[i].sheet->self_collision; });
}

// Whether sheets with these boxes are out of each other's contact range and out of
// every obstacle's reach (what the host stage would find for them).
template <class Real>
bool BasicWorld<Real>::Impl::apart(const std::vector<detail::Aabb>& boxes, detail::TrackingBroadPhase& tracker) {
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

template <class Real>
bool BasicWorld<Real>::Impl::try_frame(double h, std::uint64_t count) {
  const std::size_t n = active.size();
  active_bounds(swept);
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

// `count` substeps of h: in runs when the sheets are independent, or when a try shows
// they stayed apart; else one by one.
template <class Real>
void BasicWorld<Real>::Impl::substeps(double h, std::uint64_t count) {
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
  substeps(seconds / count, static_cast<std::uint64_t>(count));
}

// The members defined here, for both precisions: one explicit instantiation of Impl as a
// whole in each of the files that define its members would instantiate it more than once.
#define DRAPE_WORLD_FRAMES(Real)                                                                              \
  template void BasicWorld<Real>::Impl::plan_wave_blocks(std::uint32_t);                                      \
  template void BasicWorld<Real>::Impl::integrate_runs(double, std::uint64_t, std::vector<detail::Aabb>*);    \
  template bool BasicWorld<Real>::Impl::frame_may_be_contact_free() const;                                    \
  template bool BasicWorld<Real>::Impl::apart(const std::vector<detail::Aabb>&, detail::TrackingBroadPhase&); \
  template bool BasicWorld<Real>::Impl::try_frame(double, std::uint64_t);                                     \
  template void BasicWorld<Real>::Impl::substeps(double, std::uint64_t);                                      \
  template double BasicWorld<Real>::Impl::omega_max() const;                                                  \
  template double BasicWorld<Real>::Impl::contact_omega(double) const;                                        \
  template double BasicWorld<Real>::Impl::max_substep() const;                                                \
  template void BasicWorld<Real>::Impl::advance(double);
DRAPE_WORLD_FRAMES(double)
DRAPE_WORLD_FRAMES(float)
#undef DRAPE_WORLD_FRAMES

}  // namespace drape
