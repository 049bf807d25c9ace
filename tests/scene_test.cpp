// Scene files: the loader's defaults and checks, and the paper's figure scenes checked
// against what each figure shows (Figs 5, 9, 11, 12).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <utility>

#include "run.h"
#include "scene.h"

namespace {

using drape::app::parse_scene;
using drape::app::Scene;
using drape::app::SceneError;

std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "test.json");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(accepted)";
}

const char* minimal = R"({"frames": 2, "sheets": [{"grid": [4, 3], "size": [1, 2], "stiffness": 50}]})";

TEST(SceneFile, MinimalSceneGetsDocumentedDefaults) {
  const Scene s = parse_scene(minimal, "m.json");
  EXPECT_EQ(s.world.dt, 1e-3);
  EXPECT_EQ(s.world.gravity, (drape::Vec3{0, 0, -9.81}));
  EXPECT_EQ(s.world.integrator, drape::Integrator::SemiImplicitEuler);
  EXPECT_EQ(s.precision, drape::app::Precision::Float64);
  EXPECT_EQ(s.substeps, 33);  // round(1 / (30 fps · 1 ms))
  EXPECT_EQ(s.frames, 2);
  ASSERT_EQ(s.sheets.size(), 1u);
  EXPECT_EQ(s.sheets[0].m, 4u);
  EXPECT_EQ(s.sheets[0].n, 3u);
  EXPECT_EQ(s.sheets[0].width, 1.0);
  EXPECT_EQ(s.sheets[0].height, 2.0);
  EXPECT_EQ(s.sheet_names[0], "sheet0");
}

TEST(SceneFile, DurationBecomesWholeFramesOfWholeSubsteps) {
  const Scene s = parse_scene(
      R"({"dt": 0.002, "fps": 25, "duration": 1.0, "sheets": [{"grid": [1, 1], "size": [1, 1], "stiffness": 5}]})", "d.json");
  EXPECT_EQ(s.substeps, 20);  // 1 / (25 · 0.002)
  EXPECT_EQ(s.frames, 25);
}

TEST(SceneFile, AnchorsPinsRegionsAndObstaclesAreRead) {
  const Scene s = parse_scene(R"({"frames": 1, "precision": "float32", "integrator": "forward_euler",
    "sheets": [{"grid": [4, 4], "size": [1, 1], "stiffness": 50,
                "anchors": [{"at": "corners", "stiffness": 7}, {"at": [[2, 3]], "stiffness": 9, "target": [0, 0, 1]}],
                "pins": "center", "stiffness_regions": [{"rows": [0, 1], "columns": [0, 4], "stiffness": 3}]}],
    "obstacles": [{"type": "torus", "major_radius": 0.5, "minor_radius": 0.1, "c": 2, "xi": 0.05},
                  {"type": "plane", "normal": [0, 1, 0]}]})", "a.json");
  EXPECT_EQ(s.precision, drape::app::Precision::Float32);
  EXPECT_EQ(s.world.integrator, drape::Integrator::ForwardEuler);
  const auto& sh = s.sheets[0];
  ASSERT_EQ(sh.anchors.size(), 5u);
  EXPECT_EQ(sh.anchors[4].point, 2u * 5 + 3);
  EXPECT_EQ(sh.anchors[4].target, (drape::Vec3{0, 0, 1}));
  EXPECT_EQ(sh.pins, (std::vector<std::uint32_t>{12}));
  ASSERT_EQ(s.obstacles.size(), 2u);
  EXPECT_EQ(s.obstacles[0].shape, drape::ObstacleShape::Torus);
  EXPECT_EQ(s.obstacles[0].size.x, 0.5);
  // the plane's normal: local +z turned onto world +y
  const drape::Vec3 n = drape::rotate(s.obstacles[1].orientation, {0, 0, 1});
  EXPECT_NEAR(n.x, 0, 1e-12);
  EXPECT_NEAR(n.y, 1, 1e-12);
  EXPECT_NEAR(n.z, 0, 1e-12);
}

