// Building sheets: the paper's grid numbering (eqs 2–3), placement in space, the helper
// point sets of Figs 5–8, validation of definitions, and ids that outlive removal.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include "sheet_data.h"

#include <cmath>
#include <cstdint>
#include <numbers>

namespace {

TEST(Sheet, PointsAreNumberedRowMajorWithThePaperSpacings) {
  drape::World world;
  drape::SheetDef d;
  d.m = 3;  // rows i = 0..3, h2 = Lv/m = 0.5
  d.n = 4;  // columns j = 0..4, h1 = Lh/n = 0.5
  d.width = 2.0;
  d.height = 1.5;
  d.center = {10, 20, 30};
  const auto v = world.view(world.add_sheet(d));
  ASSERT_EQ(v.size(), 20u);
  for (std::uint32_t i = 0; i <= d.m; ++i)
    for (std::uint32_t j = 0; j <= d.n; ++j) {
      const std::uint32_t p = i * (d.n + 1) + j;
      EXPECT_DOUBLE_EQ(v.x[p], 10 - 1.0 + 0.5 * j);
      EXPECT_DOUBLE_EQ(v.y[p], 20 - 0.75 + 0.5 * i);
      EXPECT_DOUBLE_EQ(v.z[p], 30);
    }
}

TEST(Sheet, OrientationTurnsTheGridAboutItsCentre) {
  // a quarter turn about x takes local +y (the grid's rows) to world +z
  drape::World world;
  drape::SheetDef d;
  d.m = d.n = 2;
  d.width = d.height = 2.0;
  d.center = {1, 2, 3};
  d.orientation = drape::quat_from_axis_angle({1, 0, 0}, std::numbers::pi / 2);
  const auto v = world.view(world.add_sheet(d));
  const std::uint32_t top_left = drape::point_index(d.n, 2, 0);  // local (−1, +1, 0)
  EXPECT_NEAR(v.x[top_left], 0.0, 1e-12);
  EXPECT_NEAR(v.y[top_left], 2.0, 1e-12);
  EXPECT_NEAR(v.z[top_left], 4.0, 1e-12);
  const auto r = drape::rotate(d.orientation, {0, 0, 1});  // the normal now points along −y
  EXPECT_NEAR(r.y, -1.0, 1e-12);
}

TEST(Sheet, CornerAndCentrePointsOfThePaperSetUps) {
  EXPECT_EQ(drape::corner_points(4, 6), (std::vector<std::uint32_t>{0, 6, 28, 34}));
  EXPECT_EQ(drape::center_point(4, 6), 2u * 7 + 3);
  EXPECT_EQ(drape::corner_points(0, 3), (std::vector<std::uint32_t>{0, 3}));  // a rope has two ends
  EXPECT_EQ(drape::corner_points(0, 0), (std::vector<std::uint32_t>{0}));
}

TEST(Sheet, ValidationNamesTheFieldAndTheProblem) {
  struct Case {
    const char* field;
    void (*spoil)(drape::SheetDef&);
  };
  const Case cases[] = {
      {"width", [](drape::SheetDef& d) { d.width = 0; }},
      {"height", [](drape::SheetDef& d) { d.height = -1; }},
      {"mass", [](drape::SheetDef& d) { d.mass = std::nan(""); }},
      {"stiffness", [](drape::SheetDef& d) { d.stiffness = -5; }},
      {"damping", [](drape::SheetDef& d) { d.damping = INFINITY; }},
      {"rest_length_h", [](drape::SheetDef& d) { d.rest_length_h = -0.1; }},
      {"point_masses", [](drape::SheetDef& d) { d.point_masses = {1.0, 2.0}; }},
      {"anchors[0].point", [](drape::SheetDef& d) { d.anchors = {{999, 1.0, std::nullopt}}; }},
      {"anchors[0].stiffness", [](drape::SheetDef& d) { d.anchors = {{0, 0.0, std::nullopt}}; }},
      {"pins[1]", [](drape::SheetDef& d) { d.pins = {0, 121}; }},
      {"orientation", [](drape::SheetDef& d) { d.orientation = {2, 0, 0, 0}; }},
      {"stiffness_regions[0].rows", [](drape::SheetDef& d) { d.stiffness_regions = {{5, 11, 0, 1, 1.0}}; }},
      {"center", [](drape::SheetDef& d) { d.center.y = INFINITY; }},
  };
  drape::World world;
  for (const auto& c : cases) {
    drape::SheetDef d;  // 10×10 cells, valid as it stands
    ASSERT_EQ(drape::validate(d), "");
    c.spoil(d);
    const std::string message = drape::validate(d);
    EXPECT_EQ(message.rfind(c.field, 0), 0u) << "field " << c.field << ": message \"" << message << "\"";
    EXPECT_THROW(world.add_sheet(d), std::invalid_argument) << c.field;
  }
  EXPECT_EQ(world.sheet_count(), 0u);
}

// A sheet whose cells its coordinates cannot resolve is refused, in the precision of the
// world that would hold it: a cell edge under 16 machine epsilons times the sheet's largest
// coordinate. By hand: 1 mm cells 1 km from the origin, 16ε·1000 m = 1.9 mm in float: a float
// coordinate there is a multiple of 2^-14 m = 61 µm, so a spring's length is off by up to one
// of them, 6 % of 1 mm; in double 16ε·1000 m is 3.6e-12 m.
TEST(Sheet, CellsTheCoordinatesCannotResolveAreRefused) {
  drape::SheetDef d;
  d.m = d.n = 10;
  d.width = d.height = 0.01;  // 1 mm cells
  d.center = {1000, 0, 0};
  const float ulp = std::nextafter(1000.0f, 2000.0f) - 1000.0f;
  ASSERT_EQ(ulp, std::ldexp(1.0f, -14));
  EXPECT_EQ(drape::validate(d), "");
  EXPECT_EQ(drape::validate_float(d).rfind("width/n = 0.001 m is under 0.0019", 0), 0u)
      << drape::validate_float(d);
  drape::WorldF wf;
  EXPECT_THROW(wf.add_sheet(d), std::invalid_argument);
  drape::World w;
  EXPECT_NO_THROW(w.add_sheet(d));
  d.width = d.height = 0.02;  // 2 mm cells: over 1.9 mm, taken
  EXPECT_EQ(drape::validate_float(d), "");
  EXPECT_NO_THROW(wf.add_sheet(d));
  // double: at 1e12 m, 16ε is 3.6 mm
  d.width = d.height = 0.01;
  d.center = {0, 1e12, 0};
  EXPECT_EQ(drape::validate(d).rfind("width/n = 0.001 m is under 0.0035", 0), 0u)
      << drape::validate(d);
  // squares: an edge of 1e-160 m squares below double's smallest normal (2.2e-308); a
  // sheet 1e160 m out squares above its largest (1.8e308)
  d.center = {0, 0, 0};
  d.width = d.height = 1e-159;
  EXPECT_NE(drape::validate(d).find("smallest normal double"), std::string::npos) << drape::validate(d);
  d.width = d.height = 1;
  d.center = {1e160, 0, 0};
  EXPECT_NE(drape::validate(d).find("overflow double"), std::string::npos) << drape::validate(d);
}

// The arrays' allocator (aligned.h): every array on a cache line, and one of 2 MiB or more
// on a 2 MiB boundary, where a huge page can back it from its first byte; a sheet that
// large gets its arrays that way.
TEST(Sheet, LargeArraysStartOnHugePageBoundariesAndSmallOnesOnCacheLines) {
  using drape::detail::huge_block;
  const auto offset = [](const void* p, std::size_t to) { return reinterpret_cast<std::uintptr_t>(p) % to; };
  for (std::size_t n : {std::size_t(1), std::size_t(3), std::size_t(1000), huge_block / sizeof(double) - 1}) {
    drape::detail::AlignedArray<double> a(n);
    EXPECT_EQ(offset(a.data(), 64), 0u) << n;
  }
  for (std::size_t n : {huge_block / sizeof(double), huge_block / sizeof(double) + 5, 3 * huge_block / sizeof(float)}) {
    drape::detail::AlignedArray<double> a(n);
    EXPECT_EQ(offset(a.data(), huge_block), 0u) << n;
    a.assign(n / 2, 1.0);  // shrinking keeps the block: freed with the alignment it was made with
  }
  drape::SheetDef big;
  big.m = big.n = 511;  // 262,144 points: 2 MiB per array in double
  const auto s = drape::detail::build_sheet<double>(big);
  for (const auto* a : {&s.position.x, &s.position.y, &s.position.z, &s.velocity.z, &s.mass, &s.inv_mass})
    EXPECT_EQ(offset(a->data(), huge_block), 0u);
}

TEST(World, RemovedSheetIdsAreRecognisedAsStale) {
  drape::World world;
  drape::SheetDef d;
  const auto a = world.add_sheet(d);
  world.remove_sheet(a);
  EXPECT_FALSE(world.contains(a));
  const auto b = world.add_sheet(d);  // reuses the slot with a new generation
  EXPECT_EQ(a.index, b.index);
  EXPECT_NE(a, b);
  EXPECT_TRUE(world.contains(b));
  EXPECT_THROW(world.view(a), std::invalid_argument);
  EXPECT_EQ(world.sheets(), std::vector<drape::SheetId>{b});
}

// view() spans point into the sheet's own buffers: nothing but the sheet's removal moves or
// frees them (not adding sheets, which regrows the world's slots, nor removing others,
// contacts, frames tried and undone, another integrator or set_state), and take_sheet hands
// them over with the sheet's last state, so spans taken before stay readable (the
// sanitizer build reads them after the removal).
template <class W>
void expect_buffers_stay_until_taken() {
  using Real = typename W::Scalar;
  W world;
  drape::SheetDef d;
  d.m = d.n = 8;
  d.pins = drape::corner_points(d.m, d.n);
  const auto sheet = world.add_sheet(d);
  drape::SheetDef far = d;
  far.center = {0.0, 0.0, 5.0};
  const auto other = world.add_sheet(far);
  const drape::SheetView<Real> before = world.view(sheet);
  const Real* x = before.x.data();
  const Real* vz = before.vz.data();
  for (int k = 0; k < 40; ++k) {
    far.center = {0.0, 0.0, 10.0 + k};
    world.add_sheet(far);
  }
  world.remove_sheet(other);
  drape::SheetDef falling = d;  // meets the sheet within the frame: the frame is tried, then undone
  falling.pins.clear();
  falling.center = {0.0, 0.0, 0.05};
  falling.initial_velocity = {0.0, 0.0, -2.0};
  world.add_sheet(falling);
  world.step(30);
  world.set_integrator(drape::Integrator::ImplicitEuler);
  world.step(2);
  const drape::SheetView<Real> now = world.view(sheet);
  world.set_state(sheet, now);
  EXPECT_EQ(world.view(sheet).x.data(), x);
  EXPECT_EQ(world.view(sheet).vz.data(), vz);
  const std::vector<Real> last_x(now.x.begin(), now.x.end()), last_vz(now.vz.begin(), now.vz.end());
  EXPECT_GT(std::abs(last_vz[drape::center_point(d.m, d.n)]), 0.0);  // it moved: the check below can tell

  const drape::RemovedSheet<Real> taken = world.take_sheet(sheet);
  EXPECT_FALSE(world.contains(sheet));
  EXPECT_EQ(taken.view().x.data(), x);
  EXPECT_EQ(taken.view().m, d.m);
  world.add_sheet(d);  // into the freed slot; the world steps on without the taken sheet
  world.step(5);
  EXPECT_EQ(std::vector<Real>(before.x.begin(), before.x.end()), last_x);
  EXPECT_EQ(std::vector<Real>(before.vz.begin(), before.vz.end()), last_vz);
}

TEST(World, SheetBuffersStayUntilTheSheetIsTakenOut) { expect_buffers_stay_until_taken<drape::World>(); }
TEST(World, SheetBuffersStayUntilTheSheetIsTakenOutInFloat) { expect_buffers_stay_until_taken<drape::WorldF>(); }

TEST(World, FloatAndDoubleWorldsBuildTheSameGrid) {
  drape::SheetDef d;
  d.m = 4;
  d.n = 4;
  drape::World wd;
  drape::WorldF wf;
  const auto vd = wd.view(wd.add_sheet(d));
  const auto vf = wf.view(wf.add_sheet(d));
  for (std::size_t i = 0; i < vd.size(); ++i) EXPECT_EQ(static_cast<float>(vd.x[i]), vf.x[i]);
}

}  // namespace
