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

template <class Real>
Aabb sheet_bounds(const Sheet<Real>& s) {
  Aabb box;
  const AlignedArray<Real>* axes[3] = {&s.position.x, &s.position.y, &s.position.z};
  for (int k = 0; k < 3; ++k) {
    const auto [lo, hi] = std::minmax_element(axes[k]->begin(), axes[k]->end());
    box.lo[k] = *lo;
    box.hi[k] = *hi;
  }
  return box;
}

}  // namespace drape::detail
