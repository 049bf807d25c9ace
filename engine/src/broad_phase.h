// Broad-phase of the host stage: which boxes overlap.
//
// BoxTree is a bounding-volume tree over a list of boxes: median splits along the longest
// axis of the centres (O(n log n)), the boxes copied into leaf order so a leaf's boxes
// sit together in memory. Its overlapping pairs come from one traversal of the tree
// against itself, which visits each pair of overlapping nodes once (each box is not
// queried from the root on its own). Sweep-and-prune on one axis was tried first: with
// sheets spread in 3-D it tests every box against all boxes that overlap it along that
// axis, about n^(5/3) tests for n boxes.
//
// BroadPhase builds the tree from scratch on every call. TrackingBroadPhase is what the
// world uses every substep: boxes move little between substeps, so it keeps for each box
// a fat box (the box grown by a skin) and the sorted candidate pairs whose fat boxes
// overlap. A call checks each box is still inside its fat box (O(n)) and, if all are,
// filters the candidates by the current boxes (O(candidates)). A box that escaped gets a
// new fat box, is refitted into the tree (its ancestors grow to hold it) and queried
// against it alone; when many escaped, or refits have loosened the tree, the tree and
// candidates are rebuilt. Either way the answer is exactly that of BroadPhase.
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

// The tree leaves out boxes with a NaN centre coordinate (a NaN bound, or -inf..+inf):
// they could not be ordered, and they overlap nothing.
bool box_in_tree(const Aabb& box);

class BoxTree {
 public:
  void build(std::span<const Aabb> boxes);
  // Appends every overlapping pair of boxes in the tree as (smaller, larger) index,
  // unsorted.
  void self_pairs(std::vector<BoxPair>& pairs) const;
  // Box i of the last build (false if it was left out).
  bool holds(std::uint32_t i) const { return i < slot_.size() && slot_[i] != kNone; }
  // Replaces box i (which the tree holds) by `box` and grows its ancestors to hold it:
  // queries stay exact, only slower as the nodes loosen.
  void refit(std::uint32_t i, const Aabb& box);
  // Calls found(j) for every box j in the tree, j != skip, that overlaps `box`.
  template <class Found>
  void query(const Aabb& box, std::uint32_t skip, Found&& found) const;

 private:
  static constexpr std::uint32_t kNone = ~std::uint32_t(0);
  struct Node {
    Aabb box;
    std::uint32_t begin, end;  // range of order_ below this node
    std::uint32_t right;       // right child (the left one is the next node); 0 for a leaf
    std::uint32_t parent;
  };
  std::uint32_t build(std::span<const Aabb> boxes, std::uint32_t begin, std::uint32_t end, std::uint32_t parent);

  std::vector<std::uint32_t> order_;  // box indices, grouped by leaf
  std::vector<Aabb> leaf_box_;        // leaf_box_[s] is the box of order_[s]
  std::vector<std::uint32_t> slot_;   // slot_[i]: position of box i in order_, or kNone
  std::vector<std::uint32_t> leaf_;   // leaf_[s]: the leaf node holding position s
  std::vector<Node> nodes_;
  mutable std::vector<std::uint32_t> stack_;
  // Build scratch: the boxes' centres (lo + hi) with their indices, partitioned in place,
  // so the splits read memory in order rather than a box's centre by its index.
  struct Centre {
    double c[3];
    std::uint32_t index;
  };
  std::vector<Centre> centre_;
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
  BoxTree tree_;
};

class TrackingBroadPhase {
 public:
  // Same contract as BroadPhase::find_pairs, whatever the boxes of earlier calls were: box
  // i is only ever compared with fat box i, so a wrong history costs time, never pairs.
  // The history pays when box i is the same object, moving, from call to call: a
  // different count starts over by itself; call reset() when the list was reordered or
  // its objects replaced at the same count, so no box inherits another's fat box.
  void find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs);
  void reset() { fat_.clear(); }

 private:
  void fatten(std::uint32_t i, const Aabb& box);
  void rebuild();

  BoxTree tree_;
  std::vector<Aabb> fat_;             // fat box of each box
  std::vector<Aabb> base_;            // the box its fat box was made from
  std::vector<std::uint64_t> since_;  // the call that made it
  std::vector<BoxPair> candidates_;   // pairs of overlapping fat boxes, sorted
  std::vector<BoxPair> fresh_;
  std::vector<std::uint32_t> escaped_;
  std::vector<char> is_escaped_;
  std::uint64_t call_ = 0;
  std::size_t refits_ = 0;  // since the tree was built
};

template <class Found>
void BoxTree::query(const Aabb& box, std::uint32_t skip, Found&& found) const {
  if (nodes_.empty()) return;
  stack_.assign(1, 0);
  while (!stack_.empty()) {
    const std::uint32_t id = stack_.back();
    stack_.pop_back();
    const Node& node = nodes_[id];
    if (!overlaps(node.box, box)) continue;
    if (node.right == 0) {
      for (std::uint32_t s = node.begin; s < node.end; ++s)
        if (order_[s] != skip && overlaps(leaf_box_[s], box)) found(order_[s]);
    } else {
      stack_.push_back(node.right);
      stack_.push_back(id + 1);
    }
  }
}

}  // namespace drape::detail
