// The spring force formulation (paper §2, eqs 6–7) checked against hand computation,
// conservation of momentum, and the prestress cases of §2.1.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "forces.h"
#include "sheet_data.h"

namespace {

using drape::SheetDef;
using drape::detail::Sheet;

struct Force {
  double x, y, z;
};

// Spring forces of a sheet in its current positions, through the engine's kernel.
std::vector<Force> spring_forces(Sheet<double>& s) {
  drape::detail::spring_forces(*s.topology, cptr(s.position), ptr(s.force), ptr(s.row_scratch));
  std::vector<Force> f(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) f[i] = {s.force.x[i], s.force.y[i], s.force.z[i]};
  return f;
}

void move(Sheet<double>& s, std::uint32_t p, double x, double y, double z) {
  s.position.x[p] = x;
  s.position.y[p] = y;
  s.position.z[p] = z;
}

// A 3×3-point grid with h = 1 lying in z = 0: point (i, j) at (j − 1, i − 1, 0).
SheetDef grid3x3(double k) {
  SheetDef d;
  d.m = d.n = 2;
  d.width = d.height = 2.0;
  d.stiffness = k;
  return d;
}

TEST(Springs, HandComputedForcesOnPerturbedGrid) {
  // Lift the centre (1,1) and the corner (0,0) by 0.75: each spring to a lifted point then
  // has length 1.25 (a 3-4-5 triangle), so by eq (6) its force on the lifted end is
  // −k (1.25 − 1)/1.25 · d = −0.2 k d, d the vector from the other end.
  const double k = 10.0;
  auto s = drape::detail::build_sheet<double>(grid3x3(k));
  move(s, 4, 0.0, 0.0, 0.75);     // centre (1,1): 4 springs
  move(s, 0, -1.0, -1.0, 0.75);   // corner (0,0): 2 springs
  const auto f = spring_forces(s);
  // centre: four neighbours at (±1, 0, 0), (0, ±1, 0): in-plane parts cancel, each gives −0.2k·0.75 in z
  EXPECT_NEAR(f[4].x, 0.0, 1e-12);
  EXPECT_NEAR(f[4].y, 0.0, 1e-12);
  EXPECT_NEAR(f[4].z, -6.0, 1e-12);
  // corner: d = (−1, 0, 0.75) to (0,1) and (0, −1, 0.75) to (1,0): −2·d each
  EXPECT_NEAR(f[0].x, 2.0, 1e-12);
  EXPECT_NEAR(f[0].y, 2.0, 1e-12);
  EXPECT_NEAR(f[0].z, -3.0, 1e-12);
  // edge (0,1), three springs: the corner's reaction (−2, 0, 1.5), the centre's (0, 2, 1.5),
  // and the unstretched spring to (0,2), which gives nothing
  EXPECT_NEAR(f[1].x, -2.0, 1e-12);
  EXPECT_NEAR(f[1].y, 2.0, 1e-12);
  EXPECT_NEAR(f[1].z, 3.0, 1e-12);
  // the mirror edge (1,0)
  EXPECT_NEAR(f[3].x, 2.0, 1e-12);
  EXPECT_NEAR(f[3].y, -2.0, 1e-12);
  EXPECT_NEAR(f[3].z, 3.0, 1e-12);
  // untouched corner (2,2) has two unstretched springs
  EXPECT_EQ(f[8].x, 0.0);
  EXPECT_EQ(f[8].y, 0.0);
  EXPECT_EQ(f[8].z, 0.0);
}

TEST(Springs, InternalForcesSumToZero) {
  SheetDef d;
  d.m = 17;
  d.n = 23;
  d.width = 2.3;
  d.height = 1.7;
  d.stiffness = 350.0;
  d.stiffness_regions = {{3, 9, 4, 12, 5000.0}};
  auto s = drape::detail::build_sheet<double>(d);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  for (std::size_t i = 0; i < s.size(); ++i)
    move(s, static_cast<std::uint32_t>(i), s.position.x[i] + jitter(rng), s.position.y[i] + jitter(rng), jitter(rng));
  const auto f = spring_forces(s);
  double sx = 0, sy = 0, sz = 0, scale = 0;
  for (const auto& fi : f) {
    sx += fi.x;
    sy += fi.y;
    sz += fi.z;
    scale += std::abs(fi.x) + std::abs(fi.y) + std::abs(fi.z);
  }
  ASSERT_GT(scale, 1.0);  // the perturbation really stressed the sheet
  EXPECT_LT(std::abs(sx), 1e-13 * scale);
  EXPECT_LT(std::abs(sy), 1e-13 * scale);
  EXPECT_LT(std::abs(sz), 1e-13 * scale);
}

TEST(Springs, RestSheetFeelsNoForceAndStaysExactlyStill) {
  // h = 0.25 is exact in binary, so the grid's spacings equal ℓ = h to the last bit.
  drape::WorldDef wd;
  wd.gravity = {0, 0, 0};
  drape::World world(wd);
  SheetDef d;
  d.m = d.n = 8;
  d.width = d.height = 2.0;
  d.stiffness = 1000.0;
  const auto id = world.add_sheet(d);
  const auto v0 = world.view(id);
  const std::vector<double> x0(v0.x.begin(), v0.x.end()), y0(v0.y.begin(), v0.y.end()), z0(v0.z.begin(), v0.z.end());
  world.step(10000);
  const auto v = world.view(id);
  for (std::size_t i = 0; i < v.size(); ++i) {
    ASSERT_EQ(v.x[i], x0[i]) << "point " << i;
    ASSERT_EQ(v.y[i], y0[i]) << "point " << i;
    ASSERT_EQ(v.z[i], z0[i]) << "point " << i;
  }
}

TEST(Springs, ZeroLengthSpringContributesNoDirection) {
  SheetDef d;
  d.m = 0;
  d.n = 1;
  d.width = 1.0;
  for (double rest : {0.0, 0.5}) {
    d.rest_length_h = rest;
    auto s = drape::detail::build_sheet<double>(d);
    move(s, 0, 0.3, 0.3, 0.3);
    move(s, 1, 0.3, 0.3, 0.3);  // coincident end points
    const auto f = spring_forces(s);
    for (const auto& fi : f) {
      EXPECT_EQ(fi.x, 0.0) << "rest " << rest;
      EXPECT_EQ(fi.y, 0.0) << "rest " << rest;
      EXPECT_EQ(fi.z, 0.0) << "rest " << rest;
    }
  }
}

TEST(Springs, PrestressWithRestShorterThanSpacingPullsBoundaryInward) {
  // §2.1: ℓ ≠ h stresses the flat sheet. With ℓ = h/2 each spring of length 1 pulls its
  // ends together with k·(1 − 1/2) = k/2; at a corner two such pulls add.
  const double k = 8.0;
  SheetDef d = grid3x3(k);
  d.rest_length_h = d.rest_length_v = 0.5;
  auto s = drape::detail::build_sheet<double>(d);
  const auto f = spring_forces(s);
  EXPECT_NEAR(f[0].x, k / 2, 1e-12);  // corner (0,0) at (−1,−1): pulled toward +x and +y
  EXPECT_NEAR(f[0].y, k / 2, 1e-12);
  EXPECT_NEAR(f[1].x, 0.0, 1e-12);    // edge (0,1): left and right pulls cancel, the inner one remains
  EXPECT_NEAR(f[1].y, k / 2, 1e-12);
  EXPECT_NEAR(f[4].x, 0.0, 1e-12);    // centre: balanced by symmetry
  EXPECT_NEAR(f[4].y, 0.0, 1e-12);
}

TEST(Springs, UnequalSpacingsStressTheSheetUnlessEachDirectionHasItsOwnRestLength) {
  SheetDef d;
  d.m = 4;
  d.n = 8;
  d.width = 2.0;   // h1 = 0.25
  d.height = 2.0;  // h2 = 0.5
  d.stiffness = 20.0;
  // one common ℓ = h1: the vertical springs are stretched by 0.25
  d.rest_length_h = d.rest_length_v = 0.25;
  auto common = drape::detail::build_sheet<double>(d);
  const auto f_common = spring_forces(common);
  EXPECT_NEAR(f_common[0].y, 20.0 * 0.25, 1e-12);  // corner pulled up its column by k·(h2 − ℓ)
  // ℓ1 = h1, ℓ2 = h2 (the default): no initial force anywhere
  d.rest_length_h.reset();
  d.rest_length_v.reset();
  auto own = drape::detail::build_sheet<double>(d);
  for (const auto& fi : spring_forces(own)) {
    EXPECT_EQ(fi.x, 0.0);
    EXPECT_EQ(fi.y, 0.0);
    EXPECT_EQ(fi.z, 0.0);
  }
}

TEST(Springs, StiffnessRegionsApplyToSpringsInsideThem) {
  // §5.1: different k in different parts. Stretch every spring of a 1-row strip by the
  // same amount; the forces on each point then tell which k each spring has.
  SheetDef d;
  d.m = 0;
  d.n = 4;
  d.width = 4.0;
  d.stiffness = 1.0;
  d.rest_length_h = 0.5;  // every spring of length 1 pulls with k·0.5
  d.stiffness_regions = {{0, 0, 2, 4, 100.0}};  // springs 2–3 and 3–4
  auto s = drape::detail::build_sheet<double>(d);
  const auto f = spring_forces(s);
  EXPECT_NEAR(f[1].x, 0.5 - 0.5, 1e-12);        // between two soft springs
  EXPECT_NEAR(f[2].x, 100 * 0.5 - 0.5, 1e-12);  // soft on the left, stiff on the right
  EXPECT_NEAR(f[3].x, 0.0, 1e-12);              // between two stiff springs
  EXPECT_NEAR(f[4].x, -100 * 0.5, 1e-12);
}

}  // namespace