// Every class of bad input: one message with the file, the JSON path and the problem.
TEST(SceneFile, EveryBadInputNamesFilePathAndProblem) {
  struct Case {
    std::string text, expected;
  };
  const std::string sheet = R"("grid": [4, 4], "size": [1, 1], "stiffness": 50)";
  const Case cases[] = {
      {"{\"frames\": 1,\n  \"sheets\": [}", "test.json:2:14: syntax error"},
      {R"({"frames": 1})", "test.json: sheets: missing (required)"},
      {R"({"sheets": [{)" + sheet + "}]}", "test.json: frames: missing: the scene needs frames or duration (--frames on the command line only overrides them)"},
      {R"({"frames": 1, "sheets": [{"grid": [4, 4], "size": [1, 1]}]})", "test.json: sheets[0].stiffness: missing"},
      {R"({"frames": "ten", "sheets": [{)" + sheet + "}]}", "test.json: frames: must be a number, got a string"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(, "colour": 1}]})", "test.json: sheets[0].colour: unknown key"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(}], "obstacles": [{"type": "cone"}]})",
       "test.json: obstacles[0].type: unknown obstacle type \"cone\""},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(}], "obstacles": [{"type": "torus", "radius": 1}]})",
       "test.json: obstacles[0].radius: unknown key"},
      {R"({"frames": 1, "sheets": [{"grid": [4, 4], "size": [1, -1], "stiffness": 50}]})",
       "test.json: sheets[0].size[1]: must be positive (got -1)"},
      {R"({"frames": 1, "sheets": [{"grid": [0, 4], "size": [1, 1], "stiffness": 50}]})",
       "test.json: sheets[0].grid[0]: must be between 1 and"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(, "mass": 0}]})", "test.json: sheets[0].mass: must be positive (got 0)"},
      {R"({"frames": 1, "precision": "float32", "sheets": [{"grid": [4, 4], "size": [0.004, 1], "center": [0, 1000, 0], "stiffness": 5}]})",
       "test.json: sheets[0]: width/n = 0.001 m is under 0.0019"},
      {R"({"frames": 1, "sheets": [{"grid": [4, 4], "size": [1, 1], "stiffness": -3}]})",
       "test.json: sheets[0].stiffness: must be positive (got -3)"},
      {R"({"frames": 1, "dt": 0, "sheets": [{)" + sheet + "}]}", "test.json: dt: must be positive (got 0)"},
      {R"({"frames": 1, "dt": 1e999, "sheets": [{)" + sheet + "}]}", "test.json:1:21: number 1e999 is not finite"},
      // frames so long that their substeps do not fit the count (they once wrapped negative)
      {R"({"frames": 1, "fps": 1e-300, "sheets": [{)" + sheet + "}]}",
       "test.json: fps: fps = 1e-300 with dt = 0.001 s makes frames of"},
      {R"({"frames": 1, "fps": 1e-5, "dt": 1e-6, "sheets": [{)" + sheet + "}]}",
       "test.json: fps: fps = 1e-05 with dt = 1e-06 s makes frames of 1e+11 substeps, more than 100000000"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(, "center": [0, NaN, 0]}]})", "test.json:1:90: syntax error"},
      {R"({"frames": 1, "sheets": [{"grid": [3000000000, 3000000000], "size": [1, 1], "stiffness": 5}]})",
       "test.json: sheets[0].grid: grid of 9e+18 points needs about"},
      {R"({"frames": 1, "integrator": "leapfrog", "sheets": [{)" + sheet + "}]}",
       "test.json: integrator: unknown integrator \"leapfrog\""},
      {R"({"frames": 1, "precision": "float16", "sheets": [{)" + sheet + "}]}", "test.json: precision: must be"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(, "anchors": [{"at": [99], "stiffness": 5}]}]})",
       "test.json: sheets[0].anchors[0].at[0]: must be between 0 and 24 (got 99)"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(}], "obstacles": [{"type": "sphere", "radius": 1, "xi": 0}]})",
       "test.json: obstacles[0].xi: must be positive (got 0)"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(, "friction": -0.2}]})",
       "test.json: sheets[0].friction: must not be negative (got -0.2)"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(}], "obstacles": [{"type": "box", "half_extents": [1, 1, 1], "friction": "high"}]})",
       "test.json: obstacles[0].friction: must be a number, got a string"},
      {R"({"frames": 1, "sheets": [{)" + sheet + R"(}], "obstacles": [{"type": "torus", "major_radius": 1, "minor_radius": 0.2, "damping": -3}]})",
       "test.json: obstacles[0].damping: must not be negative (got -3)"},
  };
  for (const auto& c : cases) {
    const std::string message = error_of(c.text);
    EXPECT_EQ(message.rfind(c.expected, 0), 0u) << "input: " << c.text << "\nmessage: " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;  // one line
  }
}

