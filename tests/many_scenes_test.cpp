// The many-sheet scenes of issue 4 (scenes/stack_sphere.json, scenes/rain_torus.json), on
// shortened runs: the physics they show (sheets stay outside the obstacles, stacked sheets
// keep the contact gap, in the order they fell) and that `drape run` writes the same bytes
// with one and with two threads.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "cli_fixture.h"
#include "run.h"
#include "scene.h"
#include "surface_distance.h"

namespace {

using drape::app::Scene;

Scene load(const std::string& name) { return drape::app::load_scene(std::string(DRAPE_SCENES_DIR) + "/" + name); }

// The stack, cut to its lowest eight sheets and run until they have landed (the eighth falls
// 0.5 m: 0.32 s, plus time to settle). Checked every frame: no point inside the sphere
// (|x − c| > R). At the end every sheet's centre point lies farther from the sphere's centre
// than the one of the sheet dropped before it, by at least half the contact thickness h: the gap a
// contact keeps is h + ξ·ln((c/ξ)/load), ≥ h while the load on a point (the weight of the
// points above it, 7 · 0.2 kg/81 · g = 0.17 N here) is below c/ξ (1 N); h/2 leaves room for
// the sheets not lying parallel. A sheet through another would come out below it.
TEST(ManySheetScenes, StackStaysOutsideTheSphereAndKeepsItsLayers) {
  Scene scene = load("stack_sphere.json");
  ASSERT_GE(scene.sheets.size(), 24u);
  scene.sheets.resize(8);
  drape::World world(scene.world);
  std::vector<drape::SheetId> ids;
  for (const auto& s : scene.sheets) ids.push_back(world.add_sheet(s));
  for (const auto& o : scene.obstacles) world.add_obstacle(o);
  const auto& sphere = scene.obstacles.at(0);
  ASSERT_EQ(sphere.shape, drape::ObstacleShape::Sphere);
  const double radius = sphere.size.x;

  const int frames = int(std::ceil(0.6 / scene.frame_time()));
  double closest = 1e9;
  for (int f = 0; f < frames; ++f) {
    ASSERT_TRUE(world.step(scene.substeps).ok()) << "frame " << f + 1;
    for (auto id : ids) {
      const auto v = world.view(id);
      for (std::size_t p = 0; p < v.size(); ++p)
        closest = std::min(closest, std::hypot(v.x[p] - sphere.center.x, v.y[p] - sphere.center.y, v.z[p] - sphere.center.z));
    }
  }
  EXPECT_GT(closest, radius);

  const double h = scene.world.contact_thickness;
  ASSERT_GT(h, 0);
  double below = radius;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const auto& d = scene.sheets[k];
    const auto v = world.view(ids[k]);
    const std::uint32_t c = drape::center_point(d.m, d.n);
    // layers over a sphere are shells: compare distances from its centre, which do not
    // change when a sheet slides sideways over the one below
    const double shell = std::hypot(v.x[c] - sphere.center.x, v.y[c] - sphere.center.y, v.z[c] - sphere.center.z);
    EXPECT_GT(shell, below + 0.5 * h) << "sheet " << k << " is not on top of sheet " << (k ? k - 1 : 0);
    below = shell;
  }
  // landed: every centre point within a few layers of the sphere's top, not still falling
  EXPECT_LT(below, radius + 8 * 4 * h);
}

