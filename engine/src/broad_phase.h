// Broad-phase of the host stage: which boxes overlap, found by sweep-and-prune on one
// axis (sort by lower bound, then scan forward while the next box starts before this one
// ends). Cost: O(n log n) for the sort plus O(n + k') for the scan, k' the pairs that
// overlap along the swept axis. Reusable for any list of boxes (sheets, obstacles).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bounds.h"

namespace drape::detail {

// An overlapping pair of box indices, first < second.
struct BoxPair {
  std::uint32_t first = 0, second = 0;
  friend bool operator==(const BoxPair&, const BoxPair&) = default;
  friend auto operator<=>(const BoxPair&, const BoxPair&) = default;
};

// Keeps its scratch between calls so the per-substep host stage does not allocate once
// the number of boxes has settled.
class BroadPhase {
 public:
  // Writes into `pairs` every (i, j), i < j, whose closed boxes overlap (touching counts,
  // as in `overlaps`), sorted by (first, second): the order depends only on the boxes,
  // never on the sort's tie handling or on threads. Boxes with a NaN bound overlap nothing.
  void find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs);

 private:
  struct Entry {
    double lo, hi;
    std::uint32_t index;
  };
  std::vector<Entry> sorted_;
};

}  // namespace drape::detail