// The engine's knobs: each field reaches WorldDef / SheetDef with the value the file gives,
// and a file without them gets the engine's own defaults.
TEST(SceneFile, EngineKnobsReachTheWorldAndSheetDefinitions) {
  const Scene d = parse_scene(minimal, "m.json");
  const drape::WorldDef engine;
  EXPECT_EQ(d.world.cg_tolerance, engine.cg_tolerance);
  EXPECT_EQ(d.world.cg_max_iterations, engine.cg_max_iterations);
  EXPECT_EQ(d.world.local_global_iterations, engine.local_global_iterations);
  EXPECT_EQ(d.world.vertex_block_iterations, engine.vertex_block_iterations);
  EXPECT_EQ(d.world.adaptive, engine.adaptive);
  EXPECT_EQ(d.world.adaptive_safety, engine.adaptive_safety);
  EXPECT_EQ(d.world.guard, engine.guard);
  EXPECT_EQ(d.world.guard_energy_growth, engine.guard_energy_growth);
  EXPECT_EQ(d.world.contact_thickness, engine.contact_thickness);
  EXPECT_EQ(d.world.contact_xi, engine.contact_xi);
  EXPECT_EQ(d.world.contact_strength, engine.contact_strength);
  EXPECT_EQ(d.world.contact_range, engine.contact_range);
  EXPECT_EQ(d.world.contact_damping, engine.contact_damping);
  EXPECT_EQ(d.world.contact_exact, engine.contact_exact);
  EXPECT_EQ(d.world.block_points, engine.block_points);
  EXPECT_FALSE(d.sheets[0].self_collision);

  const Scene s = parse_scene(R"({"frames": 1, "cg_tolerance": 1e-9, "cg_max_iterations": 17, "cg_preconditioner": "cholesky", "local_global_iterations": 7, "vertex_block_iterations": 9, "adaptive": true,
    "adaptive_safety": 0.5, "guard": false, "guard_energy_growth": 3.5, "contact_thickness": 0.01,
    "contact_xi": 0.004, "contact_strength": 0, "contact_range": 4, "contact_damping": 1.5, "contact_exact": true, "block_points": 1000,
    "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5, "self_collision": true, "friction": 0.4},
               {"grid": [2, 2], "size": [1, 1], "stiffness": 5, "self_collision": false}],
    "obstacles": [{"type": "plane", "friction": 0.7, "damping": 4}]})", "k.json");
  EXPECT_EQ(s.world.cg_tolerance, 1e-9);
  EXPECT_EQ(s.world.cg_max_iterations, 17);
  EXPECT_EQ(s.world.cg_preconditioner, drape::Preconditioner::Cholesky);
  EXPECT_EQ(s.world.local_global_iterations, 7);
  EXPECT_EQ(s.world.vertex_block_iterations, 9);
  EXPECT_TRUE(s.world.adaptive);
  EXPECT_EQ(s.world.adaptive_safety, 0.5);
  EXPECT_FALSE(s.world.guard);
  EXPECT_EQ(s.world.guard_energy_growth, 3.5);
  EXPECT_EQ(s.world.contact_thickness, 0.01);
  EXPECT_EQ(s.world.contact_xi, 0.004);
  EXPECT_EQ(s.world.contact_strength, 0.0);
  EXPECT_EQ(s.world.contact_range, 4.0);
  EXPECT_EQ(s.world.contact_damping, 1.5);
  EXPECT_TRUE(s.world.contact_exact);
  EXPECT_EQ(s.world.block_points, 1000u);
  EXPECT_TRUE(s.sheets[0].self_collision);
  EXPECT_FALSE(s.sheets[1].self_collision);
  EXPECT_EQ(s.sheets[0].friction, 0.4);
  EXPECT_EQ(s.sheets[1].friction, 0.0);
  EXPECT_EQ(s.obstacles[0].friction, 0.7);
  EXPECT_EQ(s.obstacles[0].damping, 4.0);
}

TEST(SceneFile, BadEngineKnobsNameTheirPath) {
  const std::string sheets = R"("sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5}])";
  const std::pair<std::string, std::string> cases[] = {
      {R"("cg_tolerance": 0)", "test.json: cg_tolerance: must be positive (got 0)"},
      {R"("cg_max_iterations": 0)", "test.json: cg_max_iterations: must be between 1 and 2147483647 (got 0)"},
      {R"("cg_max_iterations": 2.5)", "test.json: cg_max_iterations: must be a whole number (got 2.5)"},
      {R"("cg_preconditioner": "ilu")",
       "test.json: cg_preconditioner: must be \"auto\", \"block_jacobi\" or \"cholesky\" (got \"ilu\")"},
      {R"("local_global_iterations": 0)", "test.json: local_global_iterations: must be between 1 and 2147483647 (got 0)"},
      {R"("vertex_block_iterations": 0)", "test.json: vertex_block_iterations: must be between 1 and 2147483647 (got 0)"},
      {R"("adaptive": 1)", "test.json: adaptive: must be true or false, got a number"},
      {R"("adaptive_safety": 1.5)", "test.json: adaptive_safety: must be in (0, 1] (got 1.5)"},
      {R"("adaptive_safety": 0)", "test.json: adaptive_safety: must be positive (got 0)"},
      {R"("guard": "yes")", "test.json: guard: must be true or false, got a string"},
      {R"("guard_energy_growth": 1)", "test.json: guard_energy_growth: must be greater than 1 (got 1)"},
      {R"("contact_thickness": -0.001)", "test.json: contact_thickness: must not be negative (got -0.001)"},
      {R"("contact_xi": 0)", "test.json: contact_xi: must be positive (got 0)"},
      {R"("contact_strength": -1)", "test.json: contact_strength: must not be negative (got -1)"},
      {R"("contact_range": -6)", "test.json: contact_range: must be positive (got -6)"},
      {R"("contact_damping": -0.5)", "test.json: contact_damping: must not be negative (got -0.5)"},
      {R"("block_points": 0)", "test.json: block_points: must be between 1 and 4294967295 (got 0)"},
      {R"("contact_thicknes": 0.01)", "test.json: contact_thicknes: unknown key"},
  };
  for (const auto& [field, expected] : cases) {
    const std::string message = error_of(R"({"frames": 1, )" + field + ", " + sheets + "}");
    EXPECT_EQ(message.rfind(expected, 0), 0u) << "field: " << field << "\nmessage: " << message;
  }
  EXPECT_EQ(error_of(R"({"frames": 1, "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5, "self_collision": 0}]})"),
            "test.json: sheets[0].self_collision: must be true or false, got a number");
}

