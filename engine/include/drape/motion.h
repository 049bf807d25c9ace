// Motion: a prescribed rigid motion over time (rotation and translation), for rigid parts
// that move (ObstacleDef::motion) and for the targets of path and frame constraints
// (ConstraintDef). A Motion is a plain value: whoever holds it copies it.
#pragma once

#include <drape/types.h>

#include <functional>
#include <string>
#include <vector>

namespace drape {

// A rigid transform: x ↦ rotation·x + translation.
struct Pose {
  Quat rotation{};
  Vec3 translation{};
};

Vec3 apply(const Pose& pose, Vec3 x);
Pose inverse(const Pose& pose);
Pose compose(const Pose& outer, const Pose& inner);  // x ↦ outer(inner(x))
Quat multiply(const Quat& a, const Quat& b);          // rotate by b, then by a

// One knot of a keyframed motion: at `time`, points are turned by `rotation` about the
// motion's pivot, then moved by `translation`.
struct Keyframe {
  double time = 0;         // s
  Vec3 translation{};      // m
  Quat rotation{};
};

// A point carried around a circle: the translation that takes `start` to where it is at
// time t, turned by 2π·t/period about the axis through `center` (right-handed about
// `axis`). No rotation. A point at `start` at t = 0 is on the circle at every time.
struct CirclePath {
  Vec3 center{};
  Vec3 axis{0, 0, 1};
  Vec3 start{1, 0, 0};  // m; its distance from the axis is the radius
  double period = 1;    // s, one turn
};

struct Motion {
  enum class Kind {
    Keyframes,  // piecewise linear translation and slerped rotation between knots; held
                // before the first and after the last (or repeated, see `repeat`)
    Circle,     // CirclePath
    Callback,   // the API's own function of time (not in scene files)
  };
  Kind kind = Kind::Keyframes;
  Vec3 pivot{};                      // m: the point rotations turn about (Keyframes)
  std::vector<Keyframe> keyframes;   // at least two, times increasing
  bool repeat = false;               // keyframes loop with period last.time − first.time
  CirclePath circle;
  // time (s) → pose; must be pure: the same t, the same pose. step() calls it on the thread
  // that steps, one call at a time.
  std::function<Pose(double)> callback;
};

// The pose at time t (s). Keyframes: x ↦ R(t)·(x − pivot) + pivot + T(t).
Pose pose_at(const Motion& motion, double time);

// An empty string when the motion can be evaluated; otherwise one message naming the field,
// e.g. "keyframes must have at least two knots (got 1)".
std::string validate(const Motion& motion);

}  // namespace drape
