// `drape render`, run as a user runs it: the PNG has the asked size and ink exactly where the
// sheet projects (projected here by hand from render.h's camera contract), an output folder
// draws the same pixels as the scene it came from, and every bad input gives one message, its
// exit code and no file.
#include <gtest/gtest.h>
#include <render/render.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <tuple>

#include "cli_fixture.h"
#include "export.h"

namespace {

using RenderCli = Cli;

// A 1 m × 0.8 m sheet, 4×5 cells, centred at the origin in the x–y plane; a sphere below it.
std::string scene_text(const std::string& precision, const std::string& formats) {
  return R"({"frames": 3, "dt": 0.002, "fps": 50, "precision": ")" + precision + R"(",
    "sheets": [{"grid": [4, 5], "size": [1.0, 0.8], "center": [0, 0, 0.3], "stiffness": 40, "mass": 0.2,
                "damping": 0.01}],
    "obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.25, "c": 0.01, "xi": 0.01}],
    "output": {"formats": [)" + formats + "]}}";
}

int ink(const drape::render::Image& img) {
  int count = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      if (img.pixel(x, y) != std::array<std::uint8_t, 3>{255, 255, 255}) ++count;
  return count;
}

TEST_F(RenderCli, SceneFrameZeroHasInkExactlyWhereTheSheetProjects) {
  // no obstacle, so every drawn pixel belongs to the sheet
  const fs::path scene = write("s.json", R"({"frames": 2, "sheets": [{"grid": [4, 5], "size": [1.0, 0.8],
    "center": [0.1, -0.05, 0.2], "stiffness": 40, "mass": 0.2}]})");
  const int w = 200, h = 150;
  const fs::path png = dir / "a.png";
  const Result r = drape("render " + scene.string() + " --frame 0 --size 200x150 --camera \"eye=0.4,-2.5,1.8;target=0,0,0;fov=40\" -o " + png.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto img = drape::render::read_png(png.string());
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);

  // render.h's contract, computed here: f = normalize(target − eye), r = normalize(f × up),
  // u = r × f, sx = w/2 + F·(d·r)/z, sy = h/2 − F·(d·u)/z, F = (h/2)/tan(fov/2).
  const double eye[3] = {0.4, -2.5, 1.8};
  double f[3] = {-eye[0], -eye[1], -eye[2]};
  const double fl = std::hypot(f[0], f[1], f[2]);
  for (double& c : f) c /= fl;
  double rt[3] = {f[1], -f[0], 0};  // f × (0, 0, 1)
  const double rl = std::hypot(rt[0], rt[1]);
  for (double& c : rt) c /= rl;
  const double up[3] = {rt[1] * f[2] - rt[2] * f[1], rt[2] * f[0] - rt[0] * f[2], rt[0] * f[1] - rt[1] * f[0]};
  const double F = (h / 2.0) / std::tan(20.0 * std::numbers::pi / 180);
  double lo_x = 1e9, hi_x = -1e9, lo_y = 1e9, hi_y = -1e9;
  for (int i = 0; i <= 4; ++i)
    for (int j = 0; j <= 5; ++j) {
      // the initial grid: h1 = 1.0/5 along x, h2 = 0.8/4 along y, centred on the sheet's centre
      const double p[3] = {0.1 - 0.5 + j * 0.2, -0.05 - 0.4 + i * 0.2, 0.2};
      const double d[3] = {p[0] - eye[0], p[1] - eye[1], p[2] - eye[2]};
      const double z = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
      const double sx = w / 2.0 + F * (d[0] * rt[0] + d[1] * rt[1] + d[2] * rt[2]) / z;
      const double sy = h / 2.0 - F * (d[0] * up[0] + d[1] * up[1] + d[2] * up[2]) / z;
      lo_x = std::min(lo_x, sx), hi_x = std::max(hi_x, sx), lo_y = std::min(lo_y, sy), hi_y = std::max(hi_y, sy);
      // grid lines cross at every point: the pixel it lands in (or a neighbour) is inked
      bool inked = false;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int px = int(std::floor(sx)) + dx, py = int(std::floor(sy)) + dy;
          if (px >= 0 && py >= 0 && px < w && py < h && img.pixel(px, py)[0] < 200) inked = true;
        }
      EXPECT_TRUE(inked) << "no ink near point (" << i << ", " << j << ") at " << sx << ", " << sy;
    }
  ASSERT_GT(lo_x, 5);
  ASSERT_LT(hi_x, w - 5);
  // outside the projected sheet's box (2 px margin for line width and anti-aliasing): background
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (x < lo_x - 2 || x > hi_x + 2 || y < lo_y - 2 || y > hi_y + 2) {
        ASSERT_EQ(img.pixel(x, y), (std::array<std::uint8_t, 3>{255, 255, 255})) << "ink at " << x << ", " << y;
      }
}