TEST(SceneFile, ClothTermsAndWindAreReadAndOffByDefault) {
  const Scene d = parse_scene(minimal, "m.json");
  EXPECT_FALSE(d.sheets[0].shear);
  EXPECT_FALSE(d.sheets[0].bending);
  EXPECT_FALSE(d.sheets[0].air);
  EXPECT_EQ(d.world.wind, drape::WorldDef{}.wind);
  const Scene s = parse_scene(R"({"frames": 1, "wind": {"velocity": [3, 0, 1], "density": 1.0},
    "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5, "shear": {"stiffness": 2, "rest_length": 0.6},
                "bending": {"stiffness": 0.3}, "air": {"drag": 1.1, "friction": 0.02}},
               {"grid": [2, 2], "size": [1, 1], "stiffness": 5, "shear": {"stiffness": 2}, "air": {}}]})", "c.json");
  EXPECT_EQ(s.world.wind.velocity, (drape::Vec3{3, 0, 1}));
  EXPECT_EQ(s.world.wind.density, 1.0);
  ASSERT_TRUE(s.sheets[0].shear && s.sheets[0].bending && s.sheets[0].air);
  EXPECT_EQ(s.sheets[0].shear->stiffness, 2.0);
  EXPECT_EQ(s.sheets[0].shear->rest_length, 0.6);
  EXPECT_EQ(s.sheets[0].bending->stiffness, 0.3);
  EXPECT_EQ(s.sheets[0].air->drag, 1.1);
  EXPECT_EQ(s.sheets[0].air->friction, 0.02);
  EXPECT_FALSE(s.sheets[1].shear->rest_length);
  EXPECT_EQ(s.sheets[1].air->drag, drape::AirDef{}.drag);
}

TEST(SceneFile, BadClothTermsNameTheirPath) {
  const std::pair<std::string, std::string> cases[] = {
      {R"("shear": {"stiffness": -2})", "test.json: sheets[0].shear.stiffness: must be positive (got -2)"},
      {R"("shear": {})", "test.json: sheets[0].shear.stiffness: missing (required)"},
      {R"("shear": {"stiffness": 2, "rest_length": -1})", "test.json: sheets[0].shear.rest_length: must not be negative (got -1)"},
      {R"("bending": {"stiffnes": 1})", "test.json: sheets[0].bending.stiffnes: unknown key"},
      {R"("air": {"drag": -1})", "test.json: sheets[0].air.drag: must not be negative (got -1)"},
      {R"("air": 3)", "test.json: sheets[0].air: must be an object"},
  };
  for (const auto& [field, expected] : cases) {
    const std::string message =
        error_of(R"({"frames": 1, "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5, )" + field + "}]}");
    EXPECT_EQ(message.rfind(expected, 0), 0u) << "field: " << field << "\nmessage: " << message;
  }
  EXPECT_EQ(error_of(R"({"frames": 1, "wind": {"density": -1}, "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 5}]})")
                .rfind("test.json: wind.density: must not be negative (got -1)", 0),
            0u);
}

TEST(SceneFile, UnreadableFileIsReported) {
  try {
    drape::app::load_scene("/nonexistent/scene.json");
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent/scene.json: cannot read", 0), 0u) << e.what();
  }
}

// `drape sweep --set`: an override is the same scene as a file that says so.
TEST(SceneFile, SetOverrideReadsAsIfTheFileSaidSo) {
  const std::string two = R"({"frames": 2, "sheets": [{"grid": [4, 3], "size": [1, 2], "stiffness": 50},
    {"grid": [2, 2], "size": [1, 1], "stiffness": 50}]})";
  std::string edited = two;
  for (auto at = edited.find("\"stiffness\": 50"); at != std::string::npos; at = edited.find("\"stiffness\": 50"))
    edited.replace(at, 15, "\"stiffness\": 80");
  edited.insert(1, "\"integrator\": \"forward_euler\", ");
  const drape::app::SceneOverride set[] = {{"sheets[*].stiffness", "80"}, {"integrator", "forward_euler"},
                                           {"sheets[1].damping", "0.5"}};
  const Scene a = parse_scene(two, "t.json", set), b = parse_scene(edited, "t.json");
  ASSERT_EQ(a.sheets.size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) EXPECT_EQ(a.sheets[k].stiffness, b.sheets[k].stiffness);
  EXPECT_EQ(a.sheets[0].stiffness, 80.0);
  EXPECT_EQ(a.world.integrator, drape::Integrator::ForwardEuler);
  EXPECT_EQ(a.sheets[0].damping, 0.0);
  EXPECT_EQ(a.sheets[1].damping, 0.5);
  // the fingerprint tells scenes that give other results apart, and only those
  EXPECT_EQ(parse_scene(two, "x.json").fingerprint, parse_scene(two, "y.json").fingerprint);
  EXPECT_NE(a.fingerprint, parse_scene(two, "t.json").fingerprint);
  EXPECT_NE(b.fingerprint, parse_scene(two, "t.json").fingerprint);
}

