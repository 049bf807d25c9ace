#include "diagnostics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "terms/terms.h"

namespace drape::detail {

template <class Real>
bool sheet_finite(const Sheet<Real>& s) {
  // A comparison per value and an OR: both vectorise, so this is one cheap pass (the guard
  // runs it every frame). NaN fails the comparison, ±inf exceeds the largest finite value.
  constexpr Real largest = std::numeric_limits<Real>::max();
  unsigned bad = 0;
  for (const auto* a : {&s.position.x, &s.position.y, &s.position.z, &s.velocity.x, &s.velocity.y, &s.velocity.z})
    for (Real v : *a) bad |= !(std::abs(v) <= largest);
  return bad == 0;
}

namespace {

// Σ term(i) for i < count with eight independent partial sums, so the additions pipeline
// (and vectorise) instead of each waiting for the previous one. `omp simd` on the eight makes
// them one vector: left to itself GCC vectorised across eight blocks at once and transposed
// them back (vpermt2pd), and the guard's energies took more than a substep of free sheets.
template <class Term>
double lane_sum(std::size_t count, Term term) {
  constexpr int lanes = 8;
  double part[lanes] = {};
  std::size_t i = 0;
  for (; i + lanes <= count; i += lanes) {
#pragma omp simd
    for (int lane = 0; lane < lanes; ++lane) part[lane] += term(i + lane);
  }
  for (; i < count; ++i) part[0] += term(i);
  double sum = 0;
  for (double p : part) sum += p;
  return sum;
}

// ½ k (|xa − xb| − ℓ)² over `count` springs whose ends are at a[i] and b[i].
template <class Real>
double spring_energy_run(std::size_t count, const Real* ax, const Real* ay, const Real* az, const Real* bx,
                         const Real* by, const Real* bz, const Real* rest, const Real* k) {
  return lane_sum(count, [&](std::size_t e) {
    const double dx = double(ax[e]) - bx[e], dy = double(ay[e]) - by[e], dz = double(az[e]) - bz[e];
    const double stretch = std::sqrt(dx * dx + dy * dy + dz * dz) - rest[e];
    return 0.5 * k[e] * stretch * stretch;
  });
}

}  // namespace

template <class Real>
Energies sheet_energies(const Sheet<Real>& s, Vec3 g) {
  Energies e;
  const auto& x = s.position;
  const auto& v = s.velocity;
  e.kinetic = lane_sum(s.size(), [&](std::size_t i) {
    const double vx = v.x[i], vy = v.y[i], vz = v.z[i];
    return 0.5 * double(s.mass[i]) * (vx * vx + vy * vy + vz * vz);
  });
  e.gravity = -lane_sum(s.size(), [&](std::size_t i) {
    return double(s.mass[i]) * (g.x * x.x[i] + g.y * x.y[i] + g.z * x.z[i]);
  });
  // The edge buffer's fixed order (sheet_data.h) lets the springs be walked without its
  // index arrays: row i's horizontal springs join points i·cols + j and i·cols + j + 1; the
  // vertical springs, in one run, join p and p + cols.
  const auto& t = *s.topology;
  const std::size_t cols = t.cols(), n = t.n, horizontal = t.horizontal_count();
  const Real* rest = t.rest_length.data();
  const Real* k = t.stiffness.data();
  for (std::size_t i = 0; i < t.rows() && n > 0; ++i) {
    const std::size_t p = i * cols, q = i * n;
    e.spring += spring_energy_run(n, x.x.data() + p, x.y.data() + p, x.z.data() + p, x.x.data() + p + 1,
                                  x.y.data() + p + 1, x.z.data() + p + 1, rest + q, k + q);
  }
  const std::size_t vertical = t.springs() - horizontal;
  e.spring += spring_energy_run(vertical, x.x.data(), x.y.data(), x.z.data(), x.x.data() + cols, x.y.data() + cols,
                                x.z.data() + cols, rest + horizontal, k + horizontal);
  add_term_energies(s, cptr(x), e.spring, e.bending);
  const auto& an = s.anchors;
  for (std::size_t a = 0; a < an.point.size(); ++a) {
    const std::uint32_t p = an.point[a];
    const double dx = double(x.x[p]) - an.tx[a], dy = double(x.y[p]) - an.ty[a], dz = double(x.z[p]) - an.tz[a];
    e.anchor += 0.5 * an.stiffness[a] * (dx * dx + dy * dy + dz * dz);
  }
  return e;
}

template <class Real>
SheetDiagnostics sheet_diagnostics(const Sheet<Real>& s, Vec3 g) {
  SheetDiagnostics d;
  d.energy = sheet_energies(s, g);
  const auto& x = s.position;
  const auto& t = *s.topology;
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    const std::uint32_t a = t.a[e], b = t.b[e];
    const double rest = t.rest_length[e];
    if (!(rest > 0)) continue;
    const double dx = double(x.x[a]) - x.x[b], dy = double(x.y[a]) - x.y[b], dz = double(x.z[a]) - x.z[b];
    d.max_strain = std::max(d.max_strain, std::abs(std::sqrt(dx * dx + dy * dy + dz * dz) / rest - 1.0));
  }
  d.finite = sheet_finite(s) && std::isfinite(d.energy.total());
  return d;
}

