// Integrators for M ẍ + C ẋ = f(x) − f_spr(x) (eq 4), M and C diagonal, so every update
// is per point and linear in the number of points (paper §4).
#include "integrate.h"

#include "forces.h"

#include <cstdint>

namespace drape::detail {

namespace {

// Hard pins: whatever the update did, a pinned point is back on its pin and at rest.
// Only the pins among points [begin, end), the range a block of the world updated.
template <class Real>
void apply_pins(Sheet<Real>& s, std::size_t begin = 0, std::size_t end = SIZE_MAX) {
  const auto& pins = s.pins;
  for (std::size_t k = 0; k < pins.point.size(); ++k) {
    const std::uint32_t p = pins.point[k];
    if (p < begin || p >= end) continue;
    s.position.x[p] = pins.tx[k];
    s.position.y[p] = pins.ty[k];
    s.position.z[p] = pins.tz[k];
    s.velocity.x[p] = s.velocity.y[p] = s.velocity.z[p] = Real(0);
  }
}

// One component of forward Euler: x and v both advance from the old state.
template <class Real>
void forward_euler_axis(std::size_t count, Real dt, Real g, Real* __restrict x, Real* __restrict v,
                        const Real* __restrict f, const Real* __restrict inv_mass) {
  for (std::size_t i = 0; i < count; ++i) {
    const Real a = f[i] * inv_mass[i] + g;
    x[i] += dt * v[i];
    v[i] += dt * a;
  }
}

// One component of semi-implicit Euler: the new velocity moves the point.
template <class Real>
void semi_implicit_euler_axis(std::size_t count, Real dt, Real g, Real* __restrict x, Real* __restrict v,
                              const Real* __restrict f, const Real* __restrict inv_mass) {
  for (std::size_t i = 0; i < count; ++i) {
    v[i] += dt * (f[i] * inv_mass[i] + g);
    x[i] += dt * v[i];
  }
}

template <class Real, class AxisUpdate>
void first_order_step(Sheet<Real>& s, const StepParams<Real>& p, AxisUpdate update) {
  sheet_forces(s, cptr(s.position), cptr(s.velocity), ptr(s.force));
  const std::size_t count = s.size();
  const Real* inv_mass = s.inv_mass.data();
  update(count, p.dt, p.gx, s.position.x.data(), s.velocity.x.data(), s.force.x.data(), inv_mass);
  update(count, p.dt, p.gy, s.position.y.data(), s.velocity.y.data(), s.force.y.data(), inv_mass);
  update(count, p.dt, p.gz, s.position.z.data(), s.velocity.z.data(), s.force.z.data(), inv_mass);
}

}  // namespace

template <class Real>
void integrate(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p) {
  switch (integrator) {
    case Integrator::ForwardEuler: first_order_step(s, p, forward_euler_axis<Real>); break;
    case Integrator::SemiImplicitEuler: first_order_step(s, p, semi_implicit_euler_axis<Real>); break;
  }
  apply_pins(s);
}

bool updates_per_point(Integrator integrator) {
  return integrator == Integrator::ForwardEuler || integrator == Integrator::SemiImplicitEuler;
}

template <class Real>
void update_points(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p, std::size_t begin,
                   std::size_t end) {
  auto run = [&](auto update) {
    const std::size_t count = end - begin;
    const Real* inv_mass = s.inv_mass.data() + begin;
    update(count, p.dt, p.gx, s.position.x.data() + begin, s.velocity.x.data() + begin, s.force.x.data() + begin, inv_mass);
    update(count, p.dt, p.gy, s.position.y.data() + begin, s.velocity.y.data() + begin, s.force.y.data() + begin, inv_mass);
    update(count, p.dt, p.gz, s.position.z.data() + begin, s.velocity.z.data() + begin, s.force.z.data() + begin, inv_mass);
  };
  switch (integrator) {
    case Integrator::ForwardEuler: run(forward_euler_axis<Real>); break;
    case Integrator::SemiImplicitEuler: run(semi_implicit_euler_axis<Real>); break;
  }
  apply_pins(s, begin, end);
}

template void update_points<double>(Integrator, Sheet<double>&, const StepParams<double>&, std::size_t, std::size_t);
template void update_points<float>(Integrator, Sheet<float>&, const StepParams<float>&, std::size_t, std::size_t);
template void integrate<double>(Integrator, Sheet<double>&, const StepParams<double>&);
template void integrate<float>(Integrator, Sheet<float>&, const StepParams<float>&);

}  // namespace drape::detail