TEST(SceneFile, SetOverrideOnAMissingPathNamesIt) {
  auto error = [](const std::string& path) {
    const drape::app::SceneOverride set[] = {{path, "1"}};
    try {
      parse_scene(minimal, "m.json", set);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(error("sheets[1].stiffness"), "m.json: --set sheets[1].stiffness: index 1 is past the end (1 elements)");
  EXPECT_EQ(error("output.dir"), "m.json: --set output.dir: the scene has no \"output\"");
  EXPECT_EQ(error("frames[0]"), "m.json: --set frames[0]: \"[0]\" needs an array, the scene has a number");
  EXPECT_EQ(error("sheets[x].m"), "m.json: --set sheets[x].m: \"[x]\" is not an index or [*]");
  EXPECT_EQ(error("sheets[*].stifness"), "m.json: sheets[0].stifness: unknown key (did you mean \"stiffness\"? known "
                                         "here: name, grid, size, "
                                         "center, orientation, velocity, mass, point_mass, stiffness, "
                                         "stiffness_regions, rest_length, damping, anchors, pins, self_collision, shear, "
                                         "bending, air, friction)");
}

// An unknown key that misspells a known one by a few edits (a third of its length, at least
// one: a letter added, dropped, changed, or two swapped) is named with the key it likely
// means; a key near none is not, nor is one nearer another than the obvious word.
TEST(SceneFile, UnknownKeyNamesTheKnownKeyItMisspells) {
  const std::string sheet = R"("grid": [4, 4], "size": [1, 1], "stiffness": 50)";
  auto top = [&](const std::string& field) { return error_of(R"({"frames": 1, )" + field + R"(, "sheets": [{)" + sheet + "}]}"); };
  auto in_sheet = [&](const std::string& field) { return error_of(R"({"frames": 1, "sheets": [{)" + sheet + ", " + field + "}]}"); };
  const struct {
    std::string message, expected;
  } cases[] = {
      {in_sheet(R"("slef_collision": true)"), "test.json: sheets[0].slef_collision: unknown key (did you mean \"self_collision\"? known here: name,"},
      {in_sheet(R"("frction": 0.5)"), "test.json: sheets[0].frction: unknown key (did you mean \"friction\"? known here:"},
      {in_sheet(R"("Mass": 2)"), "test.json: sheets[0].Mass: unknown key (did you mean \"mass\"? known here:"},
      {top(R"("contact_thicknes": 0.01)"), "test.json: contact_thicknes: unknown key (did you mean \"contact_thickness\"? known here:"},
      {top(R"("dtt": 0.001)"), "test.json: dtt: unknown key (did you mean \"dt\"? known here:"},
      // too far from every key: no guess
      {in_sheet(R"("colour": 1)"), "test.json: sheets[0].colour: unknown key (known here: name,"},
      {in_sheet(R"("stiff": 1)"), "test.json: sheets[0].stiff: unknown key (known here: name,"},
      {top(R"("frame_rate": 30)"), "test.json: frame_rate: unknown key (known here: description,"},
  };
  for (const auto& [message, expected] : cases) EXPECT_EQ(message.rfind(expected, 0), 0u) << message;
}

// An unknown integrator, obstacle type or constraint type is refused with the names the
// loader knows and, where it is a few edits from one of them, that one first.
TEST(SceneFile, UnknownNameListsTheKnownOnesAndTheOneItMisspells) {
  const std::string sheet = R"({"grid": [4, 4], "size": [1, 1], "stiffness": 50})";
  const struct {
    std::string text, expected;
  } cases[] = {
      {R"({"frames": 1, "integrator": "semi_implict_euler", "sheets": [)" + sheet + "]}",
       "test.json: integrator: unknown integrator \"semi_implict_euler\" (did you mean \"semi_implicit_euler\"? known: "
       "forward_euler, semi_implicit_euler,"},
      {R"({"frames": 1, "integrator": "leapfrog", "sheets": [)" + sheet + "]}",
       "test.json: integrator: unknown integrator \"leapfrog\" (known: forward_euler, semi_implicit_euler,"},
      {R"({"frames": 1, "sheets": [)" + sheet + R"(], "obstacles": [{"type": "sphear"}]})",
       "test.json: obstacles[0].type: unknown obstacle type \"sphear\" (did you mean \"sphere\"? known: plane, sphere,"},
      {R"({"frames": 1, "sheets": [)" + sheet + R"(], "obstacles": [{"type": "cone"}]})",
       "test.json: obstacles[0].type: unknown obstacle type \"cone\" (known: plane, sphere,"},
      {R"({"frames": 1, "sheets": [)" + sheet + R"(], "constraints": [{"type": "rial"}]})",
       "test.json: constraints[0].type: unknown constraint type \"rial\" (did you mean \"rail\"? known: point_to_point, "
       "path, frame, rail)"},
  };
  for (const auto& c : cases) {
    const std::string message = error_of(c.text);
    EXPECT_EQ(message.rfind(c.expected, 0), 0u) << message;
  }
}

// Inputs the fuzzer (scene_fuzz) found or that are built like them: each is refused with a
// message naming its file, or read; the sanitizer build checks memory and arithmetic.
TEST(SceneFile, FuzzRegressionInputsAreRefusedOrReadCleanly) {
  std::size_t count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(DRAPE_SCENE_REGRESSIONS)) {
    if (entry.path().extension() == ".md") continue;
    ++count;
    try {
      drape::app::load_scene(entry.path());
    } catch (const SceneError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(entry.path().string() + ":", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(count, 0u);
}

// --- constraints and moving obstacles (issue 14) -----------------------------------------

const char* two_sheets = R"("sheets": [{"name": "left", "grid": [2, 2], "size": [1, 1], "stiffness": 50},
                                         {"name": "right", "grid": [2, 3], "size": [1, 1], "stiffness": 50}])";

TEST(SceneFile, ConstraintsAndMovingObstaclesAreRead) {
  const Scene s = parse_scene(std::string(R"({"frames": 1, )") + two_sheets + R"(,
    "obstacles": [{"type": "sphere", "radius": 0.2, "motion": {"pivot": [0, 0, 1], "repeat": true,
                   "keyframes": [{"time": 0}, {"time": 2, "translation": [1, 0, 0],
                                                  "rotation": {"axis": [0, 0, 1], "degrees": 90}}]}}],
    "constraints": [
      {"type": "point_to_point", "sheet": "left", "points": {"column": 2}, "other_sheet": 1,
       "other_points": {"column": 0}, "stiffness": 400, "rest_length": 0.01},
      {"type": "path", "sheet": "right", "points": {"row": 0}, "stiffness": 10,
       "motion": {"circle": {"center": [0, 0, 0], "start": [1, 0, 0], "period": 3}}},
      {"type": "frame", "sheet": 0, "points": [[2, 2]], "stiffness": 20, "obstacle": 0},
      {"type": "rail", "sheet": "left", "points": "corners", "stiffness": 30, "rail": [[0, 0, 0], [1, 0, 0]]}]})",
                              "c.json");
  ASSERT_TRUE(s.obstacles.at(0).motion.has_value());
  const drape::Motion& m = *s.obstacles[0].motion;
  EXPECT_TRUE(m.repeat);
  ASSERT_EQ(m.keyframes.size(), 2u);
  EXPECT_EQ(m.keyframes[1].translation, (drape::Vec3{1, 0, 0}));
  EXPECT_NEAR(m.keyframes[1].rotation.w, std::sqrt(0.5), 1e-15);
  ASSERT_EQ(s.constraints.size(), 4u);
  const auto& join = s.constraints[0];
  EXPECT_EQ(join.kind, drape::ConstraintKind::PointToPoint);
  EXPECT_EQ(join.sheet.index, 0u);
  EXPECT_EQ(join.other_sheet.index, 1u);
  EXPECT_EQ(join.points, (std::vector<std::uint32_t>{2, 5, 8}));        // column 2 of a 3x3 grid
  EXPECT_EQ(join.other_points, (std::vector<std::uint32_t>{0, 4, 8}));  // column 0 of a 3x4 grid
  EXPECT_EQ(join.rest_length, 0.01);
  EXPECT_EQ(join.stiffness, 400);
  EXPECT_EQ(s.constraints[1].points, (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(s.constraints[1].motion.kind, drape::Motion::Kind::Circle);
  EXPECT_EQ(s.constraints[1].motion.circle.period, 3);
  ASSERT_TRUE(s.constraints[2].carrier.has_value());
  EXPECT_EQ(s.constraints[2].carrier->index, 0u);
  EXPECT_EQ(s.constraints[3].rail.size(), 2u);
  // and the world takes them
  std::vector<drape::SheetId> ids;
  const auto world = drape::app::build_world<double>(s, 1, ids);
  EXPECT_EQ(world.constraint_count(), 4u);
  // A Scene changed by a program after loading (the benchmarks drop its obstacles) is
  // checked again: a constraint naming what is gone is an error that names it.
  Scene without_obstacles = s;
  without_obstacles.obstacles.clear();
  ids.clear();
  try {
    (void)drape::app::build_world<double>(without_obstacles, 1, ids);
    ADD_FAILURE() << "a frame constraint on a missing obstacle was taken";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "c.json: constraints[2] names obstacle 0, but the scene has 0");
  }
  EXPECT_TRUE(ids.empty());  // nothing was built
  Scene one_sheet = s;
  one_sheet.sheets.pop_back();
  EXPECT_THROW((void)drape::app::build_world<double>(one_sheet, 1, ids), SceneError);
  EXPECT_TRUE(ids.empty());
}

TEST(SceneFile, BadConstraintsNameTheirPath) {
  struct Case {
    std::string constraint, expected;
  };
  const std::string p2p = R"("type": "point_to_point", "stiffness": 5, )";
  const Case cases[] = {
      {p2p + R"("sheet": "middle", "points": [0], "other_sheet": 1, "other_points": [0])",
       "test.json: constraints[0].sheet: no sheet is named \"middle\""},
      {p2p + R"("sheet": 2, "points": [0], "other_sheet": 1, "other_points": [0])",
       "test.json: constraints[0].sheet: must be between 0 and 1 (got 2)"},
      {p2p + R"("sheet": 0, "points": [0, 9], "other_sheet": 1, "other_points": [0, 1])",
       "test.json: constraints[0].points[1]: must be between 0 and 8 (got 9)"},
      {p2p + R"("sheet": 0, "points": [[0, 3]], "other_sheet": 1, "other_points": [0])",
       "test.json: constraints[0].points[0][1]: must be between 0 and 2 (got 3)"},
      {p2p + R"("sheet": 0, "points": [4, 3], "other_sheet": "left", "other_points": [1, 3])",
       "test.json: constraints[0]: other_points[1] is points[1] (3) of the same sheet"},
      {p2p + R"("sheet": 0, "points": [4, 3], "other_sheet": 1, "other_points": [1])",
       "test.json: constraints[0]: other_points must pair with points one to one (got 1 for 2)"},
      {R"("type": "rail", "sheet": 0, "points": [0], "stiffness": 5, "rail": [[0, 0, 0]])",
       "test.json: constraints[0]: rail must have at least two knots (got 1)"},
      {R"("type": "path", "sheet": 0, "points": [0], "stiffness": 5, "motion": {"keyframes": [{"time": 0}]})",
       "test.json: constraints[0].motion: keyframes must have at least two knots (got 1)"},
      {R"("type": "path", "sheet": 0, "points": [0], "stiffness": 5,
          "motion": {"keyframes": [{"time": 1}, {"time": 0.5}]})",
       "test.json: constraints[0].motion: keyframes[1].time must be later than keyframes[0].time"},
      {R"("type": "frame", "sheet": 0, "points": [0], "stiffness": 5, "obstacle": 0)",
       "test.json: constraints[0].obstacle: the scene has no obstacles"},
      {R"("type": "hinge", "sheet": 0, "points": [0], "stiffness": 5)",
       "test.json: constraints[0].type: unknown constraint type \"hinge\""},
      {R"("type": "path", "sheet": 0, "points": [0], "stiffness": 0, "motion": {"keyframes": []})",
       "test.json: constraints[0].stiffness: must be positive (got 0)"},
  };
  for (const auto& c : cases) {
    const std::string text = std::string(R"({"frames": 1, )") + two_sheets + R"(, "constraints": [{)" + c.constraint + "}]}";
    const std::string message = error_of(text);
    EXPECT_EQ(message.rfind(c.expected, 0), 0u) << "input: " << text << "\nmessage: " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  EXPECT_EQ(error_of(std::string(R"({"frames": 1, )") + two_sheets +
                     R"(, "obstacles": [{"type": "sphere", "radius": 1, "motion": {"circle": {"center": [0, 0, 0],
                         "start": [0, 0, 1], "period": 1}}}]})")
                .rfind("test.json: obstacles[0].motion: circle.start must not lie on the circle's axis", 0),
            0u);
}

