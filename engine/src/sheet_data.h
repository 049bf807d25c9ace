// Internal storage of one sheet: the shared, immutable spring topology and the
// per-instance structure-of-arrays buffers. Only engine/src sees these types.
#pragma once

#include "aligned.h"

#include <drape/sheet.h>
#include <drape/types.h>

#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <vector>

namespace drape::detail {

struct Obstacle;  // obstacles.h

// Contact damping (WorldDef::contact_damping, ObstacleDef::damping): the damping coefficient
// of one contact is capped at this share of m/dt (m the point's, or between sheets the
// pair's effective, mass). An explicit damper is stable while the coefficients acting on a
// point, summed, stay below 2m/dt, and a point can feel several: a contact between sheets
// enters twice (once per direction of its pair) besides the shares a point takes as a corner
// of other points' triangles, and a sheet can touch an obstacle and other sheets at once.
// Uncapped, issue 13's settling stack blew up (the figures are in the commit that added it).
inline constexpr double kDampingShare = 0.25;

// An obstacle the host stage found near a sheet, with the exponent cap this sheet uses
// (obstacles.h, exponent_cap: it depends on the sheet's lightest point and on dt), and what
// its friction needs: μ (the larger of the sheet's and the obstacle's), the substep's
// length and gravity (friction stops the slip the substep would otherwise produce).
struct NearObstacle {
  const Obstacle* obstacle;
  double exponent_cap;
  double friction = 0;
  double damping = 0;  // α of ObstacleDef::damping
  double dt = 0;
  double gravity[3] = {0, 0, 0};
  // The obstacle's rigid velocity over the substep, so friction and damping act against the slip
  // relative to its surface: v_surface(x) = linear + angular × (x − center). All zero for a
  // still obstacle, where subtracting it leaves the point's velocity bit for bit.
  double linear[3] = {0, 0, 0};   // m/s, its centre's motion over [t, t + dt]
  double angular[3] = {0, 0, 0};  // rad/s, axis·angle of q(t + dt)·q(t)⁻¹ over dt
  double center[3] = {0, 0, 0};   // m, its centre at t
};

// Edge buffer of a grid (paper Fig 1). Springs are stored in a fixed order so the force
// kernel never reads a or b: first the horizontal springs row by row, spring i·n + j joining
// (i, j)–(i, j+1); then the vertical ones, spring H + i·(n+1) + j joining (i, j)–(i+1, j),
// with H = (m+1)·n. a/b are kept for code that walks edges generically (export, Jacobians).
// Identical sheets share one Topology (Jolt's shared settings vs per-instance state).
template <class Real>
struct Topology {
  std::uint32_t m = 0, n = 0;
  std::vector<std::uint32_t> a, b;
  std::vector<Real> rest_length;  // ℓ per spring, m
  std::vector<Real> stiffness;    // k per spring, N/m

  // Set when every spring has one stiffness and each direction one rest length (any sheet
  // without stiffness regions): the spring kernel then reads constants instead of two
  // arrays, chosen once per sheet. Empty means per spring, which is always correct.
  struct Uniform {
    Real stiffness, rest_h, rest_v;
    friend bool operator==(const Uniform&, const Uniform&) = default;
  };
  std::optional<Uniform> uniform;

  // Terms beyond the paper's grid springs that depend only on the definition (terms.h).
  // Empty: the sheet does not have the term.
  struct Shear {
    Real stiffness, rest;
    friend bool operator==(const Shear&, const Shear&) = default;
  };
  std::optional<Shear> shear;
  std::optional<Real> bending;  // k_b

  std::uint32_t cols() const { return n + 1; }
  // A row of Sheet::row_scratch: the row's n horizontal spring forces (forces.cpp) from
  // scratch_pad on, between zeros at scratch_pad − 1 and scratch_pad + n; the pad and the
  // length are whole cache lines, so the springs' vector stores start on one.
  static constexpr std::uint32_t scratch_pad = 64 / sizeof(Real);
  std::uint32_t scratch_cols() const { return scratch_pad + (cols() + scratch_pad - 1) / scratch_pad * scratch_pad; }
  std::uint32_t rows() const { return m + 1; }
  std::uint32_t points() const { return rows() * cols(); }
  std::uint32_t horizontal_count() const { return rows() * n; }
  std::uint32_t springs() const { return static_cast<std::uint32_t>(a.size()); }

  friend bool operator==(const Topology&, const Topology&) = default;

