// Prescribed rigid motions: keyframes (linear translation, slerped rotation), circles, and
// callbacks, evaluated at a substep's time by the host stage (constraints.cpp).
#include <drape/motion.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

namespace drape {

namespace {

Vec3 add(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 scale(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
bool finite(Vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
Quat conjugate(const Quat& q) { return {q.w, -q.x, -q.y, -q.z}; }

// Shortest-arc spherical interpolation between unit quaternions, s in [0, 1].
Quat slerp(Quat a, Quat b, double s) {
  double c = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
  if (c < 0) {  // q and −q are the same rotation: take the short way
    b = {-b.w, -b.x, -b.y, -b.z};
    c = -c;
  }
  double wa = 1 - s, wb = s;
  if (c < 1 - 1e-12) {
    const double angle = std::acos(c), sn = std::sin(angle);
    wa = std::sin((1 - s) * angle) / sn;
    wb = std::sin(s * angle) / sn;
  }
  Quat q{wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z};
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

// Turned about `pivot`, then moved: x ↦ R(x − p) + p + T.
Pose about(const Quat& r, Vec3 pivot, Vec3 translation) {
  return {r, sub(add(pivot, translation), rotate(r, pivot))};
}

Pose keyframe_pose(const Motion& m, double t) {
  const auto& k = m.keyframes;
  const double first = k.front().time, last = k.back().time;
  if (m.repeat && t > last) t = first + std::fmod(t - first, last - first);
  if (t <= first) return about(k.front().rotation, m.pivot, k.front().translation);
  if (t >= last) return about(k.back().rotation, m.pivot, k.back().translation);
  const auto next = std::upper_bound(k.begin(), k.end(), t, [](double v, const Keyframe& f) { return v < f.time; });
  const Keyframe& b = *next;
  const Keyframe& a = *(next - 1);
  const double s = (t - a.time) / (b.time - a.time);
  const Vec3 translation = add(scale(a.translation, 1 - s), scale(b.translation, s));
  return about(slerp(a.rotation, b.rotation, s), m.pivot, translation);
}

Pose circle_pose(const CirclePath& c, double t) {
  const Quat turn = quat_from_axis_angle(c.axis, 2 * std::numbers::pi * t / c.period);
  const Vec3 at = add(c.center, rotate(turn, sub(c.start, c.center)));
  return {Quat{}, sub(at, c.start)};
}

bool unit(const Quat& q) { return std::abs(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z - 1) < 1e-6; }

}  // namespace

Vec3 apply(const Pose& p, Vec3 x) { return add(rotate(p.rotation, x), p.translation); }

Pose inverse(const Pose& p) {
  const Quat r = conjugate(p.rotation);
  return {r, scale(rotate(r, p.translation), -1)};
}

Quat multiply(const Quat& a, const Quat& b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

Pose compose(const Pose& outer, const Pose& inner) {
  return {multiply(outer.rotation, inner.rotation), apply(outer, inner.translation)};
}

Pose pose_at(const Motion& m, double t) {
  switch (m.kind) {
    case Motion::Kind::Keyframes: return keyframe_pose(m, t);
    case Motion::Kind::Circle: return circle_pose(m.circle, t);
    case Motion::Kind::Callback: return m.callback(t);
  }
  return {};
}

std::string validate(const Motion& m) {
  std::ostringstream out;
  switch (m.kind) {
    case Motion::Kind::Keyframes: {
      if (!finite(m.pivot)) return "pivot must be finite";
      if (m.keyframes.size() < 2) {
        out << "keyframes must have at least two knots (got " << m.keyframes.size() << ")";
        return out.str();
      }
      for (std::size_t k = 0; k < m.keyframes.size(); ++k) {
        const Keyframe& f = m.keyframes[k];
        out << "keyframes[" << k << "].";
        if (!std::isfinite(f.time)) return out.str() + "time must be finite";
        if (k > 0 && !(f.time > m.keyframes[k - 1].time)) {
          out << "time must be later than keyframes[" << k - 1 << "].time (got " << f.time << " after "
              << m.keyframes[k - 1].time << ")";
          return out.str();
        }
        if (!finite(f.translation)) return out.str() + "translation must be finite";
        if (!unit(f.rotation)) return out.str() + "rotation must be a unit quaternion";
        out.str("");
      }
      return {};
    }
    case Motion::Kind::Circle: {
      const CirclePath& c = m.circle;
      if (!finite(c.center)) return "circle.center must be finite";
      if (!finite(c.start)) return "circle.start must be finite";
      if (!finite(c.axis) || dot(c.axis, c.axis) == 0) return "circle.axis must be a finite, non-zero vector";
      if (!(c.period > 0) || !std::isfinite(c.period)) {
        out << "circle.period must be positive and finite (got " << c.period << ")";
        return out.str();
      }
      const Vec3 r = sub(c.start, c.center);
      const double along = dot(r, c.axis) / std::sqrt(dot(c.axis, c.axis));
      if (!(dot(r, r) - along * along > 0)) return "circle.start must not lie on the circle's axis (radius 0)";
      return {};
    }
    case Motion::Kind::Callback:
      if (!m.callback) return "callback must be set";
      return {};
  }
  return "kind is not a kind of motion";
}

}  // namespace drape
