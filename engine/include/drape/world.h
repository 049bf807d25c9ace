// BasicWorld<Real>: owns every sheet's structure-of-arrays buffers and steps them.
// Callers hold SheetIds, never pointers. A sheet's buffers never move while it is in the
// world: spans returned by view()/state() stay valid until that sheet is removed (stepping,
// adding and removing other sheets never reallocate them), or longer with take_sheet.
// Real is the storage and arithmetic type of the hot loops (double or float).
#pragma once

#include <drape/constraint.h>
#include <drape/obstacle.h>
#include <drape/sheet.h>
#include <drape/types.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace drape {

// The most worker threads a world takes (WorldDef::threads): far beyond any core count, and
// below where oneTBB 2021's arena failed (a world of 70,000 crashed when destroyed).
inline constexpr int max_threads = 4096;

struct WorldDef {
  double dt = 1e-3;                    // s, one substep (with `adaptive`: the frame unit of step())
  Vec3 gravity{0.0, 0.0, -9.81};       // m/s²; z is up
  Integrator integrator = Integrator::SemiImplicitEuler;
  Wind wind{};                         // for sheets with SheetDef::air only
  int threads = 0;                     // worker threads for step(); 0: all cores; at most max_threads

  // Implicit Euler's conjugate-gradient solve: stop at relative residual |r|/|b| below
  // cg_tolerance or after cg_max_iterations iterations, whichever comes first. A solve
  // stopped by the cap is counted in solver_stats() and in the StabilityReport.
  // cg_preconditioner: see Preconditioner (types.h); Auto picks per sheet and step.
  double cg_tolerance = 1e-6;
  int cg_max_iterations = 200;
  Preconditioner cg_preconditioner = Preconditioner::Auto;

  // Local/global (Integrator::LocalGlobal): iterations per step, the method's one knob
  // (more: closer to the converged backward-Euler step; cost linear in it).
  // Its solve counts as converged when the step's backward-Euler residual is below cg_tolerance.
  int local_global_iterations = 10;
  // Vertex block descent (Integrator::VertexBlockDescent): Gauss–Seidel sweeps over the
  // colours per step, its one knob; converged as for local/global.
  int vertex_block_iterations = 10;

  // Adaptive stepping ("stable, as fast as possible"): an explicit integrator takes each
  // substep as adaptive_safety × its critical step (integrator_critical_step() on the
  // world's stiffest sheet), whatever dt says; step(n) then advances n·dt seconds in as many
  // equal substeps as that needs. Implicit Euler keeps dt.
  bool adaptive = false;
  double adaptive_safety = 0.8;  // in (0, 1]

  // Stability guard, run at the end of every step()/advance() call: a sheet whose state is
  // not finite, or (explicit integrators) whose total energy grew by more than
  // guard_energy_growth × its energy scale (see StabilityReport), halts the world and is
  // reported. Cost: one pass over points and springs per call, not per substep.
  bool guard = true;
  double guard_energy_growth = 10.0;

