// `drape run --format glb` (apps/drape/gltf.h), read back by a reader written here from the
// glTF 2.0 specification: the container, every buffer view and accessor inside its buffer,
// bounds equal to the data, indices inside their vertex lists, unit normals, a valid STEP
// animation; and every frame's positions equal to the run's exact OBJ frames in float32.
#include <gtest/gtest.h>

#include <render/surface.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <limits>

#include "cli_fixture.h"
#include "export.h"

namespace {

using nlohmann::json;

struct Glb {
  json doc;
  std::vector<std::uint8_t> bin;

  // The bytes of accessor a, as floats (component 5126) or unsigned ints (5125), checked.
  template <class T>
  std::vector<T> read(int a) const {
    const json& acc = doc["accessors"].at(a);
    const json& view = doc["bufferViews"].at(acc["bufferView"].get<int>());
    const std::size_t width = acc["type"] == "VEC3" ? 3 : acc["type"] == "SCALAR" ? 1 : 0;
    EXPECT_NE(width, 0u) << "accessor " << a << " type " << acc["type"];
    const std::size_t offset = view.value("byteOffset", 0) + acc.value("byteOffset", 0);
    const std::size_t bytes = acc["count"].get<std::size_t>() * width * sizeof(T);
    EXPECT_LE(acc.value("byteOffset", 0) + bytes, view["byteLength"].get<std::size_t>()) << "accessor " << a;
    EXPECT_EQ(offset % sizeof(T), 0u) << "accessor " << a << " is not aligned";
    std::vector<T> out(acc["count"].get<std::size_t>() * width);
    if (offset + bytes <= bin.size()) std::memcpy(out.data(), bin.data() + offset, bytes);
    return out;
  }
};

std::uint32_t u32(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(s[at + k]);
  return v;
}

// The container and the structure every reader relies on; fails the test where they break.
Glb read_glb(const std::string& bytes) {
  Glb g;
  EXPECT_GE(bytes.size(), 28u);
  if (bytes.size() < 28) return g;
  EXPECT_EQ(u32(bytes, 0), 0x46546C67u);  // "glTF"
  EXPECT_EQ(u32(bytes, 4), 2u);
  EXPECT_EQ(u32(bytes, 8), bytes.size());
  const std::uint32_t json_length = u32(bytes, 12);
  EXPECT_EQ(u32(bytes, 16), 0x4E4F534Au);  // "JSON"
  EXPECT_EQ(json_length % 4, 0u);
  g.doc = json::parse(bytes.substr(20, json_length));
  const std::size_t bin_at = 20 + json_length;
  const std::uint32_t bin_length = u32(bytes, bin_at);
  EXPECT_EQ(u32(bytes, bin_at + 4), 0x004E4942u);  // "BIN\0"
  EXPECT_EQ(bin_at + 8 + bin_length, bytes.size());
  g.bin.assign(bytes.begin() + std::ptrdiff_t(bin_at + 8), bytes.end());

  const json& d = g.doc;
  EXPECT_EQ(d["asset"]["version"], "2.0");
  EXPECT_EQ(d["buffers"].size(), 1u);
  EXPECT_LE(d["buffers"][0]["byteLength"].get<std::size_t>(), g.bin.size());
  EXPECT_GE(d["buffers"][0]["byteLength"].get<std::size_t>() + 3, g.bin.size());
  for (const json& v : d["bufferViews"])
    EXPECT_LE(v.value("byteOffset", 0) + v["byteLength"].get<std::size_t>(), d["buffers"][0]["byteLength"].get<std::size_t>());
  // Bounds, where given, are the data's own.
  for (std::size_t a = 0; a < d["accessors"].size(); ++a) {
    const json& acc = d["accessors"][a];
    if (acc["componentType"] == 5125) {
      (void)g.read<std::uint32_t>(int(a));
      continue;
    }
    EXPECT_EQ(acc["componentType"], 5126);
    const std::vector<float> data = g.read<float>(int(a));
    if (!acc.contains("min")) continue;
    const std::size_t width = acc["min"].size();
    for (std::size_t c = 0; c < width; ++c) {
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (std::size_t k = c; k < data.size(); k += width) lo = std::min(lo, data[k]), hi = std::max(hi, data[k]);
      EXPECT_EQ(acc["min"][c].get<float>(), lo) << "accessor " << a;
      EXPECT_EQ(acc["max"][c].get<float>(), hi) << "accessor " << a;
    }
  }
  // Primitives: indices inside POSITION, positions bounded, unit normals.
  for (const json& mesh : d["meshes"])
    for (const json& p : mesh["primitives"]) {
      const int position = p["attributes"]["POSITION"];
      EXPECT_TRUE(d["accessors"][position].contains("min")) << "POSITION needs bounds";
      const std::size_t vertices = d["accessors"][position]["count"];
      for (std::uint32_t i : g.read<std::uint32_t>(p["indices"])) EXPECT_LT(i, vertices);
      const std::vector<float> n = g.read<float>(p["attributes"]["NORMAL"]);
      EXPECT_EQ(n.size(), vertices * 3);
      for (std::size_t k = 0; k + 2 < n.size(); k += 3)
        EXPECT_NEAR(std::sqrt(n[k] * n[k] + n[k + 1] * n[k + 1] + n[k + 2] * n[k + 2]), 1.0, 1e-5);
    }
  return g;
}

const std::string scene_text = R"({"frames": 5, "dt": 0.001, "fps": 50,
  "camera": {"eye": [2, -3, 1.5], "target": [0, 0, 0.2], "fov_degrees": 35},
  "sheets": [{"name": "a", "grid": [4, 6], "size": [1, 1.2], "center": [0, 0, 0.6], "stiffness": 60},
             {"name": "b", "grid": [3, 3], "size": [0.5, 0.5], "center": [0.2, 0.1, 1.0], "stiffness": 40}],
  "obstacles": [{"type": "sphere", "radius": 0.3, "center": [0, 0, 0.2]},
                {"type": "plane", "center": [0, 0, -0.2]},
                {"type": "box", "half_extents": [0.1, 0.2, 0.1], "center": [0.6, 0, 0]},
                {"type": "torus", "major_radius": 0.3, "minor_radius": 0.05, "center": [-0.6, 0, 0]}]})";

