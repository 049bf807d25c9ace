// Contacts between sheets (and of a sheet with itself): the narrow phase of the host stage.
//
// A point p of one sheet is repelled by the surface of another sheet, its grid cells split
// into triangles (cell (i, j) into (i,j)(i,j+1)(i+1,j+1) and (i,j)(i+1,j+1)(i+1,j)), through
// the potential
//     E(d) = c·exp(−(d − h)/ξ) − shift,   d = min over triangles T of dist(p, T), h = thickness,
// the obstacles' potential of eq (9) with the distance to the surface minus the thickness
// in place of the implicit function. Only the nearest triangle acts: summing over every
// triangle in range would make a flat sheet bumpy (a point over a vertex feels six
// triangles, over a face one or two) and let resting sheets creep. The force −dE/dd = (c/ξ)·exp(−(d − h)/ξ) is
// cut off at d = R = h + range_in_xi·ξ and shifted so it falls continuously to 0 there;
// since d ≥ 0 it never exceeds (c/ξ)·exp(h/ξ): a fast or deep penetration meets a large
// but finite force, never an overflow. Where the substep cannot resolve its stiffness for
// the pair's lightest point, the exponent is capped lower (ContactParams::exponent_cap).
// The force on p acts along p − q (q the closest point of the nearest T; T's normal when p
// lies on T), and the opposite force is shared by T's three vertices with q's barycentric
// weights, so every contact conserves momentum to rounding.
// With friction (μ = the larger of the two sheets' SheetDef::friction), the force on p also
// opposes p's velocity relative to q (the corners' velocities with the same weights),
// tangential to p − q: the smaller of μ·|F| and the force that stops that slip within dt
// for the pair's effective mass 1/(1/m_p + Σ w_k²/m_k). It joins the repulsion before the
// reaction is shared, so it is equal and opposite too.
//
// Candidates come from boxes each sheet makes once per substep and shares with all of its
// pairs (SheetBoxes), never all points against all cells, and never a structure per pair.
// The grid's topology gives the hierarchy, so nothing is sorted or binned: a box per cell,
// per strip (a row of 8 cells) and per patch (8×8 cells). A patch's box holds its cells
// and also its points (rows and columns 8p … 8p + 8), so the same box serves as the query
// side's block of points. Points of sheet q against the cells of sheet s go block by
// block: a block whose box, grown by R, misses s's box is skipped; otherwise the patches
// of s within R of it (one branch-free pass over s's patch boxes), and of those the strips
// within R of it, are gathered contiguous, or the block is skipped when there is none.
// Each point of the block then measures its gap to every gathered strip box in one
// vectorised pass and, for the strips within R, to their 8 cells' boxes (a fixed count:
// one or two vector operations), keeping the cells within R. First the point's nearest
// cell of the last substep is tested (kept per pair and direction: usually still the
// nearest, it makes the bound tight at once), or without one the cell whose box is
// nearest; then the others in the order met while their boxes are still nearer than the
// best triangle (a cell whose box is no nearer cannot hold a nearer one). The winner is the
// nearest triangle whatever is tried first; the order only decides between triangles whose
// distances agree to rounding (of exactly equal ones the lowest cell, then the cell's
// first triangle), and then the force on the point is the same.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "bounds.h"
#include "sheet_data.h"