  // Contacts between sheets (engine/src/contacts.h): a point at distance d from another
  // sheet's surface feels E = c·exp(−(d − h)/ξ), cut off (continuously) at
  // d = h + contact_range·ξ; the force never exceeds (c/ξ)·exp(h/ξ), nor, for a pair whose
  // lightest point m the substep dt cannot hold against that stiffness, the force at the
  // exponent ln(m·ξ²/(c·dt²)) (at least the force at d = h), like the obstacles' cap. Sheets
  // whose boxes are farther apart than that distance cost nothing. contact_strength = 0: no
  // contacts.
  double contact_thickness = 0.005;  // h, m: the gap contacts keep between surfaces
  double contact_xi = 0.002;         // ξ, m: how fast the repulsion decays with distance
  double contact_strength = 1e-3;    // c, J: the barrier at d = 0 is c·exp(h/ξ) ≈ 0.012 J
  double contact_range = 6.0;        // cut-off beyond h, in units of ξ
  // α, s/m: Hunt–Crossley damping of the repulsion, which becomes F·(1 − α·ḋ) with ḋ the
  // rate at which the gap grows: surfaces that meet at speed v lose about a fraction of their
  // approach energy that grows with α·v, and layers resting on each other stop bouncing. The
  // damping coefficient α·F is capped where the substep could not resolve it, and the force
  // is never attractive. The default lets layers of cloth pinned or resting near each other
  // come to rest (with 0 the points beside pinned corners rattle against the next layer at
  // metres per second); 0: the repulsion alone, which conserves energy.
  double contact_damping = 2.0;
  // Between two searches for contacts, each point near another sheet follows its nearest
  // triangle by walking across that sheet's grid from the triangle it had (fast, and the
  // nearest triangle wherever the other sheet is not folded within contact range of the
  // point); true: every point tests every cell within reach instead, the exact nearest
  // triangle at several times the cost (the reference the walk is tested against).
  bool contact_exact = false;
  // Contacts are between points and triangles; with contact_rims the edges of each sheet's
  // rim (its outer rows and columns) also repel the other sheet's edges passing them within
  // the contact range, by the same law of the distance between the two edges, so an edge
  // cannot cut across another sheet's rim where no point comes near it (coarse grids, rims
  // hooking into each other; docs/architecture.md, sheets through each other). Off by
  // default: it costs a search of the rims' edges, and it doubles the contact at the rims
  // of stacked layers, which made a dense stack at a step where the contact's exponent cap
  // binds pass through itself more, not less.
  bool contact_rims = false;

  // A sheet of at least 2·block_points points is stepped as row blocks of about this many
  // points, so one large sheet keeps every core busy; the result is the same bit for bit.
  std::uint32_t block_points = 8192;

  // A step() of several substeps on sheets that contacts, obstacles or constraints couple
  // tries them in groups (the sheets in contact with each other or joined, each group
  // stepping the frame alone while its state is in cache, kept only if no two groups met)
  // in worlds of at least this many points whose groups hold at least an eighth of it each
  // on average (a thirty-second where groups cannot meet: no contacts, no obstacles); 0: in
  // every world.
  // The result is the same bit for bit either way (frame_stats() counts the tries).
  std::uint32_t group_points = 65536;
};

// Throws nothing: an empty string when the definition is usable, else one message naming
// the field, e.g. "cg_tolerance must be positive and finite (got 0)".
std::string validate(const WorldDef& def);

struct Energies {
  double kinetic = 0;  // ½ Σ m v²
  double spring = 0;   // ½ Σ k (|x1 − x2| − ℓ)², grid and shear springs
  double bending = 0;  // ½ k_b Σ |x_a − 2x_b + x_c|² (SheetDef::bending)
  double gravity = 0;  // −Σ m g·x (zero at the origin)
  double anchor = 0;   // ½ Σ k |x − p0|², eq (8)
  double obstacle = 0; // Σ c·exp(−f/ξ) over points and obstacles, eq (9) (cut off at 16ξ, linear past the cap)
  double total() const { return kinetic + spring + bending + gravity + anchor + obstacle; }
};

struct SheetDiagnostics {
  Energies energy;
  double max_strain = 0;  // max over springs of |ℓcur/ℓ − 1| (springs with ℓ = 0 skipped)
  bool finite = true;     // every position and velocity is finite
};

// How deep a sheet's deepest point lies inside an obstacle: −f there, in m (f is the
// distance from the surface for a plane, sphere, torus and box; for an ellipsoid its
// smallest semi-axis times the scaled radius less 1, near the distance close to the
// surface). A point gets inside when it arrives faster than the potential stops it
// (docs/scene-format.md, safe speeds) or rests on a potential too weak for its weight.
struct ObstaclePenetration {
  double depth = 0;     // m; 0 when every point is outside every obstacle
  ObstacleId obstacle;  // the obstacle it is inside (of several, the deepest); invalid when depth is 0
  std::uint32_t point = 0;  // the sheet's point that lies deepest
};

