// Sheet definitions: helpers, validation, and building the SoA buffers of one sheet.
#include "sheet_data.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <string_view>

namespace drape {

Quat quat_from_axis_angle(Vec3 axis, double radians) {
  const double len = std::sqrt(axis.x * axis.x + axis.y * axis.y + axis.z * axis.z);
  if (len == 0.0) return {};
  const double s = std::sin(radians / 2) / len;
  return {std::cos(radians / 2), axis.x * s, axis.y * s, axis.z * s};
}

Vec3 rotate(const Quat& q, Vec3 v) {
  // v' = v + 2w(u×v) + 2u×(u×v), u the vector part of q
  const Vec3 u{q.x, q.y, q.z};
  const Vec3 t{2 * (u.y * v.z - u.z * v.y), 2 * (u.z * v.x - u.x * v.z), 2 * (u.x * v.y - u.y * v.x)};
  return {v.x + q.w * t.x + (u.y * t.z - u.z * t.y), v.y + q.w * t.y + (u.z * t.x - u.x * t.z),
          v.z + q.w * t.z + (u.x * t.y - u.y * t.x)};
}

std::vector<std::uint32_t> corner_points(std::uint32_t m, std::uint32_t n) {
  std::vector<std::uint32_t> corners{point_index(n, 0, 0), point_index(n, 0, n), point_index(n, m, 0),
                                     point_index(n, m, n)};
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
  return corners;
}

std::uint32_t center_point(std::uint32_t m, std::uint32_t n) { return point_index(n, m / 2, n / 2); }

std::vector<AnchorDef> anchors_at(std::span<const std::uint32_t> points, double stiffness) {
  std::vector<AnchorDef> anchors;
  anchors.reserve(points.size());
  for (std::uint32_t p : points) anchors.push_back({p, stiffness, std::nullopt});
  return anchors;
}

namespace {

bool positive(double v) { return std::isfinite(v) && v > 0; }
bool non_negative(double v) { return std::isfinite(v) && v >= 0; }
bool finite(Vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

template <class T>
std::string problem(const std::string& field, const std::string& what, const T& got) {
  std::ostringstream out;
  out << field << " " << what << " (got " << got << ")";
  return out.str();
}

std::string indexed(const char* field, std::size_t i, const char* member = nullptr) {
  std::string s = std::string(field) + "[" + std::to_string(i) + "]";
  if (member) s += std::string(".") + member;
  return s;
}

// The grid's cells resolved where the sheet lies, in a precision of machine epsilon `eps`
// whose normal numbers span [tiny, huge]: its smallest cell edge at least 16·eps times its
// largest coordinate, 8 to 16 units in the last place there (each end of a spring is rounded
// by up to half a unit, so its length by up to one: 6 to 12 %, and eq (6)'s forces become
// rounding noise), and the squares of edges and coordinates that eq (6) and the contacts
// take neither underflow nor overflow.
std::string resolution_problem(const SheetDef& d, double eps, double tiny, double huge, const char* precision) {
  double edge = std::numeric_limits<double>::infinity();
  const char* field = nullptr;
  if (d.n > 0 && d.width / d.n < edge) {
    edge = d.width / d.n;
    field = "width/n";
  }
  if (d.m > 0 && d.height / d.m < edge) {
    edge = d.height / d.m;
    field = "height/m";
  }
  if (!field) return {};  // one point: no spring
  const double reach = std::max({std::abs(d.center.x), std::abs(d.center.y), std::abs(d.center.z)}) +
                       0.5 * std::hypot(d.n > 0 ? d.width : 0.0, d.m > 0 ? d.height : 0.0);
  std::ostringstream out;
  if (edge < 1e3 * std::sqrt(tiny)) {
    out << field << " = " << edge << " m: cells this small have squared lengths near the smallest normal " << precision
        << " (" << tiny << "); use larger cells (lengths in metres)";
  } else if (reach > 1e-3 * std::sqrt(huge)) {
    out << "the sheet reaches " << reach << " m from the origin, where squared distances overflow " << precision
        << "; move the scene nearer the origin";
  } else if (edge < 16 * eps * reach) {
    out << field << " = " << edge << " m is under " << 16 * eps * reach << " m, 16 machine epsilons of " << precision
        << " times the sheet's largest coordinate (" << reach
        << " m): its springs' lengths would be rounding noise; move the scene nearer the origin, use larger cells"
        << (std::string_view(precision) == "float" ? ", or float64" : "");
  }
  return out.str();
}

}  // namespace

std::string validate_float(const SheetDef& d) {
  if (std::string p = validate(d); !p.empty()) return p;
  using F = std::numeric_limits<float>;
  return resolution_problem(d, F::epsilon(), F::min(), F::max(), "float");
}

std::string validate(const SheetDef& d) {
  constexpr std::uint64_t max_points = std::uint64_t(1) << 31;
  const std::uint64_t points = std::uint64_t(d.m + 1) * std::uint64_t(d.n + 1);
  if (d.m >= max_points || d.n >= max_points || points > max_points)
    return problem("m×n", "gives more points than one sheet can hold (2^31)", points);
  if (d.n > 0 && !positive(d.width)) return problem("width", "must be positive and finite", d.width);
  if (d.m > 0 && !positive(d.height)) return problem("height", "must be positive and finite", d.height);
  if (!finite(d.center)) return "center must be finite";
  if (!finite(d.initial_velocity)) return "initial_velocity must be finite";
  const double qn = d.orientation.w * d.orientation.w + d.orientation.x * d.orientation.x +
                    d.orientation.y * d.orientation.y + d.orientation.z * d.orientation.z;
  if (!(std::abs(qn - 1.0) < 1e-6)) return problem("orientation", "must be a unit quaternion; its norm² is", qn);
  if (d.point_masses.empty()) {
    if (!positive(d.mass)) return problem("mass", "must be positive and finite", d.mass);
  } else {
    if (d.point_masses.size() != points)
      return problem("point_masses", "must have one value per point, (m+1)·(n+1) = " + std::to_string(points) + "; size",
                     d.point_masses.size());
    for (std::size_t i = 0; i < d.point_masses.size(); ++i)
      if (!positive(d.point_masses[i])) return problem(indexed("point_masses", i), "must be positive and finite", d.point_masses[i]);
  }
  if (!positive(d.stiffness)) return problem("stiffness", "must be positive and finite", d.stiffness);
  for (std::size_t r = 0; r < d.stiffness_regions.size(); ++r) {
    const auto& reg = d.stiffness_regions[r];
    if (!positive(reg.stiffness)) return problem(indexed("stiffness_regions", r, "stiffness"), "must be positive and finite", reg.stiffness);
    if (reg.row_begin > reg.row_end || reg.row_end > d.m)
      return indexed("stiffness_regions", r, "rows") + " must satisfy row_begin <= row_end <= m";
    if (reg.col_begin > reg.col_end || reg.col_end > d.n)
      return indexed("stiffness_regions", r, "cols") + " must satisfy col_begin <= col_end <= n";
  }
  if (d.rest_length_h && !non_negative(*d.rest_length_h))
    return problem("rest_length_h", "must be non-negative and finite", *d.rest_length_h);
  if (d.rest_length_v && !non_negative(*d.rest_length_v))
    return problem("rest_length_v", "must be non-negative and finite", *d.rest_length_v);
  if (!non_negative(d.damping)) return problem("damping", "must be non-negative and finite", d.damping);
  if (!non_negative(d.friction)) return problem("friction", "must be non-negative and finite", d.friction);
  if (!d.point_damping.empty()) {
    if (d.point_damping.size() != points) return problem("point_damping", "must have one value per point; size", d.point_damping.size());
    for (std::size_t i = 0; i < d.point_damping.size(); ++i)
      if (!non_negative(d.point_damping[i])) return problem(indexed("point_damping", i), "must be non-negative and finite", d.point_damping[i]);
  }
  for (std::size_t a = 0; a < d.anchors.size(); ++a) {
    const auto& an = d.anchors[a];
    if (an.point >= points) return problem(indexed("anchors", a, "point"), "is not a point of the grid", an.point);
    if (!positive(an.stiffness)) return problem(indexed("anchors", a, "stiffness"), "must be positive and finite", an.stiffness);
    if (an.target && !finite(*an.target)) return indexed("anchors", a, "target") + " must be finite";
  }
  for (std::size_t p = 0; p < d.pins.size(); ++p)
    if (d.pins[p] >= points) return problem(indexed("pins", p), "is not a point of the grid", d.pins[p]);
  if (d.shear) {
    if (!positive(d.shear->stiffness)) return problem("shear.stiffness", "must be positive and finite", d.shear->stiffness);
    if (d.shear->rest_length && !non_negative(*d.shear->rest_length))
      return problem("shear.rest_length", "must be non-negative and finite", *d.shear->rest_length);
  }
  if (d.bending && !positive(d.bending->stiffness))
    return problem("bending.stiffness", "must be positive and finite", d.bending->stiffness);
  if (d.air) {
    if (!non_negative(d.air->drag)) return problem("air.drag", "must be non-negative and finite", d.air->drag);
    if (!non_negative(d.air->friction)) return problem("air.friction", "must be non-negative and finite", d.air->friction);
  }
  using D = std::numeric_limits<double>;
  return resolution_problem(d, D::epsilon(), D::min(), D::max(), "double");
}

namespace detail {

template <class Real>
Sheet<Real> build_sheet(const SheetDef& d) {
  const std::uint32_t m = d.m, n = d.n, cols = n + 1, count = point_count(m, n);
  const double h1 = n > 0 ? d.width / n : 0.0;
  const double h2 = m > 0 ? d.height / m : 0.0;

  auto topo = std::make_shared<Topology<Real>>();
  topo->m = m;
  topo->n = n;
  const std::uint32_t springs = spring_count(m, n);
  topo->a.reserve(springs);
  topo->b.reserve(springs);
  for (std::uint32_t i = 0; i <= m; ++i)
    for (std::uint32_t j = 0; j < n; ++j) {
      topo->a.push_back(point_index(n, i, j));
      topo->b.push_back(point_index(n, i, j + 1));
    }
  for (std::uint32_t i = 0; i < m; ++i)
    for (std::uint32_t j = 0; j <= n; ++j) {
      topo->a.push_back(point_index(n, i, j));
      topo->b.push_back(point_index(n, i + 1, j));
    }
  const Real l1 = static_cast<Real>(d.rest_length_h.value_or(h1));
  const Real l2 = static_cast<Real>(d.rest_length_v.value_or(h2));
  topo->rest_length.assign(springs, l2);
  std::fill_n(topo->rest_length.begin(), topo->horizontal_count(), l1);
  topo->stiffness.assign(springs, static_cast<Real>(d.stiffness));
  for (const auto& reg : d.stiffness_regions) {
    auto inside = [&](std::uint32_t p) {
      const std::uint32_t i = p / cols, j = p % cols;
      return i >= reg.row_begin && i <= reg.row_end && j >= reg.col_begin && j <= reg.col_end;
    };
    for (std::uint32_t e = 0; e < springs; ++e)
      if (inside(topo->a[e]) && inside(topo->b[e])) topo->stiffness[e] = static_cast<Real>(reg.stiffness);
  }
  topo->find_uniform();
  if (d.shear)
    topo->shear = typename Topology<Real>::Shear{static_cast<Real>(d.shear->stiffness),
                                                 static_cast<Real>(d.shear->rest_length.value_or(std::hypot(double(l1), double(l2))))};
  if (d.bending) topo->bending = static_cast<Real>(d.bending->stiffness);

  Sheet<Real> s;
  s.topology = std::move(topo);
  s.position.resize(count);
  s.velocity.resize(count);
  s.force.resize(count);
  s.row_scratch.resize(s.topology->scratch_cols());
  s.self_collision = d.self_collision;
  if (d.air) {
    s.air.emplace();
    s.air->drag_coefficient = d.air->drag;
    s.air->friction_coefficient = d.air->friction;
    set_wind(s, Wind{});
  }
  s.friction = d.friction;
  for (std::uint32_t i = 0; i <= m; ++i)
    for (std::uint32_t j = 0; j <= n; ++j) {
      // eqs (2)–(3): row-major; local grid centred on the sheet's centre
      const Vec3 local{j * h1 - 0.5 * d.width * (n > 0), i * h2 - 0.5 * d.height * (m > 0), 0.0};
      const Vec3 r = rotate(d.orientation, local);
      const std::uint32_t p = point_index(n, i, j);
      s.position.x[p] = static_cast<Real>(d.center.x + r.x);
      s.position.y[p] = static_cast<Real>(d.center.y + r.y);
      s.position.z[p] = static_cast<Real>(d.center.z + r.z);
      s.velocity.x[p] = static_cast<Real>(d.initial_velocity.x);
      s.velocity.y[p] = static_cast<Real>(d.initial_velocity.y);
      s.velocity.z[p] = static_cast<Real>(d.initial_velocity.z);
    }
  if (d.point_masses.empty()) {
    s.mass.assign(count, static_cast<Real>(d.mass / count));
  } else {
    s.mass.assign(d.point_masses.begin(), d.point_masses.end());
  }
  s.inv_mass.resize(count);
  std::transform(s.mass.begin(), s.mass.end(), s.inv_mass.begin(), [](Real mass) { return Real(1) / mass; });

  if (!d.point_damping.empty()) {
    if (std::any_of(d.point_damping.begin(), d.point_damping.end(), [](double c) { return c > 0; }))
      s.damping.assign(d.point_damping.begin(), d.point_damping.end());
  } else if (d.damping > 0) {
    s.damping.assign(count, static_cast<Real>(d.damping));
  }

  for (const auto& an : d.anchors) {
    const Vec3 t = an.target.value_or(Vec3{s.position.x[an.point], s.position.y[an.point], s.position.z[an.point]});
    s.anchors.point.push_back(an.point);
    s.anchors.tx.push_back(static_cast<Real>(t.x));
    s.anchors.ty.push_back(static_cast<Real>(t.y));
    s.anchors.tz.push_back(static_cast<Real>(t.z));
    s.anchors.stiffness.push_back(static_cast<Real>(an.stiffness));
  }
  std::vector<std::uint32_t> pins = d.pins;
  std::sort(pins.begin(), pins.end());
  pins.erase(std::unique(pins.begin(), pins.end()), pins.end());
  for (std::uint32_t p : pins) {
    s.pins.point.push_back(p);
    s.pins.tx.push_back(s.position.x[p]);
    s.pins.ty.push_back(s.position.y[p]);
    s.pins.tz.push_back(s.position.z[p]);
    s.velocity.x[p] = s.velocity.y[p] = s.velocity.z[p] = Real(0);
  }
  return s;
}

template Sheet<double> build_sheet<double>(const SheetDef&);
template Sheet<float> build_sheet<float>(const SheetDef&);

}  // namespace detail
}  // namespace drape