// --- the paper's figures ----------------------------------------------------------------

template <class Real = double>
struct Loaded {
  Scene scene;
  std::vector<drape::SheetId> ids;  // before world: build_world fills it
  drape::BasicWorld<Real> world;
  explicit Loaded(const std::string& name)
      : scene(drape::app::load_scene(std::string(DRAPE_SCENES_DIR) + "/" + name)),
        world(drape::app::build_world<Real>(scene, 0, ids)) {}
  void run() { world.step(scene.frames * scene.substeps); }
};

// Fig 5: stiffer surfaces sag less. The weight is the same for all five, so the sag of the
// centre must fall strictly as k grows (2, 5, 10, 20, 50 N/m).
TEST(PaperScenes, Fig05StifferSurfacesSagLess) {
  Loaded<> l("fig05.json");
  l.run();
  ASSERT_TRUE(l.world.all_finite());
  double previous = 1e9;
  for (std::size_t k = 0; k < l.ids.size(); ++k) {
    const auto& d = l.scene.sheets[k];
    const double sag = d.center.z - l.world.view(l.ids[k]).z[drape::center_point(d.m, d.n)];
    EXPECT_GT(sag, 0);
    EXPECT_LT(sag, previous) << "sheet " << k << " (k = " << d.stiffness << ")";
    previous = sag;
  }
}

