// ObstacleDef: an impenetrable rigid obstacle given by an implicit inside–outside function
// f (f > 0 outside, f < 0 inside, f = 0 on the surface) with an analytic gradient, and the
// paper's repulsion potential E = c·exp(−f(x)/ξ) around it (§3, eq 9).
// An ObstacleDef is a plain value; the world copies it when the obstacle is added.
#pragma once

#include <drape/motion.h>
#include <drape/types.h>

#include <optional>
#include <string>
#include <string_view>

namespace drape {

enum class ObstacleShape {
  Plane,      // local z = 0, outside is local +z
  Sphere,     // radius = size.x
  Ellipsoid,  // semi-axes size.x, size.y, size.z (Fig 9)
  Torus,      // major radius size.x (centre to tube centre), minor radius size.y; axis local z (Figs 10–12)
  Box,        // half extents size.x, size.y, size.z
};

struct ObstacleDef {
  ObstacleShape shape = ObstacleShape::Sphere;
  Vec3 center{};
  Quat orientation{};
  Vec3 size{0.5, 0.5, 0.5};  // m, meaning per shape (above)
  double c = 1.0;            // J, strength of the potential
  double xi = 0.01;          // ξ, m: how quickly the potential decays away from the surface
  // false (default): the force is projected on the sheet's unit surface normal, as in eq (9);
  // true: the full gradient −∇E is used.
  bool full_gradient = false;
  // Force bound. The exponent −f/ξ is capped: deeper than f = −cap·ξ the energy continues
  // linearly, so the force stops growing at (c/ξ)·e^cap·|∇f|. The cap is max_exponent, or
  // lower where the potential would get stiffer than the step resolves: at most m/dt² for the
  // sheet's lightest point m, a quarter of the explicit limit 4m/dt². A point that starts
  // inside, or arrives faster than the potential can stop it, is pushed out by a finite force
  // the integrator resolves, instead of one that overflows or throws it out with extra energy.
  double max_exponent = 8.0;
  // μ, Coulomb friction of the surface (static and kinetic, ≥ 0). Against a sheet the larger
  // of this and SheetDef::friction acts; 0 on both: frictionless (docs/scene-format.md).
  double friction = 0.0;
  // α, s/m: Hunt–Crossley damping of the repulsion, which becomes F·(1 − α·ḋ), ḋ the rate at
  // which the point's distance from the surface grows (relative to a moving obstacle's
  // surface); its coefficient α·|F| is capped at a quarter of the point's m/dt, and the force
  // is never attractive. 0 (default): the potential alone, which conserves energy, so a
  // sheet dropped on the obstacle bounces off it as far as its own damping allows.
  double damping = 0.0;
  // A rigid part that moves: at time t the obstacle is turned and moved by pose_at(*motion, t)
  // from the pose above (center, orientation); sheets near it feel it where it is at the
  // start of each substep. Points attached to it: a Frame constraint with this obstacle as
  // its carrier (constraint.h).
  std::optional<Motion> motion;
};

// The scene format's name of a shape ("plane", "sphere", "ellipsoid", "torus", "box");
// "unknown" for a value outside the enum.
std::string_view obstacle_shape_name(ObstacleShape shape);

// The obstacle where its motion has it at `time` (s): center and orientation posed, no motion.
// Without a motion, the definition itself.
ObstacleDef obstacle_at(const ObstacleDef& def, double time);

// An empty string when the definition can be simulated; otherwise one message naming the
// field and the problem, e.g. "xi must be positive and finite (got 0)".
std::string validate(const ObstacleDef& def);

}  // namespace drape