// The rain: every point of every sheet stays above the plane and outside the torus's tube,
// over the first 0.5 s (the lowest sheets reach the torus at about 0.3 s).
TEST(ManySheetScenes, RainStaysOutsideTheTorusAndAboveThePlane) {
  Scene scene = load("rain_torus.json");
  ASSERT_GE(scene.sheets.size(), 36u);
  drape::World world(scene.world);
  std::vector<drape::SheetId> ids;
  for (const auto& s : scene.sheets) ids.push_back(world.add_sheet(s));
  for (const auto& o : scene.obstacles) world.add_obstacle(o);
  const auto& plane = scene.obstacles.at(0);
  const auto& torus = scene.obstacles.at(1);
  ASSERT_EQ(plane.shape, drape::ObstacleShape::Plane);
  ASSERT_EQ(torus.shape, drape::ObstacleShape::Torus);
  const double R = torus.size.x, r = torus.size.y;
  const int frames = int(std::ceil(0.5 / scene.frame_time()));
  double lowest = 1e9, tube = 1e9;
  for (int f = 0; f < frames; ++f) {
    ASSERT_TRUE(world.step(scene.substeps).ok()) << "frame " << f + 1;
    for (auto id : ids) {
      const auto v = world.view(id);
      for (std::size_t p = 0; p < v.size(); ++p) {
        lowest = std::min(lowest, double(v.z[p]) - plane.center.z);
        // distance from the tube's centre circle (torus axis along world z, unrotated)
        const double rho = std::hypot(v.x[p] - torus.center.x, v.y[p] - torus.center.y);
        tube = std::min(tube, std::hypot(rho - R, v.z[p] - torus.center.z));
      }
    }
  }
  EXPECT_GT(lowest, 0);
  EXPECT_GT(tube, r);
}

// Issue 12's flag (scenes/flag_wind.json): pinned along its edge to a pole, it flies out
// downwind, its free edge about a flag's width from the pole (1.17 m of 1.2 when written);
// in still air the same flag hangs from the pole, its free edge swinging in towards it
// (0.67 m). One second of each.
double free_edge_reach(Scene scene, bool wind) {
  if (!wind) scene.world.wind.velocity = {};
  drape::World world(scene.world);
  const auto id = world.add_sheet(scene.sheets.at(0));
  for (const auto& o : scene.obstacles) world.add_obstacle(o);
  const int frames = int(std::ceil(1.0 / scene.frame_time()));
  for (int f = 0; f < frames; ++f) EXPECT_TRUE(world.step(scene.substeps).ok()) << "frame " << f + 1;
  const auto& d = scene.sheets[0];
  const auto v = world.view(id);
  double reach = 0;  // mean distance of the free edge from the pole's line, in the horizontal plane
  for (std::uint32_t i = 0; i <= d.m; ++i) {
    const std::size_t p = std::size_t(i) * (d.n + 1) + d.n;
    reach += std::hypot(v.x[p], v.y[p]) / (d.m + 1);
  }
  return reach;
}

TEST(ClothScenes, FlagFliesOutDownwindAndHangsInStillAir) {
  const Scene scene = load("flag_wind.json");
  const double width = scene.sheets.at(0).width;
  EXPECT_GT(free_edge_reach(scene, true), 0.9 * width);
  EXPECT_LT(free_edge_reach(scene, false), 0.7 * width);
}