// Fig 9: the cloth ends at rest on the ellipsoid: nearly no kinetic energy left, its centre
// just above the top of the ellipsoid, no point inside it.
TEST(PaperScenes, Fig09ClothComesToRestOnTheEllipsoid) {
  Loaded<> l("fig09.json");
  l.run();
  const auto& o = l.scene.obstacles.at(0);
  const auto& d = l.scene.sheets.at(0);
  const auto v = l.world.view(l.ids[0]);
  const double weight = d.mass * 9.81;
  const auto e = l.world.diagnostics(l.ids[0]).energy;
  EXPECT_LT(e.kinetic, 1e-3 * weight * (d.center.z - o.center.z));  // at rest: tiny against the fall
  const double top = o.center.z + o.size.z;
  const double centre = v.z[drape::center_point(d.m, d.n)];
  EXPECT_GT(centre, top);
  EXPECT_LT(centre, top + 10 * o.xi);
  for (std::size_t p = 0; p < v.size(); ++p) {
    const double q = std::pow((v.x[p] - o.center.x) / o.size.x, 2) + std::pow((v.y[p] - o.center.y) / o.size.y, 2) +
                     std::pow((v.z[p] - o.center.z) / o.size.z, 2);
    EXPECT_GT(q, 1.0) << "point " << p << " inside the ellipsoid";
  }
}

