// The broad-phase against brute force: exactly the overlapping pairs, in sorted order.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace drape::detail
