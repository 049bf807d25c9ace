// Small value types shared by the whole public API: vectors, rotations, ids, enums.
// Everything here is a plain value; nothing owns engine storage.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string_view>

namespace drape {

// A 3-vector in SI units (m, m/s, N, ...). Definitions use double; the world may store float.
struct Vec3 {
  double x = 0, y = 0, z = 0;
  friend constexpr bool operator==(const Vec3&, const Vec3&) = default;
};

// The air every sheet with SheetDef::air moves in: uniform, steady.
struct Wind {
  Vec3 velocity{};        // m/s
  double density = 1.2;   // ρ, kg/m³ (air at 20 °C)
  friend constexpr bool operator==(const Wind&, const Wind&) = default;
};

// A unit quaternion that rotates a sheet's local frame (grid in the local x–y plane,
// normal along local +z) into the world frame. Identity: the sheet lies flat, facing +z.
struct Quat {
  double w = 1, x = 0, y = 0, z = 0;
  friend constexpr bool operator==(const Quat&, const Quat&) = default;
};

Quat quat_from_axis_angle(Vec3 axis, double radians);
Vec3 rotate(const Quat& q, Vec3 v);

// Handles the world hands out. A handle is an index into the world's pool plus a
// generation, so a handle to a removed object is detected instead of aliasing a new one.
// One template for every kind of object; the kind only keeps a SheetId from being passed
// where an ObstacleId is expected.
template <class Tag>
struct Id {
  std::uint32_t index = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t generation = 0;
  constexpr bool is_valid() const { return index != std::numeric_limits<std::uint32_t>::max(); }
  friend constexpr bool operator==(Id, Id) = default;
};
struct SheetTag;
struct ObstacleTag;
using SheetId = Id<SheetTag>;
using ObstacleId = Id<ObstacleTag>;

// Time integrators. Each is described by one row of the integrator table
// (engine/src/integrate.cpp: name, order, explicit or not, stability, knobs, step function);
// adding one is a value here, its step function in a file of its own, and its row.
enum class Integrator {
  ForwardEuler,       // x += dt·v, v += dt·a (both from the old state): the paper's literal reading. Order 1.
  SemiImplicitEuler,  // v += dt·a, then x += dt·v_new: symplectic, the default. Order 1.
  VelocityVerlet,     // half kick, drift, half kick; two force evaluations per step. Order 2.
  RK4,                // classical Runge–Kutta on (x, v); four force evaluations per step. Order 4.
  ImplicitEuler,      // backward Euler linearised once per step (Baraff & Witkin 1998), PCG solve. Order 1.
  LocalGlobal,        // backward Euler by local/global iterations (Liu et al. 2013), fixed budget. Order 1.
  VertexBlockDescent, // backward Euler by per-point Newton steps over colours (Chen et al. 2024), fixed budget. Order 1.
};

// Implicit Euler's preconditioner for its conjugate-gradient solve (WorldDef::cg_preconditioner).
enum class Preconditioner {
  Auto,         // block Jacobi while dt·ω_max ≤ 10 (ω_max: the sheet's stiffest mode, as in
                // stable_step_estimate), else Cholesky: the cheaper of the two on 64×64 and 128×128
  BlockJacobi,  // the inverse 3×3 diagonal blocks: cheap iterations, but their number grows
                // with dt·ω_max and stops at the cap on stiff sheets
  Cholesky,     // a sparse Cholesky factor of the step's own matrix, factored every step (in
                // float, in double where float's does not serve): a few iterations at any stiffness
};
std::string_view preconditioner_name(Preconditioner preconditioner);  // "auto", "block_jacobi", "cholesky"
std::optional<Preconditioner> preconditioner_from_name(std::string_view name);

// One integrator's row of the table, as a caller may read it.
struct IntegratorInfo {
  Integrator integrator;
  std::string_view name;       // the scene files' and the CLI's name
  int order;                   // global order of the positions at a fixed time
  bool is_explicit;            // explicit: stable only below integrator_critical_step
  std::string_view stability;  // the stability limit, in words
  std::string_view knobs;      // the WorldDef fields it reads beyond dt and gravity
};

// Every integrator, in the enum's order.
std::span<const IntegratorInfo> integrator_table();
std::span<const Integrator> integrators();
const IntegratorInfo& integrator_info(Integrator integrator);  // throws std::out_of_range for a value not in the table

std::string_view integrator_name(Integrator integrator);  // "unknown" for a value not in the table
std::optional<Integrator> integrator_from_name(std::string_view name);

// Global order of accuracy of the integrator's positions at a fixed time (1, 1, 2, 4, 1, 1, 1).
int integrator_order(Integrator integrator);
bool integrator_is_explicit(Integrator integrator);

// Largest step the integrator takes stably when the stiffest mode has angular frequency
// omega_max (rad/s), undamped:
//   semi-implicit Euler and velocity Verlet: ω·dt < 2 (their stability interval);
//   RK4: ω·dt < 2√2 (where its stability region crosses the imaginary axis);
//   forward Euler: no step is stable without damping (the amplification is √(1 + ω²dt²) > 1);
//     it returns the step at which the stiffest mode's energy at most doubles per simulated
//     second, ln 2 / ω² (from (1 + ω²dt²)^(1/dt) ≈ exp(ω²dt));
//   implicit Euler, local/global and vertex block descent: +inf (unconditionally stable).
double integrator_critical_step(Integrator integrator, double omega_max);
// The same for a force every integrator applies explicitly (the sheet–sheet contact): the
// explicit integrators' own step, semi-implicit Euler's for the implicit ones.
double explicit_force_critical_step(Integrator integrator, double omega);

}  // namespace drape