// Fig 11: the hole is small: the surface drapes over the torus and its centre never goes
// below the torus's middle plane (it would have to, to fall through).
TEST(PaperScenes, Fig11SheetStaysAboveTheTorus) {
  Loaded<> l("fig11.json");
  const auto& o = l.scene.obstacles.at(0);
  const auto& d = l.scene.sheets.at(0);
  const std::uint32_t c = drape::center_point(d.m, d.n);
  double lowest = 1e9;
  for (int f = 0; f < l.scene.frames; ++f) {
    l.world.step(l.scene.substeps);
    lowest = std::min(lowest, double(l.world.view(l.ids[0]).z[c]));
  }
  ASSERT_TRUE(l.world.all_finite());
  EXPECT_GT(lowest, o.center.z);
  EXPECT_LT(l.world.diagnostics(l.ids[0]).energy.kinetic, 0.01 * d.mass * 9.81);  // settled, not bouncing away
}

// Fig 12: the small sheet passes through the hole and ends entirely below the torus.
TEST(PaperScenes, Fig12SmallSheetEndsBelowTheTorus) {
  Loaded<> l("fig12.json");
  l.run();
  const auto& o = l.scene.obstacles.at(0);
  const auto v = l.world.view(l.ids[0]);
  for (std::size_t p = 0; p < v.size(); ++p) EXPECT_LT(v.z[p], o.center.z - o.size.y) << "point " << p;
}

// The same scene in float32 runs through BasicWorld<float> and agrees with float64 to
// float precision over a short run.
TEST(PaperScenes, Float32PrecisionRunsTheSameScene) {
  Loaded<double> a("fig09.json");
  Loaded<float> b("fig09.json");
  a.world.step(100);
  b.world.step(100);
  const auto va = a.world.view(a.ids[0]);
  const auto vb = b.world.view(b.ids[0]);
  for (std::size_t p = 0; p < va.size(); p += 37) EXPECT_NEAR(va.z[p], vb.z[p], 1e-4);
}

// --- the constraint scenes (issue 14) ------------------------------------------------------

// The sewn cover: its eight seams stay closed (within 1 cm, a tenth of a panel's cell is
// 5 cm) while it drops over the box, and it ends resting on the box, not inside it: the lid's
// centre where eq (9)'s force carries a point's weight, f = ξ·ln(c/(ξ·m·g)), within ξ.
TEST(ConstraintScenes, SewnBoxSeamsStayClosedAndTheCoverRestsOnTheBox) {
  Loaded<> l("sewn_box.json");
  double widest = 0;
  for (int f = 0; f < l.scene.frames; ++f) {
    ASSERT_TRUE(l.world.step(l.scene.substeps).ok()) << "frame " << f;
    for (const drape::ConstraintDef& c : l.scene.constraints) {
      const auto a = l.world.view(l.ids[c.sheet.index]), b = l.world.view(l.ids[c.other_sheet.index]);
      for (std::size_t k = 0; k < c.points.size(); ++k) {
        const auto p = c.points[k], q = c.other_points[k];
        widest = std::max(widest, std::hypot(a.x[p] - b.x[q], a.y[p] - b.y[q], a.z[p] - b.z[q]));
      }
    }
  }
  EXPECT_LT(widest, 0.01);
  const auto& box = l.scene.obstacles.at(0);
  const auto lid = l.world.view(l.ids[0]);
  const double top = box.center.z + box.size.z;
  const double centre = lid.z[drape::center_point(8, 8)];
  const double m = l.scene.sheets.at(0).mass / double(lid.size()), g = -l.scene.world.gravity.z;
  EXPECT_NEAR(centre - top, box.xi * std::log(box.c / (box.xi * m * g)), box.xi);
}

// The curtain: every point of its top row stays within 1 cm of the rail, and the pulled
// corner ends where the path leaves it, round the corner at (1.2, 0.7, 2.0).
TEST(ConstraintScenes, CurtainStaysOnItsRailAndFollowsThePull) {
  Loaded<> l("curtain_rail.json");
  const drape::ConstraintDef& rail = l.scene.constraints.at(0);
  auto distance_to_rail = [&](double x, double y, double z) {
    double best = 1e9;
    for (std::size_t k = 0; k + 1 < rail.rail.size(); ++k) {
      const auto a = rail.rail[k], b = rail.rail[k + 1];
      const double ab[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, ap[3] = {x - a.x, y - a.y, z - a.z};
      const double t = std::clamp((ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2]) /
                                      (ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2]), 0.0, 1.0);
      best = std::min(best, std::hypot(ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]));
    }
    return best;
  };
  double farthest = 0;
  for (int f = 0; f < l.scene.frames; ++f) {
    ASSERT_TRUE(l.world.step(l.scene.substeps).ok()) << "frame " << f;
    const auto v = l.world.view(l.ids[0]);
    for (std::uint32_t p : rail.points) farthest = std::max(farthest, distance_to_rail(v.x[p], v.y[p], v.z[p]));
  }
  EXPECT_LT(farthest, 0.01);
  const auto v = l.world.view(l.ids[0]);
  const std::uint32_t corner = drape::point_index(20, 20, 20);
  EXPECT_NEAR(v.x[corner], 1.2, 0.02);
  EXPECT_NEAR(v.y[corner], 0.7, 0.02);
  EXPECT_NEAR(v.z[corner], 2.0, 0.02);
}

}  // namespace
