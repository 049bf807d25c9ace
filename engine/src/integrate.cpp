// Explicit integrators for M ẍ + C ẋ = f(x) − f_spr(x) (eq 4), M and C diagonal, so every
// update is per point and linear in the number of points (paper §4), and the integrator
// table that describes every integrator. Implicit Euler lives in implicit.cpp,
// local/global in local_global.cpp.
#include "integrate.h"

#include "forces.h"
#include "implicit.h"
#include "local_global.h"
#include "vertex_block.h"
#include "simd/kernels.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <type_traits>

namespace drape::detail {

namespace {

// Hard pins (hold_pin) among points [begin, end), the range a block of the world updated.
template <class Real>
void apply_pins(Sheet<Real>& s, std::size_t begin = 0, std::size_t end = SIZE_MAX) {
  const auto& pins = s.pins;
  for (std::size_t k = 0; k < pins.point.size(); ++k)
    if (pins.point[k] >= begin && pins.point[k] < end) hold_pin(pins, k, ptr(s.position), ptr(s.velocity), pins.point[k]);
}

// The first-order step of an integrator: forward Euler (x and v both advance from the old
// state) or semi-implicit Euler (the new velocity moves the point), simd/kernels.h.
template <class Real>
simd::EulerStep<Real> euler_step(const StepParams<Real>& p, bool semi_implicit) {
  return {p.dt, p.gx, p.gy, p.gz, semi_implicit};
}

// Each row is updated as soon as its force is final, in the same sweep and on the same
// instruction set (sheet_forces_by_rows), so forces never leave the cache.
// `box`, when given, grows to contain the new positions and the pins' targets
// (sheet_forces_by_rows).
template <class Real>
void first_order_step(Sheet<Real>& s, const StepParams<Real>& p, bool semi_implicit,
                      simd::Extent<Real>* box = nullptr) {
  const simd::EulerStep<Real> step = euler_step(p, semi_implicit);
  sheet_forces_by_rows(s, cptr(s.position), cptr(s.velocity), ptr(s.force), &step, box);
}

// Whether an update can grow the sheet's box as it moves the points (update_around_pins
// walks the pins in order).
template <class Real>
bool box_in_update(const Sheet<Real>& s) {
  return s.size() > 0 && std::is_sorted(s.pins.point.begin(), s.pins.point.end());
}

// a = f(x, v)/m + g into s.force, with pinned points held at zero acceleration so that
// intermediate stages (Verlet's drift, RK4's stages) never move a pin.
template <class Real>
void accelerations(Sheet<Real>& s, const StepParams<Real>& p, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v) {
  sheet_forces(s, x, v, ptr(s.force));
  const std::size_t count = s.size();
  const Real* inv_mass = s.inv_mass.data();
  Real* f[3] = {s.force.x.data(), s.force.y.data(), s.force.z.data()};
  const Real g[3] = {p.gx, p.gy, p.gz};
  for (int k = 0; k < 3; ++k) {
    Real* __restrict a = f[k];
    for (std::size_t i = 0; i < count; ++i) a[i] = a[i] * inv_mass[i] + g[k];
  }
  for (std::uint32_t q : s.pins.point) f[0][q] = f[1][q] = f[2][q] = Real(0);
}

// Velocity Verlet (kick–drift–kick). The force at the start of the step is recomputed
// rather than carried over from the previous step, because anything may have changed in
// between (state writes, contacts gathered by the host stage, a switch of integrator).
template <class Real>
void velocity_verlet_step(Sheet<Real>& s, const StepParams<Real>& p) {
  const std::size_t count = s.size();
  const Real half = p.dt / Real(2);
  Real* x[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  Real* v[3] = {s.velocity.x.data(), s.velocity.y.data(), s.velocity.z.data()};
  const Real* a[3] = {s.force.x.data(), s.force.y.data(), s.force.z.data()};
  accelerations(s, p, cptr(s.position), cptr(s.velocity));
  for (int k = 0; k < 3; ++k) {
    Real* __restrict xk = x[k];
    Real* __restrict vk = v[k];
    const Real* __restrict ak = a[k];
    for (std::size_t i = 0; i < count; ++i) {
      vk[i] += half * ak[i];
      xk[i] += p.dt * vk[i];
    }
  }
  // the damping term sees the half-step velocity: Verlet's second order holds for forces of x only
  accelerations(s, p, cptr(s.position), cptr(s.velocity));
  for (int k = 0; k < 3; ++k) {
    Real* __restrict vk = v[k];
    const Real* __restrict ak = a[k];
    for (std::size_t i = 0; i < count; ++i) vk[i] += half * ak[i];
  }
}

// Classical RK4 on the first-order system (x, v)' = (v, a(x, v)). Scratch, 12 values per
// point in integrator_scratch: stage position and velocity, and the weighted sums of the
// four slopes of x and of v. The sheet's own position/velocity hold the start state.
template <class Real>
void rk4_step(Sheet<Real>& s, const StepParams<Real>& p) {
  const std::size_t count = s.size();
  if (s.integrator_scratch.size() != 12 * count) s.integrator_scratch.assign(12 * count, Real(0));
  Real* base = s.integrator_scratch.data();
  auto block = [&](int k) { return base + std::size_t(k) * count; };
  Real* xs[3] = {block(0), block(1), block(2)};
  Real* vs[3] = {block(3), block(4), block(5)};
  Real* sx[3] = {block(6), block(7), block(8)};
  Real* sv[3] = {block(9), block(10), block(11)};
  Real* x0[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  Real* v0[3] = {s.velocity.x.data(), s.velocity.y.data(), s.velocity.z.data()};
  const Real* a[3] = {s.force.x.data(), s.force.y.data(), s.force.z.data()};
  const Real h = p.dt, h2 = p.dt / Real(2);

  // Stages 1–3: slope (v_s, a_s) at the stage state; add it with weight 1, 2, 2; set up the
  // next stage at x0 + next·v_s, v0 + next·a_s. Stage 1's state is the start state itself.
  std::fill(base + 6 * count, base + 12 * count, Real(0));
  const Real weights[3] = {Real(1), Real(2), Real(2)};
  const Real nexts[3] = {h2, h2, h};
  for (int stage = 0; stage < 3; ++stage) {
    Real* const* stage_v = stage == 0 ? v0 : vs;
    if (stage == 0)
      accelerations(s, p, cptr(s.position), cptr(s.velocity));
    else
      accelerations(s, p, ConstVec3Ptr<Real>{xs[0], xs[1], xs[2]}, ConstVec3Ptr<Real>{vs[0], vs[1], vs[2]});
    const Real weight = weights[stage], next = nexts[stage];
    for (int k = 0; k < 3; ++k) {
      const Real* __restrict xk = x0[k];
      const Real* __restrict vk = v0[k];
      const Real* __restrict ak = a[k];
      const Real* cv = stage_v[k];  // may be vs[k], written below in the same iteration only
      Real* xsk = xs[k];
      Real* vsk = vs[k];
      Real* __restrict sxk = sx[k];
      Real* __restrict svk = sv[k];
      for (std::size_t i = 0; i < count; ++i) {
        const Real vi = cv[i], ai = ak[i];
        sxk[i] += weight * vi;
        svk[i] += weight * ai;
        xsk[i] = xk[i] + next * vi;
        vsk[i] = vk[i] + next * ai;
      }
    }
  }
  // stage 4 and the weighted update
  accelerations(s, p, ConstVec3Ptr<Real>{xs[0], xs[1], xs[2]}, ConstVec3Ptr<Real>{vs[0], vs[1], vs[2]});
  const Real w = h / Real(6);
  for (int k = 0; k < 3; ++k) {
    Real* __restrict xk = x0[k];
    Real* __restrict vk = v0[k];
    const Real* __restrict ak = a[k];
    const Real* __restrict vsk = vs[k];
    const Real* __restrict sxk = sx[k];
    const Real* __restrict svk = sv[k];
    for (std::size_t i = 0; i < count; ++i) {
      xk[i] += w * (sxk[i] + vsk[i]);
      vk[i] += w * (svk[i] + ak[i]);
    }
  }
}

// Per-point first-order updates as whole-sheet steps, for the table.
template <class Real>
void forward_euler_step(Sheet<Real>& s, const StepParams<Real>& p) { first_order_step(s, p, false); }
template <class Real>
void semi_implicit_euler_step(Sheet<Real>& s, const StepParams<Real>& p) { first_order_step(s, p, true); }

double forward_euler_limit(double omega) { return std::numbers::ln2 / (omega * omega); }
double interval_two(double omega) { return 2.0 / omega; }
double rk4_limit(double omega) { return 2.0 * std::numbers::sqrt2 / omega; }
double unconditional(double) { return std::numeric_limits<double>::infinity(); }

// One row per integrator: what a caller reads (IntegratorInfo), then what the engine runs.
struct IntegratorRow {
  IntegratorInfo info;
  bool per_point;                        // updates_per_point(): forces once, then each point alone
  bool memoryless;                       // remembers_nothing(): a substep reads x and v only
  double (*critical_step)(double omega);  // integrator_critical_step() for ω_max > 0
  StepFunction<double> step_double;
  StepFunction<float> step_float;
};

#define DRAPE_STEP(f) &f<double>, &f<float>
constexpr IntegratorRow table[] = {
    {{Integrator::ForwardEuler, "forward_euler", 1, true, "no step without damping (amplification √(1 + ω²dt²))", ""},
     true, true, forward_euler_limit, DRAPE_STEP(forward_euler_step)},
    {{Integrator::SemiImplicitEuler, "semi_implicit_euler", 1, true, "ω·dt < 2", ""},
     true, true, interval_two, DRAPE_STEP(semi_implicit_euler_step)},
    {{Integrator::VelocityVerlet, "velocity_verlet", 2, true, "ω·dt < 2", ""},
     false, true, interval_two, DRAPE_STEP(velocity_verlet_step)},
    {{Integrator::RK4, "rk4", 4, true, "ω·dt < 2√2", ""}, false, true, rk4_limit, DRAPE_STEP(rk4_step)},
    {{Integrator::ImplicitEuler, "implicit_euler", 1, false, "any step", "cg_tolerance, cg_max_iterations, cg_preconditioner"},
     false, false, unconditional, DRAPE_STEP(implicit_euler_step)},
    {{Integrator::LocalGlobal, "local_global", 1, false, "any step", "local_global_iterations (cg_tolerance: converged)"},
     false, false, unconditional, DRAPE_STEP(local_global_step)},
    {{Integrator::VertexBlockDescent, "vertex_block_descent", 1, false, "any step",
      "vertex_block_iterations (cg_tolerance: converged)"},
     false, false, unconditional, DRAPE_STEP(vertex_block_step)},
};
#undef DRAPE_STEP

constexpr bool table_in_enum_order() {
  for (std::size_t k = 0; k < std::size(table); ++k)
    if (static_cast<std::size_t>(table[k].info.integrator) != k) return false;
  return true;
}
static_assert(table_in_enum_order(), "the integrator table has one row per Integrator, in the enum's order");

constexpr auto infos = [] {
  std::array<IntegratorInfo, std::size(table)> out{};
  for (std::size_t k = 0; k < std::size(table); ++k) out[k] = table[k].info;
  return out;
}();
constexpr auto values = [] {
  std::array<Integrator, std::size(table)> out{};
  for (std::size_t k = 0; k < std::size(table); ++k) out[k] = table[k].info.integrator;
  return out;
}();

const IntegratorRow* find_row(Integrator integrator) {
  const auto k = static_cast<std::size_t>(integrator);
  return k < std::size(table) ? &table[k] : nullptr;
}

const IntegratorRow& row_of(Integrator integrator) {
  const IntegratorRow* row = find_row(integrator);
  if (!row) throw std::out_of_range("drape: not an integrator");
  return *row;
}

}  // namespace

template <class Real>
void integrate(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p, Aabb* bounds) {
  const IntegratorRow& row = row_of(integrator);
  if (bounds && row.per_point && box_in_update(s)) {  // the box from the update's registers
    auto box = simd::Extent<Real>::none();
    first_order_step(s, p, integrator == Integrator::SemiImplicitEuler, &box);
    apply_pins(s);
    *bounds = empty_box();
    include_extent(*bounds, box);
    return;
  }
  if constexpr (std::is_same_v<Real, double>)
    row.step_double(s, p);
  else
    row.step_float(s, p);
  apply_pins(s);
  if (bounds) *bounds = sheet_bounds(s);  // a pass over the points
}

bool updates_per_point(Integrator integrator) { return row_of(integrator).per_point; }
bool remembers_nothing(Integrator integrator) { return row_of(integrator).memoryless; }

void record_solve(SolveStats& stats, int iterations, double relative_residual, bool converged) {
  stats.iterations = iterations;
  stats.relative_residual = relative_residual;
  stats.converged = converged;
  if (!converged) ++stats.unconverged_solves;
}

template <class Real>
void update_points(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p, std::size_t begin,
                   std::size_t end, simd::Extent<Real>* box) {
  // the same update as the whole-sheet step, on this block's points only (one dispatch per run)
  const bool first_order = integrator == Integrator::ForwardEuler || integrator == Integrator::SemiImplicitEuler;
  auto run = [&](std::size_t b, std::size_t e, simd::Extent<Real>* grow) {
    simd::update_points(simd::PointUpdate<Real>::of(e - b, s.position.x.data() + b, s.position.y.data() + b,
                                                    s.position.z.data() + b, s.velocity.x.data() + b,
                                                    s.velocity.y.data() + b, s.velocity.z.data() + b,
                                                    s.force.x.data() + b, s.force.y.data() + b, s.force.z.data() + b,
                                                    s.inv_mass.data() + b)
                            .step(euler_step(p, integrator == Integrator::SemiImplicitEuler))
                            .grow(grow));
  };
  const bool grows = box && first_order && begin < end && box_in_update(s);
  if (grows) {
    const auto& pins = s.pins.point;
    auto next_pin = std::size_t(std::lower_bound(pins.begin(), pins.end(), begin) - pins.begin());
    update_around_pins(s.pins, next_pin, begin, end, *box, run);
  } else if (first_order) {
    run(begin, end, nullptr);
  }
  // the other integrators: updates_per_point() keeps them whole, never split
  apply_pins(s, begin, end);
  if (box && !grows && begin < end)  // a pass over the block's points
    box->include(simd::points_extent(s.position.x.data() + begin, s.position.y.data() + begin,
                                     s.position.z.data() + begin, end - begin));
}

template <class Real>
void integrate_wave(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p, std::uint32_t levels,
                    std::uint32_t row_begin, std::uint32_t row_end, WaveScratch<Real>& scratch, Aabb* swept) {
  // updates_per_point() integrators only
  if (integrator != Integrator::ForwardEuler && integrator != Integrator::SemiImplicitEuler) return;
  sheet_wave(s, levels, row_begin, row_end, scratch, euler_step(p, integrator == Integrator::SemiImplicitEuler), swept);
}

template void integrate_wave<double>(Integrator, Sheet<double>&, const StepParams<double>&, std::uint32_t,
                                     std::uint32_t, std::uint32_t, WaveScratch<double>&, Aabb*);
template void integrate_wave<float>(Integrator, Sheet<float>&, const StepParams<float>&, std::uint32_t, std::uint32_t,
                                    std::uint32_t, WaveScratch<float>&, Aabb*);
template void update_points<double>(Integrator, Sheet<double>&, const StepParams<double>&, std::size_t, std::size_t,
                                    simd::Extent<double>*);
template void update_points<float>(Integrator, Sheet<float>&, const StepParams<float>&, std::size_t, std::size_t,
                                   simd::Extent<float>*);
template void integrate<double>(Integrator, Sheet<double>&, const StepParams<double>&, Aabb*);
template void integrate<float>(Integrator, Sheet<float>&, const StepParams<float>&, Aabb*);

}  // namespace drape::detail

namespace drape {

using detail::find_row;
using detail::row_of;

std::span<const IntegratorInfo> integrator_table() { return detail::infos; }
std::span<const Integrator> integrators() { return detail::values; }
const IntegratorInfo& integrator_info(Integrator integrator) {
  return detail::infos[static_cast<std::size_t>(row_of(integrator).info.integrator)];
}

std::string_view integrator_name(Integrator integrator) {
  const auto* row = find_row(integrator);
  return row ? row->info.name : std::string_view("unknown");
}

std::optional<Integrator> integrator_from_name(std::string_view name) {
  for (const IntegratorInfo& info : detail::infos)
    if (info.name == name) return info.integrator;
  return std::nullopt;
}

int integrator_order(Integrator integrator) { return row_of(integrator).info.order; }
bool integrator_is_explicit(Integrator integrator) { return row_of(integrator).info.is_explicit; }

double integrator_critical_step(Integrator integrator, double omega_max) {
  if (!(omega_max > 0)) return std::numeric_limits<double>::infinity();
  return row_of(integrator).critical_step(omega_max);
}

double explicit_force_critical_step(Integrator integrator, double omega) {
  return integrator_critical_step(integrator_is_explicit(integrator) ? integrator : Integrator::SemiImplicitEuler, omega);
}

}  // namespace drape
