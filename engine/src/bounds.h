// Axis-aligned bounding boxes: what each substep's update leaves for the next host stage
// (integrate's bounds) and what the broad-phase and the obstacle test compare.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include "sheet_data.h"
#include "simd/kernels.h"

namespace drape::detail {

struct Aabb {
  double lo[3] = {0, 0, 0};
  double hi[3] = {0, 0, 0};

  Aabb inflated(double margin) const {
    return {{lo[0] - margin, lo[1] - margin, lo[2] - margin}, {hi[0] + margin, hi[1] + margin, hi[2] + margin}};
  }
  // The box of the segment between points p and q.
  static Aabb segment(const double (&p)[3], const double (&q)[3]) {
    return {{std::min(p[0], q[0]), std::min(p[1], q[1]), std::min(p[2], q[2])},
            {std::max(p[0], q[0]), std::max(p[1], q[1]), std::max(p[2], q[2])}};
  }
  // Closed intervals: touching boxes overlap.
  friend bool overlaps(const Aabb& a, const Aabb& b) {
    return a.lo[0] <= b.hi[0] && b.lo[0] <= a.hi[0] && a.lo[1] <= b.hi[1] && b.lo[1] <= a.hi[1] &&
           a.lo[2] <= b.hi[2] && b.lo[2] <= a.hi[2];
  }
};

// Grows `box` to contain the extent of some points (simd/kernels.h): a NaN bound, of
// either, stays NaN, and a NaN box overlaps nothing.
template <class Real>
void include_extent(Aabb& box, const simd::Extent<Real>& e) {
  for (int k = 0; k < 3; ++k) {
    const double lo = e.lo[k], hi = e.hi[k];
    box.lo[k] = std::isnan(lo) || std::isnan(box.lo[k]) ? lo + box.lo[k] : std::min(box.lo[k], lo);
    box.hi[k] = std::isnan(hi) || std::isnan(box.hi[k]) ? hi + box.hi[k] : std::max(box.hi[k], hi);
  }
}

// Grows `box` to contain points [0, count) of the three coordinate arrays: the pass for
// boxes the explicit update does not take as it moves the points (integrate.h), as an
// explicit vector kernel on the widest instruction set the CPU has (one dispatch per call). A NaN coordinate is skipped unless it is the first; a NaN first point gives a
// NaN box.
template <class Real>
void include_points(Aabb& box, const Real* x, const Real* y, const Real* z, std::size_t count) {
  if (count == 0) return;
  include_extent(box, simd::points_extent(x, y, z, count));
}

// Grows `box` to contain `other` (a NaN bound stays NaN).
inline void include_box(Aabb& box, const Aabb& other) {
  for (int k = 0; k < 3; ++k) {
    box.lo[k] = std::isnan(other.lo[k]) ? other.lo[k] : std::min(box.lo[k], other.lo[k]);
    box.hi[k] = std::isnan(other.hi[k]) ? other.hi[k] : std::max(box.hi[k], other.hi[k]);
  }
}

// A box that include_points grows into the first points' box.
inline Aabb empty_box() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {{inf, inf, inf}, {-inf, -inf, -inf}};
}

template <class Real>
Aabb sheet_bounds(const Sheet<Real>& s) {
  if (s.size() == 0) return {};
  Aabb box = empty_box();
  include_points(box, s.position.x.data(), s.position.y.data(), s.position.z.data(), s.size());
  return box;
}

}  // namespace drape::detail