// Σ over the springs and anchors at each point of the stiffness matrix's row bound: 2k per
// spring (Gershgorin), the terms' own bounds, k per anchor; 0 at pins (they do not move).
template <class Real>
static std::vector<double> row_stiffness_bounds(const Sheet<Real>& s) {
  const auto& t = *s.topology;
  std::vector<double> k_sum(s.size(), 0.0);
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    k_sum[t.a[e]] += 2.0 * t.stiffness[e];
    k_sum[t.b[e]] += 2.0 * t.stiffness[e];
  }
  add_term_stiffness_bounds(s, k_sum.data());
  for (std::size_t k = 0; k < s.anchors.point.size(); ++k) k_sum[s.anchors.point[k]] += s.anchors.stiffness[k];
  for (std::uint32_t p : s.pins.point) k_sum[p] = 0.0;
  return k_sum;
}

// The largest over the points of ω_i = √(2Σk_i/m_i) (Gershgorin), or, with `damped`, of
// (γ_i + √(γ_i² + 4ω_i²))/2 with eq (4)'s damping rate γ_i = c_i/m_i: semi-implicit Euler on
// x'' = −ω²x − γx' (the damping from the step's velocity) is stable while ω²dt² + 2γdt < 4
// (Jury's conditions on its 2×2 step), i.e. dt < 2/ω_eff: 2/ω undamped, 2/γ (= 2m/c) for
// damping alone, which the springs' bound missed. (Measured on damping alone: velocity
// Verlet holds beyond it; RK4, scaled to 2√2/ω_eff, holds to 2.785/γ, 1.5 % short of that.)
template <class Real>
static double highest_frequency(const Sheet<Real>& s, bool damped) {
  const std::vector<double> k_sum = row_stiffness_bounds(s);
  std::vector<bool> pinned(s.size(), false);  // a pin's damping moves nothing
  for (std::uint32_t p : s.pins.point) pinned[p] = true;
  const bool has_damping = damped && !s.damping.empty();
  double omega = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double omega2 = k_sum[i] / double(s.mass[i]);
    const double g = has_damping && !pinned[i] ? double(s.damping[i]) / double(s.mass[i]) : 0.0;
    omega = std::max(omega, g > 0 ? 0.5 * (g + std::sqrt(g * g + 4.0 * omega2)) : std::sqrt(omega2));
  }
  return omega;
}

template <class Real>
double sheet_spring_frequency(const Sheet<Real>& s) {
  return highest_frequency(s, false);
}

template <class Real>
double sheet_stable_step(const Sheet<Real>& s) {
  const double omega = highest_frequency(s, true);
  return omega > 0 ? 2.0 / omega : std::numeric_limits<double>::infinity();
}

template Energies sheet_energies<double>(const Sheet<double>&, Vec3);
template Energies sheet_energies<float>(const Sheet<float>&, Vec3);
template SheetDiagnostics sheet_diagnostics<double>(const Sheet<double>&, Vec3);
template SheetDiagnostics sheet_diagnostics<float>(const Sheet<float>&, Vec3);
template bool sheet_finite<double>(const Sheet<double>&);
template bool sheet_finite<float>(const Sheet<float>&);
template double sheet_stable_step<double>(const Sheet<double>&);
template double sheet_spring_frequency<double>(const Sheet<double>&);
template double sheet_stable_step<float>(const Sheet<float>&);
template double sheet_spring_frequency<float>(const Sheet<float>&);

}  // namespace drape::detail
