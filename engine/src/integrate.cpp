// Integrators for M ẍ + C ẋ = f(x) − f_spr(x) (eq 4), M and C diagonal, so every update
// is per point and linear in the number of points (paper §4).
#include "integrate.h"

#include "forces.h"

namespace drape::detail {

namespace {

// Hard pins: whatever the update did, a pinned point is back on its pin and at rest.
template <class Real>
void apply_pins(Sheet<Real>& s) {
  const auto& pins = s.pins;
  for (std::size_t k = 0; k < pins.point.size(); ++k) {
    const std::uint32_t p = pins.point[k];
    s.position.x[p] = pins.tx[k];
    s.position.y[p] = pins.ty[k];
    s.position.z[p] = pins.tz[k];
    s.velocity.x[p] = s.velocity.y[p] = s.velocity.z[p] = Real(0);
  }
}

// Both first-order updates run over all three axes in one pass, so inv_mass is read once
// and every array is streamed once per substep.
template <class Real>
struct FirstOrderArrays {
  Real* __restrict x;
  Real* __restrict y;
  Real* __restrict z;
  Real* __restrict vx;
  Real* __restrict vy;
  Real* __restrict vz;
  const Real* __restrict fx;
  const Real* __restrict fy;
  const Real* __restrict fz;
  const Real* __restrict inv_mass;
};

// Forward Euler (SemiImplicit = false): x and v both advance from the old state.
// Semi-implicit Euler (SemiImplicit = true): the new velocity moves the point.
template <class Real, bool SemiImplicit>
void first_order_update(std::size_t count, const StepParams<Real>& p, FirstOrderArrays<Real> a) {
  Real* __restrict x = a.x;
  Real* __restrict y = a.y;
  Real* __restrict z = a.z;
  Real* __restrict vx = a.vx;
  Real* __restrict vy = a.vy;
  Real* __restrict vz = a.vz;
  const Real* __restrict fx = a.fx;
  const Real* __restrict fy = a.fy;
  const Real* __restrict fz = a.fz;
  const Real* __restrict im = a.inv_mass;
  const Real dt = p.dt, gx = p.gx, gy = p.gy, gz = p.gz;
  for (std::size_t i = 0; i < count; ++i) {
    if constexpr (!SemiImplicit) {
      x[i] += dt * vx[i];
      y[i] += dt * vy[i];
      z[i] += dt * vz[i];
    }
    vx[i] += dt * (fx[i] * im[i] + gx);
    vy[i] += dt * (fy[i] * im[i] + gy);
    vz[i] += dt * (fz[i] * im[i] + gz);
    if constexpr (SemiImplicit) {
      x[i] += dt * vx[i];
      y[i] += dt * vy[i];
      z[i] += dt * vz[i];
    }
  }
}

// Each row is updated as soon as its force is final (sheet_forces_by_rows), so forces
// never leave the cache.
template <class Real, class Update>
void first_order_step(Sheet<Real>& s, const StepParams<Real>& p, Update update) {
  auto row_done = [&](std::size_t first, std::size_t count) {
    update(count, p,
           FirstOrderArrays<Real>{s.position.x.data() + first, s.position.y.data() + first,
                                  s.position.z.data() + first, s.velocity.x.data() + first,
                                  s.velocity.y.data() + first, s.velocity.z.data() + first,
                                  s.force.x.data() + first, s.force.y.data() + first, s.force.z.data() + first,
                                  s.inv_mass.data() + first});
  };
  sheet_forces_by_rows(s, cptr(s.position), cptr(s.velocity), ptr(s.force), RowSink::of(row_done));
}

}  // namespace

template <class Real>
void integrate(Integrator integrator, Sheet<Real>& s, const StepParams<Real>& p) {
  switch (integrator) {
    case Integrator::ForwardEuler: first_order_step(s, p, first_order_update<Real, false>); break;
    case Integrator::SemiImplicitEuler: first_order_step(s, p, first_order_update<Real, true>); break;
  }
  apply_pins(s);
}

template void integrate<double>(Integrator, Sheet<double>&, const StepParams<double>&);
template void integrate<float>(Integrator, Sheet<float>&, const StepParams<float>&);

}  // namespace drape::detail
