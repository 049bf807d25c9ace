#include "broad_phase.h"

#include <algorithm>
#include <cmath>

namespace drape::detail {

void BroadPhase::find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs) {
  pairs.clear();
  // Sweep the axis along which the box centres spread most: fewest pairs overlap there
  // by accident, so the scan tests fewest candidates.
  double c_lo[3], c_hi[3];
  std::fill(c_lo, c_lo + 3, INFINITY);
  std::fill(c_hi, c_hi + 3, -INFINITY);
  for (const Aabb& b : boxes)
    for (int k = 0; k < 3; ++k) {
      const double c = 0.5 * (b.lo[k] + b.hi[k]);
      if (std::isfinite(c)) {
        c_lo[k] = std::min(c_lo[k], c);
        c_hi[k] = std::max(c_hi[k], c);
      }
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (c_hi[k] - c_lo[k] > c_hi[axis] - c_lo[axis]) axis = k;

  sorted_.clear();
  for (std::uint32_t i = 0; i < boxes.size(); ++i) {
    const Aabb& b = boxes[i];
    bool nan = false;
    for (int k = 0; k < 3; ++k) nan = nan || std::isnan(b.lo[k]) || std::isnan(b.hi[k]);
    if (!nan) sorted_.push_back({b.lo[axis], b.hi[axis], i});
  }
  // Ties on lo are broken by index, so the sort is a strict total order (no NaN left).
  std::sort(sorted_.begin(), sorted_.end(),
            [](const Entry& a, const Entry& b) { return a.lo < b.lo || (a.lo == b.lo && a.index < b.index); });
  for (std::size_t s = 0; s < sorted_.size(); ++s) {
    const Entry& a = sorted_[s];
    // Every later box has lo ≥ a.lo; it overlaps a along the axis iff its lo ≤ a.hi.
    for (std::size_t t = s + 1; t < sorted_.size() && sorted_[t].lo <= a.hi; ++t) {
      const std::uint32_t i = a.index, j = sorted_[t].index;
      if (overlaps(boxes[i], boxes[j])) pairs.push_back({std::min(i, j), std::max(i, j)});
    }
  }
  std::sort(pairs.begin(), pairs.end());
}

}  // namespace drape::detail
