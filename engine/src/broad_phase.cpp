#include "broad_phase.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace drape::detail {

namespace {

constexpr std::uint32_t kLeafSize = 4;

// The skin of a fat box: an eighth of the box's largest extent on every side (a sheet at
// rest, or jiggling in place, keeps its fat box), plus, on each face, kSkinSteps times
// how far that face moved outward per call since the fat box was last made: a box moving
// steadily keeps its fat box for kSkinSteps calls at least, whatever its speed, and fast
// boxes get thicker skins than slow ones. The motion term is capped at the box's extent,
// so a box that jumped once (a state was set) does not drag a huge fat box around.
// Thicker skins mean more candidates to filter per call, thinner ones more escapes;
// BM_BroadPhaseTracking is flat within ±15 % from 1/8 to 1/4 and 16 to 64 calls, and
// twice as slow at 1/32 and 8.
constexpr double kSkinFraction = 1.0 / 8;
constexpr double kSkinSteps = 16;
// Refits only grow the tree's nodes; once there have been as many refits as boxes since
// the tree was built, the tree and the candidates are rebuilt. (Rebuilding at a quarter
// of that was 1.5× slower on BM_BroadPhaseTracking; at 4× no faster.)
constexpr double kRefitsPerRebuild = 1;

bool inside(const Aabb& box, const Aabb& fat) {
  // `&`, not `&&`: six compares without a branch each (almost every box is inside).
  return (fat.lo[0] <= box.lo[0]) & (box.hi[0] <= fat.hi[0]) & (fat.lo[1] <= box.lo[1]) & (box.hi[1] <= fat.hi[1]) &
         (fat.lo[2] <= box.lo[2]) & (box.hi[2] <= fat.hi[2]);
}

}  // namespace

bool box_in_tree(const Aabb& box) {
  return !std::isnan(box.lo[0] + box.hi[0]) && !std::isnan(box.lo[1] + box.hi[1]) &&
         !std::isnan(box.lo[2] + box.hi[2]);
}

// ---- BoxTree ----

void BoxTree::build(std::span<const Aabb> boxes) {
  order_.clear();
  nodes_.clear();
  slot_.assign(boxes.size(), kNone);
  centre_.clear();
  for (std::uint32_t i = 0; i < boxes.size(); ++i) {
    const Aabb& b = boxes[i];
    if (box_in_tree(b)) centre_.push_back({{b.lo[0] + b.hi[0], b.lo[1] + b.hi[1], b.lo[2] + b.hi[2]}, i});
  }
  order_.resize(centre_.size());
  leaf_box_.resize(centre_.size());
  leaf_.resize(centre_.size());
  if (centre_.empty()) return;
  build(boxes, 0, static_cast<std::uint32_t>(centre_.size()), 0);
}

