// The broad-phase against brute force: exactly the overlapping pairs, in sorted order,
// from scratch and tracked over many calls with moving boxes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "broad_phase.h"

namespace drape::detail {
namespace {

std::vector<BoxPair> brute_force(const std::vector<Aabb>& boxes) {
  std::vector<BoxPair> pairs;
  for (std::uint32_t i = 0; i < boxes.size(); ++i)
    for (std::uint32_t j = i + 1; j < boxes.size(); ++j) {
      bool hit = true;
      for (int k = 0; k < 3; ++k) hit = hit && boxes[i].lo[k] <= boxes[j].hi[k] && boxes[j].lo[k] <= boxes[i].hi[k];
      if (hit) pairs.push_back({i, j});
    }
  return pairs;  // generated in (i, j) order: already sorted
}

// Corners on a coarse integer lattice, so many boxes touch exactly (shared faces, edges,
// corners), and a third of the extents are zero (flat boxes, segments, points).
std::vector<Aabb> random_boxes(std::size_t count, unsigned seed, int lattice, int max_extent) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pos(0, lattice), ext(0, max_extent), zero(0, 2);
  std::vector<Aabb> boxes(count);
  for (Aabb& b : boxes)
    for (int k = 0; k < 3; ++k) {
      b.lo[k] = pos(rng) * 0.25;
      b.hi[k] = b.lo[k] + (zero(rng) == 0 ? 0 : ext(rng)) * 0.25;
    }
  return boxes;
}

TEST(BroadPhase, FindsExactlyTheOverlappingPairsOfRandomBoxes) {
  BroadPhase bp;
  std::vector<BoxPair> pairs;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const auto boxes = random_boxes(3000, seed, 40, 4);
    bp.find_pairs(boxes, pairs);
    const auto expected = brute_force(boxes);
    // The check means something: many pairs, many of them only touching.
    std::size_t touching = 0;
    for (const auto& [i, j] : expected)
      for (int k = 0; k < 3; ++k)
        if (boxes[i].lo[k] == boxes[j].hi[k] || boxes[j].lo[k] == boxes[i].hi[k]) {
          ++touching;
          break;
        }
    ASSERT_GT(expected.size(), 1000u);
    ASSERT_GT(touching, 300u);
    EXPECT_EQ(pairs, expected) << "seed " << seed;
  }
}

TEST(BroadPhase, TouchingAndDegenerateBoxesOverlap) {
  std::vector<Aabb> boxes = {
      {{0, 0, 0}, {1, 1, 1}},
      {{1, 0, 0}, {2, 1, 1}},        // shares a face with 0
      {{2, 1, 1}, {2, 1, 1}},        // a point on 1's corner
      {{0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}},  // a point inside 0
      {{3, 3, 3}, {3, 3, 3}},        // an isolated point
      {{3, 3, 3}, {3, 3, 3}},        // the same point again
      {{1.5, -5, 0.5}, {1.5, 5, 0.5}},  // a segment through 1
  };
  BroadPhase bp;
  std::vector<BoxPair> pairs;
  bp.find_pairs(boxes, pairs);
  const std::vector<BoxPair> expected = {{0, 1}, {0, 3}, {1, 2}, {1, 6}, {4, 5}};
  EXPECT_EQ(pairs, expected);
}

TEST(BroadPhase, BoxesWithNanBoundsOverlapNothing) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Aabb> boxes = {{{0, 0, 0}, {1, 1, 1}}, {{nan, 0, 0}, {1, 1, 1}}, {{0, 0, 0}, {1, nan, 1}},
                             {{0.5, 0.5, 0.5}, {2, 2, 2}}};
  BroadPhase bp;
  std::vector<BoxPair> pairs;
  bp.find_pairs(boxes, pairs);
  EXPECT_EQ(pairs, (std::vector<BoxPair>{{0, 3}}));
}

TEST(BroadPhase, ResultDoesNotDependOnInputOrderBeyondRenaming) {
  // Reversing the list renames box i to N−1−i; the set of pairs must map accordingly.
  const auto boxes = random_boxes(500, 7, 20, 3);
  std::vector<Aabb> reversed(boxes.rbegin(), boxes.rend());
  BroadPhase bp;
  std::vector<BoxPair> a, b;
  bp.find_pairs(boxes, a);
  bp.find_pairs(reversed, b);
  const auto last = std::uint32_t(boxes.size() - 1);
  for (auto& p : b) p = {last - p.second, last - p.first};
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
}

TEST(BroadPhase, EmptyAndSingleBoxGiveNoPairs) {
  BroadPhase bp;
  std::vector<BoxPair> pairs{{0, 1}};
  bp.find_pairs({}, pairs);
  EXPECT_TRUE(pairs.empty());
  const std::vector<Aabb> one = {{{0, 0, 0}, {1, 1, 1}}};
  bp.find_pairs(one, pairs);
  EXPECT_TRUE(pairs.empty());
}

// Boxes moving over many calls, on a lattice of 1/64 m so that boxes often touch exactly:
// most drift slowly, some fast, a few teleport now and then, some change size, some turn
// NaN (or infinite) for a while and come back. The tracker must give exactly the brute-
// force pairs after every move, and so must the from-scratch broad-phase.
struct Mover {
  long lo[3], size[3], vel[3];
};