TEST_F(RenderCli, SeveralFramesMakeAStripOfEqualPanels) {
  const fs::path scene = write("s.json", scene_text("float64", "\"obj\""));
  const Result one = drape("render " + scene.string() + " --frame 1 --size 120x90 -o " + (dir / "one.png").string());
  ASSERT_EQ(one.code, 0) << one.err;
  // the automatic camera frames all panels' content: the same frame twice frames the same box
  const Result two = drape("render " + scene.string() + " --frame 1,1 --size 120x90 -o " + (dir / "two.png").string());
  ASSERT_EQ(two.code, 0) << two.err;
  const auto a = drape::render::read_png((dir / "one.png").string());
  const auto b = drape::render::read_png((dir / "two.png").string());
  ASSERT_EQ(b.width, 240);
  ASSERT_EQ(b.height, 90);
  EXPECT_GT(ink(a), 100);
  for (int y = 0; y < 90; ++y)
    for (int x = 1; x < 120; ++x) {  // column 0 of the second panel is the rule between panels
      ASSERT_EQ(b.pixel(x, y), a.pixel(x, y));
      ASSERT_EQ(b.pixel(120 + x, y), a.pixel(x, y));
    }
}

// `drape run` writes frames in exact form, so drawing a frame read back from the folder gives
// the very pixels of drawing the scene simulated to that frame.
TEST_F(RenderCli, OutputFolderDrawsTheSamePixelsAsTheScene) {
  const std::pair<std::string, std::string> cases[] = {
      {"float64", "\"obj\""}, {"float32", "\"vtk\""}, {"float32", "\"ply\""}, {"float64", "\"vtk\", \"ply\""}};
  int k = 0;
  for (const auto& [precision, formats] : cases) {
    const fs::path scene = write("s" + std::to_string(k) + ".json", scene_text(precision, formats));
    const fs::path out = dir / ("out" + std::to_string(k++));
    const Result run = drape("run " + scene.string() + " --out " + out.string());
    ASSERT_EQ(run.code, 0) << run.err;
    EXPECT_TRUE(fs::exists(out / "scene.json"));
    for (const std::string frame : {"", " --frame 2", " --frame 0,3"}) {
      const fs::path a = dir / "from_scene.png", b = dir / "from_folder.png";
      ASSERT_EQ(drape("render " + scene.string() + frame + " --size 160x120 -o " + a.string()).code, 0);
      const Result r = drape("render " + out.string() + frame + " --size 160x120 -o " + b.string());
      ASSERT_EQ(r.code, 0) << r.err;
      const auto ia = drape::render::read_png(a.string()), ib = drape::render::read_png(b.string());
      EXPECT_GT(ink(ia), 100) << precision << formats << frame;
      EXPECT_TRUE(ia.width == ib.width && ia.height == ib.height && ia.rgb == ib.rgb) << precision << formats << frame;
    }
  }
}

