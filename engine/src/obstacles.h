// Obstacles: implicit functions with analytic gradients, the repulsion potential of eq (9)
// around them, and the test that decides which sheets come near which obstacle.
#pragma once

#include <drape/obstacle.h>

#include "bounds.h"
#include "forces.h"
#include "sheet_data.h"

namespace drape::detail {

// An obstacle as the step uses it: the definition plus its frame as a rotation matrix
// (local → world columns) and the world box beyond which its potential is negligible.
struct Obstacle {
  ObstacleDef def;
  double center[3] = {0, 0, 0};
  double rot[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};  // rot[k][l]: world axis k, local axis l
  bool bounded = true;  // false for the plane
  Aabb reach;           // bounded shapes: world box of the shape inflated by reach_distance()
  double reach_distance = 0;
};

// The potential is cut off at f = R = reach_exponent·ξ and shifted so its force falls
// continuously to zero there: −dE/df = (c/ξ)·(e^(−f/ξ) − e^(−reach_exponent)) for f < R, and 0
// beyond, so points beyond R cost nothing but f and sheets whose box is beyond it skip the
// obstacle. The force differs from the uncut one by at most (c/ξ)·e^−16 ≈ 1.1·10⁻⁷·c/ξ
// anywhere (Obstacles.CutOffForceStaysWithinItsBoundOfTheExactOne).
inline constexpr double reach_exponent = 16.0;

Obstacle make_obstacle(const ObstacleDef& def);

// f and ∇f in world coordinates; f > 0 outside, f < 0 inside.
struct ImplicitSample {
  double f = 0;
  double grad[3] = {0, 0, 0};
};
ImplicitSample implicit_at(const Obstacle& o, const double p[3]);

// The force bound. The exponent −f/ξ is capped at `cap`: past it E continues linearly, so the
// force stops growing at (c/ξ)·e^cap·|∇f|. The cap is the definition's max_exponent, lowered
// where needed so the potential's stiffness d²E/df² = (c/ξ²)·e^e stays at or below m/dt² for
// the sheet's lightest point m: a quarter of the explicit step's limit 4m/dt² (ω·dt < 2), so a
// point that arrives fast or starts inside meets a force the step resolves, not one that
// throws it out with more energy than it brought.
double exponent_cap(const ObstacleDef& def, double lightest_mass, double dt);

// The exponent at which a potential c·e^e with e = −(distance)/ξ reaches the stiffness
// d²E/d(distance)² = (c/ξ²)·e^e = m/dt² for a point of mass m: ln(m·ξ²/(c·dt²)). The obstacles'
// cap above and the contacts' (ContactParams::exponent_cap) both come from here.
double stiffness_exponent_cap(double strength, double xi, double lightest_mass, double dt);

// E(f) = c·exp(−f/ξ), cut off and shifted at reach_exponent·ξ (above), continued linearly past
// the exponent cap, and −dE/df, the factor that multiplies ∇f in the force (the kernel's own
// arithmetic, with vector_exp below).
double potential_energy(const ObstacleDef& def, double f, double cap);
double potential_force_scale(const ObstacleDef& def, double f, double cap);

// The kernel's exp on one value (every instruction set gives the same bits; the contact
// force uses it too): e^x within 10⁻¹⁵ of it (relative) for x in [−700, 709], e^−700
// below and e^709 above.
double vector_exp(double x);

// Host stage: can a sheet whose bounding box is `box` feel the obstacle at all?
bool may_touch(const Obstacle& o, const Aabb& box);

// eq (9): adds the obstacle's repulsion to f for every point of the sheet; projected on the
// sheet's unit normal (from the neighbouring grid points) unless def.full_gradient. With
// near.damping > 0 the force is damped against the point's normal velocity (reading v and the
// inverse mass), and with near.friction > 0 Coulomb friction follows, which reads the point's
// velocity v, its inverse mass and the total force f holds so far (call it after every other term).
template <class Real>
void obstacle_forces(const Topology<Real>& topo, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f);
// The same on the grid rows [row_begin, row_end) only: a row's points read the positions of
// the rows on either side (the normal), so those must not have moved yet.
template <class Real>
void obstacle_forces(const Topology<Real>& topo, const NearObstacle& near, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v,
                     const Real* inv_mass, Vec3Ptr<Real> f, std::uint32_t row_begin, std::uint32_t row_end);

// Σ potential_energy over the sheet's points, in vectors on the widest instruction set (the
// kernel's exp: within rounding of the sum of potential_energy, whose exp is the C library's).
template <class Real>
double obstacle_energy(const Sheet<Real>& sheet, const Obstacle& o, double cap);

}  // namespace drape::detail