// Two sheets passing through each other, or a sheet through itself (World::sheet_crossings):
// an edge of one surface crosses a triangle of the other, each cell split into the two
// triangles the contacts use. Contacts keep surfaces about contact_thickness apart, so a
// crossing means points met faster than the contact stops them (the safe speeds in
// docs/scene-format.md), a load pressed them through, or they started through each other;
// the repulsion then holds them so, each point pushed away from the surface it is behind.
struct SheetCrossing {
  SheetId a, b;           // a before b in sheets(); a == b: a self-colliding sheet through itself
  std::size_t edges = 0;  // edge–triangle crossings between them, either sheet's edges
  // Of one crossing (the same one on every run): the point of a and the point of b
  // nearest where the edge meets the triangle.
  std::uint32_t point_a = 0, point_b = 0;
};

// Read-only, zero-copy view of one sheet's state; row-major point order of eqs (2)–(3).
template <class Real>
struct SheetView {
  std::uint32_t m = 0, n = 0;
  std::span<const Real> x, y, z;
  std::span<const Real> vx, vy, vz;
  std::size_t size() const { return x.size(); }
};

// Mutable view: writes take effect at the next step. Pinned points are reset to their pin.
template <class Real>
struct SheetState {
  std::uint32_t m = 0, n = 0;
  std::span<Real> x, y, z;
  std::span<Real> vx, vy, vz;
  std::size_t size() const { return x.size(); }
};

// A sheet taken out of a world (BasicWorld::take_sheet): it owns the sheet's buffers, moved
// out unchanged, so spans that view() and state() gave for it stay valid (showing its last
// state) while this object lives. Movable; empty when default-constructed.
template <class Real>
class RemovedSheet {
 public:
  RemovedSheet() = default;
  RemovedSheet(std::shared_ptr<const void> storage, SheetView<Real> view) : storage_(std::move(storage)), view_(view) {}
  const SheetView<Real>& view() const { return view_; }
  bool empty() const { return storage_ == nullptr; }

 private:
  std::shared_ptr<const void> storage_;
  SheetView<Real> view_;
};

enum class StabilityStatus {
  Stable,        // every sheet finite, no energy growth beyond the guard's limit
  EnergyGrowth,  // finite, but energy grew past WorldDef::guard_energy_growth: blowing up
  NonFinite,     // a position or velocity is NaN or infinite
};

// The stiffest term of a failing sheet, the one its stable step comes from.
enum class StepLimit {
  Springs,  // its springs and anchors (every integrator but the implicit ones is bound by them)
  // the sheet–sheet contact (a sheet that met others or collides with itself): at the contact
  // thickness its stiffness is contact_strength/contact_xi², which its lightest point must
  // hold. Every integrator applies the contact force explicitly, so no integrator resolves
  // it: only a shorter step or a softer contact (a larger contact_xi; a smaller
  // contact_strength also lowers the barrier that keeps fast sheets apart).
  Contact,
};

// What the stability guard found. For a failure: the first failing sheet (in the order the
// sheets were added), when it was detected and how bad it was, and what would be stable.
//
// energy_growth is dimensionless: 1 + (E − E₀)/S. E is the sheet's total energy (kinetic +
// spring + bending + gravity + anchors + obstacles); E₀ its value when the guard took its reference: at
// add_sheet, and again at the first step after state()/set_state() handed out the state,
// after obstacles were added or removed, or after the stepping changed (set_dt, ...). S is
// the energy scale at that reference: kinetic + spring + bending + anchor + obstacle energy, and at
// least the work gravity does over the sheet's extent (≥ 1 mm) and what rounding makes a
// sheet at rest vibrate with. Energy that only changes form (a sheet falling) leaves E − E₀
// near 0 however large it gets. 1 means energy conserved, below 1 dissipation; an unstable
// explicit step grows it geometrically. Sheets that came within contact range of each other
// since their references, or are joined point to point, pass energy between them: their
// growth is that of their sums, and the one whose energy grew most is reported.
// Implicit Euler is halted only by non-finite state: at steps that move points by a sizeable
// part of a spring its linearisation can add energy for a step, which then decays.
struct StabilityReport {
  StabilityStatus status = StabilityStatus::Stable;
  SheetId sheet;                // invalid when stable
  std::uint64_t step = 0;       // substeps taken when detected
  double time = 0;              // s, simulated, when detected
  double energy_growth = 1;     // of the reported sheet (the largest over sheets when stable)
  Integrator integrator = Integrator::SemiImplicitEuler;  // in use
  double dt = 0;                // s, the substep in use
  // The largest step the integrator in use takes stably on that sheet (estimate, safety
  // applied), from its stiffest term; and the cheapest integrator stable at the step in use
  // (semi-implicit Euler, RK4, else implicit Euler; forward Euler is never suggested; with
  // StepLimit::Contact the integrator in use, as none resolves the contact).
  double stable_dt = 0;
  Integrator stable_integrator = Integrator::ImplicitEuler;
  StepLimit step_limit = StepLimit::Springs;
  // Implicit integrators: solves, over all sheets since they were added, that stopped
  // before reaching their tolerance (solver_stats() has each sheet's last one).
  std::uint64_t unconverged_solves = 0;
  bool ok() const { return status == StabilityStatus::Stable; }
};

