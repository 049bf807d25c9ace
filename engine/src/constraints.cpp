// Constraints (paper §5.2): validation, the pool, and the host stage that writes the
// targets of the anchors each constraint puts on its sheets; moving obstacles' poses.
#include "constraints.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace drape {

std::string_view constraint_kind_name(ConstraintKind kind) {
  switch (kind) {
    case ConstraintKind::PointToPoint: return "point_to_point";
    case ConstraintKind::Path: return "path";
    case ConstraintKind::Frame: return "frame";
    case ConstraintKind::Rail: return "rail";
  }
  return "unknown";
}

std::vector<std::uint32_t> row_points(std::uint32_t, std::uint32_t n, std::uint32_t i) {
  std::vector<std::uint32_t> points;
  for (std::uint32_t j = 0; j <= n; ++j) points.push_back(i * (n + 1) + j);
  return points;
}

std::vector<std::uint32_t> column_points(std::uint32_t m, std::uint32_t n, std::uint32_t j) {
  std::vector<std::uint32_t> points;
  for (std::uint32_t i = 0; i <= m; ++i) points.push_back(i * (n + 1) + j);
  return points;
}

namespace {

bool finite(Vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// The points of one end: each must be a point of its sheet.
std::string check_points(const char* field, const std::vector<std::uint32_t>& points, std::uint64_t count) {
  if (points.empty()) return std::string(field) + " must name at least one point";
  for (std::size_t k = 0; k < points.size(); ++k)
    if (points[k] >= count) {
      std::ostringstream out;
      out << field << '[' << k << "] is not a point of the sheet (got " << points[k] << "; it has " << count
          << " points)";
      return out.str();
    }
  return {};
}

}  // namespace

std::string validate(const ConstraintDef& d, const ConstraintContext& world) {
  std::ostringstream out;
  if (!(d.stiffness > 0) || !std::isfinite(d.stiffness)) {
    out << "stiffness must be positive and finite (got " << d.stiffness << ")";
    return out.str();
  }
  const std::uint64_t count = world.sheet_points(d.sheet);
  if (count == 0) return "sheet " + std::to_string(d.sheet.index) + " is not a sheet of the world";
  if (std::string p = check_points("points", d.points, count); !p.empty()) return p;
  switch (d.kind) {
    case ConstraintKind::PointToPoint: {
      const std::uint64_t other = world.sheet_points(d.other_sheet);
      if (other == 0) return "other_sheet " + std::to_string(d.other_sheet.index) + " is not a sheet of the world";
      if (d.other_points.size() != d.points.size()) {
        out << "other_points must pair with points one to one (got " << d.other_points.size() << " for "
            << d.points.size() << ")";
        return out.str();
      }
      if (std::string p = check_points("other_points", d.other_points, other); !p.empty()) return p;
      if (d.sheet == d.other_sheet)
        for (std::size_t k = 0; k < d.points.size(); ++k)
          if (d.points[k] == d.other_points[k]) {
            out << "other_points[" << k << "] is points[" << k << "] (" << d.points[k]
                << ") of the same sheet: a point cannot be joined to itself";
            return out.str();
          }
      if (!(d.rest_length >= 0) || !std::isfinite(d.rest_length)) {
        out << "rest_length must be non-negative and finite (got " << d.rest_length << ")";
        return out.str();
      }
      return {};
    }
    case ConstraintKind::Path:
      if (std::string p = validate(d.motion); !p.empty()) return "motion." + p;
      return {};
    case ConstraintKind::Frame:
      if (d.carrier) {
        if (!world.has_obstacle(*d.carrier))
          return "carrier " + std::to_string(d.carrier->index) + " is not an obstacle of the world";
        return {};
      }
      if (std::string p = validate(d.motion); !p.empty()) return "motion." + p;
      return {};
    case ConstraintKind::Rail:
      if (d.rail.size() < 2) {
        out << "rail must have at least two knots (got " << d.rail.size() << ")";
        return out.str();
      }
      for (std::size_t k = 0; k < d.rail.size(); ++k)
        if (!finite(d.rail[k])) return "rail[" + std::to_string(k) + "] must be finite";
      return {};
  }
  return "kind is not a kind of constraint";
}

ObstacleDef obstacle_at(const ObstacleDef& def, double time) {
  ObstacleDef placed = def;
  if (!def.motion) return placed;
  placed.motion.reset();
  const Pose pose = pose_at(*def.motion, time);
  placed.center = apply(pose, def.center);
  placed.orientation = multiply(pose.rotation, def.orientation);
  return placed;
}

namespace detail {

namespace {

Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 plus(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

template <class Real>
Vec3 position(const Sheet<Real>& s, std::uint32_t p) {
  return {double(s.position.x[p]), double(s.position.y[p]), double(s.position.z[p])};
}

template <class Real>
void set_target(Anchors<Real>& an, std::size_t a, Vec3 t) {
  an.tx[a] = static_cast<Real>(t.x);
  an.ty[a] = static_cast<Real>(t.y);
  an.tz[a] = static_cast<Real>(t.z);
}

// The point of the polyline nearest to x; of equally near ones, the first along the rail.
Vec3 nearest_on_rail(const std::vector<Vec3>& rail, Vec3 x) {
  Vec3 best = rail.front();
  double best_d2 = dot(sub(x, best), sub(x, best));
  for (std::size_t k = 0; k + 1 < rail.size(); ++k) {
    const Vec3 a = rail[k], ab = sub(rail[k + 1], a);
    const double len2 = dot(ab, ab);
    const double s = len2 > 0 ? std::clamp(dot(sub(x, a), ab) / len2, 0.0, 1.0) : 0.0;
    const Vec3 q{a.x + s * ab.x, a.y + s * ab.y, a.z + s * ab.z};
    const double d2 = dot(sub(x, q), sub(x, q));
    if (d2 < best_d2) {
      best = q;
      best_d2 = d2;
    }
  }
  return best;
}

// The pose a path or frame constraint follows at `time`: its own motion, or its carrier's
// (an obstacle without a motion stands still).
template <class Access>
Pose frame_pose(const ConstraintDef& d, double time, const Access& world) {
  if (d.carrier) {
    const ObstacleDef* o = world.obstacle(*d.carrier);
    return o && o->motion ? pose_at(*o->motion, time) : Pose{};
  }
  return pose_at(d.motion, time);
}

}  // namespace

void place_obstacle(Obstacle& o, const ObstacleDef& def, double time) { o = make_obstacle(obstacle_at(def, time)); }

void set_obstacle_velocity(NearObstacle& near, const ObstacleDef& def, double time, double h) {
  if (!def.motion || !(h > 0)) return;
  const ObstacleDef a = obstacle_at(def, time), b = obstacle_at(def, time + h);
  near.center[0] = a.center.x;
  near.center[1] = a.center.y;
  near.center[2] = a.center.z;
  near.linear[0] = (b.center.x - a.center.x) / h;
  near.linear[1] = (b.center.y - a.center.y) / h;
  near.linear[2] = (b.center.z - a.center.z) / h;
  // the turn over the substep, q(t + h)·q(t)⁻¹, as axis·angle (the shorter way round)
  const Quat qa = a.orientation, qb = b.orientation;
  const Quat d = multiply(qb, Quat{qa.w, -qa.x, -qa.y, -qa.z});
  const double sign = d.w < 0 ? -1.0 : 1.0;
  const double s = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  if (!(s > 0)) return;
  const double per_unit = 2 * std::atan2(s, sign * d.w) / s / h;
  near.angular[0] = sign * d.x * per_unit;
  near.angular[1] = sign * d.y * per_unit;
  near.angular[2] = sign * d.z * per_unit;
}

template <class Real>
ConstraintId ConstraintPool<Real>::add(const ConstraintDef& def, double time, const Access& world) {
  const ConstraintContext context{[&](SheetId id) -> std::uint64_t {
                                    const Sheet<Real>* s = world.sheet(id);
                                    return s ? s->size() : 0;
                                  },
                                  [&](ObstacleId id) { return world.obstacle(id) != nullptr; }};
  if (std::string problem = validate(def, context); !problem.empty())
    throw std::invalid_argument("drape: constraint " + problem);
  Entry e{def, {}, 0, 0};
  const Sheet<Real>& s = *world.sheet(def.sheet);
  if (def.kind == ConstraintKind::Path || def.kind == ConstraintKind::Frame) {
    const Pose start = frame_pose(def, time, world);
    const Pose back = inverse(start);
    const Vec3 pivot = apply(start, def.motion.pivot);
    for (std::uint32_t p : def.points)
      e.local.push_back(def.kind == ConstraintKind::Path ? sub(position(s, p), pivot) : apply(back, position(s, p)));
  }
  const std::uint32_t index = ids_.acquire();
  if (index == slots_.size()) slots_.emplace_back();
  slots_[index] = std::move(e);
  active_.push_back(index);
  rebuild(world);
  set_targets(time, world);
  return ids_.id(index);
}

template <class Real>
bool ConstraintPool<Real>::contains(ConstraintId id) const {
  return ids_.contains(id);
}

template <class Real>
typename ConstraintPool<Real>::Entry& ConstraintPool<Real>::entry(ConstraintId id) {
  if (!contains(id)) throw std::invalid_argument("drape: unknown or removed ConstraintId " + std::to_string(id.index));
  return *slots_[id.index];
}

template <class Real>
const ConstraintDef& ConstraintPool<Real>::def(ConstraintId id) const {
  return const_cast<ConstraintPool*>(this)->entry(id).def;
}

template <class Real>
std::vector<ConstraintId> ConstraintPool<Real>::ids() const {
  return ids_.ids(active_);
}

template <class Real>
void ConstraintPool<Real>::remove(ConstraintId id, const Access& world) {
  entry(id);  // throws on a stale id
  slots_[id.index].reset();
  ids_.release(id.index);
  std::erase(active_, id.index);
  rebuild(world);
}

template <class Real>
bool ConstraintPool<Real>::erase_if(const std::function<bool(const ConstraintDef&)>& drop, const Access& world) {
  bool any = false;
  for (std::uint32_t index : std::vector<std::uint32_t>(active_))
    if (drop(slots_[index]->def)) {
      slots_[index].reset();
      ids_.release(index);
      std::erase(active_, index);
      any = true;
    }
  if (any) rebuild(world);
  return any;
}

template <class Real>
bool ConstraintPool<Real>::forget(SheetId sheet, const Access& world) {
  const bool any = erase_if([&](const ConstraintDef& d) {
    return d.sheet == sheet || (d.kind == ConstraintKind::PointToPoint && d.other_sheet == sheet);
  }, world);
  std::erase_if(own_, [&](const OwnAnchors& o) { return o.sheet == sheet; });
  return any;
}

template <class Real>
bool ConstraintPool<Real>::forget(ObstacleId carrier, const Access& world) {
  return erase_if([&](const ConstraintDef& d) { return d.kind == ConstraintKind::Frame && d.carrier == carrier; },
                  world);
}

template <class Real>
void ConstraintPool<Real>::rebuild(const Access& world) {
  // back to each sheet's own anchors (a sheet no longer alive is forgotten)
  std::erase_if(own_, [&](const OwnAnchors& o) { return world.sheet(o.sheet) == nullptr; });
  for (const OwnAnchors& o : own_) {
    Anchors<Real>& an = world.sheet(o.sheet)->anchors;
    for (auto* v : {&an.tx, &an.ty, &an.tz, &an.stiffness}) v->resize(o.count);
    an.point.resize(o.count);
  }
  auto append = [&](SheetId id, const std::vector<std::uint32_t>& points, double k) {
    Sheet<Real>& s = *world.sheet(id);
    if (std::none_of(own_.begin(), own_.end(), [&](const OwnAnchors& o) { return o.sheet == id; }))
      own_.push_back({id, s.anchors.point.size()});
    const std::size_t base = s.anchors.point.size();
    for (std::uint32_t p : points) {
      s.anchors.point.push_back(p);
      s.anchors.tx.push_back(s.position.x[p]);  // until set_targets: no force
      s.anchors.ty.push_back(s.position.y[p]);
      s.anchors.tz.push_back(s.position.z[p]);
      s.anchors.stiffness.push_back(static_cast<Real>(k));
    }
    return base;
  };
  for (std::uint32_t index : active_) {
    Entry& e = *slots_[index];
    e.base = append(e.def.sheet, e.def.points, e.def.stiffness);
    if (e.def.kind == ConstraintKind::PointToPoint)
      e.other_base = append(e.def.other_sheet, e.def.other_points, e.def.stiffness);
  }
}

template <class Real>
void ConstraintPool<Real>::set_targets(double time, const Access& world, std::span<const std::uint32_t> holds) {
  for (std::uint32_t index : active_) {
    const Entry& e = *slots_[index];
    const ConstraintDef& d = e.def;
    if (!holds.empty() && std::find(holds.begin(), holds.end(), d.sheet.index) == holds.end()) continue;
    Sheet<Real>& s = *world.sheet(d.sheet);
    switch (d.kind) {
      case ConstraintKind::PointToPoint: {
        // eq (6) as two anchors: each end pulled towards the point at rest length from the
        // other end, so k(target − x) is the spring force, equal and opposite at the
        // substep's start positions. A zero-length spring with ℓ > 0 has no direction and
        // exerts nothing, as in the spring kernel.
        Sheet<Real>& o = *world.sheet(d.other_sheet);
        for (std::size_t k = 0; k < d.points.size(); ++k) {
          const Vec3 xa = position(s, d.points[k]), xb = position(o, d.other_points[k]);
          const Vec3 ab = sub(xa, xb);
          const double len = std::sqrt(dot(ab, ab));
          Vec3 ta = xb, tb = xa;
          if (d.rest_length > 0) {
            const double r = len > 0 ? d.rest_length / len : 0.0;
            const Vec3 u{ab.x * r, ab.y * r, ab.z * r};
            ta = len > 0 ? plus(xb, u) : xa;
            tb = len > 0 ? sub(xa, u) : xb;
          }
          set_target(s.anchors, e.base + k, ta);
          set_target(o.anchors, e.other_base + k, tb);
        }
        break;
      }
      case ConstraintKind::Path: {
        const Vec3 pivot = apply(frame_pose(d, time, world), d.motion.pivot);
        for (std::size_t k = 0; k < d.points.size(); ++k) set_target(s.anchors, e.base + k, plus(pivot, e.local[k]));
        break;
      }
      case ConstraintKind::Frame: {
        const Pose pose = frame_pose(d, time, world);
        for (std::size_t k = 0; k < d.points.size(); ++k) set_target(s.anchors, e.base + k, apply(pose, e.local[k]));
        break;
      }
      case ConstraintKind::Rail:
        for (std::size_t k = 0; k < d.points.size(); ++k)
          set_target(s.anchors, e.base + k, nearest_on_rail(d.rail, position(s, d.points[k])));
        break;
    }
  }
}

template <class Real>
double ConstraintPool<Real>::join_energy_excess(SheetId id, const Sheet<Real>& s) const {
  const Anchors<Real>& an = s.anchors;
  auto half = [&](std::size_t base, std::size_t count) {
    double e = 0;
    for (std::size_t a = base; a < base + count; ++a) {
      const std::uint32_t p = an.point[a];
      const double dx = double(an.tx[a]) - s.position.x[p], dy = double(an.ty[a]) - s.position.y[p],
                   dz = double(an.tz[a]) - s.position.z[p];
      e += 0.25 * double(an.stiffness[a]) * (dx * dx + dy * dy + dz * dz);
    }
    return e;
  };
  double excess = 0;
  for (std::uint32_t index : active_) {
    const Entry& e = *slots_[index];
    if (e.def.kind != ConstraintKind::PointToPoint) continue;
    if (e.def.sheet == id) excess += half(e.base, e.def.points.size());
    if (e.def.other_sheet == id) excess += half(e.other_base, e.def.other_points.size());
  }
  return excess;
}

template <class Real>
std::vector<SheetId> ConstraintPool<Real>::driven_sheets() const {
  std::vector<SheetId> driven;
  auto has = [&](SheetId id) { return std::find(driven.begin(), driven.end(), id) != driven.end(); };
  for (std::uint32_t index : active_) {
    const ConstraintDef& d = slots_[index]->def;
    if ((d.kind == ConstraintKind::Path || d.kind == ConstraintKind::Frame) && !has(d.sheet)) driven.push_back(d.sheet);
  }
  // joins pass it on, until nothing changes (a handful of sheets: quadratic is fine)
  for (bool grew = true; grew;) {
    grew = false;
    for (std::uint32_t index : active_) {
      const ConstraintDef& d = slots_[index]->def;
      if (d.kind != ConstraintKind::PointToPoint || has(d.sheet) == has(d.other_sheet)) continue;
      driven.push_back(has(d.sheet) ? d.other_sheet : d.sheet);
      grew = true;
    }
  }
  return driven;
}

template <class Real>
std::vector<std::pair<SheetId, SheetId>> ConstraintPool<Real>::joined_sheets() const {
  std::vector<std::pair<SheetId, SheetId>> joined;
  for (std::uint32_t index : active_) {
    const ConstraintDef& d = slots_[index]->def;
    if (d.kind == ConstraintKind::PointToPoint && d.other_sheet != d.sheet) joined.emplace_back(d.sheet, d.other_sheet);
  }
  return joined;
}

template <class Real>
std::vector<std::pair<SheetId, SheetId>> ConstraintPool<Real>::held_sheets() const {
  std::vector<std::pair<SheetId, SheetId>> held;
  for (std::uint32_t index : active_) {
    const ConstraintDef& d = slots_[index]->def;
    held.emplace_back(d.sheet, d.kind == ConstraintKind::PointToPoint ? d.other_sheet : d.sheet);
  }
  return held;
}

template <class Real>
bool ConstraintPool<Real>::calls_back() const {
  return std::any_of(active_.begin(), active_.end(),
                     [&](std::uint32_t index) { return slots_[index]->def.motion.kind == Motion::Kind::Callback; });
}

template class ConstraintPool<double>;
template class ConstraintPool<float>;

}  // namespace detail

}  // namespace drape
