// Scene loader: JSON → WorldDef, SheetDefs, ObstacleDefs. Every check names the JSON path
// of the field it rejects, so a user can find the line to fix.
#include "scene.h"

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <numbers>
#include <span>
#include <sstream>
#include <string_view>
#include <vector>

#include "checkpoint.h"

namespace drape::app {

using nlohmann::json;

std::string_view precision_name(Precision p) { return p == Precision::Float32 ? "float32" : "float64"; }

std::string_view mesh_format_name(MeshFormat f) {
  switch (f) {
    case MeshFormat::Obj: return "obj";
    case MeshFormat::Ply: return "ply";
    case MeshFormat::Vtk: return "vtk";
    case MeshFormat::Glb: return "glb";
  }
  return "unknown";
}

std::optional<MeshFormat> mesh_format_from_name(std::string_view name) {
  for (MeshFormat f : {MeshFormat::Obj, MeshFormat::Ply, MeshFormat::Vtk, MeshFormat::Glb})
    if (mesh_format_name(f) == name) return f;
  return std::nullopt;
}

std::uint64_t physical_memory_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : 0;
}

std::uint64_t estimated_bytes(const SheetDef& s, Precision precision) {
  const double real = precision == Precision::Float32 ? 4 : 8;
  const double points = (double(s.m) + 1) * (double(s.n) + 1);
  const double springs = (double(s.m) + 1) * s.n + double(s.m) * (s.n + 1);
  // per point: position, velocity, force (3 each), mass, 1/mass, damping, and up to 12 values
  // of integrator scratch; per spring: two endpoint indices, rest length, stiffness
  const double bytes = points * 24 * real + springs * (8 + 2 * real);
  return bytes >= 1.8e19 ? std::uint64_t(-1) : std::uint64_t(bytes);
}

std::uint64_t estimated_bytes(const Scene& scene) {
  std::uint64_t total = 0;
  for (const auto& s : scene.sheets) {
    const std::uint64_t b = estimated_bytes(s, scene.precision);
    total = b > std::uint64_t(-1) - total ? std::uint64_t(-1) : total + b;
  }
  return total;
}