TEST_F(RenderCli, EveryBadInputGivesOneMessageItsExitCodeAndNoFile) {
  const fs::path scene = write("s.json", scene_text("float64", "\"obj\""));
  const fs::path out = dir / "out";
  ASSERT_EQ(drape("run " + scene.string() + " --out " + out.string()).code, 0);
  // a folder whose scene.json describes another grid than its frames
  const fs::path other = dir / "other";
  fs::copy(out, other);
  std::string text = scene_text("float64", "\"obj\"");
  text.replace(text.find("[4, 5]"), 6, "[4, 6]");
  std::ofstream(other / "scene.json") << text;
  // a folder with a cut-off frame
  const fs::path cut = dir / "cut";
  fs::copy(out, cut);
  fs::resize_file(cut / "frame_00003.obj", 200);
  const fs::path bare = dir / "bare";
  fs::create_directories(bare);

  // dt far above the stable step: the state is non-finite long before frame 200
  const fs::path unstable = write("unstable.json", R"({"frames": 200, "dt": 0.05, "substeps": 5, "sheets": [{"grid": [6, 6],
    "size": [1, 1], "stiffness": 500, "mass": 0.05, "anchors": [{"at": "corners", "stiffness": 100}]}]})");
  const fs::path png = dir / "p.png";
  const std::string o = " -o " + png.string();
  const std::tuple<std::string, int, std::string> cases[] = {
      {"render " + scene.string() + " --camera \"eye=1,2\"" + o, 2, "drape: --camera: "},
      {"render " + scene.string() + " --camera \"eye=0,0,0;target=0,0,0\"" + o, 2, "drape: --camera: "},
      {"render " + scene.string() + " --camera \"zoom=3\"" + o, 2, "drape: --camera: "},
      {"render " + scene.string() + " --size 800" + o, 2, "drape: --size: "},
      {"render " + scene.string() + " --size 0x10" + o, 2, "drape: --size: "},
      {"render " + scene.string() + " --size 3000x10 --frame 0,1,2" + o, 2, "drape: --size, --frame: "},
      {"render " + scene.string() + " --frame 4" + o, 2, "drape: --frame 4: "},
      {"render " + out.string() + " --frame 7" + o, 2, "drape: --frame 7: " + out.string() + " has no such frame"},
      {"render " + (dir / "nope.json").string() + o, 3, "drape: " + (dir / "nope.json").string() + ": cannot read"},
      {"render " + bare.string() + o, 3, "drape: " + bare.string() + ": not an output folder"},
      {"render " + other.string() + o, 3, "drape: " + (other / "frame_00003.obj").string() + ": holds 30 points"},
      {"render " + cut.string() + o, 3, "drape: " + (cut / "frame_00003.obj").string() + ":"},
      {"render " + scene.string() + " -o " + (dir / "no" / "p.png").string(), 4, "drape: cannot write "},
      {"render " + scene.string() + " -o " + out.string(), 4, "drape: cannot write "},
      {"render " + scene.string() + " -o " + (dir / "p.jpg").string(), 2, "drape: -o " + (dir / "p.jpg").string() + ": drape render writes PNG"},
      {"render " + unstable.string() + o, 1, "drape: " + unstable.string() + ": the simulation became unstable"},
  };
  for (const auto& [args, code, message] : cases) {
    const Result r = drape(args);
    EXPECT_EQ(r.code, code) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind(message, 0), 0u) << args << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(png)) << args;
    EXPECT_FALSE(fs::exists(dir / "no"));
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_NE(e.path().extension(), ".tmp") << args;
  }
  const Result help = drape("render --help");
  EXPECT_EQ(help.code, 0);
}

// The readers behind `drape render DIR` give back exactly the numbers the writers wrote,
// split into the sheets where the format says so.
template <class Real>
void expect_exact_read_back() {
  drape::BasicWorld<Real> world;
  drape::SheetDef a, b;
  a.m = 2, a.n = 3;
  b.m = 1, b.n = 1;
  b.center = {0.3, 0.1, 0.7};
  a.pins = drape::corner_points(a.m, a.n);
  const drape::SheetId ia = world.add_sheet(a), ib = world.add_sheet(b);
  world.step(7);  // positions with full-length mantissas
  std::vector<drape::SheetView<Real>> views{world.view(ia), world.view(ib)};
  const std::string names[] = {"a", "b"};
  for (const std::string ext : {".obj", ".ply", ".vtu"}) {
    std::ostringstream out;
    if (ext == ".obj") drape::app::write_obj<Real>(out, views, names);
    if (ext == ".ply") drape::app::write_ply<Real>(out, views);
    if (ext == ".vtu") drape::app::write_vtu<Real>(out, views);
    const auto f = drape::app::parse_frame<Real>(out.str(), ext, "f" + ext);
    ASSERT_EQ(f.x.size(), 12u + 4u) << ext;
    if (ext == ".ply") EXPECT_TRUE(f.sheet_sizes.empty());
    else EXPECT_EQ(f.sheet_sizes, (std::vector<std::uint64_t>{12, 4})) << ext;
    std::size_t p = 0;
    for (const auto& v : views)
      for (std::size_t q = 0; q < v.size(); ++q, ++p) {
        EXPECT_EQ(f.x[p], v.x[q]) << ext;
        EXPECT_EQ(f.y[p], v.y[q]) << ext;
        EXPECT_EQ(f.z[p], v.z[q]) << ext;
      }
    // cut in the middle of the points: refused with the file's name
    const std::string cut = out.str().substr(0, out.str().size() / 2);
    try {
      const auto g = drape::app::parse_frame<Real>(cut, ext, "cut" + ext);
      if (ext != ".obj") ADD_FAILURE() << ext << " cut in half was read";
      else EXPECT_LT(g.x.size(), 16u);  // an OBJ cut after a whole line is a shorter frame
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("cut" + ext + ":", 0), 0u) << e.what();
    }
  }
}

TEST(FrameReader, ReadsBackEveryFormatExactlyFloat64) { expect_exact_read_back<double>(); }
TEST(FrameReader, ReadsBackEveryFormatExactlyFloat32) { expect_exact_read_back<float>(); }

}  // namespace