namespace drape::detail {

template <class Real>
struct ContactParams {
  Real thickness;  // h, m
  Real xi;         // ξ, m
  Real strength;   // c, J
  Real range;      // R, m: no force beyond this distance
  Real tail;       // exp(−(R − h)/ξ): the shift that makes the force vanish at R
  Real dt = 0;        // s, the substep (friction stops at most the slip of one)
  Real friction = 0;  // μ of the pair, max of the two sheets' (pair_contacts sets it)
  Real damping = 0;   // α, s/m: Hunt–Crossley damping of the repulsion (above); 0: none
  Real skin;          // m, the first skin of kept candidate lists (PairContacts): R/4
  // The largest exponent (h − d)/ξ the force uses: nearer than h − exponent_cap·ξ the force
  // stops growing, so its stiffness (c/ξ²)·e^((h − d)/ξ) stays at or below m/dt² for the
  // pair's lightest point m, as the obstacles' cap does (the world sets it per pair from
  // the substep). Never below 0: at a substep so long that even the force at d = h is too
  // stiff, a contact keeps that force, and a barrier of about c·(1 + h/ξ), rather than
  // vanish. Unbounded: the model above. Where it binds, a point released deep in the
  // potential leaves with about the energy the capped potential held, not several times it
  // (an explicit step through a stiffness beyond 4m/dt² throws points out).
  Real exponent_cap = std::numeric_limits<Real>::infinity();
  // Between searches: true, every point tests every cell of its kept candidate list (exact,
  // the reference); false, every point of the kept contact set walks from its cell
  // (KeptContacts: an approximation, the default).
  bool exact = false;
  // Rims: the edges of each sheet's outer rows and columns against the other sheet's edges
  // as well (pair_contacts); false: points against triangles only.
  bool rims = false;
  // The pair's travel now: Sheet::travel of both sheets summed (a sheet with itself: twice
  // its own). A kept entry beyond R skips its walk while the sheets have not travelled the
  // entry's slack since its last test (KeptContacts::until). NaN, unknown: none skips.
  double travel = std::numeric_limits<double>::quiet_NaN();
  // Walk a pair's kept sets, and search for them, in this many parts per direction at once,
  // as tasks (contacts.cpp, walk_in_parts, search_in_parts), the parts' forces and sets
  // joined in the order one pass makes them: the same bits. The world asks for 2 when it
  // has threads to spare for its few pairs; 1: one pass.
  int parts = 1;
  // The substep this pair runs in, as the world counts them from 1 (0: none): a sheet's
  // moved_lo / moved_hi serve only when measured in it (measure_travel).
  std::uint64_t stamp = 0;

  static ContactParams make(double thickness, double xi, double strength, double range_in_xi);
};

// Sparse forces one pair puts on one sheet, in the order the pair found them: entries for
// the same point are added in this order when the sheet gathers them. Entries [0, size())
// hold forces; the arrays may be longer (room kept between substeps, so a push is one
// check and four stores, not four vectors' growth checks), and their room is not filled
// when it grows: a stack's first substeps grow every pair's forces to thousands of
// entries, and filling the room first (then writing it) took a third of its second substep.
template <class Real>
struct ContactForces {
  std::vector<std::uint32_t, Uninitialised<std::uint32_t>> point;
  std::vector<Real, Uninitialised<Real>> fx, fy, fz;
  void clear() { count = 0; }
  void push(std::uint32_t p, Real x, Real y, Real z) {
    if (count == point.size()) grow();
    push_unchecked(p, x, y, z);
  }
  std::size_t size() const { return count; }
  // Room for n more pushes, then push_unchecked as many times at most.
  void reserve_more(std::size_t n) {
    while (count + n > point.size()) grow();
  }
  void push_unchecked(std::uint32_t p, Real x, Real y, Real z) {
    point[count] = p;
    fx[count] = x;
    fy[count] = y;
    fz[count] = z;
    ++count;
  }
  // other's entries after these, in their order
  void append(const ContactForces& other) {
    const std::size_t total = count + other.count;
    while (total > point.size()) grow();
    std::copy_n(other.point.begin(), other.count, point.begin() + std::ptrdiff_t(count));
    std::copy_n(other.fx.begin(), other.count, fx.begin() + std::ptrdiff_t(count));
    std::copy_n(other.fy.begin(), other.count, fy.begin() + std::ptrdiff_t(count));
    std::copy_n(other.fz.begin(), other.count, fz.begin() + std::ptrdiff_t(count));
    count = total;
  }

