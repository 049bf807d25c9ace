// Force terms of one sheet. Each physical effect is one kernel over SoA arrays; a sheet
// runs only the kernels of the terms it has (chosen per sheet, never per point). The list
// of terms and their order: terms/terms.h. One row sweep (forces.cpp) runs them for whole
// sheets, row blocks and waves.
#pragma once

#include "bounds.h"
#include "sheet_data.h"
#include "simd/kernels.h"
#include "terms/rows.h"

namespace drape::detail {

// eq (8): anchor a's force k (p0 − x) added to point q of x and f (a whole sheet's arrays,
// or one row's with q counted from its start). Every path adds anchors through this.
template <class Real>
inline void add_anchor(const Anchors<Real>& an, std::size_t a, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, std::size_t q) {
  f.x[q] += an.stiffness[a] * (an.tx[a] - x.x[q]);
  f.y[q] += an.stiffness[a] * (an.ty[a] - x.y[q]);
  f.z[q] += an.stiffness[a] * (an.tz[a] - x.z[q]);
}

// Hard pin k: point q of x and v (indexed as in add_anchor) back on its pin and at rest,
// whatever the update did.
template <class Real>
inline void hold_pin(const Pins<Real>& pins, std::size_t k, Vec3Ptr<Real> x, Vec3Ptr<Real> v, std::size_t q) {
  x.x[q] = pins.tx[k];
  x.y[q] = pins.ty[k];
  x.z[q] = pins.tz[k];
  v.x[q] = v.y[q] = v.z[q] = Real(0);
}

// eq (6)–(7): writes (not adds) the elastic force of every spring into f, both endpoints.
// `row` is scratch of n+1 values per component.
template <class Real>
void spring_forces(const Topology<Real>& topo, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row);

// The same for rows [row_begin, row_end) only: writes f of those rows, reading x of the
// rows next to them. Each row's result is bit-identical to the whole-sheet call, so a
// sheet split into blocks of rows (one per task) gives the same state for any split.
template <class Real>
void spring_forces(const Topology<Real>& topo, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                   std::uint32_t row_begin, std::uint32_t row_end);

// Rows [row_begin, row_end) of sheet_forces, with `row` as the block's scratch row
// (Topology::scratch_cols long, as every `row` here); each
// point's terms are added in the same order as in sheet_forces, so a split sheet's forces
// are bit-identical. Never called for a sheet with obstacles near it (they read normals
// across rows): the world keeps such sheets whole.
template <class Real>
void sheet_forces_rows(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                       Vec3Ptr<Real> row, std::uint32_t row_begin, std::uint32_t row_end);

// f = springs(x) + shear, bending, air (those the sheet has) − C·v + contacts + anchors(x)
// + near obstacles(x), in the order of terms/terms.h: the total force of
// eq (4) without gravity, which the integrators add as an acceleration. Contact forces are
// the ones the host stage gathered from the positions at the start of the substep; a
// multi-stage integrator holds them constant over the substep.
template <class Real>
void sheet_forces(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f);

// sheet_forces, then, when `step` is given, that explicit Euler step of the sheet's own
// points (x and v are then the sheet's position and velocity): rows are moved in runs of
// at least update_run_points points as soon as their forces are final, while they are
// still in the nearest cache, since no later force of this sweep reads them. This saves the integrator a pass over the whole sheet's forces, which a sheet
// beyond the nearest cache would read back from a farther one. A sheet with obstacles near
// it (or anchors out of order) is moved in one pass after its forces.
// The sweep and the update run on one instruction set, chosen once per call (forces.cpp).
// `box`, when given with a step (the sheet's pins sorted by point), grows to contain the
// sheet's positions after the step and its pins (update_around_pins), from the update's
// registers: no later pass reads the points for their box.
template <class Real>
void sheet_forces_by_rows(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                          const simd::EulerStep<Real>* step, simd::Extent<Real>* box = nullptr);

// Points [begin, end) of an update whose new positions grow `box`, where hold_pin will
// then move the pinned points among them (pins sorted by point, the next at or after
// `next_pin`, which advances): update(b, e, grow) moves points [b, e) growing *grow when
// it is not null. Runs between pins grow the box; a pinned point is moved without, and
// its pin's target grows the box instead, so the box is that of the positions after the
// pins hold: the box a pass over the points would give (no NaN among them).
template <class Real, class Update>
void update_around_pins(const Pins<Real>& pins, std::size_t& next_pin, std::size_t begin, std::size_t end,
                        simd::Extent<Real>& box, Update update) {
  for (; next_pin < pins.point.size() && pins.point[next_pin] < end; ++next_pin) {
    const std::size_t q = pins.point[next_pin];
    if (q < begin) continue;
    if (q > begin) update(begin, q, &box);
    update(q, q + 1, nullptr);
    box.include(pins.tx[next_pin], pins.ty[next_pin], pins.tz[next_pin]);
    begin = q + 1;
  }
  if (begin < end) update(begin, end, &box);
}

// ---- Several substeps in one sweep (temporal blocking) ------------------------------
//
// A first-order explicit step moves a row using only the forces on it, which read the row
// and the R rows on each side (R = force_reach: 1 for the grid springs, 2 with bending). So
// substep ℓ+1 of row r can run as soon as substep ℓ has moved rows r−R … r+R: a sweep of
// `levels` substeps walks the rows as a wave, substep ℓ R rows behind substep ℓ−1, and a sheet beyond the caches is streamed from memory once
// per `levels` substeps instead of once per substep, while its arithmetic, row by row and
// term by term, is that of `levels` separate sweeps: the state is bit-identical.

// Scratch of one wave: the force rows in flight (a ring), the spring row, the anchor and
// pin cursors of each substep, and, for a block of a split sheet, private copies of the
// rows beyond its edges (its halo).
template <class Real>
struct WaveScratch {
  Vec3Array<Real> forces, row, halo_x, halo_v;
  std::vector<std::size_t> next_anchor, next_pin;
};

// Whether a sheet's terms allow the wave: no contacts and no obstacles this frame (they
// change between substeps, or read rows across the sheet), anchors and pins in point order.
template <class Real>
bool wave_ready(const Sheet<Real>& sheet);

// Substeps a wave sweeps at once for sheets of `cols` points per row whose terms reach
// `reach` rows (force_reach): as many as keep the rows in flight within about 1 MiB (an L2
// cache), between 1 and 64.
std::uint32_t wave_levels(std::uint32_t cols, std::size_t bytes_per_value, std::uint32_t reach = 1);

// Whether the whole sheet fits that budget: it then stays in cache from one substep to the
// next without a wave, and whole-sheet passes are cheaper than rows (sheet_forces_by_rows).
template <class Real>
bool fits_cache_budget(const Sheet<Real>& sheet);

// Moves rows [row_begin, row_end) of a wave_ready sheet `levels` substeps ahead by `step`,
// row by row and substep by substep, then sets the row's pins; `swept`, when
// given, grows to contain those rows at every substep. Rows outside the range are not
// written. A block that is not the whole sheet also steps the levels·R
// rows beyond each of its edges, in copies: call wave_take_halo for every block of the
// sheet before any block's wave, since the waves of other blocks move those rows.
template <class Real>
void wave_take_halo(const Sheet<Real>& sheet, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,
                    WaveScratch<Real>& scratch);
template <class Real>
void sheet_wave(Sheet<Real>& sheet, std::uint32_t levels, std::uint32_t row_begin, std::uint32_t row_end,
                WaveScratch<Real>& scratch, const simd::EulerStep<Real>& step, Aabb* swept = nullptr);

}  // namespace drape::detail
