// Obstacles (paper §3, eq 9): implicit functions of plane, sphere, ellipsoid, torus and box
// with analytic gradients, and the repulsion c·exp(−f/ξ) around them.
#include "obstacles.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace drape {

namespace {

bool positive(double v) { return std::isfinite(v) && v > 0; }

}  // namespace

std::string validate(const ObstacleDef& d) {
  std::ostringstream out;
  auto fail = [&](const char* field, const char* what, double got) {
    out << field << " " << what << " (got " << got << ")";
    return out.str();
  };
  if (!std::isfinite(d.center.x) || !std::isfinite(d.center.y) || !std::isfinite(d.center.z))
    return "center must be finite";
  const Quat& q = d.orientation;
  const double qn = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  if (!(std::abs(qn - 1.0) < 1e-6)) return fail("orientation", "must be a unit quaternion; its norm² is", qn);
  if (!positive(d.c)) return fail("c", "must be positive and finite", d.c);
  if (!positive(d.xi)) return fail("xi", "must be positive and finite", d.xi);
  if (!positive(d.max_exponent)) return fail("max_exponent", "must be positive and finite", d.max_exponent);
  if (d.motion)
    if (std::string problem = validate(*d.motion); !problem.empty()) return "motion." + problem;
  switch (d.shape) {
    case ObstacleShape::Plane: break;
    case ObstacleShape::Sphere:
      if (!positive(d.size.x)) return fail("size.x (radius)", "must be positive and finite", d.size.x);
      break;
    case ObstacleShape::Torus:
      if (!positive(d.size.x)) return fail("size.x (major radius)", "must be positive and finite", d.size.x);
      if (!positive(d.size.y)) return fail("size.y (minor radius)", "must be positive and finite", d.size.y);
      break;
    case ObstacleShape::Ellipsoid:
    case ObstacleShape::Box:
      if (!positive(d.size.x)) return fail("size.x", "must be positive and finite", d.size.x);
      if (!positive(d.size.y)) return fail("size.y", "must be positive and finite", d.size.y);
      if (!positive(d.size.z)) return fail("size.z", "must be positive and finite", d.size.z);
      break;
  }
  return {};
}