namespace {

std::string type_name(const json& j) {
  switch (j.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::string: return "a string";
    case json::value_t::array: return "an array";
    case json::value_t::object: return "an object";
    case json::value_t::number_float:
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return "a number";
    default: return "something else";
  }
}

std::string number_text(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// The edits (insert, delete, replace a character, or swap two neighbours) that turn a into
// b: the optimal string alignment distance (Damerau–Levenshtein without repeated edits of a
// substring), enough to tell a typo from another word.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The known word an unknown one most likely misspells: the nearest within a third of its
// length (at least one edit), the first of equally near ones; empty when none is that near.
std::string_view likely_word(std::string_view word, std::span<const std::string_view> known) {
  std::string_view best;
  std::size_t best_distance = std::max<std::size_t>(1, word.size() / 3) + 1;
  for (auto k : known) {
    const std::size_t distance = edit_distance(word, k);
    if (distance < best_distance) {
      best = k;
      best_distance = distance;
    }
  }
  return best;
}

// `known` as a list for a message ("a, b, c"), after a guess at the one `word` misspells if
// there is one near it (likely_word): `did you mean "b"? known: a, b, c`.
std::string known_words(std::string_view word, std::span<const std::string_view> known, std::string_view label) {
  std::string list;
  for (auto k : known) list += (list.empty() ? "" : ", ") + std::string(k);
  const std::string_view likely = likely_word(word, known);
  const std::string guess = likely.empty() ? "" : "did you mean \"" + std::string(likely) + "\"? ";
  return guess + std::string(label) + ": " + list;
}

// Reading context: the file name for messages and one JSON node with its path.
class Node {
 public:
  Node(const std::string& file, const json& j, std::string path) : file_(file), j_(j), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& problem) const {
    throw SceneError(file_ + ": " + (path_.empty() ? std::string("(top level)") : path_) + ": " + problem);
  }
  const json& value() const { return j_; }
  const std::string& path() const { return path_; }

  // An object whose keys must all be among `known` (unknown keys are errors: a typo must
  // not silently fall back to a default).
  void expect_object(std::initializer_list<std::string_view> known) const {
    if (!j_.is_object()) fail("must be an object, got " + type_name(j_));
    for (const auto& item : j_.items()) {
      if (std::find(known.begin(), known.end(), item.key()) == known.end())
        child(item.key()).fail("unknown key (" + known_words(item.key(), {known.begin(), known.size()}, "known here") + ")");
    }
  }
  bool has(const char* key) const { return j_.contains(key); }
  Node child(const std::string& key) const {
    static const json null_value;
    const std::string p = path_.empty() ? key : path_ + "." + key;
    return Node(file_, j_.contains(key) ? j_.at(key) : null_value, p);
  }
  Node at(std::size_t i) const { return Node(file_, j_.at(i), path_ + "[" + std::to_string(i) + "]"); }
  Node required(const char* key) const {
    if (!has(key)) child(key).fail("missing (required)");
    return child(key);
  }

  double number() const {
    if (!j_.is_number()) fail("must be a number, got " + type_name(j_));
    const double v = j_.get<double>();
    if (!std::isfinite(v)) fail("must be finite (got " + number_text(v) + ")");
    return v;
  }
  double positive() const {
    const double v = number();
    if (!(v > 0)) fail("must be positive (got " + number_text(v) + ")");
    return v;
  }
  double non_negative() const {
    const double v = number();
    if (v < 0) fail("must not be negative (got " + number_text(v) + ")");
    return v;
  }
  std::uint64_t whole(std::uint64_t lowest, std::uint64_t highest) const {
    const double v = number();
    if (v != std::floor(v)) fail("must be a whole number (got " + number_text(v) + ")");
    if (v < double(lowest) || v > double(highest))
      fail("must be between " + std::to_string(lowest) + " and " + std::to_string(highest) + " (got " +
           number_text(v) + ")");
    return std::uint64_t(v);
  }
  bool boolean() const {
    if (!j_.is_boolean()) fail("must be true or false, got " + type_name(j_));
    return j_.get<bool>();
  }
  std::string string() const {
    if (!j_.is_string()) fail("must be a string, got " + type_name(j_));
    return j_.get<std::string>();
  }
  std::size_t array(std::size_t min_size = 0) const {
    if (!j_.is_array()) fail("must be an array, got " + type_name(j_));
    if (j_.size() < min_size) fail("must have at least " + std::to_string(min_size) + " entries");
    return j_.size();
  }
  std::vector<double> numbers(std::size_t count) const {
    if (!j_.is_array() || j_.size() != count)
      fail("must be an array of " + std::to_string(count) + " numbers, got " +
           (j_.is_array() ? "an array of " + std::to_string(j_.size()) : type_name(j_)));
    std::vector<double> out;
    for (std::size_t i = 0; i < count; ++i) out.push_back(at(i).number());
    return out;
  }
  Vec3 vec3() const {
    const auto v = numbers(3);
    return {v[0], v[1], v[2]};
  }
  std::vector<double> positives(std::size_t count) const {
    numbers(count);
    std::vector<double> out;
    for (std::size_t i = 0; i < count; ++i) out.push_back(at(i).positive());
    return out;
  }

 private:
  const std::string& file_;
  const json& j_;
  std::string path_;
};

// A rotation: {"axis": [x, y, z], "degrees": a} or a unit quaternion [w, x, y, z].
Quat read_orientation(const Node& node) {
  if (node.value().is_array()) {
    const auto q = node.numbers(4);
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (std::abs(norm - 1) > 1e-6) node.fail("must be a unit quaternion [w, x, y, z] (its norm is " + number_text(norm) + ")");
    return {q[0], q[1], q[2], q[3]};
  }
  node.expect_object({"axis", "degrees"});
  const Vec3 axis = node.required("axis").vec3();
  if (axis.x == 0 && axis.y == 0 && axis.z == 0) node.child("axis").fail("must not be the zero vector");
  const double degrees = node.required("degrees").number();
  return quat_from_axis_angle(axis, degrees * std::numbers::pi / 180);
}

// The rotation that turns local +z into `normal` (the shortest arc).
Quat rotation_to(const Node& node, Vec3 normal) {
  const double len = std::sqrt(normal.x * normal.x + normal.y * normal.y + normal.z * normal.z);
  if (len == 0) node.fail("must not be the zero vector");
  const Vec3 n{normal.x / len, normal.y / len, normal.z / len};
  const Vec3 axis{-n.y, n.x, 0};  // z × n
  const double s = std::sqrt(axis.x * axis.x + axis.y * axis.y);
  if (s == 0) return n.z > 0 ? Quat{} : quat_from_axis_angle({1, 0, 0}, std::numbers::pi);
  return quat_from_axis_angle(axis, std::atan2(s, n.z));
}

// A set of grid points: "corners", "center"/"centre", {"row": i} or {"column": j} (the
// whole row or column, in grid order), or a list of point indices or [i, j] pairs.
std::vector<std::uint32_t> read_points(const Node& node, std::uint32_t m, std::uint32_t n) {
  if (node.value().is_object()) {
    if (node.has("row")) {
      node.expect_object({"row"});
      return row_points(m, n, std::uint32_t(node.child("row").whole(0, m)));
    }
    node.expect_object({"column"});
    return column_points(m, n, std::uint32_t(node.required("column").whole(0, n)));
  }
  if (node.value().is_string()) {
    const std::string s = node.string();
    if (s == "corners") return corner_points(m, n);
    if (s == "center" || s == "centre") return {center_point(m, n)};
    node.fail("must be \"corners\", \"center\" or a list of points (got \"" + s + "\")");
  }
  const std::size_t count = node.array(1);
  const std::uint64_t points = std::uint64_t(m + 1) * (n + 1);
  std::vector<std::uint32_t> out;
  for (std::size_t k = 0; k < count; ++k) {
    const Node p = node.at(k);
    if (p.value().is_array()) {
      if (p.value().size() != 2) p.fail("must be a point index or a pair [row, column]");
      const auto i = p.at(0).whole(0, m), j = p.at(1).whole(0, n);
      out.push_back(point_index(n, std::uint32_t(i), std::uint32_t(j)));
    } else {
      out.push_back(std::uint32_t(p.whole(0, points - 1)));
    }
  }
  return out;
}

SheetDef read_sheet(const Node& node, Precision precision, std::string& name, std::size_t index) {
  node.expect_object({"name", "grid", "size", "center", "orientation", "velocity", "mass", "point_mass", "stiffness",
                      "stiffness_regions", "rest_length", "damping", "anchors", "pins", "self_collision", "shear",
                      "bending", "air", "friction"});
  SheetDef s;
  name = node.has("name") ? node.child("name").string() : "sheet" + std::to_string(index);
  const Node grid = node.required("grid");
  grid.numbers(2);
  // at most 2^32 − 2 cells a side, so (m + 1) stays a 32-bit count; memory decides the rest
  s.m = std::uint32_t(grid.at(0).whole(1, 4294967294u));
  s.n = std::uint32_t(grid.at(1).whole(1, 4294967294u));
  const std::uint64_t bytes = estimated_bytes(s, precision), memory = physical_memory_bytes();
  if (memory > 0 && bytes > memory) {
    std::ostringstream out;
    out << "grid of " << (double(s.m) + 1) * (double(s.n) + 1) << " points needs about " << double(bytes) / 1e9
        << " GB, more than this machine's " << double(memory) / 1e9 << " GB of memory";
    grid.fail(out.str());
  }
  const std::uint64_t points = std::uint64_t(s.m + 1) * (s.n + 1);
  if (points > (std::uint64_t(1) << 31)) grid.fail("gives " + std::to_string(points) + " points; a sheet holds at most 2^31");

  const auto size = node.required("size").positives(2);
  s.width = size[0];
  s.height = size[1];
  if (node.has("center")) s.center = node.child("center").vec3();
  if (node.has("orientation")) s.orientation = read_orientation(node.child("orientation"));
  if (node.has("velocity")) s.initial_velocity = node.child("velocity").vec3();
  if (node.has("mass") && node.has("point_mass")) node.child("point_mass").fail("give either mass or point_mass, not both");
  if (node.has("point_mass")) {
    s.point_masses.assign(points, node.child("point_mass").positive());
  } else {
    s.mass = node.has("mass") ? node.child("mass").positive() : s.mass;
  }
  s.stiffness = node.required("stiffness").positive();
  if (node.has("stiffness_regions")) {
    const Node regions = node.child("stiffness_regions");
    for (std::size_t k = 0, count = regions.array(); k < count; ++k) {
      const Node r = regions.at(k);
      r.expect_object({"rows", "columns", "stiffness"});
      const Node rows = r.required("rows"), cols = r.required("columns");
      rows.numbers(2);
      cols.numbers(2);
      StiffnessRegion reg;
      reg.row_begin = std::uint32_t(rows.at(0).whole(0, s.m));
      reg.row_end = std::uint32_t(rows.at(1).whole(reg.row_begin, s.m));
      reg.col_begin = std::uint32_t(cols.at(0).whole(0, s.n));
      reg.col_end = std::uint32_t(cols.at(1).whole(reg.col_begin, s.n));
      reg.stiffness = r.required("stiffness").positive();
      s.stiffness_regions.push_back(reg);
    }
  }
  if (node.has("rest_length")) {
    const auto rest = node.child("rest_length").numbers(2);
    for (std::size_t k = 0; k < 2; ++k) node.child("rest_length").at(k).non_negative();
    s.rest_length_h = rest[0];
    s.rest_length_v = rest[1];
  }
  if (node.has("damping")) s.damping = node.child("damping").non_negative();
  if (node.has("anchors")) {
    const Node anchors = node.child("anchors");
    for (std::size_t k = 0, count = anchors.array(); k < count; ++k) {
      const Node a = anchors.at(k);
      a.expect_object({"at", "stiffness", "target"});
      const auto pts = read_points(a.required("at"), s.m, s.n);
      const double k_anchor = a.required("stiffness").positive();
      std::optional<Vec3> target;
      if (a.has("target")) {
        if (pts.size() != 1) a.child("target").fail("needs \"at\" to name exactly one point");
        target = a.child("target").vec3();
      }
      for (std::uint32_t p : pts) s.anchors.push_back({p, k_anchor, target});
    }
  }
  if (node.has("pins")) s.pins = read_points(node.child("pins"), s.m, s.n);
  if (node.has("self_collision")) s.self_collision = node.child("self_collision").boolean();
  if (node.has("shear")) {
    const Node sh = node.child("shear");
    sh.expect_object({"stiffness", "rest_length"});
    s.shear = ShearDef{sh.required("stiffness").positive(), std::nullopt};
    if (sh.has("rest_length")) s.shear->rest_length = sh.child("rest_length").non_negative();
  }
  if (node.has("bending")) {
    const Node b = node.child("bending");
    b.expect_object({"stiffness"});
    s.bending = BendingDef{b.required("stiffness").positive()};
  }
  if (node.has("air")) {
    const Node a = node.child("air");
    a.expect_object({"drag", "friction"});
    s.air = AirDef{};
    if (a.has("drag")) s.air->drag = a.child("drag").non_negative();
    if (a.has("friction")) s.air->friction = a.child("friction").non_negative();
  }
  if (node.has("friction")) s.friction = node.child("friction").non_negative();
  if (const std::string problem = precision == Precision::Float32 ? validate_float(s) : validate(s); !problem.empty())
    node.fail(problem);
  return s;
}

// A prescribed motion: {"keyframes": [{"time", "translation", "rotation"}, ...], "pivot",
// "repeat"} or {"circle": {"center", "axis", "start", "period"}}.
Motion read_motion(const Node& node) {
  Motion m;
  if (node.value().is_object() && node.has("circle")) {
    node.expect_object({"circle"});
    const Node c = node.child("circle");
    c.expect_object({"center", "axis", "start", "period"});
    m.kind = Motion::Kind::Circle;
    m.circle.center = c.required("center").vec3();
    if (c.has("axis")) m.circle.axis = c.child("axis").vec3();
    m.circle.start = c.required("start").vec3();
    m.circle.period = c.required("period").positive();
  } else {
    node.expect_object({"keyframes", "pivot", "repeat"});
    if (node.has("pivot")) m.pivot = node.child("pivot").vec3();
    if (node.has("repeat")) m.repeat = node.child("repeat").boolean();
    const Node keys = node.required("keyframes");
    for (std::size_t k = 0, count = keys.array(); k < count; ++k) {
      const Node key = keys.at(k);
      key.expect_object({"time", "translation", "rotation"});
      Keyframe f;
      f.time = key.required("time").number();
      if (key.has("translation")) f.translation = key.child("translation").vec3();
      if (key.has("rotation")) f.rotation = read_orientation(key.child("rotation"));
      m.keyframes.push_back(f);
    }
  }
  if (const std::string problem = validate(m); !problem.empty()) node.fail(problem);
  return m;
}

ObstacleDef read_obstacle(const Node& node) {
  if (!node.value().is_object()) node.fail("must be an object, got " + type_name(node.value()));
  const std::string type = node.required("type").string();
  ObstacleDef d;
  std::optional<ObstacleShape> shape;
  std::vector<std::string_view> known;  // the shapes the engine names, in the enum's order
  for (int k = 0; obstacle_shape_name(ObstacleShape(k)) != "unknown"; ++k) {
    known.push_back(obstacle_shape_name(ObstacleShape(k)));
    if (known.back() == type) shape = ObstacleShape(k);
  }
  if (!shape) node.child("type").fail("unknown obstacle type \"" + type + "\" (" + known_words(type, known, "known") + ")");
  d.shape = *shape;
  switch (d.shape) {
    case ObstacleShape::Plane:
      node.expect_object({"type", "center", "normal", "c", "xi", "full_gradient", "max_exponent", "friction", "damping",
                          "motion"});
      if (node.has("normal")) d.orientation = rotation_to(node.child("normal"), node.child("normal").vec3());
      break;
    case ObstacleShape::Sphere:
      node.expect_object({"type", "center", "orientation", "radius", "c", "xi", "full_gradient", "max_exponent",
                          "friction", "damping", "motion"});
      d.size = {node.required("radius").positive(), 0, 0};
      break;
    case ObstacleShape::Torus:
      node.expect_object({"type", "center", "orientation", "major_radius", "minor_radius", "c", "xi", "full_gradient",
                          "max_exponent", "friction", "damping", "motion"});
      d.size = {node.required("major_radius").positive(), node.required("minor_radius").positive(), 0};
      break;
    case ObstacleShape::Ellipsoid:
    case ObstacleShape::Box: {  // three positive lengths along the local axes
      const char* sizes = d.shape == ObstacleShape::Box ? "half_extents" : "semi_axes";
      node.expect_object({"type", "center", "orientation", sizes, "c", "xi", "full_gradient", "max_exponent", "friction",
                          "damping", "motion"});
      d.size = node.required(sizes).vec3();
      node.child(sizes).positives(3);
      break;
    }
  }
  if (node.has("center")) d.center = node.child("center").vec3();
  if (node.has("orientation")) d.orientation = read_orientation(node.child("orientation"));
  if (node.has("c")) d.c = node.child("c").positive();
  if (node.has("xi")) d.xi = node.child("xi").positive();
  if (node.has("full_gradient")) d.full_gradient = node.child("full_gradient").boolean();
  if (node.has("max_exponent")) d.max_exponent = node.child("max_exponent").positive();
  if (node.has("friction")) d.friction = node.child("friction").non_negative();
  if (node.has("damping")) d.damping = node.child("damping").non_negative();
  if (node.has("motion")) d.motion = read_motion(node.child("motion"));
  if (const std::string problem = validate(d); !problem.empty()) node.fail(problem);
  return d;
}

// A sheet named by its "name" or its index in "sheets"; the SheetId's index is that index.
SheetId read_sheet_ref(const Node& node, const Scene& scene) {
  if (node.value().is_string()) {
    const std::string name = node.string();
    const auto it = std::find(scene.sheet_names.begin(), scene.sheet_names.end(), name);
    if (it == scene.sheet_names.end()) node.fail("no sheet is named \"" + name + "\"");
    return {std::uint32_t(it - scene.sheet_names.begin()), 0};
  }
  return {std::uint32_t(node.whole(0, scene.sheets.size() - 1)), 0};
}

ConstraintDef read_constraint(const Node& node, const Scene& scene) {
  if (!node.value().is_object()) node.fail("must be an object, got " + type_name(node.value()));
  const std::string type = node.required("type").string();
  ConstraintDef c;
  if (type == "point_to_point") {
    node.expect_object({"type", "sheet", "points", "stiffness", "other_sheet", "other_points", "rest_length"});
    c.kind = ConstraintKind::PointToPoint;
  } else if (type == "path") {
    node.expect_object({"type", "sheet", "points", "stiffness", "motion"});
    c.kind = ConstraintKind::Path;
  } else if (type == "frame") {
    node.expect_object({"type", "sheet", "points", "stiffness", "motion", "obstacle"});
    c.kind = ConstraintKind::Frame;
  } else if (type == "rail") {
    node.expect_object({"type", "sheet", "points", "stiffness", "rail"});
    c.kind = ConstraintKind::Rail;
  } else {
    std::vector<std::string_view> kinds;  // the kinds the engine names, in the enum's order
    for (int k = 0; constraint_kind_name(ConstraintKind(k)) != "unknown"; ++k)
      kinds.push_back(constraint_kind_name(ConstraintKind(k)));
    node.child("type").fail("unknown constraint type \"" + type + "\" (" + known_words(type, kinds, "known") + ")");
  }
  auto points_of = [&](const char* key, SheetId sheet) {
    const SheetDef& s = scene.sheets[sheet.index];
    return read_points(node.required(key), s.m, s.n);
  };
  c.sheet = read_sheet_ref(node.required("sheet"), scene);
  c.points = points_of("points", c.sheet);
  c.stiffness = node.required("stiffness").positive();
  switch (c.kind) {
    case ConstraintKind::PointToPoint:
      c.other_sheet = read_sheet_ref(node.required("other_sheet"), scene);
      c.other_points = points_of("other_points", c.other_sheet);
      if (node.has("rest_length")) c.rest_length = node.child("rest_length").non_negative();
      break;
    case ConstraintKind::Path: c.motion = read_motion(node.required("motion")); break;
    case ConstraintKind::Frame:
      if (node.has("obstacle") == node.has("motion")) node.fail("give either motion or obstacle (the carrier)");
      if (node.has("obstacle")) {
        const Node o = node.child("obstacle");
        if (scene.obstacles.empty()) o.fail("the scene has no obstacles");
        c.carrier = ObstacleId{std::uint32_t(o.whole(0, scene.obstacles.size() - 1)), 0};
      } else {
        c.motion = read_motion(node.child("motion"));
      }
      break;
    case ConstraintKind::Rail: {
      const Node rail = node.required("rail");
      for (std::size_t k = 0, count = rail.array(); k < count; ++k) c.rail.push_back(rail.at(k).vec3());
      break;
    }
  }
  const ConstraintContext context{[&](SheetId id) -> std::uint64_t {
                                    return id.index < scene.sheets.size()
                                               ? point_count(scene.sheets[id.index].m, scene.sheets[id.index].n)
                                               : 0;
                                  },
                                  [&](ObstacleId id) { return id.index < scene.obstacles.size(); }};
  if (const std::string problem = validate(c, context); !problem.empty()) node.fail(problem);
  return c;
}

// "line L, column C" of a byte offset, for syntax errors.
std::pair<std::size_t, std::size_t> line_column(std::string_view text, std::size_t byte) {
  byte = std::min(byte, text.size());
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i + 1 < byte; ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return {line, column};
}

// One --set: walks `path` ("integrator", "sheets[*].stiffness", "obstacles[0].center") in
// the document and puts `value` at its end; "[*]" means every element of the array. The last
// key may be new (e.g. damping on a sheet that had none); everything before it must exist.
// The reader checks the result as it checks any file, so a wrong key is named there.
void apply_override(json& root, const SceneOverride& o, const std::string& file) {
  auto fail = [&](const std::string& problem) -> void {
    throw SceneError(file + ": --set " + o.path + ": " + problem);
  };
  json value;
  try {
    value = json::parse(o.value);
  } catch (const json::exception&) {
    value = o.value;  // not JSON: a bare word such as forward_euler is a string
  }
  // segments: a key, or "[N]" / "[*]"
  std::vector<std::string> segments;
  for (std::size_t i = 0; i < o.path.size();) {
    if (o.path[i] == '.') {
      ++i;
      continue;
    }
    if (o.path[i] == '[') {
      const auto close = o.path.find(']', i);
      if (close == std::string::npos) fail("unclosed [");
      segments.push_back(o.path.substr(i, close - i + 1));
      i = close + 1;
    } else {
      const auto end = o.path.find_first_of(".[", i);
      segments.push_back(o.path.substr(i, end == std::string::npos ? std::string::npos : end - i));
      i = end == std::string::npos ? o.path.size() : end;
    }
  }
  if (segments.empty()) fail("empty path");
  auto walk = [&](auto& self, json& node, std::size_t k) -> void {
    const std::string& seg = segments[k];
    const bool last = k + 1 == segments.size();
    if (seg.front() == '[') {
      if (!node.is_array()) fail("\"" + seg + "\" needs an array, the scene has " + type_name(node));
      const std::string inner = seg.substr(1, seg.size() - 2);
      std::vector<std::size_t> indices;
      if (inner == "*") {
        for (std::size_t i = 0; i < node.size(); ++i) indices.push_back(i);
      } else {
        if (inner.empty() || inner.find_first_not_of("0123456789") != std::string::npos || inner.size() > 9)
          fail("\"" + seg + "\" is not an index or [*]");
        const std::size_t i = std::stoul(inner);
        if (i >= node.size()) fail("index " + inner + " is past the end (" + std::to_string(node.size()) + " elements)");
        indices.push_back(i);
      }
      for (std::size_t i : indices) {
        if (last) node[i] = value;
        else self(self, node[i], k + 1);
      }
    } else {
      if (!node.is_object()) fail("\"" + seg + "\" needs an object, the scene has " + type_name(node));
      if (last) {
        node[seg] = value;
      } else {
        if (!node.contains(seg)) fail("the scene has no \"" + seg + "\"");
        self(self, node[seg], k + 1);
      }
    }
  };
  walk(walk, root, 0);
}

// The engine's knobs beyond dt, gravity and integrator (WorldDef): the same ranges as
// drape::validate(WorldDef), checked here so the message names the JSON path.
void read_world_knobs(const Node& top, WorldDef& w) {
  if (top.has("cg_tolerance")) w.cg_tolerance = top.child("cg_tolerance").positive();
  if (top.has("cg_max_iterations")) w.cg_max_iterations = int(top.child("cg_max_iterations").whole(1, 2147483647));
  if (top.has("cg_preconditioner")) {
    const Node n = top.child("cg_preconditioner");
    const std::string name = n.string();
    const auto preconditioner = preconditioner_from_name(name);
    if (!preconditioner) n.fail("must be \"auto\", \"block_jacobi\" or \"cholesky\" (got \"" + name + "\")");
    w.cg_preconditioner = *preconditioner;
  }
  if (top.has("local_global_iterations"))
    w.local_global_iterations = int(top.child("local_global_iterations").whole(1, 2147483647));
  if (top.has("vertex_block_iterations"))
    w.vertex_block_iterations = int(top.child("vertex_block_iterations").whole(1, 2147483647));
  if (top.has("adaptive")) w.adaptive = top.child("adaptive").boolean();
  if (top.has("adaptive_safety")) {
    const Node n = top.child("adaptive_safety");
    w.adaptive_safety = n.positive();
    if (w.adaptive_safety > 1) n.fail("must be in (0, 1] (got " + number_text(w.adaptive_safety) + ")");
  }
  if (top.has("guard")) w.guard = top.child("guard").boolean();
  if (top.has("guard_energy_growth")) {
    const Node n = top.child("guard_energy_growth");
    w.guard_energy_growth = n.number();
    if (!(w.guard_energy_growth > 1)) n.fail("must be greater than 1 (got " + number_text(w.guard_energy_growth) + ")");
  }
  if (top.has("contact_thickness")) w.contact_thickness = top.child("contact_thickness").non_negative();
  if (top.has("contact_xi")) w.contact_xi = top.child("contact_xi").positive();
  if (top.has("contact_strength")) w.contact_strength = top.child("contact_strength").non_negative();
  if (top.has("contact_range")) w.contact_range = top.child("contact_range").positive();
  if (top.has("contact_damping")) w.contact_damping = top.child("contact_damping").non_negative();
  if (top.has("contact_exact")) w.contact_exact = top.child("contact_exact").boolean();
  if (top.has("contact_rims")) w.contact_rims = top.child("contact_rims").boolean();
  if (top.has("block_points")) w.block_points = std::uint32_t(top.child("block_points").whole(1, 4294967295u));
  if (top.has("group_points")) w.group_points = std::uint32_t(top.child("group_points").whole(0, 4294967295u));
  if (top.has("wind")) {
    const Node wind = top.child("wind");
    wind.expect_object({"velocity", "density"});
    if (wind.has("velocity")) w.wind.velocity = wind.child("velocity").vec3();
    if (wind.has("density")) w.wind.density = wind.child("density").non_negative();
  }
}

}  // namespace