// One line for a person, with what to change, e.g. "sheet 2: energy grew 3.1e+05-fold by step
// 1200 (t = 1.2 s) with forward_euler at dt = 0.001 s; stable below dt ~ 0.00021 s
// (estimate), or use implicit_euler at this dt". Where the step in use is within the stable
// step of every term the guard knows (state written between steps, say), it says so.
std::string describe(const StabilityReport& report);

template <class Real>
class BasicWorld {
 public:
  using Scalar = Real;

  explicit BasicWorld(const WorldDef& def = {});
  ~BasicWorld();
  BasicWorld(BasicWorld&&) noexcept;
  BasicWorld& operator=(BasicWorld&&) noexcept;
  BasicWorld(const BasicWorld&) = delete;
  BasicWorld& operator=(const BasicWorld&) = delete;

  // Throws std::invalid_argument with validate()'s message for a bad definition.
  SheetId add_sheet(const SheetDef& def);
  // Removes the sheet, its constraints and its contact work; spans of it become invalid.
  void remove_sheet(SheetId id);
  // remove_sheet that hands over the sheet's buffers instead of freeing them: spans of it
  // taken before stay valid while the result lives (what keeps a removed sheet's NumPy
  // arrays readable in Python).
  RemovedSheet<Real> take_sheet(SheetId id);
  bool contains(SheetId id) const;
  std::size_t sheet_count() const;
  std::vector<SheetId> sheets() const;  // in the order they were added

  // Obstacles (eq 9). Throws std::invalid_argument with validate()'s message for a bad
  // definition. Only sheets whose bounding box comes within the obstacle's reach pay for it.
  ObstacleId add_obstacle(const ObstacleDef& def);
  void remove_obstacle(ObstacleId id);
  bool contains(ObstacleId id) const;
  std::size_t obstacle_count() const;
  std::vector<ObstacleId> obstacles() const;  // in the order they were added
  const ObstacleDef& obstacle(ObstacleId id) const;

  // Constraints (paper §5.2, constraint.h). Throws std::invalid_argument with validate()'s
  // message for a bad definition. A path or frame constraint keeps its points' offsets from
  // the motion's pose at time() when it is added. Removing a sheet removes the constraints
  // on it; removing an obstacle removes the frame constraints it carries. Every constrained
  // point's target is written at the start of each substep; in a frame of several substeps
  // (step(n)) of a world of at least def().group_points points, the sheets a join holds step
  // it together and a constrained sheet in a group of its own, or with the sheets it touches
  // (frames of groups, below). A world with a moving obstacle, or a constraint following a
  // callback motion, steps substep by substep. Either way the result does not depend on the
  // thread count, and step(n) equals n calls of step(1).
  ConstraintId add_constraint(const ConstraintDef& def);
  void remove_constraint(ConstraintId id);
  bool contains(ConstraintId id) const;
  std::size_t constraint_count() const;
  std::vector<ConstraintId> constraints() const;  // in the order they were added
  const ConstraintDef& constraint(ConstraintId id) const;

  SheetView<Real> view(SheetId id) const;
  SheetState<Real> state(SheetId id);