TEST_F(Cli, GlbOfARunValidatesAndHoldsEveryFramesPositions) {
  const fs::path scene = write("s.json", scene_text);
  const fs::path out = dir / "out";
  const Result r = drape("run " + scene.string() + " --out " + out.string() + " --format obj,glb");
  ASSERT_EQ(r.code, 0) << r.err;
  const Glb g = read_glb(slurp(out / "run.glb"));
  const json& d = g.doc;

  // 6 frames (0..5), 4 obstacles, the camera: children of the z-up root
  ASSERT_EQ(d["nodes"][0]["children"].size(), 6u + 4u + 1u);
  EXPECT_EQ(d["scenes"][0]["extras"]["drape"]["frames"], 6);
  for (int f = 0; f <= 5; ++f) {
    const json& node = d["nodes"][1 + f];
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d", f);
    EXPECT_EQ(node["name"], name);
    EXPECT_EQ(node["scale"][0].get<double>(), f == 0 ? 1.0 : 0.0);
    const json& prims = d["meshes"][node["mesh"].get<int>()]["primitives"];
    ASSERT_EQ(prims.size(), 2u);
    // the exact frame, as the OBJ holds it; the glb has it in float32
    const auto frame = drape::app::read_frame<double>(out / (std::string(name) + ".obj"));
    std::size_t at = 0;
    for (int s = 0; s < 2; ++s) {
      const std::vector<float> p = g.read<float>(prims[s]["attributes"]["POSITION"]);
      ASSERT_EQ(p.size(), 3 * frame.sheet_sizes[s]);
      for (std::size_t k = 0; k < frame.sheet_sizes[s]; ++k, ++at) {
        EXPECT_EQ(p[3 * k], float(frame.x[at])) << name << " sheet " << s << " point " << k;
        EXPECT_EQ(p[3 * k + 1], float(frame.y[at]));
        EXPECT_EQ(p[3 * k + 2], float(frame.z[at]));
      }
      // two triangles per grid cell
      EXPECT_EQ(d["accessors"][prims[s]["indices"].get<int>()]["count"], s == 0 ? 4 * 6 * 6 : 3 * 3 * 6);
    }
  }
  // The sheets fall: the last frame is not the first (the round trip is not of a constant).
  const json& first = d["accessors"][d["meshes"][0]["primitives"][0]["attributes"]["POSITION"].get<int>()];
  const json& last = d["accessors"][d["meshes"][5]["primitives"][0]["attributes"]["POSITION"].get<int>()];
  EXPECT_LT(last["min"][2].get<float>(), first["min"][2].get<float>());

  // The STEP animation shows frame k from its time (k·substeps·dt = k·0.02 s) to the next.
  const json& anim = d["animations"][0];
  ASSERT_EQ(anim["channels"].size(), 6u);
  for (int f = 0; f <= 5; ++f) {
    const json& ch = anim["channels"][f];
    EXPECT_EQ(ch["target"]["node"], 1 + f);
    EXPECT_EQ(ch["target"]["path"], "scale");
    const json& sampler = anim["samplers"][ch["sampler"].get<int>()];
    EXPECT_EQ(sampler["interpolation"], "STEP");
    const std::vector<float> t = g.read<float>(sampler["input"]);
    const std::vector<float> s = g.read<float>(sampler["output"]);
    ASSERT_EQ(s.size(), 3 * t.size());
    for (std::size_t k = 1; k < t.size(); ++k) EXPECT_LT(t[k - 1], t[k]) << "times must increase";
    for (std::size_t k = 0; k < t.size(); ++k) {
      const bool shown = std::abs(t[k] - float(f * 0.02)) < 1e-6f;
      EXPECT_EQ(s[3 * k], shown ? 1.0f : 0.0f) << "frame " << f << " key " << k;
    }
  }

  // Obstacles are meshes; the camera stands at the scene's eye looking at its target.
  for (int k = 0; k < 4; ++k) EXPECT_EQ(d["nodes"][7 + k]["name"], "obstacle" + std::to_string(k));
  const json& cam = d["nodes"][11];
  EXPECT_EQ(cam["translation"], json({2.0, -3.0, 1.5}));
  EXPECT_NEAR(d["cameras"][0]["perspective"]["yfov"].get<double>(), 35 * M_PI / 180, 1e-12);
  // the camera looks down its local −z: rotate (0, 0, −1) by its quaternion
  const double qx = cam["rotation"][0], qy = cam["rotation"][1], qz = cam["rotation"][2], qw = cam["rotation"][3];
  const double v[3] = {0, 0, -1};
  const double tx = 2 * (qy * v[2] - qz * v[1]), ty = 2 * (qz * v[0] - qx * v[2]), tz = 2 * (qx * v[1] - qy * v[0]);
  const double look[3] = {v[0] + qw * tx + (qy * tz - qz * ty), v[1] + qw * ty + (qz * tx - qx * tz),
                          v[2] + qw * tz + (qx * ty - qy * tx)};
  const double want[3] = {-2, 3, -1.3}, wl = std::sqrt(4 + 9 + 1.69);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(look[k], want[k] / wl, 1e-12);
}