 private:
  [[gnu::noinline]] void grow() {
    const std::size_t room = std::max<std::size_t>(64, 2 * point.size());
    point.resize(room);
    fx.resize(room);
    fy.resize(room);
    fz.resize(room);
  }
  std::size_t count = 0;
};

// The boxes of one sheet's cells and patches (above), made once per substep for a sheet
// that is in some pair and read, never written, by all of its pairs.
template <class Real>
struct SheetBoxes {
  static constexpr std::uint32_t kPatch = 8;  // cells along a patch's side
  // Patch rows (columns) of a sheet of `cells` cell rows (columns).
  static std::uint32_t patches_along(std::uint32_t cells) { return cells == 0 ? 1 : (cells + kPatch - 1) / kPatch; }
  std::uint32_t m = 0, n = 0;                 // the sheet's cells
  Aabb box;                                   // every point
  // Cell (i, j), i < m, j < n, at its first corner i·(n + 1) + j (structure of arrays),
  // padded so that the 8 boxes from any cell on can be read.
  std::vector<Real> cell_lo[3], cell_hi[3];
  // Patch (pi, pj) at pi·patch_cols + pj: cells [8pi, 8pi + 8) × [8pj, 8pj + 8) (cut at the
  // sheet's edge); its box holds points [8pi, 8pi + 8] × [8pj, 8pj + 8], and the last patch
  // row and column reach the sheet's last point row and column. A sheet without cells (a
  // line or a single point) has one patch row or column of points and no cells.
  std::uint32_t patch_rows = 0, patch_cols = 0;
  std::vector<Real> patch_lo[3], patch_hi[3];
  // Strip (i, pj), the cells of row i in patch column pj, at i·patch_cols + pj.
  std::vector<Real> strip_lo[3], strip_hi[3];
  // Point rows (or columns) of patch row (column) p: [first, end).
  std::uint32_t first(std::uint32_t p) const { return p * kPatch; }
  std::uint32_t end_point(std::uint32_t p, std::uint32_t count, std::uint32_t cells) const {
    return p + 1 == count ? cells + 1 : (p + 1) * kPatch;
  }
};

// Box k of one level of SheetBoxes (its lo and hi arrays), in double.
template <class Real>
Aabb box_at(const std::vector<Real> (&lo)[3], const std::vector<Real> (&hi)[3], std::size_t k) {
  return {{double(lo[0][k]), double(lo[1][k]), double(lo[2][k])},
          {double(hi[0][k]), double(hi[1][k]), double(hi[2][k])}};
}

// Calls f(c) for each cell c (by first corner) of patch t of bs whose box meets `box`,
// through the patch's strips, in row order.
template <class Real, class F>
void cells_meeting(const SheetBoxes<Real>& bs, std::uint32_t t, const Aabb& box, F&& f) {
  constexpr std::uint32_t P = SheetBoxes<Real>::kPatch;
  const std::uint32_t cols = bs.n + 1, tr = t / bs.patch_cols, tc = t % bs.patch_cols;
  const std::uint32_t i1 = std::min(tr * P + P, bs.m), j1 = std::min(tc * P + P, bs.n);
  for (std::uint32_t i = tr * P; i < i1; ++i) {
    if (!overlaps(box, box_at(bs.strip_lo, bs.strip_hi, std::size_t(i) * bs.patch_cols + tc))) continue;
    for (std::uint32_t j = tc * P; j < j1; ++j)
      if (overlaps(box, box_at(bs.cell_lo, bs.cell_hi, std::size_t(i) * cols + j))) f(i * cols + j);
  }
}

// Makes `out` the boxes of `s` now (reusing out's storage).
template <class Real>
void build_boxes(const Sheet<Real>& s, SheetBoxes<Real>& out);

// Scratch of the narrow phase. Its contents never reach the result's order, so one per
// thread serves every pair that thread computes.
template <class Real>
struct ContactScratch {
  struct Near {  // a cell whose box is within R of the query point
    std::uint32_t corner;
    Real gap2;  // squared distance from the point to the cell's box
  };
  std::vector<std::uint32_t> patches;          // of the other sheet, within R of one block
  std::vector<Real> run_lo[3], run_hi[3];      // the cells within R of one run of points,
  std::vector<std::uint32_t> run_corner;       // gathered contiguous, with their grid row
  std::vector<std::uint32_t> run_row, run_col;  // and column (self-contact's ring)
  std::vector<Real> gap2;                      // one query point: squared gaps to those boxes
  std::vector<std::uint32_t> pick;             // one query point: which of them are within R,
  std::vector<Near> near;                      // and those cells
  std::vector<Real> mid_a[3], mid_b[3];        // per patch of each sheet of a pair: the middle
  std::vector<Real> radius_a, radius_b;        // and spread of its points' displacements
  std::vector<Real> column_lo[3], column_hi[3], column_nan;  // patch_motion's, per column
  std::vector<std::uint8_t> in_set;  // per point of the query sheet: walked in this block (all 0 between blocks)
};

// Candidate cells of one direction of a pair: for point p of the query sheet, the cells
// (by first corner) cell[begin[p]] … cell[begin[p] + count[p] − 1] of the other sheet, in
// the order the search met them.
struct Candidates {
  std::vector<std::uint32_t> begin, count, cell;
};

// The kept contact set of one direction of a pair (structure of arrays, entry e): point
// point[e] of the query sheet and its cell cell[e] of the other sheet (by first corner),
// the cell of its nearest triangle when last evaluated. A search puts every point within
// R + skin of some cell in the set, in the order the search visits points, starting at the
// cell of its nearest triangle (or, beyond R, the cell whose box is nearest). Between
// searches each entry walks: the point is tested against its cell's two triangles, and
// while the closest point lies on the cell's outer edge or corner the neighbouring cells
// across it are tested too, moving to one that holds a nearer triangle. The walk ends at a
// local minimum of the distance over the grid, which is the nearest triangle wherever the
// other sheet is the graph of a function over the point's neighbourhood; where two parts
// of the other sheet are both within R of the point (a crease, a fold of it), it may stay
// on the farther one until the next search. An entry beyond R skips its walks until the
// two sheets have travelled its slack (until, below; Sheet::travel); where the walk finds
// the nearest triangle, that changes no force. A point not in the set costs nothing.
//
// Only blocks (patches) with points outside the set need the relative-motion test of
// PairContacts, and when it fails only their points outside the set are searched again (a
// partial search; every point in the set walks); every 64 substeps every block is searched. The contact gap test of a walk
// is two triangles per entry (a local-minimum grid point needs none of its neighbours'),
// read straight from the sheet's position arrays by point index; with AVX2 or AVX-512 an
// entry's first cell, the move test there (a corner's test too) and its force go a vector of entries at a time
// (contacts.cpp, points_walking), the rest one entry at a time.
struct KeptContacts {
  std::vector<std::uint32_t> point, cell;
  // Per entry: the pair's travel (ContactParams::travel) below which its walk is skipped.
  // An entry that a walk left beyond R, at distance d, cannot be nearer than d less the
  // sheets' travel since, so it comes within R no sooner than the pair has travelled
  // 0.99·(d − R) more; a search's entry beyond R takes its nearest cell box's gap as d.
  // −∞: walked every substep (within R, a walk cut short, not a number).
  std::vector<double> until;
  // Per patch of the query sheet (SheetBoxes): 1 if some point of its block is not in the
  // set. Only open patches can bring a point into range unseen (PairContacts).
  std::vector<std::uint8_t> open;
  // Entries of the query sheet's block (patch) k: [block_begin[k], block_begin[k + 1]).
  std::vector<std::uint32_t> block_begin;
  void clear() {
    point.clear();
    cell.clear();
    until.clear();
  }
};

// Adds to s.travel the largest distance a point of s moved since the last call (the
// positions then kept in s.travel_from); the first call, or one after the sheet changed
// size, starts from the positions now. A displacement not a number makes the travel
// infinite: no entry skips again.
template <class Real>
void advance_travel(Sheet<Real>& s);
// The same, taking the distance measure_travel found in substep `stamp` if it ran then (the
// same value: the pass is not made twice).
template <class Real>
void advance_travel(Sheet<Real>& s, std::uint64_t stamp);

// The largest distance of a point of s from travel_from now, rounded up as advance_travel
// rounds it, and where that puts the sheet on its travel scale (Sheet::moved_lo(), moved_hi()),
// for substep `stamp`. A pair's kept lists hold while no point moved more than 0.45·skin
// since they were made (lists_hold); the sheet's moved_hi now less its moved_lo then bounds
// that, so one pass per sheet answers for all of its pairs, and only a pair the bound does
// not clear runs the exact test over its points. The bound implies the exact test (the
// rounding up covers the rounding of both), so every decision, and every bit, is the same.
template <class Real>
void measure_travel(Sheet<Real>& s, std::uint64_t stamp);
// Whether measure_travel ran on s in substep `stamp` (0: no substep, never).
template <class Real>
bool measured_in(const Sheet<Real>& s, std::uint64_t stamp) {
  return stamp != 0 && s.moved_stamp == stamp;
}

// The positions a pair's kept lists were made at. Copies of a pair's work share them (a
// frame's saved state, frames.cpp) until a search makes new ones, which then go to a buffer
// of their own: saving the work copies no positions, and a search with no copy around
// reuses its buffer.
template <class Real>
class KeptPositions {
 public:
  const Vec3Array<Real>& get() const { return *at_; }
  std::size_t size() const { return at_->x.size(); }
  Vec3Array<Real>& to_write() {
    if (!at_ || at_.use_count() > 1) at_ = std::make_shared<Vec3Array<Real>>();
    return *at_;
  }

