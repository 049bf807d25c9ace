// A 1-D reference for contact damping tests: the gap d(t) of a body meeting a repulsion,
// d̈ = accel(d, ḋ), integrated by classical RK4 (independent of the engine's integrators).
#pragma once

#include <utility>

namespace drape::test {

// (gap, rate) after `seconds` from (start, −approach), in RK4 steps of `step`.
template <class Accel>
std::pair<double, double> gap_after(Accel accel, double start, double approach, double seconds, double step) {
  double gap = start, rate = -approach;
  for (double t = 0; t < seconds; t += step) {
    const double k1x = rate, k1v = accel(gap, rate);
    const double k2x = rate + 0.5 * step * k1v, k2v = accel(gap + 0.5 * step * k1x, k2x);
    const double k3x = rate + 0.5 * step * k2v, k3v = accel(gap + 0.5 * step * k2x, k3x);
    const double k4x = rate + step * k3v, k4v = accel(gap + step * k3x, k4x);
    gap += step / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
    rate += step / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
  }
  return {gap, rate};
}

}  // namespace drape::test