TEST_F(Cli, GlbOfASurfaceHoldsItsSamples) {
  const fs::path scene = write("s.json", scene_text);
  const fs::path out = dir / "out";
  const Result r = drape("run " + scene.string() + " --frames 2 --out " + out.string() +
                         " --format obj,glb --surface bezier --surface-samples 3");
  ASSERT_EQ(r.code, 0) << r.err;
  const Glb g = read_glb(slurp(out / "run.glb"));
  const auto frame = drape::app::read_frame<double>(out / "frame_00002.obj");
  const json& prim = g.doc["meshes"][2]["primitives"][0];  // frame 2, sheet a: 4×6 cells
  const std::vector<float> p = g.read<float>(prim["attributes"]["POSITION"]);
  ASSERT_EQ(p.size(), 3u * (4 * 3 + 1) * (6 * 3 + 1));
  const std::span<const double> x(frame.x.data(), 35), y(frame.y.data(), 35), z(frame.z.data(), 35);
  const drape::render::SheetMesh grid{4, 6, x, y, z};
  // sample (a, b) is the surface at (u, v) = (a/3, b/3)
  for (int a : {0, 5, 12})
    for (int b : {0, 7, 18}) {
      const auto s = drape::render::surface_point(grid, drape::render::SurfaceKind::Bezier, a / 3.0, b / 3.0);
      const std::size_t k = std::size_t(a) * 19 + b;
      EXPECT_NEAR(p[3 * k], s.p.x, 1e-6);
      EXPECT_NEAR(p[3 * k + 1], s.p.y, 1e-6);
      EXPECT_NEAR(p[3 * k + 2], s.p.z, 1e-6);
    }
  EXPECT_EQ(g.doc["scenes"][0]["extras"]["drape"]["surface"], "bezier");
}

TEST_F(Cli, AGlbAboveFourGibIsRefusedBeforeTheRunSteps) {
  // 101² points sampled 64 times per cell: 6401² vertices × 24 bytes ≈ 938 MiB a frame; 6 frames
  const fs::path scene = write("big.json", R"({"frames": 5, "sheets": [{"grid": [100, 100], "size": [1, 1], "stiffness": 10}]})");
  const fs::path out = dir / "out";
  const Result r = drape("run " + scene.string() + " --out " + out.string() + " --format glb --surface bspline --surface-samples 64");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("6 frames make a glb of at least 5626 MiB, above glTF's 4 GiB"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(Cli, GlbCannotBeResumedAndSaysSo) {
  const fs::path scene = write("s.json", scene_text);
  const fs::path out = dir / "out";
  ASSERT_EQ(drape("run " + scene.string() + " --out " + out.string() + " --checkpoint-every 2").code, 0);
  const Result r = drape("run " + scene.string() + " --resume " + out.string() + " --format glb");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("the glb format holds every frame"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out / "run.glb"));
}

}  // namespace

namespace {

TEST_F(Cli, GlbIsTheSameBytesWithOneAndTwoThreads) {
  const fs::path scene = write("s.json", scene_text);
  std::string bytes[2];
  for (int threads : {1, 2}) {
    std::string name = "threads";  // appended, not "t" + …: GCC 12 warns falsely (-Wrestrict)
    name += std::to_string(threads);
    const fs::path out = dir / name;
    const Result r = drape("run " + scene.string() + " --threads " + std::to_string(threads) + " --out " + out.string() +
                           " --format glb --surface bspline --surface-samples 2");
    ASSERT_EQ(r.code, 0) << r.err;
    bytes[threads - 1] = slurp(out / "run.glb");
  }
  EXPECT_GT(bytes[0].size(), 1000u);
  EXPECT_EQ(bytes[0], bytes[1]);
}

}  // namespace
