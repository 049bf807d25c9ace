// Obstacles (paper §3, eq 9): implicit functions of plane, sphere, ellipsoid, torus and box
// with analytic gradients, and the repulsion c·exp(−f/ξ) around them.
//
// Highway's foreach_target compiles the eq (9) term once per instruction set
// (simd/targets.h), like the row sweep (forces.cpp): its omp simd loops vectorise for each,
// and obstacle_forces dispatches to the widest the CPU has once per sheet and obstacle.
// Contraction into FMA is off here (engine/CMakeLists.txt), so every target gives the same
// bits. The rest (validation, placement, energies) is compiled once and uses the build's
// own target's copy of the shapes.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "obstacles.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "obstacles.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <limits>
#include <sstream>
#include <type_traits>

HWY_BEFORE_NAMESPACE();
namespace drape::detail {
namespace HWY_NAMESPACE {

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

// e^x for x ≥ −700 without a call or a branch, so a loop over points vectorises (std::exp
// does not: GCC has no vector exp without -ffast-math). x = k·ln2 + r with |r| ≤ ln2/2, e^r by
// its Taylor series to r^13 (truncation below 2e-16 relative), 2^k put into the exponent bits.
inline double exp_lanes(double x) {
  x = x < -700.0 ? -700.0 : x;
  constexpr double shifter = 0x1.8p52;  // adding it rounds to an integer held in the low bits
  const double shifted = x * 0x1.71547652b82fep0 + shifter;
  const std::uint64_t k = std::bit_cast<std::uint64_t>(shifted);
  const double kd = shifted - shifter;
  const double r = (x - kd * 0x1.62e42fefa3800p-1) - kd * 0x1.ef35793c7673p-45;  // ln2 in two parts
  double p = 1.0 / 6227020800.0;
  p = p * r + 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  return std::bit_cast<double>(std::bit_cast<std::uint64_t>(p) + (k << 52));
}

// The cut-off, shifted eq (9) for whole vectors of points: −dE/df, zero at and beyond the reach.
struct ForceScale {
  double c_over_xi, inv_xi, cap, tail, reach;  // tail = e^−reach_exponent
  double operator()(double f) const {
    const double e = std::min(-f * inv_xi, cap);
    const double s = c_over_xi * std::max(exp_lanes(e) - tail, 0.0);  // ≥ 0 even for a cap below −reach
    return f < reach ? s : 0.0;
  }
};

ForceScale force_scale_of(const ObstacleDef& d, double cap) {
  return {d.c / d.xi, 1.0 / d.xi, cap, std::exp(-reach_exponent), reach_exponent * d.xi};
}

// Points go through in chunks of a row: first f and ∇f of every point (plain loops), then,
// only if some point of the chunk is within reach, the force scale of every point (exp_lanes,
// zero beyond reach), then the force along the sheet's normal. Every loop runs the same
// arithmetic on every point, so they vectorise; a chunk wholly beyond reach costs only f.
constexpr std::uint32_t chunk_points = 64;

struct Chunk {
  alignas(64) double f[chunk_points];
  alignas(64) double gx[chunk_points], gy[chunk_points], gz[chunk_points];
  alignas(64) double s[chunk_points];
};

// A plane's ∇f is its unit normal everywhere: the chunk holds only f, and the loops below
// read the normal from the obstacle.
template <LocalFn fn>
inline constexpr bool constant_gradient = fn == &plane_f;

// f and ∇f per shape, local → world as in sample(); the plane's f is one dot product.
template <LocalFn fn, class Real>
inline void implicit_chunk(const Obstacle& o, const Real* x, const Real* y, const Real* z, std::uint32_t count,
                           Chunk& c) {
  if constexpr (constant_gradient<fn>) {
    const double nx = o.rot[0][2], ny = o.rot[1][2], nz = o.rot[2][2];
    const double cx = o.center[0], cy = o.center[1], cz = o.center[2];
#pragma omp simd
    for (std::uint32_t k = 0; k < count; ++k)
      c.f[k] = nx * (double(x[k]) - cx) + ny * (double(y[k]) - cy) + nz * (double(z[k]) - cz);
  } else {
    for (std::uint32_t k = 0; k < count; ++k) {
      const double p[3] = {double(x[k]), double(y[k]), double(z[k])};
      const ImplicitSample s = sample<fn>(o, p);
      c.f[k] = s.f;
      c.gx[k] = s.grad[0];
      c.gy[k] = s.grad[1];
      c.gz[k] = s.grad[2];
    }
  }
}

// The per-point pieces of the loops below (the projection, friction, the point's force)
// must inline into their `#pragma omp simd` loops: a call left in one makes the loop scalar
// with a call per point. GCC's inliner gave up on them once the moving-obstacle slip made
// the friction point's body bigger (19b3f0b: friction went from +40-60 % to +600-1000 % of a
// frictionless floor, BM_Feature_obstacle_friction), so they are forced.
#define DRAPE_POINT_INLINE __attribute__((always_inline))

// eq (9)'s projection on the sheet's unit normal n = a × b, a and b the differences across
// the point along its row and its column: F·n/|n|² n. A lone point or row has no normal
// (|n| = 0) and keeps the full gradient.
DRAPE_POINT_INLINE inline void project_on_normal(double ax, double ay, double az, double bx, double by, double bz, double& fx, double& fy,
                              double& fz) {
  const double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
  const double nn = nx * nx + ny * ny + nz * nz;
  const double dot = (fx * nx + fy * ny + fz * nz) / (nn > 0 ? nn : 1.0);
  fx = nn > 0 ? dot * nx : fx;
  fy = nn > 0 ? dot * ny : fy;
  fz = nn > 0 ? dot * nz : fz;
}

// Coulomb friction on one point (docs/scene-format.md, Friction): N the repulsion F's part
// along g = ∇f, v* the velocity the substep would leave the point with (its total force
// so far, F included, and gravity) relative to the obstacle's surface there (v is passed
// in relative already), and the force against v*'s tangential part, the smaller
// of μ·N and m·|v*_t|/dt (what stops the slip within the substep). Adds it to F.
struct Rub {
  double mu, dt, gravity[3];
  DRAPE_POINT_INLINE void operator()(const double g[3], double F[3], const double total[3], const double v[3],
                                     double inv_mass) const {
    const double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    const double inv_g2 = g2 > 0 ? 1.0 / g2 : 0.0;
    const double along = F[0] * g[0] + F[1] * g[1] + F[2] * g[2];
    const double load = along > 0 ? along * std::sqrt(inv_g2) : 0.0;  // N
    double w[3];
    for (int k = 0; k < 3; ++k) w[k] = v[k] + dt * (inv_mass * total[k] + gravity[k]);
    const double wn = (w[0] * g[0] + w[1] * g[1] + w[2] * g[2]) * inv_g2;
    double slip[3];
    for (int k = 0; k < 3; ++k) slip[k] = w[k] - wn * g[k];
    const double speed = std::sqrt(slip[0] * slip[0] + slip[1] * slip[1] + slip[2] * slip[2]);
    const double stop = inv_mass > 0 ? 1.0 / (inv_mass * dt) : std::numeric_limits<double>::infinity();
    const double k = speed > 0 ? std::min(mu * load / (speed > 0 ? speed : 1.0), stop) : 0.0;
    for (int c = 0; c < 3; ++c) F[c] -= k * slip[c];
  }
};

// One loop per shape, force mode and friction, chosen once per obstacle: no feature branch
// per point.
template <LocalFn fn, bool project, bool rub, class Real>
void repel(const Topology<Real>& t, const Obstacle& o, const NearObstacle& near, ConstVec3Ptr<Real> x,
           ConstVec3Ptr<Real> v, const Real* inv_mass, Vec3Ptr<Real> f) {
  const std::uint32_t m = t.m, n = t.n, cols = t.cols();
  const ForceScale scale = force_scale_of(o.def, near.exponent_cap);
  const Rub friction{near.friction, near.dt, {near.gravity[0], near.gravity[1], near.gravity[2]}};
  const double normal[3] = {o.rot[0][2], o.rot[1][2], o.rot[2][2]};  // ∇f where constant_gradient
  Chunk c;
  for (std::uint32_t i = 0; i <= m; ++i) {
    const std::size_t row = std::size_t(i) * cols;
    const std::size_t up = std::size_t(std::min(i + 1, m)) * cols, down = std::size_t(i > 0 ? i - 1 : 0) * cols;
    for (std::uint32_t j0 = 0; j0 < cols; j0 += chunk_points) {
      const std::uint32_t count = std::min(chunk_points, cols - j0);
      const std::size_t p0 = row + j0;
      implicit_chunk<fn>(o, x.x + p0, x.y + p0, x.z + p0, count, c);
      double lowest = c.f[0];
#pragma omp simd reduction(min : lowest)
      for (std::uint32_t k = 0; k < count; ++k) lowest = std::min(lowest, c.f[k]);
      if (!(lowest < scale.reach)) continue;  // the whole chunk is beyond reach
#pragma omp simd
      for (std::uint32_t k = 0; k < count; ++k) c.s[k] = scale(c.f[k]);
      // The force on point j0 + k, written back into f (and projected first, for eq (9)); its
      // neighbours along the row are l and r. Every index is 64-bit and affine in k: a 32-bit
      // j0 + k may wrap as far as the compiler knows, and it reads the neighbours with
      // gathers instead of plain vector loads.
      auto apply = [&](std::uint32_t k, std::size_t l, std::size_t r) DRAPE_POINT_INLINE {
        const std::size_t p = p0 + k, j = std::size_t(j0) + k;
        const double g[3] = {constant_gradient<fn> ? normal[0] : c.gx[k], constant_gradient<fn> ? normal[1] : c.gy[k],
                             constant_gradient<fn> ? normal[2] : c.gz[k]};
        double F[3] = {c.s[k] * g[0], c.s[k] * g[1], c.s[k] * g[2]};
        if constexpr (project)
          project_on_normal(double(x.x[row + r]) - x.x[row + l], double(x.y[row + r]) - x.y[row + l],
                            double(x.z[row + r]) - x.z[row + l], double(x.x[up + j]) - x.x[down + j],
                            double(x.y[up + j]) - x.y[down + j], double(x.z[up + j]) - x.z[down + j], F[0], F[1],
                            F[2]);
        if constexpr (rub) {
          const double total[3] = {f.x[p] + F[0], f.y[p] + F[1], f.z[p] + F[2]};
          // the slip relative to the obstacle's surface here: v − (linear + angular × (x − center))
          const double* w = near.angular;
          const double r[3] = {double(x.x[p]) - near.center[0], double(x.y[p]) - near.center[1],
                               double(x.z[p]) - near.center[2]};
          const double vel[3] = {double(v.x[p]) - (near.linear[0] + (w[1] * r[2] - w[2] * r[1])),
                                 double(v.y[p]) - (near.linear[1] + (w[2] * r[0] - w[0] * r[2])),
                                 double(v.z[p]) - (near.linear[2] + (w[0] * r[1] - w[1] * r[0]))};
          friction(g, F, total, vel, double(inv_mass[p]));
        }
        f.x[p] += static_cast<Real>(F[0]);
        f.y[p] += static_cast<Real>(F[1]);
        f.z[p] += static_cast<Real>(F[2]);
      };
      // Central differences along the row inside it, one-sided at its two ends.
      const std::uint32_t first = j0 == 0 ? 1 : 0, last = j0 + count > n ? count - 1 : count;
      if (first > 0) apply(0, 0, std::min(1u, n));
#pragma omp simd
      for (std::uint32_t k = first; k < last; ++k) apply(k, std::size_t(j0) + k - 1, std::size_t(j0) + k + 1);
      if (last < count && (first == 0 || count > 1)) apply(count - 1, n > 0 ? n - 1 : 0, n);
    }
  }
}

template <bool project, bool rub, class Real>
void repel_shape(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                 const Real* inv_mass, Vec3Ptr<Real> f) {
  const Obstacle& o = *near.obstacle;
  switch (o.def.shape) {
    case ObstacleShape::Plane: repel<plane_f, project, rub>(t, o, near, x, v, inv_mass, f); break;
    case ObstacleShape::Sphere: repel<sphere_f, project, rub>(t, o, near, x, v, inv_mass, f); break;
    case ObstacleShape::Ellipsoid: repel<ellipsoid_f, project, rub>(t, o, near, x, v, inv_mass, f); break;
    case ObstacleShape::Torus: repel<torus_f, project, rub>(t, o, near, x, v, inv_mass, f); break;
    case ObstacleShape::Box: repel<box_f, project, rub>(t, o, near, x, v, inv_mass, f); break;
  }
}

template <class Real>
void obstacle_forces_of(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f) {
  const bool project = !near.obstacle->def.full_gradient, rub = near.friction > 0;
  if (project && rub) repel_shape<true, true>(t, near, x, v, inv_mass, f);
  if (project && !rub) repel_shape<true, false>(t, near, x, v, inv_mass, f);
  if (!project && rub) repel_shape<false, true>(t, near, x, v, inv_mass, f);
  if (!project && !rub) repel_shape<false, false>(t, near, x, v, inv_mass, f);
}


void ObstacleForcesF64(const Topology<double>& t, const NearObstacle& near, ConstVec3Ptr<double> x,
                       ConstVec3Ptr<double> v, const double* inv_mass, Vec3Ptr<double> f) {
  obstacle_forces_of(t, near, x, v, inv_mass, f);
}
void ObstacleForcesF32(const Topology<float>& t, const NearObstacle& near, ConstVec3Ptr<float> x,
                       ConstVec3Ptr<float> v, const float* inv_mass, Vec3Ptr<float> f) {
  obstacle_forces_of(t, near, x, v, inv_mass, f);
}

}  // namespace HWY_NAMESPACE
}  // namespace drape::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
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
  if (!(std::isfinite(d.friction) && d.friction >= 0)) return fail("friction", "must be non-negative and finite", d.friction);
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