 private:
  std::shared_ptr<Vec3Array<Real>> at_ = std::make_shared<Vec3Array<Real>>();
};

// Substeps a pair's work (PairContacts) waits for the pair's return after it left the
// world's list; then it is dropped. About a frame of substeps or a few, so a pair that
// flickers at the broad phase's range keeps its lists, and a scene whose pairs keep
// changing holds only the work of pairs present lately.
inline constexpr std::uint64_t kGoneSubsteps = 64;

// The contact work of one overlapping pair of sheets (a < b), or of one sheet with itself
// (a == b, only on_a used). Written by one task, read by the gather: no sharing.
//
// Candidates are kept from one substep to the next: each point's list holds the cells
// whose boxes were within R + skin of it when the list was made (by the search above, run
// with R + skin), in the order the search met them. A point can come nearer to a cell by
// at most how far the two moved RELATIVE to each other, so the lists hold while, for
// every patch A of one sheet and B of the other (the same patch boxes: a patch's points
// are its block), A's spread of displacements since then (the largest distance of a
// point's displacement from the middle of them all) plus B's plus the distance between
// the two middles stays within 0.9 of the slack the lists had: the skin, or the two
// patches' gap then less R if that is more (patches far apart may drift far). A stack that
// sags and swings together keeps its lists; a point off its list is then still beyond R,
// so reading the lists finds exactly the cells the search would, in its order: the forces
// are the same bit for bit. Otherwise, or when the pair's sheets are not the ones the
// lists were made for, the search runs again and takes that substep's forces in the same
// pass. The skin follows the pair: R/4 at first, halved (down to R/16) when the last lists
// did not outlive their substep or served more than 32, doubled (up to R/2) when fewer
// than 4. Lists at R/16 that did not outlive their substep make the pair search without
// lists for the next 16 substeps (making them costs more than it saves while the sheets
// move that fast), then start again at R/4. A kept contact set's skin (below) doubles up
// to 2R and never halves below R/2.
//
// What a pair carries from one substep to the next: its sheets, kept lists and sets, the
// positions and clearances they were made at, its counters, decisions and guesses. Written
// as words by write_contact_memory; copied as it is for a frame's saved state (frames.cpp).
template <class Real>
struct PairMemory {
  std::uint32_t a = 0, b = 0;  // positions in the world's sheet order
  const Sheet<Real>* kept_a = nullptr;  // the sheets the kept lists were made for
  const Sheet<Real>* kept_b = nullptr;
  const Topology<Real>* kept_topology_a = nullptr;
  const Topology<Real>* kept_topology_b = nullptr;
  KeptPositions<Real> made_at_a, made_at_b;  // their positions then
  std::vector<Real> clearance;           // then: the gap of patch A of a to patch B of b
  Candidates a_near_b, b_near_a;         // points of a against cells of b, and back (exact)
  KeptContacts a_on_b, b_on_a;           // the same as kept contact sets (not exact)
  bool kept_exact = false;               // which of the two the search made
  Real skin = 0;                         // of the kept lists (0: none made yet)
  std::uint32_t kept_for = 0;            // substeps the kept lists have served
  std::uint32_t since_full = 0;          // substeps since every block of a set was searched
  std::uint32_t resting = 0;             // substeps left to search without lists
  // Per point of a (against b) and of b (against a): its nearest cell last substep (first
  // corner; ~0 for none), tested first; and the grids those cells belong to.
  std::vector<std::uint32_t> last_a, last_b;
  // Sheet::moved_lo of a and b in the substep the kept lists were made (−∞: not measured).
  double moved_lo_a = -std::numeric_limits<double>::infinity();
  double moved_lo_b = -std::numeric_limits<double>::infinity();
  const Topology<Real>* guessed_a = nullptr;
  const Topology<Real>* guessed_b = nullptr;
  std::uint64_t searches = 0;            // how often the lists were made (for tests)
  // The last substep (its contact stamp) the pair was in the world's list: a pair gone for
  // more than kGoneSubsteps substeps since does not find this work again on its return
  // (step.cpp, keep_pair_work). A rule of the pair's own, so that sheets stepped in groups
  // (frames.cpp) keep and drop the same work as the whole world stepped at once.
  std::uint64_t present_at = 0;
  signed char decided = -1;              // pair_needs_boxes's decision: 1 keep, 0 search, −1 none
  // The rims' candidates (ContactParams::rims): edge pairs within R + R/2 (R/2 their skin)
  // when made, a's rim edges against b's edges, then b's rim edges against a's off its rim, each
  // as (u, v) of the rim's sheet and (p, w) of the other, in the order a search meets them.
  // They serve while the pair's travel stays below rims_until (the travel then plus the
  // skin): no two points of the sheets can have come nearer by more than that, nor two edges
  // (rims_due). Forces from them are those of searching every substep, bit for bit.
  std::vector<std::array<std::uint32_t, 4>> rims_ab, rims_ba;
  double rims_until = -std::numeric_limits<double>::infinity();
  const Topology<Real>* rims_topology_a = nullptr;
  const Topology<Real>* rims_topology_b = nullptr;
  std::uint64_t rim_searches = 0;  // how often the rims' candidates were made (for tests)
};

// The pair's memory, with its work within a substep: its forces on each sheet (read by
// the gather), the sets a search makes while it walks the old ones, and its parts' scratch.
template <class Real>
struct PairContacts : PairMemory<Real> {
  ContactForces<Real> on_a, on_b;
  KeptContacts spare_a, spare_b;
  // The forces of each part of a walk or search in parts (ContactParams::parts), on the
  // points' sheet and on the cells' (the same buffer for a sheet with itself), a search's
  // kept set of each part, and the scratch of every part but the first (which has the
  // pair's): scratch within a substep, not memory.
  std::vector<ContactForces<Real>> part_on_q, part_on_s;
  std::vector<KeptContacts> part_kept;
  std::vector<ContactScratch<Real>> part_scratch;
};

// Whether the pair's rim candidates must be made again this substep (both sheets' boxes then
// needed): none made yet, made for other grids, or the pair's travel (`travel`, both
// sheets' Sheet::travel summed; NaN, as in exact mode: always) has reached rims_until.
template <class Real>
bool rims_due(const PairContacts<Real>& w, const Sheet<Real>& a, const Sheet<Real>& b, double travel) {
  return w.rims_topology_a != a.topology.get() || w.rims_topology_b != b.topology.get() || !(travel < w.rims_until);
}

// The first half of a pair's substep, before any boxes are made: whether its kept lists or
// set serve this substep (then counted as served), else it will search. Returns whether
// the pair needs both sheets' boxes: to search, or to read exact lists; a kept contact set
// that holds needs none. pair_contacts / self_contacts then follow the decision; called
// without it, they decide themselves.
template <class Real>
bool pair_needs_boxes(const Sheet<Real>& a, const Sheet<Real>& b, const ContactParams<Real>& params,
                      PairContacts<Real>& work, ContactScratch<Real>& scratch);

// Points of `a` against the cells of `b` and points of `b` against the cells of `a`, each
// sheet's boxes made by build_boxes from its positions now. Clears and fills work.on_a/on_b.
// With params.rims, then the rims (contacts.cpp, rims_of_pair): each edge of a's rim (its
// first and last rows and columns) against every edge of b passing it within R, and each
// edge of b's rim against the edges of a off its rim, repelled by the points' law at the
// distance between the edges' nearest points (damping and friction alike), the force shared by each edge's ends as the nearest
// point divides it. The pair's rim candidates are made again from both sheets' boxes when
// rims_due says so; the world makes the boxes then.
template <class Real>
void pair_contacts(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                   const SheetBoxes<Real>& boxes_b, const ContactParams<Real>& params, PairContacts<Real>& work,
                   ContactScratch<Real>& scratch);

// A sheet folding onto itself: points against the sheet's own cells, skipping the cells
// within `self_contact_ring` rows/columns of the point (its grid neighbourhood, which
// is always within contact range of it). Clears and fills work.on_a.
template <class Real>
void self_contacts(const Sheet<Real>& s, const SheetBoxes<Real>& boxes, const ContactParams<Real>& params,
                   PairContacts<Real>& work, ContactScratch<Real>& scratch);

// Rows/columns around a point whose cells self-contact ignores: enough that the cells a
// point touches at rest spacing never count, 1 + ⌈R / smallest rest spacing⌉, at most 16.
template <class Real>
std::uint32_t self_contact_ring(const Sheet<Real>& s, const ContactParams<Real>& params);

// The contact potential (J) of the points of q against the surface of s (both boxes made
// from their positions now): Σ over q's points of the energy whose −gradient the repulsion is,
// E(d) = c·(e^((h − d)/ξ) − t) − c·t·((h − d)/ξ + (R − h)/ξ), t the tail (zero at R, linear
// past the exponent cap), at each point's exact nearest triangle within R. q == s: the
// sheet against itself, without the cells self_contacts leaves out.
template <class Real>
double contact_energy(const Sheet<Real>& q, const SheetBoxes<Real>& boxes_q, const Sheet<Real>& s,
                      const SheetBoxes<Real>& boxes_s, const ContactParams<Real>& params);

// The potential (J) of the rim contacts of a and b (pair_contacts with ContactParams::rims):
// each edge of either sheet's rim and each edge of the other passing it within R, at the
// distance of their nearest points, the edges of both rims once.
template <class Real>
double rim_energy(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                  const SheetBoxes<Real>& boxes_b, const ContactParams<Real>& prm);

// Writes the sum of `sources` into points [begin, end) of `out` (zeroing them first),
// adding in source order and, within a source, in entry order: the same bits whatever
// thread runs it and however the sheet is split into blocks.
template <class Real>
void gather_contacts(std::span<const ContactForces<Real>* const> sources, Vec3Array<Real>& out, std::size_t begin,
                     std::size_t end);

// The contact stage's memory between substeps, as words (a Real by its bits), for
// checkpoints: every pair's kept lists and sets (with their entries' skips), the positions
// and clearances they were made at, their skin and counters, and its guesses, in
// pair_work's order (gone pairs too), then every sheet's travel (Sheet::travel and
// travel_from). A kept set's walk and the substeps that search depend on all of it, so a
// world that takes it back continues bit for bit. `sheets` are the world's sheets in order.
// read_contact_memory checks every count and index against them and throws
// std::invalid_argument naming the problem, leaving `pair_work` and `travel` as they were;
// `travel` gets one entry per sheet, or none from a layout before 3. Layout 4 (written
// by default) packs indices, flags and floats two to a word as layouts 2 and 3 do, and
// holds each pair's last substep in the list; layout 3 lacks that (its pairs read as
// present at `present_at`, the world's last substep), layouts 2 and 1 (one word per entry)
// lack skips and travel too; all are still read (for older checkpoints), the entries of
// layouts 2 and 1 walking every substep until the next search.
template <class Real>
struct SheetTravel {
  double travel = 0;
  Vec3Array<Real> from;
};
template <class Real>
std::vector<std::uint64_t> write_contact_memory(const std::vector<PairContacts<Real>>& pair_work,
                                                std::span<const Sheet<Real>* const> sheets, int layout = 4);
template <class Real>
void read_contact_memory(std::span<const std::uint64_t> memory, std::span<const Sheet<Real>* const> sheets,
                         std::vector<PairContacts<Real>>& pair_work, std::vector<SheetTravel<Real>>& travel,
                         std::uint64_t present_at = 0);

}  // namespace drape::detail
