// BasicWorld<Real>: owns every sheet's structure-of-arrays buffers and steps them.
// Callers hold SheetIds, never pointers; spans returned by view()/state() stay valid until
// the next add_sheet/remove_sheet on the same world (stepping never reallocates).
// Real is the storage and arithmetic type of the hot loops (double or float).
#pragma once

#include <drape/obstacle.h>
#include <drape/sheet.h>
#include <drape/types.h>

#include <cstdint>
#include <memory>
#include <span>
#include <type_traits>
#include <vector>

namespace drape {

struct WorldDef {
  double dt = 1e-3;                    // s, one substep
  Vec3 gravity{0.0, 0.0, -9.81};       // m/s²; z is up
  Integrator integrator = Integrator::SemiImplicitEuler;
  int threads = 0;                     // worker threads for step(); 0: all cores
};

struct Energies {
  double kinetic = 0;  // ½ Σ m v²
  double spring = 0;   // ½ Σ k (|x1 − x2| − ℓ)²
  double gravity = 0;  // −Σ m g·x (zero at the origin)
  double anchor = 0;   // ½ Σ k |x − p0|², eq (8)
  double obstacle = 0; // Σ c·exp(−f/ξ) over points and obstacles, eq (9) (linear past the cap)
  double total() const { return kinetic + spring + gravity + anchor + obstacle; }
};

struct SheetDiagnostics {
  Energies energy;
  double max_strain = 0;  // max over springs of |ℓcur/ℓ − 1| (springs with ℓ = 0 skipped)
  bool finite = true;     // every position and velocity is finite
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
  void remove_sheet(SheetId id);
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

  SheetView<Real> view(SheetId id) const;
  SheetState<Real> state(SheetId id);

  // Advances every sheet by `substeps` steps of def().dt.
  void step(int substeps = 1);

  // The per-frame loop of an embedding program: `frames` times, step(substeps_per_frame),
  // then on_frame(frame) with frame = 1, 2, ... . The callback may read view(), write
  // state(), add or remove sheets; if it returns bool, false stops the run early.
  // Returns the number of frames run.
  template <class OnFrame>
  int run_frames(int frames, int substeps_per_frame, OnFrame&& on_frame) {
    for (int frame = 1; frame <= frames; ++frame) {
      step(substeps_per_frame);
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
  double time() const;                // s, simulated: step_count()·dt
  std::uint64_t step_count() const;   // substeps taken

  // Full state, for checkpoints. Everything step() changes is the step count, each sheet's
  // positions and velocities, and the integrator's memory of each sheet; copying these out
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

  SheetDiagnostics diagnostics(SheetId id) const;
  Energies energies() const;  // summed over sheets
  bool all_finite() const;

  // Largest step at which the explicit integrators stay stable on this sheet, from a
  // Gershgorin bound on the highest spring frequency: 2/ω_max, ω_max² ≤ max_i Σk_i·2/m_i.
  double stable_step_estimate(SheetId id) const;
  double stable_step_estimate() const;  // minimum over sheets; +inf for an empty world

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

extern template class BasicWorld<double>;
extern template class BasicWorld<float>;

using World = BasicWorld<double>;
using WorldF = BasicWorld<float>;

}  // namespace drape