// The static target's copy of the per-target code, for what runs once.
namespace here = HWY_NAMESPACE;

HWY_EXPORT(ObstacleForcesF64);
HWY_EXPORT(ObstacleForcesF32);

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
    case ObstacleShape::Plane: return here::sample<here::plane_f>(o, p);
    case ObstacleShape::Sphere: return here::sample<here::sphere_f>(o, p);
    case ObstacleShape::Ellipsoid: return here::sample<here::ellipsoid_f>(o, p);
    case ObstacleShape::Torus: return here::sample<here::torus_f>(o, p);
    case ObstacleShape::Box: return here::sample<here::box_f>(o, p);
  }
  return {};
}

double exponent_cap(const ObstacleDef& d, double lightest_mass, double dt) {
  return std::min(d.max_exponent, std::log(lightest_mass * d.xi * d.xi / (d.c * dt * dt)));
}

double potential_energy(const ObstacleDef& d, double f, double cap) {
  // E(f) = ∫_f^R of the force scale below: c·(e^e − t) − c·t·(r + e), e = −f/ξ, t = e^−r,
  // continued linearly in e past the cap; zero at and beyond R = r·ξ.
  if (!(f < reach_exponent * d.xi)) return 0.0;
  const double t = std::exp(-reach_exponent), e = -f / d.xi;
  if (e <= cap) return d.c * (std::exp(e) - t) - d.c * t * (reach_exponent + e);
  return d.c * (std::exp(cap) - t) * (1.0 + (e - cap)) - d.c * t * (reach_exponent + cap);
}