std::uint32_t BoxTree::build(std::span<const Aabb> boxes, std::uint32_t begin, std::uint32_t end,
                             std::uint32_t parent) {
  const auto id = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back({{}, begin, end, 0, parent});
  if (end - begin <= kLeafSize) {
    Aabb box = boxes[centre_[begin].index];
    for (std::uint32_t s = begin; s < end; ++s) {
      const std::uint32_t i = centre_[s].index;
      order_[s] = i;
      slot_[i] = s;
      leaf_[s] = id;
      const Aabb& b = leaf_box_[s] = boxes[i];
      for (int k = 0; k < 3; ++k) {
        box.lo[k] = std::min(box.lo[k], b.lo[k]);
        box.hi[k] = std::max(box.hi[k], b.hi[k]);
      }
    }
    nodes_[id].box = box;
    return id;
  }
  // Split at the median of the centres along their longest spread; ties broken by index,
  // so the halves are the same sets whatever nth_element does inside.
  double c_lo[3], c_hi[3];
  for (int k = 0; k < 3; ++k) c_lo[k] = c_hi[k] = centre_[begin].c[k];
  for (std::uint32_t s = begin + 1; s < end; ++s)
    for (int k = 0; k < 3; ++k) {
      c_lo[k] = std::min(c_lo[k], centre_[s].c[k]);
      c_hi[k] = std::max(c_hi[k], centre_[s].c[k]);
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (c_hi[k] - c_lo[k] > c_hi[axis] - c_lo[axis]) axis = k;
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(centre_.begin() + begin, centre_.begin() + mid, centre_.begin() + end,
                   [axis](const Centre& a, const Centre& b) {
                     return a.c[axis] < b.c[axis] || (a.c[axis] == b.c[axis] && a.index < b.index);
                   });
  build(boxes, begin, mid, id);  // the left child is node id + 1
  const std::uint32_t right = build(boxes, mid, end, id);
  Aabb box = nodes_[id + 1].box;
  const Aabb& r = nodes_[right].box;
  for (int k = 0; k < 3; ++k) {
    box.lo[k] = std::min(box.lo[k], r.lo[k]);
    box.hi[k] = std::max(box.hi[k], r.hi[k]);
  }
  nodes_[id].box = box;
  nodes_[id].right = right;
  return id;
}

void BoxTree::self_pairs(std::vector<BoxPair>& pairs) const {
  if (nodes_.empty()) return;
  const auto emit = [&](std::uint32_t s, std::uint32_t t) {
    const std::uint32_t i = order_[s], j = order_[t];
    pairs.push_back(i < j ? BoxPair{i, j} : BoxPair{j, i});
  };
  // A stack of node pairs (a, b): a == b asks for the pairs inside one node, a != b for
  // the pairs across two nodes already known to overlap.
  stack_.assign({0, 0});
  while (!stack_.empty()) {
    const std::uint32_t b = stack_.back();
    stack_.pop_back();
    const std::uint32_t a = stack_.back();
    stack_.pop_back();
    const Node& na = nodes_[a];
    const Node& nb = nodes_[b];
    if (a == b) {
      if (na.right == 0) {
        for (std::uint32_t s = na.begin; s < na.end; ++s)
          for (std::uint32_t t = s + 1; t < na.end; ++t)
            if (overlaps(leaf_box_[s], leaf_box_[t])) emit(s, t);
        continue;
      }
      const std::uint32_t l = a + 1, r = na.right;
      stack_.insert(stack_.end(), {l, l, r, r});
      if (overlaps(nodes_[l].box, nodes_[r].box)) stack_.insert(stack_.end(), {l, r});
    } else if (na.right == 0 && nb.right == 0) {
      for (std::uint32_t s = na.begin; s < na.end; ++s) {
        const Aabb& box = leaf_box_[s];
        if (!overlaps(box, nb.box)) continue;
        for (std::uint32_t t = nb.begin; t < nb.end; ++t)
          if (overlaps(box, leaf_box_[t])) emit(s, t);
      }
    } else if (nb.right == 0 || (na.right != 0 && na.end - na.begin >= nb.end - nb.begin)) {
      // Split the larger node (a here) and keep the halves that meet b.
      for (const std::uint32_t c : {a + 1, na.right})
        if (overlaps(nodes_[c].box, nb.box)) stack_.insert(stack_.end(), {c, b});
    } else {
      for (const std::uint32_t c : {b + 1, nb.right})
        if (overlaps(na.box, nodes_[c].box)) stack_.insert(stack_.end(), {a, c});
    }
  }
}

void BoxTree::refit(std::uint32_t i, const Aabb& box) {
  const std::uint32_t s = slot_[i];
  leaf_box_[s] = box;
  // std::min/max keep the node's bound when the box's is NaN: a NaN box overlaps nothing.
  for (std::uint32_t id = leaf_[s];; id = nodes_[id].parent) {
    Aabb& node = nodes_[id].box;
    if (inside(box, node)) break;  // so are all the ancestors
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = std::min(node.lo[k], box.lo[k]);
      node.hi[k] = std::max(node.hi[k], box.hi[k]);
    }
    if (id == 0) break;
  }
}

// ---- BroadPhase ----

void BroadPhase::find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs) {
  pairs.clear();
  tree_.build(boxes);
  tree_.self_pairs(pairs);
  std::sort(pairs.begin(), pairs.end());
}

// ---- TrackingBroadPhase ----

