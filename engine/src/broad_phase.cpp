#include "broad_phase.h"

#include <algorithm>
#include <cmath>

namespace drape::detail {

namespace {
constexpr std::uint32_t kLeafSize = 4;
}

std::uint32_t BroadPhase::build(std::span<const Aabb> boxes, std::uint32_t begin, std::uint32_t end) {
  const auto id = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back({boxes[order_[begin]], begin, end, 0, 0});
  Aabb box = boxes[order_[begin]];
  double c_lo[3], c_hi[3];
  for (int k = 0; k < 3; ++k) c_lo[k] = c_hi[k] = box.lo[k] + box.hi[k];
  for (std::uint32_t s = begin + 1; s < end; ++s) {
    const Aabb& b = boxes[order_[s]];
    for (int k = 0; k < 3; ++k) {
      box.lo[k] = std::min(box.lo[k], b.lo[k]);
      box.hi[k] = std::max(box.hi[k], b.hi[k]);
      c_lo[k] = std::min(c_lo[k], b.lo[k] + b.hi[k]);
      c_hi[k] = std::max(c_hi[k], b.lo[k] + b.hi[k]);
    }
  }
  nodes_[id].box = box;
  if (end - begin <= kLeafSize) return id;
  // Split at the median of the centres along their longest spread; ties broken by index,
  // so the halves are the same sets whatever nth_element does inside.
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (c_hi[k] - c_lo[k] > c_hi[axis] - c_lo[axis]) axis = k;
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](std::uint32_t a, std::uint32_t b) {
                     const double ca = boxes[a].lo[axis] + boxes[a].hi[axis];
                     const double cb = boxes[b].lo[axis] + boxes[b].hi[axis];
                     return ca < cb || (ca == cb && a < b);
                   });
  const std::uint32_t left = build(boxes, begin, mid);
  const std::uint32_t right = build(boxes, mid, end);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

void BroadPhase::find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs) {
  pairs.clear();
  order_.clear();
  nodes_.clear();
  for (std::uint32_t i = 0; i < boxes.size(); ++i) {
    bool finite_order = true;  // NaN would break the tree's ordering; ±inf is fine
    for (int k = 0; k < 3; ++k) finite_order = finite_order && !std::isnan(boxes[i].lo[k] + boxes[i].hi[k]);
    if (finite_order) order_.push_back(i);
  }
  if (order_.size() < 2) return;
  build(boxes, 0, static_cast<std::uint32_t>(order_.size()));
  for (std::uint32_t i : order_) {
    const Aabb& a = boxes[i];
    stack_.assign(1, 0);
    while (!stack_.empty()) {
      const Node& node = nodes_[stack_.back()];
      stack_.pop_back();
      if (!overlaps(node.box, a)) continue;
      if (node.left == 0) {
        for (std::uint32_t s = node.begin; s < node.end; ++s) {
          const std::uint32_t j = order_[s];
          if (j > i && overlaps(a, boxes[j])) pairs.push_back({i, j});
        }
      } else {
        stack_.push_back(node.left);
        stack_.push_back(node.right);
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
}

}  // namespace drape::detail
