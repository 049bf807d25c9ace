// The .glb writer: binary data appended as frames arrive, the JSON header built at the end.
#include "gltf.h"

#include <render/surface.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace drape::app {

namespace {

constexpr int array_buffer = 34962, element_array_buffer = 34963;
constexpr int float_type = 5126, uint_type = 5125;

// Unit quaternion (x, y, z, w) of the rotation whose matrix has columns a, b, c.
std::array<double, 4> quaternion(Vec3 a, Vec3 b, Vec3 c) {
  const double m00 = a.x, m10 = a.y, m20 = a.z, m01 = b.x, m11 = b.y, m21 = b.z, m02 = c.x, m12 = c.y, m22 = c.z;
  const double trace = m00 + m11 + m22;
  std::array<double, 4> q;
  if (trace > 0) {
    const double s = 0.5 / std::sqrt(trace + 1);
    q = {(m21 - m12) * s, (m02 - m20) * s, (m10 - m01) * s, 0.25 / s};
  } else if (m00 > m11 && m00 > m22) {
    const double s = 2 * std::sqrt(1 + m00 - m11 - m22);
    q = {0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s};
  } else if (m11 > m22) {
    const double s = 2 * std::sqrt(1 + m11 - m00 - m22);
    q = {(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s};
  } else {
    const double s = 2 * std::sqrt(1 + m22 - m00 - m11);
    q = {(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s};
  }
  const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (double& v : q) v /= len;
  return q;
}

Vec3 unit(Vec3 v) {
  const double l = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return {v.x / l, v.y / l, v.z / l};
}
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }

// Vertices as float triples; a zero normal (degenerate surface) becomes +z, as glTF wants unit normals.
std::vector<float> floats(std::span<const Vec3> v, bool normals) {
  std::vector<float> out;
  out.reserve(v.size() * 3);
  for (Vec3 p : v) {
    if (normals && p.x == 0 && p.y == 0 && p.z == 0) p = {0, 0, 1};
    out.insert(out.end(), {float(p.x), float(p.y), float(p.z)});
  }
  return out;
}

// Two triangles per cell of a rows × cols sample grid, wound like the OBJ quads (export.cpp):
// counter-clockwise seen from the side the normals point to.
std::vector<std::uint32_t> grid_triangles(std::uint32_t rows, std::uint32_t cols) {
  std::vector<std::uint32_t> t;
  t.reserve(std::size_t(rows - 1) * (cols - 1) * 6);
  for (std::uint32_t i = 0; i + 1 < rows; ++i)
    for (std::uint32_t j = 0; j + 1 < cols; ++j) {
      const std::uint32_t a = i * cols + j, b = a + 1, c = a + cols + 1, d = a + cols;
      t.insert(t.end(), {a, b, c, a, c, d});
    }
  return t;
}

std::uint32_t checked_samples(GltfOptions options) {
  if (options.samples_per_cell < 1 || options.samples_per_cell > 64)
    throw std::invalid_argument("glTF: samples per cell must be 1..64 (got " + std::to_string(options.samples_per_cell) + ")");
  return std::uint32_t(options.samples_per_cell);
}
}  // namespace

GltfRun::GltfRun(const Scene& scene, GltfOptions options) : scene_(scene), options_(options) {
  checked_samples(options);
  for (std::size_t k = 0; k < scene.sheets.size(); ++k) {
    const SheetDef& s = scene.sheets[k];
    const std::uint32_t rows = s.m * std::uint32_t(options.samples_per_cell) + 1;
    const std::uint32_t cols = s.n * std::uint32_t(options.samples_per_cell) + 1;
    const std::vector<std::uint32_t> t = grid_triangles(rows, cols);
    const int view = add_view(t.data(), t.size() * 4, element_array_buffer);
    const int acc = add_accessor({view, uint_type, t.size(), "SCALAR", {}, {}});
    sheets_.push_back({k < scene.sheet_names.size() ? scene.sheet_names[k] : "sheet" + std::to_string(k), s.m, s.n, acc});
  }
}

std::uint64_t GltfRun::frame_bytes(const Scene& scene, GltfOptions options, std::uint64_t frames) {
  std::uint64_t vertices = 0;
  const std::uint64_t k = checked_samples(options);
  for (const SheetDef& s : scene.sheets) vertices += (s.m * k + 1) * (s.n * k + 1);
  return frames * vertices * 2 * 3 * sizeof(float);
}

int GltfRun::add_view(const void* data, std::size_t bytes, int target) {
  while (bin_.size() % 4) bin_.push_back(0);  // every component is 4 bytes wide
  const std::size_t offset = bin_.size();
  bin_.resize(offset + bytes);
  std::memcpy(bin_.data() + offset, data, bytes);
  views_.push_back({offset, bytes, target});
  return int(views_.size() - 1);
}

int GltfRun::add_accessor(Accessor a) {
  accessors_.push_back(std::move(a));
  return int(accessors_.size() - 1);
}

int GltfRun::add_floats(std::span<const float> v, const char* type, int target, bool bounds) {
  const std::size_t width = std::string_view(type) == "VEC3" ? 3 : 1;
  std::vector<float> lo, hi;
  if (bounds) {
    lo.assign(width, std::numeric_limits<float>::infinity());
    hi.assign(width, -std::numeric_limits<float>::infinity());
    for (std::size_t k = 0; k < v.size(); ++k) {
      lo[k % width] = std::min(lo[k % width], v[k]);
      hi[k % width] = std::max(hi[k % width], v[k]);
    }
  }
  const int view = add_view(v.data(), v.size() * sizeof(float), target);
  return add_accessor({view, float_type, v.size() / width, type, std::move(lo), std::move(hi)});
}

template <class Real>
void GltfRun::add_frame(std::span<const SheetView<Real>> sheets, double time) {
  auto& primitives = frame_primitives_.emplace_back();
  for (std::size_t k = 0; k < sheets.size() && k < sheets_.size(); ++k) {
    const SheetView<Real>& v = sheets[k];
    const std::vector<double> x(v.x.begin(), v.x.end()), y(v.y.begin(), v.y.end()), z(v.z.begin(), v.z.end());
    const render::SurfaceMesh s =
        render::sample_surface({v.m, v.n, x, y, z}, options_.surface, options_.samples_per_cell);
    for (Vec3 p : s.points) content_.add(p);
    const std::vector<float> points = floats(s.points, false), normals = floats(s.normals, true);
    const int position = add_floats(points, "VEC3", array_buffer, true);
    const int normal = add_floats(normals, "VEC3", array_buffer, false);
    primitives.emplace_back(position, normal);
  }
  times_.push_back(time);
}
template void GltfRun::add_frame<double>(std::span<const SheetView<double>>, double);
template void GltfRun::add_frame<float>(std::span<const SheetView<float>>, double);

void GltfRun::write(std::ostream& out) {
  using nlohmann::json;
  json doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "drape"}};
  json materials = json::array();
  materials.push_back({{"name", "sheet"},
                       {"doubleSided", true},
                       {"pbrMetallicRoughness", {{"baseColorFactor", {0.77, 0.26, 0.04, 1.0}}, {"metallicFactor", 0.0}, {"roughnessFactor", 0.8}}}});
  materials.push_back({{"name", "obstacle"},
                       {"pbrMetallicRoughness", {{"baseColorFactor", {0.43, 0.44, 0.47, 1.0}}, {"metallicFactor", 0.0}, {"roughnessFactor", 0.6}}}});

  json meshes = json::array(), nodes = json::array();
  json root_children = json::array();
  nodes.push_back({{"name", "drape (z up)"}, {"rotation", {-std::numbers::sqrt2 / 2, 0.0, 0.0, std::numbers::sqrt2 / 2}}});
  const int frames = int(frame_primitives_.size());
  for (int f = 0; f < frames; ++f) {
    json prims = json::array();
    for (std::size_t k = 0; k < frame_primitives_[f].size(); ++k)
      prims.push_back({{"attributes", {{"POSITION", frame_primitives_[f][k].first}, {"NORMAL", frame_primitives_[f][k].second}}},
                       {"indices", sheets_[k].indices},
                       {"material", 0}});
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d", f);
    meshes.push_back({{"name", name}, {"primitives", prims}});
    const double scale = f == 0 ? 1.0 : 0.0;  // a reader without animation shows frame 0
    nodes.push_back({{"name", name}, {"mesh", int(meshes.size() - 1)}, {"scale", {scale, scale, scale}}});
    root_children.push_back(int(nodes.size() - 1));
  }
  for (std::size_t k = 0; k < scene_.obstacles.size(); ++k) {
    const render::TriangleMesh m = render::obstacle_mesh(scene_.obstacles[k], content_);
    const int position = add_floats(floats(m.points, false), "VEC3", array_buffer, true);
    const int normal = add_floats(floats(m.normals, true), "VEC3", array_buffer, false);
    const int view = add_view(m.triangles.data(), m.triangles.size() * 4, element_array_buffer);
    const int indices = add_accessor({view, uint_type, m.triangles.size(), "SCALAR", {}, {}});
    const std::string name = "obstacle" + std::to_string(k);
    meshes.push_back({{"name", name},
                      {"primitives", json::array({{{"attributes", {{"POSITION", position}, {"NORMAL", normal}}},
                                                   {"indices", indices},
                                                   {"material", 1}}})}});
    nodes.push_back({{"name", name}, {"mesh", int(meshes.size() - 1)}});
    root_children.push_back(int(nodes.size() - 1));
  }

  // The camera: the scene's, or the automatic framing of every frame and obstacle.
  render::Camera cam;
  if (scene_.camera) {
    cam = {scene_.camera->eye, scene_.camera->target, scene_.camera->up, scene_.camera->fov_degrees};
  } else {
    render::Bounds all = content_;
    all.add(render::scene_bounds({}, scene_.obstacles));
    cam = render::Camera::looking_at_bounds(all, 4.0 / 3.0);
  }
  const Vec3 f = unit({cam.target.x - cam.eye.x, cam.target.y - cam.eye.y, cam.target.z - cam.eye.z});
  const Vec3 r = unit(cross(f, cam.up)), u = cross(r, f);
  const auto q = quaternion(r, u, {-f.x, -f.y, -f.z});  // a glTF camera looks down its −z, y up
  const double distance = std::hypot(cam.target.x - cam.eye.x, cam.target.y - cam.eye.y, cam.target.z - cam.eye.z);
  json cameras = json::array({{{"name", "camera"},
                               {"type", "perspective"},
                               {"perspective", {{"yfov", cam.fov_deg * std::numbers::pi / 180}, {"znear", 0.01 * distance},
                                                {"aspectRatio", 4.0 / 3.0}}}}});
  nodes.push_back({{"name", "camera"}, {"camera", 0}, {"translation", {cam.eye.x, cam.eye.y, cam.eye.z}},
                   {"rotation", {q[0], q[1], q[2], q[3]}}});
  root_children.push_back(int(nodes.size() - 1));
  nodes[0]["children"] = root_children;

  // The animation: frame k's node has scale 1 from its time to the next frame's, 0 elsewhere.
  json samplers = json::array(), channels = json::array();
  if (frames > 1) {
    const double t0 = times_.front();
    for (int k = 0; k < frames; ++k) {
      std::vector<float> keys, scales;
      auto key = [&](double t, float s) {
        keys.push_back(float(t - t0));
        scales.insert(scales.end(), {s, s, s});
      };
      if (k > 0) key(t0, 0);
      key(times_[k], 1);
      if (k + 1 < frames) key(times_[k + 1], 0);
      const int input = add_floats(keys, "SCALAR", 0, true);
      const int output = add_floats(scales, "VEC3", 0, false);
      samplers.push_back({{"input", input}, {"output", output}, {"interpolation", "STEP"}});
      channels.push_back({{"sampler", k}, {"target", {{"node", 1 + k}, {"path", "scale"}}}});
    }
    doc["animations"] = json::array({{{"name", "run"}, {"samplers", samplers}, {"channels", channels}}});
  }

  json views = json::array(), accessors = json::array();
  for (const View& v : views_) {
    json j = {{"buffer", 0}, {"byteOffset", v.offset}, {"byteLength", v.length}};
    if (v.target) j["target"] = v.target;
    views.push_back(j);
  }
  for (const Accessor& a : accessors_) {
    json j = {{"bufferView", a.view}, {"componentType", a.component}, {"count", a.count}, {"type", a.type}};
    if (!a.lo.empty()) {
      j["min"] = a.lo;
      j["max"] = a.hi;
    }
    accessors.push_back(j);
  }
  json sheet_info = json::array();
  for (const SheetLayout& s : sheets_)
    sheet_info.push_back({{"name", s.name}, {"m", s.m}, {"n", s.n},
                          {"rows", s.m * std::uint32_t(options_.samples_per_cell) + 1},
                          {"cols", s.n * std::uint32_t(options_.samples_per_cell) + 1}});
  doc["scene"] = 0;
  doc["scenes"] = json::array({{{"name", scene_.file},
                                {"nodes", {0}},
                                {"extras", {{"drape", {{"frames", frames},
                                                       {"times", times_},
                                                       {"surface", render::surface_kind_name(options_.surface)},
                                                       {"samples_per_cell", options_.samples_per_cell},
                                                       {"sheets", sheet_info}}}}}}});
  doc["nodes"] = nodes;
  doc["meshes"] = meshes;
  doc["materials"] = materials;
  doc["cameras"] = cameras;
  doc["accessors"] = accessors;
  doc["bufferViews"] = views;
  while (bin_.size() % 4) bin_.push_back(0);
  doc["buffers"] = json::array({{{"byteLength", bin_.size()}}});

  std::string text = doc.dump();
  while (text.size() % 4) text.push_back(' ');  // the JSON chunk is padded with spaces
  auto u32 = [&](std::uint32_t v) {
    const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                                static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
    out.write(reinterpret_cast<const char*>(b), 4);
  };
  const std::uint64_t total = 12 + 8 + text.size() + 8 + bin_.size();
  if (total > max_bytes)
    throw std::runtime_error("the run is " + std::to_string(total >> 20) + " MiB as glTF, above the format's 4 GiB; "
                             "write fewer frames or fewer surface samples");
  u32(0x46546C67);  // "glTF"
  u32(2);
  u32(std::uint32_t(total));
  u32(std::uint32_t(text.size()));
  u32(0x4E4F534A);  // "JSON"
  out.write(text.data(), std::streamsize(text.size()));
  u32(std::uint32_t(bin_.size()));
  u32(0x004E4942);  // "BIN"
  out.write(reinterpret_cast<const char*>(bin_.data()), std::streamsize(bin_.size()));
}

}  // namespace drape::app
