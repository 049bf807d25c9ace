// Force kernels: springs (eqs 6–7), damping (eq 4's C), anchors (eq 8); obstacles (eq 9) live in obstacles.cpp.
#include "forces.h"

#include "obstacles.h"

#include <cmath>

namespace drape::detail {

namespace {

// Spring force on the first endpoint of a spring whose endpoints differ by d = x1 − x2:
// −k (|d| − ℓ)/|d| · d (eq 6 carries the opposite sign because the paper moves f_spr to
// the right-hand side of eq 4). A zero-length spring has no direction and contributes
// nothing: the select keeps 0/0 out of the result.
template <class Real>
inline Real spring_scale(Real dx, Real dy, Real dz, Real rest, Real k) {
  const Real len = std::sqrt(dx * dx + dy * dy + dz * dz);
  const Real inv = len > Real(0) ? Real(1) / len : Real(0);
  return -k * (len - rest) * inv;
}

// Horizontal springs of one row: forces go to a scratch row first, so the scatter into
// both endpoints becomes a dependency-free second loop the compiler can vectorise.
template <class Real>
inline void row_springs(std::uint32_t n, const Real* __restrict x, const Real* __restrict y, const Real* __restrict z,
                        const Real* __restrict rest, const Real* __restrict k, Real* __restrict sx, Real* __restrict sy,
                        Real* __restrict sz, Real* __restrict fx, Real* __restrict fy, Real* __restrict fz) {
  for (std::uint32_t j = 0; j < n; ++j) {
    const Real dx = x[j] - x[j + 1], dy = y[j] - y[j + 1], dz = z[j] - z[j + 1];
    const Real s = spring_scale(dx, dy, dz, rest[j], k[j]);
    sx[j] = s * dx;
    sy[j] = s * dy;
    sz[j] = s * dz;
  }
  // point j gets +s[j] from the spring on its right and −s[j−1] from the one on its left
  if (n == 0) {
    fx[0] = fy[0] = fz[0] = Real(0);
    return;
  }
  fx[0] = sx[0];
  fy[0] = sy[0];
  fz[0] = sz[0];
  for (std::uint32_t j = 1; j < n; ++j) {
    fx[j] = sx[j] - sx[j - 1];
    fy[j] = sy[j] - sy[j - 1];
    fz[j] = sz[j] - sz[j - 1];
  }
  fx[n] = -sx[n - 1];
  fy[n] = -sy[n - 1];
  fz[n] = -sz[n - 1];
}

// Vertical springs between row `a` and the row below it, `b`: no two iterations touch
// the same point, so it vectorises as it stands.
template <class Real>
inline void column_springs(std::uint32_t cols, const Real* __restrict xa, const Real* __restrict ya,
                           const Real* __restrict za, const Real* __restrict xb, const Real* __restrict yb,
                           const Real* __restrict zb, const Real* __restrict rest, const Real* __restrict k,
                           Real* __restrict fxa, Real* __restrict fya, Real* __restrict fza, Real* __restrict fxb,
                           Real* __restrict fyb, Real* __restrict fzb) {
  for (std::uint32_t j = 0; j < cols; ++j) {
    const Real dx = xa[j] - xb[j], dy = ya[j] - yb[j], dz = za[j] - zb[j];
    const Real s = spring_scale(dx, dy, dz, rest[j], k[j]);
    fxa[j] += s * dx;
    fya[j] += s * dy;
    fza[j] += s * dz;
    fxb[j] -= s * dx;
    fyb[j] -= s * dy;
    fzb[j] -= s * dz;
  }
}

}  // namespace

template <class Real>
void spring_forces_rows(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                        std::uint32_t r0, std::uint32_t r1) {
  const std::uint32_t n = t.n, cols = t.cols();
  const Real* rest = t.rest_length.data();
  const Real* k = t.stiffness.data();
  const std::uint32_t vertical = t.horizontal_count();
  auto horizontal = [&](std::uint32_t i) {
    const std::size_t p = std::size_t(i) * cols, e = std::size_t(i) * n;
    row_springs(n, x.x + p, x.y + p, x.z + p, rest + e, k + e, row.x, row.y, row.z, f.x + p, f.y + p, f.z + p);
  };
  // The vertical springs between rows i and i+1, each block keeping only the share of the
  // endpoint in its rows: `upper` the a-side (row i), otherwise the b-side (row i+1).
  auto boundary = [&](std::uint32_t i, bool upper) {
    const std::size_t a = std::size_t(i) * cols, b = a + cols, e = vertical + std::size_t(i) * cols;
    for (std::uint32_t j = 0; j < cols; ++j) {
      const Real dx = x.x[a + j] - x.x[b + j], dy = x.y[a + j] - x.y[b + j], dz = x.z[a + j] - x.z[b + j];
      const Real s = spring_scale(dx, dy, dz, rest[e + j], k[e + j]);
      if (upper) {
        f.x[a + j] += s * dx;
        f.y[a + j] += s * dy;
        f.z[a + j] += s * dz;
      } else {
        f.x[b + j] -= s * dx;
        f.y[b + j] -= s * dy;
        f.z[b + j] -= s * dz;
      }
    }
  };
  // Row i+1's horizontal springs assign its forces before the vertical springs of rows
  // i–i+1 add to them, so f needs no separate clearing pass. Every row thus gets: its
  // horizontal springs, then the spring above it, then the spring below it.
  horizontal(r0);
  if (r0 > 0) boundary(r0 - 1, false);
  for (std::uint32_t i = r0; i + 1 < r1; ++i) {
    horizontal(i + 1);
    const std::size_t a = std::size_t(i) * cols, b = a + cols, e = vertical + std::size_t(i) * cols;
    column_springs(cols, x.x + a, x.y + a, x.z + a, x.x + b, x.y + b, x.z + b, rest + e, k + e, f.x + a, f.y + a,
                   f.z + a, f.x + b, f.y + b, f.z + b);
  }
  if (r1 <= t.m) boundary(r1 - 1, true);
}

template <class Real>
void spring_forces(const Topology<Real>& t, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row) {
  spring_forces_rows(t, x, f, row, 0, t.rows());
}

template <class Real>
void sheet_forces_rows(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                       Vec3Ptr<Real> row, std::uint32_t r0, std::uint32_t r1) {
  spring_forces_rows(*s.topology, x, f, row, r0, r1);
  const std::size_t cols = s.topology->cols(), begin = r0 * cols, end = r1 * cols;
  if (!s.damping.empty()) {  // eq (4): −C ẋ, C diagonal
    const Real* c = s.damping.data();
    for (std::size_t i = begin; i < end; ++i) {
      f.x[i] -= c[i] * v.x[i];
      f.y[i] -= c[i] * v.y[i];
      f.z[i] -= c[i] * v.z[i];
    }
  }
  if (s.has_contacts) {  // gathered by the host stage (contacts.h)
    const auto& c = s.contact_force;
    for (std::size_t i = begin; i < end; ++i) {
      f.x[i] += c.x[i];
      f.y[i] += c.y[i];
      f.z[i] += c.z[i];
    }
  }
  const auto& an = s.anchors;
  for (std::size_t a = 0; a < an.point.size(); ++a) {  // eq (8): k (p0 − x)
    const std::uint32_t p = an.point[a];
    if (p < begin || p >= end) continue;
    f.x[p] += an.stiffness[a] * (an.tx[a] - x.x[p]);
    f.y[p] += an.stiffness[a] * (an.ty[a] - x.y[p]);
    f.z[p] += an.stiffness[a] * (an.tz[a] - x.z[p]);
  }
  // eq (9): only obstacles the host stage found near this sheet (whole sheets only: the
  // world never splits a sheet into row blocks while an obstacle is near it)
  for (const NearObstacle& o : s.near_obstacles) obstacle_forces(*s.topology, o, x, f);
}

template <class Real>
void sheet_forces(Sheet<Real>& s, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f) {
  sheet_forces_rows(s, x, v, f, ptr(s.row_scratch), 0, s.topology->rows());
}

template void spring_forces<double>(const Topology<double>&, ConstVec3Ptr<double>, Vec3Ptr<double>, Vec3Ptr<double>);
template void spring_forces<float>(const Topology<float>&, ConstVec3Ptr<float>, Vec3Ptr<float>, Vec3Ptr<float>);
template void spring_forces_rows<double>(const Topology<double>&, ConstVec3Ptr<double>, Vec3Ptr<double>,
                                         Vec3Ptr<double>, std::uint32_t, std::uint32_t);
template void spring_forces_rows<float>(const Topology<float>&, ConstVec3Ptr<float>, Vec3Ptr<float>, Vec3Ptr<float>,
                                        std::uint32_t, std::uint32_t);
template void sheet_forces_rows<double>(Sheet<double>&, ConstVec3Ptr<double>, ConstVec3Ptr<double>, Vec3Ptr<double>,
                                        Vec3Ptr<double>, std::uint32_t, std::uint32_t);
template void sheet_forces_rows<float>(Sheet<float>&, ConstVec3Ptr<float>, ConstVec3Ptr<float>, Vec3Ptr<float>,
                                       Vec3Ptr<float>, std::uint32_t, std::uint32_t);
template void sheet_forces<double>(Sheet<double>&, ConstVec3Ptr<double>, ConstVec3Ptr<double>, Vec3Ptr<double>);
template void sheet_forces<float>(Sheet<float>&, ConstVec3Ptr<float>, ConstVec3Ptr<float>, Vec3Ptr<float>);

}  // namespace drape::detail
