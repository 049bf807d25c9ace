// SheetDef: the plain description of one elastic sheet (paper §2), with defaults, and
// helpers that pick the grid points the paper constrains. A SheetDef is only a value:
// the world copies what it needs when the sheet is added.
#pragma once

#include <drape/types.h>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace drape {

// Springs whose two end points both lie in rows [row_begin, row_end] and columns
// [col_begin, col_end] (inclusive) get this stiffness instead of SheetDef::stiffness (§5.1).
// Later regions win where regions overlap.
struct StiffnessRegion {
  std::uint32_t row_begin = 0, row_end = 0;
  std::uint32_t col_begin = 0, col_end = 0;
  double stiffness = 0;  // N/m
};

// eq (8): a spring of its own stiffness from grid point `point` to a fixed point in space.
struct AnchorDef {
  std::uint32_t point = 0;
  double stiffness = 0;         // N/m
  std::optional<Vec3> target;   // m; default: the point's initial position
};

// Shear springs (issue 12): both diagonals of every cell, (i, j)–(i+1, j+1) and
// (i, j+1)–(i+1, j), with the spring force of eq (6). Resists in-plane shear, which the
// paper's grid springs resist only to third order in the shear.
struct ShearDef {
  double stiffness = 0;              // N/m, every diagonal spring
  std::optional<double> rest_length{};  // m; default: the diagonal of the rest cell, √(ℓ1² + ℓ2²)
};

// Bending (issue 12): a quadratic energy on three consecutive points along every grid line,
// E = ½ k_b Σ |x_a − 2 x_b + x_c|² (Bergou et al. 2006, quadratic bending for a flat rest
// state). Zero for straight lines, unchanged by rigid motions, with a constant Hessian. A
// line of spacing h behaves as a beam of bending stiffness EI = k_b·h³ (docs/architecture.md).
struct BendingDef {
  double stiffness = 0;  // k_b, N/m
};

// Air (issue 12): per cell, against the world's wind (WorldDef::wind), with v the cell's
// mean velocity relative to the air, n its unit normal and A its area:
//   pressure  F = −½ ρ C_n A |v·n| (v·n) n   (drag of a falling sheet; across the flow it is
//             the lift of an inclined plate)
//   friction  F = −½ ρ C_t A |v_t| v_t,      v_t = v − (v·n) n
// a quarter of each on every corner of the cell.
struct AirDef {
  double drag = 1.0;      // C_n, dimensionless
  double friction = 0.0;  // C_t, dimensionless
};

// A grid of (m+1)×(n+1) points: m cells vertically (rows i = 0..m), n cells horizontally
// (columns j = 0..n). Point (i, j) has index i·(n+1)+j, as in eqs (2)–(3). The grid spans
// width Lh along local x (h1 = Lh/n) and height Lv along local y (h2 = Lv/m), centred on
// `center` and turned by `orientation`.
struct SheetDef {
  std::uint32_t m = 10;
  std::uint32_t n = 10;
  double width = 1.0;   // Lh, m
  double height = 1.0;  // Lv, m
  Vec3 center{};
  Quat orientation{};
  Vec3 initial_velocity{};  // m/s, every point

  double mass = 1.0;                 // kg, whole sheet, spread evenly over the points
  std::vector<double> point_masses;  // kg per point; when given, overrides `mass`

  double stiffness = 100.0;  // k, N/m, every spring unless a region says otherwise
  std::vector<StiffnessRegion> stiffness_regions;

  // §2.1: rest lengths of horizontal (ℓ1) and vertical (ℓ2) springs, m.
  // Default: the spacings h1, h2, so the flat sheet starts without stress.
  std::optional<double> rest_length_h;
  std::optional<double> rest_length_v;

  // Terms beyond the paper, each off unless set (a sheet without them runs the paper's
  // kernel and pays nothing for them).
  std::optional<ShearDef> shear{};
  std::optional<BendingDef> bending{};
  std::optional<AirDef> air{};

  double damping = 0.0;               // C of eq (4), N·s/m per point; 0: no damping term
  std::vector<double> point_damping;  // per point; when given, overrides `damping`

  std::vector<AnchorDef> anchors;    // soft constraints, eq (8)
  std::vector<std::uint32_t> pins;   // hard constraints: these points never move

  // Contacts of the sheet with itself (folding), with the world's contact parameters
  // (WorldDef::contact_*). Off by default: it costs a grid over the whole sheet per substep.
  bool self_collision = false;

  // μ, Coulomb friction of the sheet (static and kinetic, ≥ 0) against obstacles and other
  // sheets; the larger of the two sides' coefficients acts (docs/scene-format.md).
  double friction = 0.0;
};

constexpr std::uint32_t point_index(std::uint32_t n, std::uint32_t i, std::uint32_t j) {
  return i * (n + 1) + j;
}
constexpr std::uint32_t point_count(std::uint32_t m, std::uint32_t n) { return (m + 1) * (n + 1); }
// Horizontal springs first (row by row), then vertical ones: (m+1)·n + m·(n+1).
constexpr std::uint32_t spring_count(std::uint32_t m, std::uint32_t n) {
  return (m + 1) * n + m * (n + 1);
}

// The paper's two set-ups: the four corners (Figs 5, 7) and the centre (Figs 6, 8).
// For a grid with an odd number of cells the centre is the nearest point below and left.
std::vector<std::uint32_t> corner_points(std::uint32_t m, std::uint32_t n);
std::uint32_t center_point(std::uint32_t m, std::uint32_t n);
std::vector<AnchorDef> anchors_at(std::span<const std::uint32_t> points, double stiffness);

// An empty string when the definition can be simulated; otherwise one message naming the
// field and the problem, e.g. "stiffness must be positive and finite (got -3)". In double, as
// a World stores a sheet; validate_float adds what a WorldF's float coordinates need: cells
// of at least 16 machine epsilons times the sheet's largest coordinate, 8 to 16 units in the
// last place there (a 1 mm cell 1 km from the origin is not: float rounds to 61 µm there).
std::string validate(const SheetDef& def);
std::string validate_float(const SheetDef& def);

}  // namespace drape