Aabb to_box(const Mover& m) {
  Aabb b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = double(m.lo[k]) / 64;
    b.hi[k] = double(m.lo[k] + m.size[k]) / 64;
  }
  return b;
}

void check_tracking(std::size_t count, unsigned seed, int calls) {
  std::mt19937 rng(seed);
  const long side = long(64 * std::cbrt(double(count)));
  std::uniform_int_distribution<long> pos(0, side), size(0, 64), slow(-1, 1), fast(-40, 40);
  std::uniform_int_distribution<int> percent(0, 99);
  const auto make = [&] {
    Mover m;
    const bool is_fast = percent(rng) < 20;
    for (int k = 0; k < 3; ++k) {
      m.lo[k] = pos(rng);
      m.size[k] = percent(rng) < 10 ? 0 : size(rng);
      m.vel[k] = is_fast ? fast(rng) : slow(rng);
    }
    return m;
  };
  std::vector<Mover> movers(count);
  for (auto& m : movers) m = make();
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  std::vector<int> odd(count, 0);  // > 0: calls left as a NaN or infinite box
  TrackingBroadPhase tracker;
  BroadPhase scratch;
  std::vector<BoxPair> tracked, from_scratch;
  std::size_t total_pairs = 0;
  for (int call = 0; call < calls; ++call) {
    // Now and then the list itself changes: boxes appended or dropped.
    if (call == calls / 3) {
      for (std::size_t k = 0; k < count / 10; ++k) movers.push_back(make());
      odd.resize(movers.size(), 0);
    }
    if (call == 2 * calls / 3) {
      movers.resize(movers.size() - count / 5);
      odd.resize(movers.size());
    }
    std::vector<Aabb> boxes(movers.size());
    for (std::size_t i = 0; i < movers.size(); ++i) {
      Mover& m = movers[i];
      const int roll = percent(rng);
      if (roll == 0) {
        m.lo[0] = pos(rng), m.lo[1] = pos(rng), m.lo[2] = pos(rng);  // teleport
      } else if (roll == 1) {
        m.size[percent(rng) % 3] = size(rng);  // grows or shrinks
      } else if (roll == 2 && odd[i] == 0 && i % 7 == 0) {
        odd[i] = 1 + percent(rng) % 5;
      }
      for (int k = 0; k < 3; ++k) {
        m.lo[k] += m.vel[k];
        if (m.lo[k] < 0 || m.lo[k] > side) m.vel[k] = -m.vel[k];  // stay in the cube
      }
      boxes[i] = to_box(m);
      if (odd[i] > 0) {
        --odd[i];
        if (i % 2) boxes[i].lo[i % 3] = nan;
        else boxes[i].lo[i % 3] = -inf, boxes[i].hi[i % 3] = inf;  // centre is NaN: left out
      }
    }
    tracker.find_pairs(boxes, tracked);
    scratch.find_pairs(boxes, from_scratch);
    auto expected = brute_force(boxes);
    // brute_force counts -inf..+inf boxes as overlapping; the broad-phase leaves them out.
    std::erase_if(expected, [&](const BoxPair& p) { return !box_in_tree(boxes[p.first]) || !box_in_tree(boxes[p.second]); });
    ASSERT_EQ(tracked, expected) << "seed " << seed << ", call " << call;
    ASSERT_EQ(from_scratch, expected) << "seed " << seed << ", call " << call;
    total_pairs += expected.size();
  }
  EXPECT_GT(total_pairs, std::size_t(calls) * count / 4);  // the check means something
}

TEST(TrackingBroadPhase, MatchesBruteForceEveryCallWithMovingBoxes) {
  check_tracking(400, 1, 300);
  check_tracking(2000, 2, 60);
  check_tracking(30, 3, 300);
}

TEST(TrackingBroadPhase, ExactAfterReorderingWithOrWithoutReset) {
  // Reset only spares the boxes each other's fat boxes; the pairs are exact either way.
  for (const bool reset : {true, false}) {
    auto boxes = random_boxes(500, 11, 20, 3);
    TrackingBroadPhase tracker;
    std::vector<BoxPair> pairs;
    tracker.find_pairs(boxes, pairs);
    std::reverse(boxes.begin(), boxes.end());
    if (reset) tracker.reset();
    tracker.find_pairs(boxes, pairs);
    EXPECT_EQ(pairs, brute_force(boxes)) << "reset " << reset;
    std::shuffle(boxes.begin(), boxes.end(), std::mt19937(5));
    if (reset) tracker.reset();
    tracker.find_pairs(boxes, pairs);
    EXPECT_EQ(pairs, brute_force(boxes)) << "reset " << reset;
  }
}

TEST(TrackingBroadPhase, BoxesAtRestKeepTheirPairs) {
  const auto boxes = random_boxes(1000, 12, 30, 4);
  TrackingBroadPhase tracker;
  std::vector<BoxPair> pairs;
  const auto expected = brute_force(boxes);
  for (int call = 0; call < 5; ++call) {
    tracker.find_pairs(boxes, pairs);
    EXPECT_EQ(pairs, expected);
  }
  tracker.find_pairs({}, pairs);
  EXPECT_TRUE(pairs.empty());
}

}  // namespace
}  // namespace drape::detail