Scene parse_scene(std::string_view text, const std::string& file) { return parse_scene(text, file, {}); }

Scene parse_scene(std::string_view text, const std::string& file, std::span<const SceneOverride> overrides) {
  json root;
  try {
    root = json::parse(text.begin(), text.end());
  } catch (const json::out_of_range& e) {
    // a number literal too large for a double (e.g. 1e999): nlohmann names the literal, not
    // its place, so find it in the text
    std::string what = e.what();
    std::size_t byte = 0;
    if (const auto q = what.find('\''); q != std::string::npos) {
      const std::string literal = what.substr(q + 1, what.find('\'', q + 1) - q - 1);
      byte = text.find(literal) + 1;
      what = "number " + literal + " is not finite (too large for a double)";
    }
    const auto [line, column] = line_column(text, byte);
    throw SceneError(file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + what);
  } catch (const json::parse_error& e) {
    const auto [line, column] = line_column(text, e.byte);
    // nlohmann's own text starts with "[json.exception.parse_error.101] parse error at …: "
    std::string what = e.what();
    if (const auto colon = what.find(": "); colon != std::string::npos) what = what.substr(colon + 2);
    throw SceneError(file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": syntax error: " + what);
  }
  for (const auto& o : overrides) apply_override(root, o, file);
  const Node top(file, root, "");
  top.expect_object({"description", "dt", "substeps", "fps", "frames", "duration", "integrator", "precision",
                     "gravity", "cg_tolerance", "cg_max_iterations", "cg_preconditioner", "local_global_iterations", "vertex_block_iterations", "adaptive", "adaptive_safety", "guard",
                     "guard_energy_growth", "contact_thickness", "contact_xi", "contact_strength", "contact_range",
                     "contact_damping", "contact_exact", "contact_rims", "block_points", "group_points", "wind", "sheets", "obstacles", "constraints", "output", "camera"});
  Scene scene;
  scene.file = file;
  scene.source = std::string(text);
  {
    // what the results depend on: the text, then every override in order
    std::string identity(text);
    for (const auto& o : overrides) identity += "\n--set " + o.path + "=" + o.value;
    scene.fingerprint = fnv1a64(std::span(reinterpret_cast<const unsigned char*>(identity.data()), identity.size()));
  }
  if (top.has("description")) scene.description = top.child("description").string();
  if (top.has("precision")) {
    const std::string p = top.child("precision").string();
    if (p == "float64") scene.precision = Precision::Float64;
    else if (p == "float32") scene.precision = Precision::Float32;
    else top.child("precision").fail("must be \"float64\" or \"float32\" (got \"" + p + "\")");
  }
  if (top.has("dt")) scene.world.dt = top.child("dt").positive();
  if (top.has("gravity")) scene.world.gravity = top.child("gravity").vec3();
  if (top.has("integrator")) {
    const std::string name = top.child("integrator").string();
    const auto integrator = integrator_from_name(name);
    if (!integrator) {
      std::vector<std::string_view> known;
      for (Integrator i : integrators()) known.push_back(integrator_name(i));
      top.child("integrator").fail("unknown integrator \"" + name + "\" (" + known_words(name, known, "known") + ")");
    }
    scene.world.integrator = *integrator;
  }
  read_world_knobs(top, scene.world);
  // the engine's own check last: a range this reader does not know yet is still named
  if (const std::string problem = validate(scene.world); !problem.empty()) top.fail(problem);
  if (top.has("fps")) scene.fps = top.child("fps").positive();
  constexpr int kMostSubsteps = 100000000;  // per frame, given or derived
  if (top.has("substeps")) {
    scene.substeps = int(top.child("substeps").whole(1, kMostSubsteps));
  } else {
    // one output frame every 1/fps s, rounded to whole substeps (a frame too long for an
    // int of substeps is named here, not wrapped into a negative count)
    const double per_frame = std::max(1.0, std::round(1.0 / (scene.fps * scene.world.dt)));
    if (!(per_frame <= kMostSubsteps)) {
      std::ostringstream out;
      out << "fps = " << scene.fps << " with dt = " << scene.world.dt << " s makes frames of " << per_frame
          << " substeps, more than " << kMostSubsteps << ": raise fps or dt, or give substeps";
      (top.has("fps") ? top.child("fps") : top.child("dt")).fail(out.str());
    }
    scene.substeps = int(per_frame);
  }
  if (top.has("frames") && top.has("duration")) top.child("duration").fail("give either frames or duration, not both");
  if (top.has("frames")) {
    scene.frames = int(top.child("frames").whole(1, 10000000));
  } else if (top.has("duration")) {
    const double duration = top.child("duration").positive();
    const double frames = std::ceil(duration / scene.frame_time() - 1e-9);
    if (frames > 1e7) top.child("duration").fail("gives more than 10^7 frames");
    scene.frames = int(std::max(1.0, frames));
  } else {
    top.child("frames").fail("missing: the scene needs frames or duration (--frames on the command line only overrides them)");
  }
  const Node sheets = top.required("sheets");
  for (std::size_t k = 0, count = sheets.array(1); k < count; ++k) {
    std::string name;
    scene.sheets.push_back(read_sheet(sheets.at(k), scene.precision, name, k));
    scene.sheet_names.push_back(name);
  }
  const std::uint64_t bytes = estimated_bytes(scene), memory = physical_memory_bytes();
  if (memory > 0 && bytes > memory) {
    std::ostringstream out;
    out << "all sheets together need about " << double(bytes) / 1e9 << " GB, more than this machine's "
        << double(memory) / 1e9 << " GB of memory";
    sheets.fail(out.str());
  }
  if (top.has("obstacles")) {
    const Node obstacles = top.child("obstacles");
    for (std::size_t k = 0, count = obstacles.array(); k < count; ++k)
      scene.obstacles.push_back(read_obstacle(obstacles.at(k)));
  }
  if (top.has("constraints")) {
    const Node constraints = top.child("constraints");
    for (std::size_t k = 0, count = constraints.array(); k < count; ++k)
      scene.constraints.push_back(read_constraint(constraints.at(k), scene));
  }
  if (top.has("output")) {
    const Node out = top.child("output");
    out.expect_object({"dir", "formats"});
    if (out.has("dir")) {
      scene.output.dir = out.child("dir").string();
      if (scene.output.dir.empty()) out.child("dir").fail("must not be empty");
    }
    if (out.has("formats")) {
      const Node formats = out.child("formats");
      scene.output.formats.clear();
      for (std::size_t k = 0, count = formats.array(1); k < count; ++k) {
        const std::string name = formats.at(k).string();
        const auto f = mesh_format_from_name(name);
        if (!f) formats.at(k).fail("unknown format \"" + name + "\" (known: obj, ply, vtk, glb)");
        if (std::find(scene.output.formats.begin(), scene.output.formats.end(), *f) == scene.output.formats.end())
          scene.output.formats.push_back(*f);
      }
    }
  }
  if (top.has("camera")) {
    const Node cam = top.child("camera");
    cam.expect_object({"eye", "target", "up", "fov_degrees"});
    Camera c;
    if (cam.has("eye")) c.eye = cam.child("eye").vec3();
    if (cam.has("target")) c.target = cam.child("target").vec3();
    if (cam.has("up")) c.up = cam.child("up").vec3();
    if (cam.has("fov_degrees")) {
      c.fov_degrees = cam.child("fov_degrees").positive();
      if (c.fov_degrees >= 180) cam.child("fov_degrees").fail("must be below 180");
    }
    if (c.eye == c.target) cam.child("target").fail("must differ from eye");
    scene.camera = c;
  }
  return scene;
}

Scene load_scene(const std::filesystem::path& file, std::span<const SceneOverride> overrides) {
  std::ifstream in(file, std::ios::binary);
  std::error_code ec;
  if (!in || std::filesystem::is_directory(file, ec))
    throw SceneError(file.string() + ": cannot read the file (missing, unreadable or a directory)");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw SceneError(file.string() + ": cannot read the file");
  return parse_scene(text.str(), file.string(), overrides);
}

}  // namespace drape::app
