// The browser viewer (apps/viewer) served by `drape view`, in headless Chromium: it loads a run
// of a shipped scene, the sheet shows where the file's camera projects it, and another frame
// gives another picture. The run's .glb also passes the Khronos glTF validator (node).
// Skipped, saying why, where Chromium, node or the built viewer is missing.
#include <gtest/gtest.h>

#include <render/render.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "cli_fixture.h"
#include "export.h"
#include "scene.h"

namespace {

bool executable(const std::string& path) { return !path.empty() && ::access(path.c_str(), X_OK) == 0; }

// `drape view DIR --port 0` in the background; its first line names the port.
class Server {
 public:
  explicit Server(const fs::path& dir) {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDERR_FILENO);
      ::close(fds[0]);
      ::execl(DRAPE_BIN, DRAPE_BIN, "view", dir.c_str(), "--port", "0", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    std::string line;
    char c;
    while (::read(fds[0], &c, 1) == 1 && c != '\n') line += c;
    ::close(fds[0]);
    first_line = line;
    const auto at = line.find("127.0.0.1:");
    if (at != std::string::npos) port = std::atoi(line.c_str() + at + 10);
  }
  ~Server() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  std::string first_line;
  int port = 0;

 private:
  pid_t pid_ = -1;
};

class Viewer : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    if (!executable(DRAPE_CHROMIUM)) GTEST_SKIP() << "Chromium is not installed (tools/setup.sh installs Debian's chromium)";
    if (!fs::exists(fs::path(DRAPE_VIEWER_DIR) / "viewer.js"))
      GTEST_SKIP() << "the viewer is not built (needs npm and the npm registry when building: see apps/viewer)";
  }
  // A screenshot of the page at `query`, 640×480 (the picture is the top 640×432).
  drape::render::Image screenshot(int port, const std::string& query, const std::string& name) {
    const fs::path png = dir / (name + ".png");
    // Built from a named string: GCC 12 at -O3 warns falsely (-Warray-bounds) on
    // "literal" + std::string(...) when the string's header is precompiled.
    std::string cmd = "timeout 60 ";
    cmd += DRAPE_CHROMIUM;
    cmd += " --headless --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader --user-data-dir=";
    cmd += (dir / "profile").string();
    cmd += " --window-size=640,480 --hide-scrollbars --virtual-time-budget=5000 --screenshot=";
    cmd += png.string() + " 'http://127.0.0.1:" + std::to_string(port) + "/" + query + "' > ";
    cmd += (dir / "chromium.log").string() + " 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << slurp(dir / "chromium.log");
    return drape::render::read_png(png.string());
  }
};