  // Advances every sheet by `substeps` (≥ 0, else std::invalid_argument) steps of def().dt
  // (with def().adaptive: by substeps·dt seconds in adaptive substeps, see WorldDef), then
  // runs the stability guard when def().guard is on. A halted world (the guard failed) does
  // not step until set_dt/set_integrator/set_adaptive; it returns the failure again. step(n)
  // gives the same bits as n calls of step(1), and is faster: substeps that nothing couples
  // (no contact, no obstacle near) run while each sheet is in cache (docs/architecture.md).
  StabilityReport step(int substeps = 1);
  // Advances by `seconds` in equal substeps no longer than the step in use (def().dt, or the
  // adaptive step), landing exactly on time() + seconds; then the guard as in step().
  // std::invalid_argument for a negative or non-finite time, or one needing more than 2^53
  // substeps.
  StabilityReport advance(double seconds);

  // The guard's check of the present state, without stepping; cost O(points + springs).
  StabilityReport check() const;
  bool halted() const;

  // The substep the next step()/advance() would take at most (dt, or the adaptive step).
  double substep_dt() const;

  // The per-frame loop of an embedding program: `frames` times, step(substeps_per_frame),
  // then on_frame(frame) with frame = 1, 2, ... . The callback may read view(), write
  // state(), add or remove sheets; if it returns bool, false stops the run early. A frame
  // whose step the guard fails ends the run before its callback (halted() and check() say
  // why). Returns the number of frames run, each handed to on_frame.
  template <class OnFrame>
  int run_frames(int frames, int substeps_per_frame, OnFrame&& on_frame) {
    for (int frame = 1; frame <= frames; ++frame) {
      if (!step(substeps_per_frame).ok()) return frame - 1;
      if constexpr (std::is_same_v<std::invoke_result_t<OnFrame&, int>, bool>) {
        if (!on_frame(frame)) return frame;
      } else {
        on_frame(frame);
      }
    }
    return frames;
  }

  const WorldDef& def() const;
  void set_integrator(Integrator integrator);
  void set_dt(double dt);
  void set_adaptive(bool adaptive, double safety = 0.8);
  void set_cg(double tolerance, int max_iterations);

  // The last solve of an implicit integrator on this sheet (all zero before the first):
  // implicit Euler's conjugate gradient, or local/global's iterations with the residual of
  // the backward-Euler equations they leave. converged: the residual reached cg_tolerance;
  // unconverged_solves: how many of this sheet's solves so far did not.
  struct SolverStats {
    int iterations = 0;
    double relative_residual = 0;
    bool converged = true;
    std::uint64_t unconverged_solves = 0;
  };
  SolverStats solver_stats(SheetId id) const;
  // Puts back what solver_stats() returned, e.g. from a checkpoint, so the counts of a
  // resumed run go on from where they were.
  void set_solver_stats(SheetId id, const SolverStats& stats);
  // s, simulated: step_count()·dt while the substep never changed (runs of equal substeps
  // are exact; advance() and adaptive steps add their own lengths)
  double time() const;
  // Worker threads of step(); 0: all cores. Results do not depend on it, bit for bit.
  void set_threads(int threads);
  // Overlapping sheet pairs (including a sheet with itself when self_collision is on) that
  // the last substep's host stage handed to the contact stage (0 after a frame of substeps
  // that no contact coupled).
  std::size_t contact_pair_count() const;
  std::uint64_t step_count() const;   // substeps taken
  // How step() ran its frames (calls of more than one substep, in tries of up to 32) on
  // sheets that contacts or obstacles could couple: each try steps the sheets ahead in
  // groups of sheets in contact (a sheet near nothing on its own), kept if no two groups came
  // within range of each other, nor a lone sheet within an obstacle's reach; undone ones
  // were stepped again substep by substep (computed twice). docs/architecture.md, "Frames
  // of groups".
  struct FrameStats {
    std::uint64_t kept = 0, undone = 0;
  };
  FrameStats frame_stats() const;