// The smallest distance, over the points of every sheet, to the surface of any other sheet
// whose box (grown by `range`) holds the point: every triangle of that sheet, no grid.
double closest_to_other_sheets(const drape::World& world, const std::vector<drape::SheetId>& ids, double range) {
  struct Box {
    double lo[3], hi[3];
  };
  std::vector<Box> boxes;
  for (auto id : ids) {
    const auto v = world.view(id);
    Box b{{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
    for (std::size_t p = 0; p < v.size(); ++p) {
      const double x[3] = {v.x[p], v.y[p], v.z[p]};
      for (int k = 0; k < 3; ++k) {
        b.lo[k] = std::min(b.lo[k], x[k] - range);
        b.hi[k] = std::max(b.hi[k], x[k] + range);
      }
    }
    boxes.push_back(b);
  }
  double best = INFINITY;
  for (std::size_t a = 0; a < ids.size(); ++a) {
    const auto va = world.view(ids[a]);
    for (std::size_t b = 0; b < ids.size(); ++b) {
      if (a == b) continue;
      const auto vb = world.view(ids[b]);
      auto at = [&](std::uint32_t k) { return drape::test::P3{vb.x[k], vb.y[k], vb.z[k]}; };
      for (std::size_t p = 0; p < va.size(); ++p) {
        const double x[3] = {va.x[p], va.y[p], va.z[p]};
        bool inside = true;
        for (int k = 0; k < 3; ++k) inside = inside && x[k] >= boxes[b].lo[k] && x[k] <= boxes[b].hi[k];
        if (inside) best = std::min(best, drape::test::surface_distance({x[0], x[1], x[2]}, vb.m, vb.n, at));
      }
    }
  }
  return best;
}

// Issue 13, no tunnelling in the shipped many-sheet scenes (shortened as above): at every
// frame, the smallest distance from any point to another sheet's surface stays above half
// the contact thickness h (the resting gap is h + ξ·ln((c/ξ)/load) > h; landing and sliding
// brought it to 0.8 h and 0.93 h when this test was written), and no edge of a sheet passes
// through another (World::sheet_crossings; a point's distance cannot see an edge cut across a
// rim: with the points' contacts alone both scenes' rims hooked into each other, and the
// scenes turn contact_rims on).
TEST(ManySheetScenes, NoPointComesWithinHalfTheThicknessOfAnotherSheet) {
  for (const char* name : {"stack_sphere.json", "rain_torus.json"}) {
    Scene scene = load(name);
    const bool stack = std::string(name) == "stack_sphere.json";
    if (stack) scene.sheets.resize(8);
    drape::World world(scene.world);
    std::vector<drape::SheetId> ids;
    for (const auto& s : scene.sheets) ids.push_back(world.add_sheet(s));
    for (const auto& o : scene.obstacles) world.add_obstacle(o);
    const double h = scene.world.contact_thickness;
    const double range = h + scene.world.contact_range * scene.world.contact_xi;
    const int frames = int(std::ceil((stack ? 0.6 : 0.5) / scene.frame_time()));
    double closest = INFINITY;
    for (int f = 0; f < frames; ++f) {
      ASSERT_TRUE(world.step(scene.substeps).ok()) << name << " frame " << f + 1;
      closest = std::min(closest, closest_to_other_sheets(world, ids, range));
      for (const drape::SheetCrossing& c : world.sheet_crossings())
        ADD_FAILURE() << name << " frame " << f + 1 << ": sheets " << c.a.index << " and " << c.b.index << " cross ("
                      << c.edges << " edges)";
    }
    EXPECT_GT(closest, 0.5 * h) << name;
    EXPECT_LT(closest, range) << name << ": no two sheets came near each other";
  }
}

// Sheets that start through each other stay so (each point is pushed away from the surface it
// is behind): every shipped scene starts with no pair of sheets crossing (World::sheet_crossings,
// an edge of one through a triangle of the other; crossings_test.cpp tests it against a brute
// force). rain_torus.json started with three such pairs, tilted neighbours at one height,
// before tools/make_many_scenes.py placed its sheets 3 cm apart at least.
TEST(ShippedScenes, NoSceneStartsWithSheetsThroughEachOther) {
  std::size_t scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(DRAPE_SCENES_DIR)) {
    if (entry.path().extension() != ".json") continue;
    const Scene scene = drape::app::load_scene(entry.path().string());
    std::vector<drape::SheetId> ids;
    const drape::World world = drape::app::build_world<double>(scene, 1, ids);
    for (const drape::SheetCrossing& c : world.sheet_crossings())
      ADD_FAILURE() << entry.path().filename() << ": sheets " << c.a.index << " and " << c.b.index << " cross ("
                    << c.edges << " edges)";
    ++scenes;
  }
  EXPECT_GE(scenes, 10u);
}

// Signed distance to an axis-aligned box (the table), written out here: > 0 outside.
double box_distance(const drape::ObstacleDef& box, double x, double y, double z) {
  const double q[3] = {std::abs(x - box.center.x) - box.size.x, std::abs(y - box.center.y) - box.size.y,
                       std::abs(z - box.center.z) - box.size.z};
  const double out = std::hypot(std::max(q[0], 0.0), std::max(q[1], 0.0), std::max(q[2], 0.0));
  return out > 0 ? out : std::max({q[0], q[1], q[2]});
}

// Issue 13: the tablecloth thrown sideways onto the table (scenes/tablecloth.json) never
// enters it, and friction stops it on the table: after 3 s its centre point lies on the
// top, not sliding, and no point is lower than half the table's height. The same throw without
// friction slides off the far edge and falls past the table's foot.
TEST(ManySheetScenes, TableclothStaysOnTheTableOnlyWithFriction) {
  for (bool friction : {true, false}) {
    Scene scene = load("tablecloth.json");
    ASSERT_EQ(scene.sheets.size(), 1u);
    const auto& table = scene.obstacles.at(0);
    ASSERT_EQ(table.shape, drape::ObstacleShape::Box);
    ASSERT_GT(scene.sheets[0].friction + table.friction, 0.0);
    if (!friction) {
      scene.sheets[0].friction = 0;
      scene.obstacles[0].friction = 0;
    }
    drape::World world(scene.world);
    const auto id = world.add_sheet(scene.sheets[0]);
    world.add_obstacle(scene.obstacles[0]);
    const int frames = int(std::ceil(3.0 / scene.frame_time()));
    double closest = 1e9;
    for (int f = 0; f < frames; ++f) {
      ASSERT_TRUE(world.step(scene.substeps).ok()) << "frame " << f + 1;
      const auto v = world.view(id);
      for (std::size_t p = 0; p < v.size(); ++p) closest = std::min(closest, box_distance(table, v.x[p], v.y[p], v.z[p]));
    }
    EXPECT_GT(closest, 0.0) << "friction " << friction;
    const auto v = world.view(id);
    const double top = table.center.z + table.size.z;
    const std::uint32_t c = drape::center_point(scene.sheets[0].m, scene.sheets[0].n);
    double lowest = 1e9;
    for (std::size_t p = 0; p < v.size(); ++p) lowest = std::min(lowest, double(v.z[p]));
    if (friction) {
      EXPECT_LT(std::abs(v.x[c] - table.center.x), table.size.x);
      EXPECT_LT(std::abs(v.y[c] - table.center.y), table.size.y);
      // resting where eq (9)'s force carries the point's weight: f = ξ·ln(c/(ξ·m·g))
      const double m = scene.sheets[0].mass / double(v.size()), g = -scene.world.gravity.z;
      EXPECT_NEAR(v.z[c] - top, table.xi * std::log(table.c / (table.xi * m * g)), 0.1 * table.xi);
      EXPECT_LT(std::hypot(v.vx[c], v.vy[c]), 1e-4);  // held: no sliding along the top
      EXPECT_GT(lowest, table.center.z);
    } else {
      EXPECT_LT(lowest, table.center.z - table.size.z);  // past the foot: it slid off
    }
  }
}

// Issue 4: the same scene with contacts gives the same bytes with 1 and 2 threads. The
// stack's first eight sheets for 8 frames (0.27 s): the lowest land on the sphere and on
// each other, so contacts between sheets and with the sphere are in play.
class ManySheetCli : public Cli {};

TEST_F(ManySheetCli, StackFramesAreByteIdenticalWithOneAndTwoThreads) {
  nlohmann::json scene = nlohmann::json::parse(slurp(std::string(DRAPE_SCENES_DIR) + "/stack_sphere.json"));
  scene["sheets"].erase(scene["sheets"].begin() + 8, scene["sheets"].end());
  const fs::path file = write("stack8.json", scene.dump());
  for (const char* threads : {"1", "2"}) {
    const Result r = drape("run " + file.string() + " --frames 8 --threads " + threads + " --out " +
                           (dir / (std::string("t") + threads)).string());
    ASSERT_EQ(r.code, 0) << r.err;
  }
  for (int f = 0; f <= 8; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.obj", f);
    const std::string one = slurp(dir / "t1" / name), two = slurp(dir / "t2" / name);
    ASSERT_FALSE(one.empty()) << name;
    EXPECT_TRUE(one == two) << name << " differs between 1 and 2 threads";
  }
  // and the frames moved: the test compares a run, not two copies of the start
  EXPECT_NE(slurp(dir / "t1" / "frame_00000.obj"), slurp(dir / "t1" / "frame_00008.obj"));
}

}  // namespace