double potential_force_scale(const ObstacleDef& d, double f, double cap) { return here::force_scale_of(d, cap)(f); }

bool may_touch(const Obstacle& o, const Aabb& box) {
  if (o.bounded) return overlaps(o.reach, box);
  // The plane's f is linear, so its minimum over the box is at one of the eight corners.
  double lowest = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    const double p[3] = {c & 1 ? box.hi[0] : box.lo[0], c & 2 ? box.hi[1] : box.lo[1], c & 4 ? box.hi[2] : box.lo[2]};
    lowest = std::min(lowest, here::sample<here::plane_f>(o, p).f);
  }
  return lowest < o.reach_distance;
}

// One dispatch per sheet and obstacle per substep: the chunks, the shapes' f and ∇f, the
// force scale, the projection and friction run on the widest instruction set the CPU has.
template <class Real>
void obstacle_forces(const Topology<Real>& t, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f) {
  if constexpr (std::is_same_v<Real, double>)
    HWY_DYNAMIC_DISPATCH(ObstacleForcesF64)(t, near, x, v, inv_mass, f);
  else
    HWY_DYNAMIC_DISPATCH(ObstacleForcesF32)(t, near, x, v, inv_mass, f);
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

template void obstacle_forces<double>(const Topology<double>&, const NearObstacle&, ConstVec3Ptr<double>,
                                      ConstVec3Ptr<double>, const double*, Vec3Ptr<double>);
template void obstacle_forces<float>(const Topology<float>&, const NearObstacle&, ConstVec3Ptr<float>,
                                     ConstVec3Ptr<float>, const float*, Vec3Ptr<float>);
template double obstacle_energy<double>(const Sheet<double>&, const Obstacle&, double);
template double obstacle_energy<float>(const Sheet<float>&, const Obstacle&, double);

}  // namespace detail
}  // namespace drape
#endif  // HWY_ONCE
