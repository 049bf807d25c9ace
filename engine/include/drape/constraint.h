// ConstraintDef: the paper's §5.2 constraints "taken into account by using external
// forces": points joined to points (of the same sheet or of another), points held to a path
// that moves in time or free to slide along a fixed curve, points carried by a frame that
// moves (an orientation constraint, or a moving rigid part). Each constrained point feels an
// eq (8) spring of the constraint's stiffness towards a target that the world's host stage
// computes at the start of every substep. A ConstraintDef is a plain value; the world copies
// it when the constraint is added and hands back a ConstraintId.
#pragma once

#include <drape/motion.h>
#include <drape/types.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace drape {

struct ConstraintTag;
using ConstraintId = Id<ConstraintTag>;

enum class ConstraintKind {
  // points[k] of `sheet` and other_points[k] of `other_sheet` joined by a spring of
  // `stiffness` and `rest_length` (0: a weld), eq (6) with forces equal and opposite.
  PointToPoint,
  // points[k] follow the path of the motion's pivot, keeping their offsets from it at the
  // time the constraint was added (translation only: the points are not turned).
  Path,
  // points[k] carried rigidly by the motion (an orientation constraint): target =
  // pose(t) · pose(t_added)⁻¹ · (the point's position when the constraint was added).
  // With `carrier`, the motion is that obstacle's: the points ride on a moving rigid part.
  Frame,
  // points[k] free to slide, without friction, along the fixed polyline `rail`: the target
  // is the point of the rail nearest to the point.
  Rail,
};

std::string_view constraint_kind_name(ConstraintKind kind);

// The edges seams and rails hold, in a grid of (m+1)×(n+1) points: every point of row i
// (columns 0 … n in order), every point of column j (rows 0 … m in order).
std::vector<std::uint32_t> row_points(std::uint32_t m, std::uint32_t n, std::uint32_t i);
std::vector<std::uint32_t> column_points(std::uint32_t m, std::uint32_t n, std::uint32_t j);  // "point_to_point", "path", "frame", "rail"

struct ConstraintDef {
  ConstraintKind kind = ConstraintKind::PointToPoint;
  double stiffness = 1000.0;  // N/m, per constrained point (eq 8's k)
  SheetId sheet;
  std::vector<std::uint32_t> points;  // grid indices i·(n+1)+j of `sheet`
  // PointToPoint
  SheetId other_sheet;
  std::vector<std::uint32_t> other_points;  // as many as `points`
  double rest_length = 0.0;                 // m
  // Path, Frame
  Motion motion;
  std::optional<ObstacleId> carrier;  // Frame: use this obstacle's motion (none: it stands still)
  // Rail: at least two knots, m
  std::vector<Vec3> rail;
};

// What validate() needs to know of the world: a sheet's point count (0 for no such sheet),
// and whether an obstacle exists.
struct ConstraintContext {
  std::function<std::uint64_t(SheetId)> sheet_points;
  std::function<bool(ObstacleId)> has_obstacle;
};

// An empty string when the constraint can be added; otherwise one message naming the field
// and the problem, e.g. "points[2] is not a point of the sheet (got 130; it has 121)".
std::string validate(const ConstraintDef& def, const ConstraintContext& context);

}  // namespace drape