  // Full state, for checkpoints. Everything step() changes is the step count, each sheet's
  // positions and velocities, the integrator's memory of each sheet and the contact
  // stage's memory; copying these out
  // and back into a world built from the same definitions (same sheets added in the same
  // order, same WorldDef) continues bit for bit. The engine does no I/O: a caller stores
  // the spans as it likes (apps/common/checkpoint.h is one format).
  void set_step_count(std::uint64_t steps);
  // Copies positions and velocities into the sheet. Every span of `from` must hold exactly
  // the sheet's point count (else std::invalid_argument). As with state(), pinned points
  // go back to their pins at the next step.
  void set_state(SheetId id, const SheetView<Real>& from);
  // Values an integrator carries from one substep to the next (may be empty; its size may
  // change when the integrator does). set_integrator_memory replaces them.
  std::span<const Real> integrator_memory(SheetId id) const;
  void set_integrator_memory(SheetId id, std::span<const Real> memory);
  // What the contact stage carries from one substep to the next (each pair's kept contact
  // sets and lists, when it searches next, how far each sheet has travelled): without it a
  // world in contact searches afresh and may continue differently. Opaque words, valid only
  // for a world built from the same definitions. set_contact_memory checks them (else
  // std::invalid_argument naming the problem, the world unchanged); an empty span forgets:
  // the next substep searches.
  std::vector<std::uint64_t> contact_memory() const;
  void set_contact_memory(std::span<const std::uint64_t> memory);

  SheetDiagnostics diagnostics(SheetId id) const;
  // The deepest any point of the sheet lies inside an obstacle now: one pass over the points
  // near each obstacle (the broad phase's box test first), O(points) per obstacle reached.
  ObstaclePenetration obstacle_penetration(SheetId id) const;
  Energies energies() const;  // summed over sheets
  // Every pair of sheets that contacts could hold apart (contact_strength > 0; a sheet with
  // itself when self_collision is on) and that passes through each other now, in the order
  // of sheets(); empty when none does. Each pair whose boxes meet is searched edge by edge
  // against the other's triangles (exact orientation tests in double), about as costly as
  // contact_energy(): call it per frame, not per substep.
  std::vector<SheetCrossing> sheet_crossings() const;
  // The potential (J) of the sheet–sheet contacts, which energies() leaves out: for every
  // pair of sheets within contact range, both ways, and every self-colliding sheet against
  // itself, Σ over points of c·(e^((h − d)/ξ) − t) − c·t·(R − d)/ξ at the point's nearest
  // triangle within R (t = e^(−(R − h)/ξ): zero at R, its −gradient the repulsion; linear
  // where the exponent cap at dt binds). energies().total() + contact_energy() is the energy
  // the frictionless, undamped model conserves. An exact search of every such pair, as
  // costly as several substeps of sheets in contact: call it per frame, not per substep
  // (BM_ContactEnergy prices it). 0 without contacts.
  double contact_energy() const;
  bool all_finite() const;

  // Largest step at which the explicit integrators stay stable on this sheet, from a
  // Gershgorin bound on the highest spring frequency, ω_i² = Σk_i·2/m_i at point i, and the
  // damping rate of eq (4) there, γ_i = c_i/m_i: 2/ω_max with ω_max the largest
  // (γ_i + √(γ_i² + 4ω_i²))/2, which is ω_i undamped and γ_i for damping alone (semi-implicit
  // Euler on such a point is stable while ω²dt² + 2γdt < 4). (The interval of semi-implicit
  // Euler and Verlet; integrator_critical_step() scales it.)
  double stable_step_estimate(SheetId id) const;
  double stable_step_estimate() const;  // minimum over sheets; +inf for an empty world
  // integrator_critical_step(integrator, ω_max) of the stiffest sheet; +inf for an empty world.
  double critical_step(Integrator integrator) const;
  // The same interval for the sheet–sheet contact on this sheet: its stiffness at the contact
  // thickness, contact_strength/contact_xi², against the sheet's lightest point m, so
  // 2·contact_xi·√(m/contact_strength); +inf when contact_strength is 0. The contact's
  // exponent cap keeps it resolvable at any step up to this (architecture.md); beyond it a
  // contact may blow up whatever the integrator, as every integrator applies the contact
  // force explicitly. Adaptive steps and the guard's report take it into account where
  // sheets may touch (docs/integrators.md).
  double contact_step_estimate(SheetId id) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

extern template class BasicWorld<double>;
extern template class BasicWorld<float>;

using World = BasicWorld<double>;
using WorldF = BasicWorld<float>;

}  // namespace drape
