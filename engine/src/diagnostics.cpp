#include "diagnostics.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace drape::detail {

template <class Real>
bool sheet_finite(const Sheet<Real>& s) {
  // v − v is 0 for a finite v and NaN otherwise; OR-ing the failed comparisons is an
  // integer reduction the compiler vectorises (a floating-point sum would stay serial,
  // and cost as much as a whole substep).
  unsigned bad = 0;
  for (const auto* a : {&s.position.x, &s.position.y, &s.position.z, &s.velocity.x, &s.velocity.y, &s.velocity.z})
    for (Real v : *a) bad |= unsigned(!(v - v == Real(0)));
  return bad == 0;
}

template <class Real>
SheetDiagnostics sheet_diagnostics(const Sheet<Real>& s, Vec3 g) {
  SheetDiagnostics d;
  const auto& x = s.position;
  const auto& v = s.velocity;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double m = s.mass[i];
    const double vx = v.x[i], vy = v.y[i], vz = v.z[i];
    d.energy.kinetic += 0.5 * m * (vx * vx + vy * vy + vz * vz);
    d.energy.gravity -= m * (g.x * x.x[i] + g.y * x.y[i] + g.z * x.z[i]);
  }
  const auto& t = *s.topology;
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    const std::uint32_t a = t.a[e], b = t.b[e];
    const double dx = double(x.x[a]) - x.x[b], dy = double(x.y[a]) - x.y[b], dz = double(x.z[a]) - x.z[b];
    const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double rest = t.rest_length[e];
    d.energy.spring += 0.5 * t.stiffness[e] * (len - rest) * (len - rest);
    if (rest > 0) d.max_strain = std::max(d.max_strain, std::abs(len / rest - 1.0));
  }
  const auto& an = s.anchors;
  for (std::size_t k = 0; k < an.point.size(); ++k) {
    const std::uint32_t p = an.point[k];
    const double dx = double(x.x[p]) - an.tx[k], dy = double(x.y[p]) - an.ty[k], dz = double(x.z[p]) - an.tz[k];
    d.energy.anchor += 0.5 * an.stiffness[k] * (dx * dx + dy * dy + dz * dz);
  }
  d.finite = sheet_finite(s) && std::isfinite(d.energy.total());
  return d;
}

template <class Real>
double sheet_stable_step(const Sheet<Real>& s) {
  // Gershgorin: the stiffness matrix's row i is bounded by 2·Σ k over the springs at i
  // (plus anchors), so ω_max² ≤ max_i 2Σk_i / m_i and explicit steps need dt < 2/ω_max.
  const auto& t = *s.topology;
  std::vector<double> k_sum(s.size(), 0.0);
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    k_sum[t.a[e]] += 2.0 * t.stiffness[e];
    k_sum[t.b[e]] += 2.0 * t.stiffness[e];
  }
  for (std::size_t k = 0; k < s.anchors.point.size(); ++k) k_sum[s.anchors.point[k]] += s.anchors.stiffness[k];
  for (std::uint32_t p : s.pins.point) k_sum[p] = 0.0;  // pinned points do not move
  double omega2 = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) omega2 = std::max(omega2, k_sum[i] / double(s.mass[i]));
  return omega2 > 0 ? 2.0 / std::sqrt(omega2) : std::numeric_limits<double>::infinity();
}

template SheetDiagnostics sheet_diagnostics<double>(const Sheet<double>&, Vec3);
template SheetDiagnostics sheet_diagnostics<float>(const Sheet<float>&, Vec3);
template bool sheet_finite<double>(const Sheet<double>&);
template bool sheet_finite<float>(const Sheet<float>&);
template double sheet_stable_step<double>(const Sheet<double>&);
template double sheet_stable_step<float>(const Sheet<float>&);

}  // namespace drape::detail