  // Fills `uniform` from the arrays; call after the last change to them.
  void find_uniform() {
    uniform.reset();
    const std::size_t h = horizontal_count();
    if (rest_length.empty()) return;
    const Real k = stiffness.front(), rh = h > 0 ? rest_length.front() : Real(0);
    const Real rv = rest_length.size() > h ? rest_length[h] : Real(0);
    for (std::size_t e = 0; e < rest_length.size(); ++e)
      if (stiffness[e] != k || rest_length[e] != (e < h ? rh : rv)) return;
    uniform = Uniform{k, rh, rv};
  }
};

// Air on a sheet (terms/air.h): its coefficients times ½ρ, and the wind, which the world
// sets from WorldDef::wind.
template <class Real>
struct Air {
  Real pressure = 0;  // ½ ρ C_n
  Real friction = 0;  // ½ ρ C_t
  Real wind[3] = {0, 0, 0};
  double drag_coefficient = 0, friction_coefficient = 0;  // C_n, C_t, to redo the products when ρ changes
};

template <class Real>
struct Sheet;
template <class Real>
void set_wind(Sheet<Real>& sheet, const Wind& wind);

template <class Real>
struct Anchors {  // eq (8), structure of arrays
  std::vector<std::uint32_t> point;
  std::vector<Real> tx, ty, tz, stiffness;
  bool empty() const { return point.empty(); }
};

template <class Real>
struct Pins {
  std::vector<std::uint32_t> point;
  std::vector<Real> tx, ty, tz;
  bool empty() const { return point.empty(); }
};

template <class Real>
using AlignedArray = std::vector<Real, CacheAligned<Real>>;

// Three parallel arrays, the unit every kernel reads and writes.
template <class Real>
struct Vec3Array {
  AlignedArray<Real> x, y, z;
  void resize(std::size_t count, Real value = Real(0)) {
    x.assign(count, value);
    y.assign(count, value);
    z.assign(count, value);
  }
};

// Implicit Euler's assembled system and solver (implicit.h); built on a sheet's first
// implicit step and reused by every later one.
template <class Real>
struct ImplicitScratch;
// Local/global's factored system (local_global.h), rebuilt only when what it depends on changes;
// vertex block descent's adjacency and colours (vertex_block.h).
struct LocalGlobalScratch;
struct VertexBlockScratch;

// The last solve of an implicit integrator on a sheet: iterations, relative residual,
// whether it reached its tolerance, and how many of the sheet's solves so far did not.
// All zero (and converged) before the first implicit step.
struct SolveStats {
  int iterations = 0;
  double relative_residual = 0;
  bool converged = true;
  std::uint64_t unconverged_solves = 0;
};

template <class Real>
struct Sheet {
  std::shared_ptr<const Topology<Real>> topology;
  Vec3Array<Real> position, velocity;
  Vec3Array<Real> force;              // scratch of the force kernels
  AlignedArray<Real> mass, inv_mass;  // per point
  AlignedArray<Real> damping;         // per point; empty: the sheet has no damping term
  Anchors<Real> anchors;
  Pins<Real> pins;
  std::optional<Air<Real>> air;
  Vec3Array<Real> row_scratch;       // a row's horizontal spring forces, Topology::scratch_cols per row
  std::vector<Real> integrator_scratch;  // extra state an integrator may keep (RK4's stages)
  // Shared between copies of a sheet only until one of them steps implicitly again: the
  // integrator replaces a scratch it does not own alone (implicit.cpp).
  std::shared_ptr<ImplicitScratch<Real>> implicit_scratch;
  std::shared_ptr<LocalGlobalScratch> local_global_scratch;  // the same sharing rule
  std::shared_ptr<VertexBlockScratch> vertex_block_scratch;  // the same sharing rule
  SolveStats last_solve;
  // Contact forces of this substep, gathered by the host stage in fixed pair order;
  // sheet_forces adds them only when has_contacts (a per-sheet, not per-point, choice).
  Vec3Array<Real> contact_force;
  bool has_contacts = false;
  bool self_collision = false;
  double friction = 0;  // μ (SheetDef::friction)
  // How far the sheet has travelled, for the contact stage (contacts.h, advance_travel): the
  // sum, over the substeps it spent in some pair, of the largest distance any of its points
  // moved since the last of them, and its positions then. No two of its points can have
  // moved farther apart than the growth of `travel` between two of those substeps.
  double travel = 0;
  Vec3Array<Real> travel_from;
  // Where the sheet is on that scale in the substep `moved_stamp` (measure_travel): within
  // `moved` of `moved_travel` (the travel then), `moved` the largest distance of a point from
  // travel_from, rounded up (∞ unknown or not a number). No point moved farther between two
  // measured substeps than the later moved_travel + moved less the earlier moved_travel − moved.
  double moved = std::numeric_limits<double>::infinity(), moved_travel = 0;
  std::uint64_t moved_stamp = 0;
  double moved_lo() const { return moved_travel - moved; }
  double moved_hi() const { return moved_travel + moved; }
  // Obstacles whose reach overlaps this sheet's bounding box, chosen by the world's host
  // stage every substep (the world clears these lists whenever its obstacle pool changes).
  std::vector<NearObstacle> near_obstacles;

  std::size_t size() const { return position.x.size(); }
};

// Builds a sheet from a validated definition. The topology is built fresh; the world
// swaps in a shared equal one when it has it.
template <class Real>
Sheet<Real> build_sheet(const SheetDef& def);

// The world's wind into a sheet with air (nothing for a sheet without).
template <class Real>
void set_wind(Sheet<Real>& s, const Wind& wind) {
  if (!s.air) return;
  auto& a = *s.air;
  a.pressure = static_cast<Real>(0.5 * wind.density * a.drag_coefficient);
  a.friction = static_cast<Real>(0.5 * wind.density * a.friction_coefficient);
  a.wind[0] = static_cast<Real>(wind.velocity.x);
  a.wind[1] = static_cast<Real>(wind.velocity.y);
  a.wind[2] = static_cast<Real>(wind.velocity.z);
}

}  // namespace drape::detail