void TrackingBroadPhase::fatten(std::uint32_t i, const Aabb& box) {
  Aabb fat;
  if (!box_in_tree(box)) {
    // Overlaps nothing, like the box; and escapes at once, so the next finite box is seen.
    for (int k = 0; k < 3; ++k) fat.lo[k] = fat.hi[k] = std::numeric_limits<double>::quiet_NaN();
  } else {
    double extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max(extent, box.hi[k] - box.lo[k]);
    const double skin = kSkinFraction * extent;
    const Aabb& base = base_[i];
    const double calls = since_[i] < call_ && box_in_tree(base) ? double(call_ - since_[i]) : 0.0;
    for (int k = 0; k < 3; ++k) {
      const double down = calls > 0 ? std::max(0.0, (base.lo[k] - box.lo[k]) / calls) : 0.0;
      const double up = calls > 0 ? std::max(0.0, (box.hi[k] - base.hi[k]) / calls) : 0.0;
      fat.lo[k] = box.lo[k] - skin - std::min(kSkinSteps * down, extent);
      fat.hi[k] = box.hi[k] + skin + std::min(kSkinSteps * up, extent);
    }
    // Infinite or huge boxes: a fat box the tree would leave out (or NaN) would lose pairs.
    if (!box_in_tree(fat) || !inside(box, fat)) fat = box;
  }
  fat_[i] = fat;
  base_[i] = box;
  since_[i] = call_;
}

void TrackingBroadPhase::rebuild() {
  tree_.build(fat_);
  candidates_.clear();
  tree_.self_pairs(candidates_);
  std::sort(candidates_.begin(), candidates_.end());
  refits_ = 0;
}

void TrackingBroadPhase::find_pairs(std::span<const Aabb> boxes, std::vector<BoxPair>& pairs) {
  ++call_;
  const auto count = static_cast<std::uint32_t>(boxes.size());
  if (fat_.size() != count) {
    fat_.resize(count);
    base_.resize(count);
    since_.assign(count, call_);  // no history: no motion term
    for (std::uint32_t i = 0; i < count; ++i) fatten(i, boxes[i]);
    rebuild();
  } else {
    escaped_.clear();
    bool must_rebuild = false;
    for (std::uint32_t i = 0; i < count; ++i) {
      if (inside(boxes[i], fat_[i])) continue;
      if (!tree_.holds(i)) {
        if (!box_in_tree(boxes[i])) continue;  // still overlaps nothing
        must_rebuild = true;                   // back from NaN: needs a place in the tree
      }
      escaped_.push_back(i);
    }
    for (std::uint32_t e : escaped_) fatten(e, boxes[e]);
    refits_ += escaped_.size();
    if (must_rebuild || double(refits_) > kRefitsPerRebuild * count) {
      rebuild();
    } else if (!escaped_.empty()) {
      // Drop the escaped boxes' candidates, refit their new fat boxes, query each against
      // the tree and merge what it finds back in order.
      is_escaped_.resize(count);
      for (std::uint32_t e : escaped_) {
        is_escaped_[e] = 1;
        tree_.refit(e, fat_[e]);
      }
      std::erase_if(candidates_, [&](const BoxPair& p) { return is_escaped_[p.first] || is_escaped_[p.second]; });
      fresh_.clear();
      for (std::uint32_t e : escaped_)
        tree_.query(fat_[e], e, [&](std::uint32_t j) {
          if (!is_escaped_[j]) fresh_.push_back(e < j ? BoxPair{e, j} : BoxPair{j, e});
          else if (e < j) fresh_.push_back({e, j});  // two escaped boxes: found twice, kept once
        });
      for (std::uint32_t e : escaped_) is_escaped_[e] = 0;
      std::sort(fresh_.begin(), fresh_.end());
      const auto middle = static_cast<std::ptrdiff_t>(candidates_.size());
      candidates_.insert(candidates_.end(), fresh_.begin(), fresh_.end());
      std::inplace_merge(candidates_.begin(), candidates_.begin() + middle, candidates_.end());
    }
  }
  pairs.clear();
  for (const BoxPair& p : candidates_)
    if (overlaps(boxes[p.first], boxes[p.second])) pairs.push_back(p);
}

}  // namespace drape::detail