TEST_F(Viewer, PlaysAShippedRunShowingTheSheetWhereTheCameraSeesIt) {
  const fs::path scene_file = fs::path(DRAPE_SCENES_DIR) / "fig09.json";
  const fs::path out = dir / "out";
  const Result run = drape("run " + scene_file.string() + " --frames 12 --format obj,glb --out " + out.string());
  ASSERT_EQ(run.code, 0) << run.err;
  Server server(out);
  ASSERT_GT(server.port, 0) << server.first_line;

  const auto first = screenshot(server.port, "?frame=0", "first");
  ASSERT_EQ(first.width, 640);
  ASSERT_EQ(first.height, 480);
  // The file's camera is the scene's; the page shows it over 640×432 pixels: project the
  // sheet's centre of frame 0 with the pinhole of render.h.
  const drape::app::Scene scene = drape::app::load_scene(scene_file);
  ASSERT_TRUE(scene.camera);
  const auto frame = drape::app::read_frame<double>(out / "frame_00000.obj");
  drape::Vec3 c{0, 0, 0};
  for (std::size_t k = 0; k < frame.x.size(); ++k) c = {c.x + frame.x[k], c.y + frame.y[k], c.z + frame.z[k]};
  const double n = double(frame.x.size());
  c = {c.x / n, c.y / n, c.z / n};
  const drape::Vec3 eye = scene.camera->eye, t = scene.camera->target;
  const double f[3] = {t.x - eye.x, t.y - eye.y, t.z - eye.z}, fl = std::hypot(f[0], f[1], f[2]);
  const double fw[3] = {f[0] / fl, f[1] / fl, f[2] / fl};
  const double rw0[3] = {fw[1], -fw[0], 0}, rl = std::hypot(rw0[0], rw0[1]);  // f × (0, 0, 1)
  const double rw[3] = {rw0[0] / rl, rw0[1] / rl, 0};
  const double uw[3] = {rw[1] * fw[2] - rw[2] * fw[1], rw[2] * fw[0] - rw[0] * fw[2], rw[0] * fw[1] - rw[1] * fw[0]};
  const double d[3] = {c.x - eye.x, c.y - eye.y, c.z - eye.z};
  const double x = d[0] * rw[0] + d[1] * rw[1] + d[2] * rw[2], y = d[0] * uw[0] + d[1] * uw[1] + d[2] * uw[2],
               z = d[0] * fw[0] + d[1] * fw[1] + d[2] * fw[2];
  const double focal = 216 / std::tan(scene.camera->fov_degrees * M_PI / 360);
  const int sx = int(320 + focal * x / z), sy = int(216 - focal * y / z);
  // the sheet's front (its +z side, seen from above) in the viewer's orange: red well above blue
  int sheet_pixels = 0;
  for (int py = sy - 3; py <= sy + 3; ++py)
    for (int px = sx - 3; px <= sx + 3; ++px) {
      const auto p = first.pixel(px, py);
      sheet_pixels += p[0] > p[2] + 60;
    }
  EXPECT_GT(sheet_pixels, 40) << "at (" << sx << ", " << sy << "): " << int(first.pixel(sx, sy)[0]) << ","
                              << int(first.pixel(sx, sy)[1]) << "," << int(first.pixel(sx, sy)[2]);
  const std::array<std::uint8_t, 3> white{255, 255, 255};
  EXPECT_EQ(first.pixel(4, 4), white) << "the background away from the content";

  // The slider, moved by ?frame=12 (the page sets it and fires its input event, as a drag
  // does), shows another frame.
  const auto later = screenshot(server.port, "?frame=12", "later");
  int changed = 0;
  for (int py = 0; py < 432; ++py)
    for (int px = 0; px < 640; ++px) changed += later.pixel(px, py) != first.pixel(px, py);
  EXPECT_GT(changed, 1000);
}

TEST_F(Cli, ViewRefusesAFolderWithoutARunAndRenderAnUnknownStyle) {
  const Result view = drape("view " + dir.string() + " --port 0");
  EXPECT_EQ(view.code, 2);
  EXPECT_EQ(view.err, "drape: view " + dir.string() + ": no run.glb there; write one with `drape run SCENE --out " +
                          dir.string() + " --format glb`\n");
  const fs::path scene = write("s.json", R"({"frames": 1, "sheets": [{"grid": [2, 2], "size": [1, 1], "stiffness": 10}]})");
  const Result render = drape("render " + scene.string() + " --style cartoon -o " + (dir / "a.png").string());
  EXPECT_EQ(render.code, 2);
  EXPECT_NE(render.err.find("--style"), std::string::npos) << render.err;
  EXPECT_FALSE(fs::exists(dir / "a.png"));
}

TEST_F(Cli, GlbPassesTheKhronosValidator) {
  const fs::path validate = fs::path(DRAPE_VIEWER_WORK) / "src" / "validate.mjs";
  if (!executable(DRAPE_NODE)) GTEST_SKIP() << "node is not installed";
  if (!fs::exists(fs::path(DRAPE_VIEWER_WORK) / "node_modules" / "gltf-validator"))
    GTEST_SKIP() << "the viewer's npm packages (gltf-validator) are not installed: the viewer is not built";
  const fs::path out = dir / "out";
  for (const std::string surface : {"grid", "bspline"}) {
    const Result run = drape("run " + (fs::path(DRAPE_SCENES_DIR) / "fig09.json").string() +
                             " --frames 3 --format glb --surface " + surface + " --out " + out.string());
    ASSERT_EQ(run.code, 0) << run.err;
    const std::string cmd = std::string(DRAPE_NODE) + " " + validate.string() + " " + (out / "run.glb").string() +
                            " > " + (dir / "report").string() + " 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << slurp(dir / "report");
    EXPECT_EQ(slurp(dir / "report").rfind("errors 0 warnings 0", 0), 0u) << slurp(dir / "report");
  }
}

}  // namespace
