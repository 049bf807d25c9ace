// The penetration measure the benchmarks report beside drape's and Bullet's stacks
// (bench/penetration.h), against distances worked out by hand on flat sheets.
#include <gtest/gtest.h>

#include "penetration.h"

#include <cmath>

namespace {

using drape::Vec3;
using drape::bench::MeasuredSheet;
using drape::bench::measure_penetration;

constexpr std::uint32_t side = 8;
constexpr double spacing = 0.1;  // m between grid points
constexpr double reach = 0.05;

// A flat side×side sheet at height z, point (i,j) at (j·spacing + x0, i·spacing, z).
MeasuredSheet flat(int column, int layer, double z, double x0 = 0, double y0 = 0) {
  MeasuredSheet s{column, layer, {}};
  for (std::uint32_t i = 0; i < side; ++i)
    for (std::uint32_t j = 0; j < side; ++j) s.points.push_back({x0 + j * spacing, y0 + i * spacing, z});
  return s;
}

TEST(Penetration, ParallelSheetsAreApartByTheirGap) {
  const auto p = measure_penetration({flat(0, 0, 0.0), flat(0, 1, 0.01)}, side, reach);
  EXPECT_EQ(p.crossed, 0u);
  EXPECT_EQ(p.max_depth, 0.0);
  EXPECT_NEAR(p.min_gap, 0.01, 1e-15);
}

// An interior point of the upper sheet pushed 3 mm below the lower one has crossed it by
// 3 mm; the lower sheet's point right under it is then above the upper sheet's dent, so it
// has crossed too (by less: the dent's faces slope up from there).
TEST(Penetration, PointPushedThroughTheSheetBelowIsCrossedByItsDepth) {
  auto upper = flat(0, 1, 0.01);
  upper.points[3 * side + 4].z = -0.003;
  const auto p = measure_penetration({flat(0, 0, 0.0), upper}, side, reach);
  EXPECT_EQ(p.crossed, 2u);
  EXPECT_NEAR(p.max_depth, 0.003, 1e-15);
  // The dent's faces rise 13 mm over a spacing of 100 mm; a lower point 10 mm under one of
  // their upper corners is 10 mm · cos(atan(0.13)) from them, nearer than anything else.
  EXPECT_NEAR(p.min_gap, 0.01 / std::sqrt(1 + 0.13 * 0.13), 1e-12);
}

// The same sheets with the lower one given the higher layer: every point of each is on the
// wrong side of the other, so all cross (the order of layers is what "started above" means).
TEST(Penetration, LayersOutOfOrderAreAllCrossed) {
  const auto p = measure_penetration({flat(0, 1, 0.0), flat(0, 0, 0.01)}, side, reach);
  // points over the other sheet's outermost ring of cells or its inner edge (rows and
  // columns 0, 1, side-2, side-1) are beside it, not judged
  EXPECT_EQ(p.crossed, std::size_t(2 * (side - 4) * (side - 4)));
  EXPECT_NEAR(p.max_depth, 0.01, 1e-15);
}

TEST(Penetration, SheetsOfOtherColumnsAndBeyondReachAreNotCompared) {
  EXPECT_EQ(measure_penetration({flat(0, 1, 0.0), flat(1, 0, 0.01)}, side, reach).crossed, 0u);
  const auto far = measure_penetration({flat(0, 1, 0.0), flat(0, 0, 0.06)}, side, reach);
  EXPECT_EQ(far.crossed, 0u);
  EXPECT_TRUE(std::isinf(far.min_gap));
}

// A sheet whose points are flung metres apart (an engine that blew up) has triangles across
// the whole search grid; the measure says it could not measure instead of listing them all.
TEST(Penetration, TornApartSheetsAreReportedUnmeasured) {
  auto torn = flat(0, 1, 0.01);
  for (std::size_t p = 0; p < torn.points.size(); p += 2) torn.points[p].z += 100.0 * double(p);
  const auto p = measure_penetration({flat(0, 0, 0.0), torn}, side, reach, 100000);
  EXPECT_FALSE(p.measured);
  EXPECT_TRUE(measure_penetration({flat(0, 0, 0.0), flat(0, 1, 0.01)}, side, reach, 100000).measured);
}

// The lower sheet's first row folded back over it (row 0 at y = 0.2, z = 0.01; the fold is
// row 1, at y = 0.1), and one point of the upper sheet pulled down beside the fold, at
// (0.35, 0.07, 0.002): above the lower sheet's plane, outside what is left of its footprint.
// Its nearest point is on the fold's edge, (0.35, 0.1, 0), 0.03 m away, where the folded
// flap's triangle (whose up side now faces down) would call it below: beside, not crossed.
TEST(Penetration, PointBesideACurledEdgeIsNotCrossed) {
  auto lower = flat(0, 0, 0.0);
  for (std::uint32_t j = 0; j < side; ++j) lower.points[j] = {j * spacing, 0.2, 0.01};
  auto upper = flat(0, 1, 0.05, 0.0, -0.03);
  upper.points[side + 3] = {0.35, 0.07, 0.002};
  const auto p = measure_penetration({lower, upper}, side, reach);
  EXPECT_EQ(p.crossed, 0u);
  EXPECT_LT(p.min_gap, reach);  // the sheets are within reach of each other: they were compared
}

}  // namespace
