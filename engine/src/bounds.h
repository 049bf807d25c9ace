// Axis-aligned bounding boxes: what the host stage refreshes every substep and what the
// broad-phase and the obstacle test compare.
#pragma once

#include <algorithm>
#include <cstddef>

#include "sheet_data.h"

namespace drape::detail {

struct Aabb {
  double lo[3] = {0, 0, 0};
  double hi[3] = {0, 0, 0};

  Aabb inflated(double margin) const {
    return {{lo[0] - margin, lo[1] - margin, lo[2] - margin}, {hi[0] + margin, hi[1] + margin, hi[2] + margin}};
  }
  // Closed intervals: touching boxes overlap.
  friend bool overlaps(const Aabb& a, const Aabb& b) {
    return a.lo[0] <= b.hi[0] && b.lo[0] <= a.hi[0] && a.lo[1] <= b.hi[1] && b.lo[1] <= a.hi[1] &&
           a.lo[2] <= b.hi[2] && b.lo[2] <= a.hi[2];
  }
};

// Eight independent running minima/maxima per axis: no iterator bookkeeping and no
// single dependency chain, so the compiler turns the loop into packed min/max (the host
// stage reads every point of every sheet each substep; this keeps it cheap).
template <class Real>
Aabb sheet_bounds(const Sheet<Real>& s) {
  Aabb box;
  const AlignedArray<Real>* axes[3] = {&s.position.x, &s.position.y, &s.position.z};
  for (int k = 0; k < 3; ++k) {
    const Real* a = axes[k]->data();
    const std::size_t count = axes[k]->size();
    if (count == 0) continue;
    constexpr std::size_t lanes = 8;
    Real lo[lanes], hi[lanes];
    for (std::size_t l = 0; l < lanes; ++l) lo[l] = hi[l] = a[0];
    std::size_t i = 0;
    for (; i + lanes <= count; i += lanes)
      for (std::size_t l = 0; l < lanes; ++l) {
        lo[l] = a[i + l] < lo[l] ? a[i + l] : lo[l];
        hi[l] = a[i + l] > hi[l] ? a[i + l] : hi[l];
      }
    for (; i < count; ++i) {
      lo[0] = a[i] < lo[0] ? a[i] : lo[0];
      hi[0] = a[i] > hi[0] ? a[i] : hi[0];
    }
    box.lo[k] = *std::min_element(lo, lo + lanes);
    box.hi[k] = *std::max_element(hi, hi + lanes);
  }
  return box;
}

}  // namespace drape::detail
