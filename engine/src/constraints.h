// Host stage of constraints and moving rigid parts (paper §5.2): each constraint of the
// world becomes eq (8) anchors on the sheets it holds, and once per substep, before the
// parallel stage, this stage writes every such anchor's target from the substep's start
// time and start positions, and puts every moving obstacle at its pose for that time.
// The force terms, the row blocks and implicit Euler's Jacobian then see ordinary anchors.
#pragma once

#include <drape/constraint.h>
#include <drape/obstacle.h>

#include <functional>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "id_pool.h"
#include "obstacles.h"
#include "sheet_data.h"

namespace drape::detail {

// Moves `o` to where def's motion has it at `time` (the world keeps the caller's `def`).
void place_obstacle(Obstacle& o, const ObstacleDef& def, double time);

// The rigid velocity def's motion gives the obstacle over [time, time + h] into near's
// linear, angular and center (NearObstacle); left at zero for an obstacle without a motion.
void set_obstacle_velocity(NearObstacle& near, const ObstacleDef& def, double time, double h);

template <class Real>
class ConstraintPool {
 public:
  // How the pool reaches the world: a live sheet (nullptr when there is none) and the
  // caller's definition of a live obstacle (nullptr likewise).
  struct Access {
    std::function<Sheet<Real>*(SheetId)> sheet;
    std::function<const ObstacleDef*(ObstacleId)> obstacle;
  };

  // Throws std::invalid_argument with validate()'s message. `time` is the world's time: a
  // path or frame keeps the points' offsets from the motion's pose at this time.
  ConstraintId add(const ConstraintDef& def, double time, const Access& world);
  void remove(ConstraintId id, const Access& world);
  // Drops every constraint on the sheet (before the sheet goes), or carried by the obstacle;
  // true when there was any.
  bool forget(SheetId sheet, const Access& world);
  bool forget(ObstacleId carrier, const Access& world);

  bool contains(ConstraintId id) const;
  const ConstraintDef& def(ConstraintId id) const;  // throws for an unknown id
  std::vector<ConstraintId> ids() const;            // in the order they were added
  std::size_t size() const { return active_.size(); }
  bool empty() const { return active_.empty(); }

  // The host stage: every constrained point's anchor target for a substep that starts at
  // `time`, from the positions at its start. Serial, constraint by constraint in the order
  // they were added, so the targets do not depend on threads or on how sheets are split.
  // With `holds`, only the constraints on the sheets it holds (the index of each SheetId):
  // a group of sheets stepping a frame alone (frames.cpp), which holds both sheets of
  // every join on one of its sheets. Each constraint writes its own anchors from its own
  // sheets' positions, so the targets are the same either way.
  void set_targets(double time, const Access& world, std::span<const std::uint32_t> holds = {});

  // A join's spring is two anchors, one at each end, each of energy ½k(|d| − ℓ)² at the
  // substep's start: the sheet's anchor energy counts it twice. This is the half to take
  // off from `sheet` (½ · ½k|target − x|² of each join anchor it holds, at its positions now).
  double join_energy_excess(SheetId id, const Sheet<Real>& sheet) const;

  // Sheets that a path or frame constraint moves, and every sheet joined to one of them
  // point-to-point (directly or through others): prescribed motion does work on them, so
  // their energy may grow without any instability.
  std::vector<SheetId> driven_sheets() const;

  // The two sheets of every point-to-point join between different sheets, in order added.
  std::vector<std::pair<SheetId, SheetId>> joined_sheets() const;
  // The sheets each constraint holds, in order added: a join's two, or its one sheet twice.
  std::vector<std::pair<SheetId, SheetId>> held_sheets() const;
  // Whether a path or frame follows a motion of the caller's (Motion::Kind::Callback),
  // which set_targets calls: the world then calls it on the stepping thread only.
  bool calls_back() const;

 private:
  struct Entry {
    ConstraintDef def;
    std::vector<Vec3> local;  // Path: offset from the pivot's position; Frame: in the motion's frame
    std::size_t base = 0, other_base = 0;  // first anchor of this constraint on sheet / other_sheet
  };
  struct OwnAnchors {  // a sheet's anchors from its SheetDef; constraint anchors follow them
    SheetId sheet;
    std::size_t count;
  };
  Entry& entry(ConstraintId id);
  bool erase_if(const std::function<bool(const ConstraintDef&)>& drop, const Access& world);
  // Every sheet's anchors: its own, then each constraint's in the order they were added.
  void rebuild(const Access& world);

  std::vector<std::optional<Entry>> slots_;
  IdPool<ConstraintTag> ids_;
  std::vector<std::uint32_t> active_;  // live slots in the order constraints were added
  std::vector<OwnAnchors> own_;
};

}  // namespace drape::detail
