// Broad-phase of the host stage: which boxes overlap. A bounding-volume tree is built
// over the boxes (median splits along the longest axis of the centres, O(n log n)) and
// every box queries it for later boxes it meets (O(log n + k) each). Sweep-and-prune on
// one axis was tried first: with sheets spread in 3-D it tests every box against all
// boxes that overlap it along that axis, about n^(5/3) tests for n boxes.
// Reusable for any list of boxes (sheets, obstacles).
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
  // never on the tree's shape or on threads. Boxes with a NaN bound overlap nothing.
  void find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs);

 private:
  struct Node {
    Aabb box;
    std::uint32_t begin, end;  // range of order_ below this node
    std::uint32_t left, right; // children; left == 0 for a leaf (the root is never a child)
  };
  std::uint32_t build(std::span<const Aabb> boxes, std::uint32_t begin, std::uint32_t end);

  std::vector<std::uint32_t> order_;  // box indices, grouped by leaf
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> stack_;
};

}  // namespace drape::detail