namespace detail {

namespace {

// Local implicit functions: f and ∇f of a point p in the obstacle's own frame. Where the
// gradient has no direction (a sphere's centre, a torus's axis or core circle) a fixed unit
// direction is used, so a point there is still pushed out and never gets 0/0.
struct Local {
  double f;
  double g[3];
};

Local plane_f(const double p[3], const Vec3&) { return {p[2], {0, 0, 1}}; }

Local sphere_f(const double p[3], const Vec3& s) {
  const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
  if (r == 0) return {-s.x, {0, 0, 1}};
  return {r - s.x, {p[0] / r, p[1] / r, p[2] / r}};
}

// Not the exact distance (which has no closed form): k·(q − 1), q the point's radius in the
// unit-sphere coordinates (x/a, y/b, z/c), scaled by k = the smallest semi-axis so f is
// measured in metres, matches the distance on the smallest axis and never exceeds it
// elsewhere, and ξ keeps its meaning as a length.
Local ellipsoid_f(const double p[3], const Vec3& s) {
  const double k = std::min({s.x, s.y, s.z});
  const double ux = p[0] / s.x, uy = p[1] / s.y, uz = p[2] / s.z;
  const double q = std::sqrt(ux * ux + uy * uy + uz * uz);
  if (q == 0) return {-k, {0, 0, 1}};
  return {k * (q - 1), {k * ux / (s.x * q), k * uy / (s.y * q), k * uz / (s.z * q)}};
}

// Exact signed distance to a torus around local z: major radius R = s.x, minor r = s.y.
Local torus_f(const double p[3], const Vec3& s) {
  const double rho = std::sqrt(p[0] * p[0] + p[1] * p[1]);
  const double cx = rho > 0 ? p[0] / rho : 1.0, cy = rho > 0 ? p[1] / rho : 0.0;
  const double d = rho - s.x;
  const double len = std::sqrt(d * d + p[2] * p[2]);
  if (len == 0) return {-s.y, {0, 0, 1}};
  return {len - s.y, {d / len * cx, d / len * cy, p[2] / len}};
}

// Exact signed distance to a box of half extents s. Outside it is continuously
// differentiable; inside, the gradient points to the nearest face and jumps across the
// planes where two faces are equally near (documented choice: the force there still
// pushes out through a nearest face).
Local box_f(const double p[3], const Vec3& s) {
  const double h[3] = {s.x, s.y, s.z};
  double q[3], out2 = 0;
  for (int k = 0; k < 3; ++k) {
    q[k] = std::abs(p[k]) - h[k];
    out2 += q[k] > 0 ? q[k] * q[k] : 0.0;
  }
  auto sgn = [](double v) { return v < 0 ? -1.0 : 1.0; };
  if (out2 > 0) {
    const double out = std::sqrt(out2);
    Local r{out, {}};
    for (int k = 0; k < 3; ++k) r.g[k] = q[k] > 0 ? sgn(p[k]) * q[k] / out : 0.0;
    return r;
  }
  const int a = q[0] >= q[1] ? (q[0] >= q[2] ? 0 : 2) : (q[1] >= q[2] ? 1 : 2);
  Local r{q[a], {0, 0, 0}};
  r.g[a] = sgn(p[a]);
  return r;
}

using LocalFn = Local (*)(const double[3], const Vec3&);

template <LocalFn fn>
inline ImplicitSample sample(const Obstacle& o, const double p[3]) {
  const double d[3] = {p[0] - o.center[0], p[1] - o.center[1], p[2] - o.center[2]};
  double local[3];
  for (int l = 0; l < 3; ++l) local[l] = o.rot[0][l] * d[0] + o.rot[1][l] * d[1] + o.rot[2][l] * d[2];
  const Local r = fn(local, o.def.size);
  ImplicitSample s;
  s.f = r.f;
  for (int k = 0; k < 3; ++k) s.grad[k] = o.rot[k][0] * r.g[0] + o.rot[k][1] * r.g[1] + o.rot[k][2] * r.g[2];
  return s;
}

// One loop per shape and force mode, chosen once per obstacle: no feature branch per point.
template <LocalFn fn, bool project, class Real>
void repel(const Topology<Real>& t, const Obstacle& o, double cap, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f) {
  const std::uint32_t m = t.m, n = t.n, cols = t.cols();
  for (std::uint32_t i = 0; i <= m; ++i) {
    const std::uint32_t up = std::min(i + 1, m), down = i > 0 ? i - 1 : 0;
    for (std::uint32_t j = 0; j <= n; ++j) {
      const std::uint32_t p = i * cols + j;
      const double pos[3] = {double(x.x[p]), double(x.y[p]), double(x.z[p])};
      const ImplicitSample s = sample<fn>(o, pos);
      const double scale = potential_force_scale(o.def, s.f, cap);  // −dE/df ≥ 0: push along +∇f
      double F[3] = {scale * s.grad[0], scale * s.grad[1], scale * s.grad[2]};
      if constexpr (project) {
        // eq (9): keep only the part along the sheet's unit normal, the cross product of the
        // central (one-sided at the border) differences along the row and the column.
        const std::uint32_t r = i * cols + std::min(j + 1, n), l = i * cols + (j > 0 ? j - 1 : 0);
        const std::uint32_t u = up * cols + j, d = down * cols + j;
        const double a[3] = {double(x.x[r]) - x.x[l], double(x.y[r]) - x.y[l], double(x.z[r]) - x.z[l]};
        const double b[3] = {double(x.x[u]) - x.x[d], double(x.y[u]) - x.y[d], double(x.z[u]) - x.z[d]};
        const double nv[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        const double nn = nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2];
        // A single point or a single row has no normal: it gets the full gradient.
        if (nn > 0) {
          const double dot = (F[0] * nv[0] + F[1] * nv[1] + F[2] * nv[2]) / nn;
          F[0] = dot * nv[0];
          F[1] = dot * nv[1];
          F[2] = dot * nv[2];
        }
      }
      f.x[p] += static_cast<Real>(F[0]);
      f.y[p] += static_cast<Real>(F[1]);
      f.z[p] += static_cast<Real>(F[2]);
    }
  }
}

template <bool project, class Real>
void repel_shape(const Topology<Real>& t, const Obstacle& o, double cap, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f) {
  switch (o.def.shape) {
    case ObstacleShape::Plane: repel<plane_f, project>(t, o, cap, x, f); break;
    case ObstacleShape::Sphere: repel<sphere_f, project>(t, o, cap, x, f); break;
    case ObstacleShape::Ellipsoid: repel<ellipsoid_f, project>(t, o, cap, x, f); break;
    case ObstacleShape::Torus: repel<torus_f, project>(t, o, cap, x, f); break;
    case ObstacleShape::Box: repel<box_f, project>(t, o, cap, x, f); break;
  }
}

}  // namespace

Obstacle make_obstacle(const ObstacleDef& def) {
  Obstacle o;
  o.def = def;
  o.center[0] = def.center.x;
  o.center[1] = def.center.y;
  o.center[2] = def.center.z;
  const Vec3 axes[3] = {rotate(def.orientation, {1, 0, 0}), rotate(def.orientation, {0, 1, 0}),
                        rotate(def.orientation, {0, 0, 1})};
  for (int l = 0; l < 3; ++l) {
    o.rot[0][l] = axes[l].x;
    o.rot[1][l] = axes[l].y;
    o.rot[2][l] = axes[l].z;
  }
  const Vec3& s = def.size;
  double half[3] = {0, 0, 0};
  double stretch = 1;  // how much farther than f a point can be: only the ellipsoid's f is not a distance
  switch (def.shape) {
    case ObstacleShape::Plane: o.bounded = false; break;
    case ObstacleShape::Sphere: half[0] = half[1] = half[2] = s.x; break;
    case ObstacleShape::Ellipsoid:
      half[0] = s.x, half[1] = s.y, half[2] = s.z;
      stretch = std::max({s.x, s.y, s.z}) / std::min({s.x, s.y, s.z});
      break;
    case ObstacleShape::Torus: half[0] = half[1] = s.x + s.y, half[2] = s.y; break;
    case ObstacleShape::Box: half[0] = s.x, half[1] = s.y, half[2] = s.z; break;
  }
  o.reach_distance = reach_exponent * def.xi * stretch;
  for (int k = 0; k < 3; ++k) {
    double ext = 0;
    for (int l = 0; l < 3; ++l) ext += std::abs(o.rot[k][l]) * half[l];
    o.reach.lo[k] = o.center[k] - ext - o.reach_distance;
    o.reach.hi[k] = o.center[k] + ext + o.reach_distance;
  }
  return o;
}

ImplicitSample implicit_at(const Obstacle& o, const double p[3]) {
  switch (o.def.shape) {
    case ObstacleShape::Plane: return sample<plane_f>(o, p);
    case ObstacleShape::Sphere: return sample<sphere_f>(o, p);
    case ObstacleShape::Ellipsoid: return sample<ellipsoid_f>(o, p);
    case ObstacleShape::Torus: return sample<torus_f>(o, p);
    case ObstacleShape::Box: return sample<box_f>(o, p);
  }
  return {};
}

double exponent_cap(const ObstacleDef& d, double lightest_mass, double dt) {
  return std::min(d.max_exponent, std::log(lightest_mass * d.xi * d.xi / (d.c * dt * dt)));
}

double potential_energy(const ObstacleDef& d, double f, double cap) {
  const double e = -f / d.xi;
  if (e <= cap) return d.c * std::exp(e);
  return d.c * std::exp(cap) * (1.0 + (e - cap));
}

double potential_force_scale(const ObstacleDef& d, double f, double cap) {
  return d.c / d.xi * std::exp(std::min(-f / d.xi, cap));
}

bool may_touch(const Obstacle& o, const Aabb& box) {
  if (o.bounded) return overlaps(o.reach, box);
  // The plane's f is linear, so its minimum over the box is at one of the eight corners.
  double lowest = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    const double p[3] = {c & 1 ? box.hi[0] : box.lo[0], c & 2 ? box.hi[1] : box.lo[1], c & 4 ? box.hi[2] : box.lo[2]};
    lowest = std::min(lowest, sample<plane_f>(o, p).f);
  }
  return lowest < o.reach_distance;
}

template <class Real>
void obstacle_forces(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f) {
  const Obstacle& o = *near.obstacle;
  if (o.def.full_gradient)
    repel_shape<false>(t, o, near.exponent_cap, x, f);
  else
    repel_shape<true>(t, o, near.exponent_cap, x, f);
}

template <class Real>
double obstacle_energy(const Sheet<Real>& s, const Obstacle& o, double cap) {
  double e = 0;
  for (std::size_t p = 0; p < s.size(); ++p) {
    const double pos[3] = {double(s.position.x[p]), double(s.position.y[p]), double(s.position.z[p])};
    e += potential_energy(o.def, implicit_at(o, pos).f, cap);
  }
  return e;
}

template void obstacle_forces<double>(const Topology<double>&, const NearObstacle&, ConstVec3Ptr<double>, Vec3Ptr<double>);
template void obstacle_forces<float>(const Topology<float>&, const NearObstacle&, ConstVec3Ptr<float>, Vec3Ptr<float>);
template double obstacle_energy<double>(const Sheet<double>&, const Obstacle&, double);
template double obstacle_energy<float>(const Sheet<float>&, const Obstacle&, double);

}  // namespace detail
}  // namespace drape
