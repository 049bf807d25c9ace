"""The module's bindings of the cloth terms (shear, bending, air and wind, friction), moving
obstacles and constraints: a world built field by field from Python steps bit for bit as the
C++ scene loader's world of the same file, every bound field changes the result, and the
physics of a rail and of bending against hand-computed answers."""
import copy
import json
import math
import threading

import numpy as np
import pytest

import drape

# What the scenes below use, per part; a key outside these fails the test instead of being
# silently left out of the Python-built world.
TOP_KEYS = {"description", "dt", "fps", "duration", "wind", "contact_strength", "sheets", "obstacles", "constraints",
            "output", "camera"}
SHEET_KEYS = {"name", "grid", "size", "center", "orientation", "velocity", "mass", "stiffness", "damping", "shear",
              "bending", "air", "friction", "pins"}
OBSTACLE_KEYS = {"type", "center", "semi_axes", "radius", "half_extents", "c", "xi", "friction", "motion"}
CONSTRAINT_KEYS = {"type", "sheet", "points", "stiffness", "other_sheet", "other_points", "rail", "motion", "obstacle"}


def known(part, keys, where):
    unknown = set(part) - keys
    assert not unknown, f"{where}: the test does not build {sorted(unknown)}"


def rotation(value):
    if isinstance(value, dict):
        return drape.quat_from_axis_angle(value["axis"], value["degrees"] * math.pi / 180)
    return tuple(value)


def motion(doc):
    return drape.Motion(pivot=doc.get("pivot", (0, 0, 0)), repeat=doc.get("repeat", False), keyframes=[
        drape.Keyframe(time=k["time"], translation=k.get("translation", (0, 0, 0)),
                       rotation=rotation(k.get("rotation", [1, 0, 0, 0]))) for k in doc["keyframes"]])


def world_from_json(doc, threads, world_class=drape.World):
    """The scene's world built through the module's definitions alone (not its loader)."""
    known(doc, TOP_KEYS, "scene")
    world = world_class(dt=doc["dt"], threads=threads, contact_strength=doc.get("contact_strength", 1e-3),
                        wind=drape.Wind(**doc.get("wind", {})))
    sheets, shapes = {}, {}
    for s in doc["sheets"]:
        known(s, SHEET_KEYS, s["name"])
        m, n = s["grid"]
        d = drape.SheetDef(m=m, n=n, width=s["size"][0], height=s["size"][1], center=s["center"],
                           mass=s["mass"], stiffness=s["stiffness"], damping=s["damping"],
                           friction=s.get("friction", 0.0),
                           pins=[drape.point_index(n, i, j) for i, j in s.get("pins", [])])
        if "orientation" in s:
            d.orientation = rotation(s["orientation"])
        if "velocity" in s:
            d.initial_velocity = s["velocity"]
        if "shear" in s:
            d.shear = drape.ShearDef(**s["shear"])
        if "bending" in s:
            d.bending = drape.BendingDef(**s["bending"])
        if "air" in s:
            d.air = drape.AirDef(**s["air"])
        sheets[s["name"]] = world.add_sheet(d)
        shapes[s["name"]] = (m, n)
    obstacles = []
    for o in doc.get("obstacles", []):
        known(o, OBSTACLE_KEYS, o["type"])
        d = drape.ObstacleDef(shape=getattr(drape.ObstacleShape, o["type"].capitalize()), center=o["center"],
                              c=o["c"], xi=o["xi"], friction=o.get("friction", 0.0))
        if "semi_axes" in o:
            d.size = o["semi_axes"]
        if "half_extents" in o:
            d.size = o["half_extents"]
        if "radius" in o:
            d.size = (o["radius"], 0, 0)
        if "motion" in o:
            d.motion = motion(o["motion"])
        obstacles.append(world.add_obstacle(d))

    def points(value, name):
        m, n = shapes[name]
        if isinstance(value, dict):
            return drape.row_points(m, n, value["row"])
        return [drape.point_index(n, i, j) for i, j in value]

    for c in doc.get("constraints", []):
        known(c, CONSTRAINT_KEYS, c["type"])
        d = drape.ConstraintDef(kind=c["type"], sheet=sheets[c["sheet"]], points=points(c["points"], c["sheet"]),
                                stiffness=c["stiffness"])
        if "other_sheet" in c:
            d.other_sheet = sheets[c["other_sheet"]]
            d.other_points = points(c["other_points"], c["other_sheet"])
        if "rail" in c:
            d.rail = c["rail"]
        if "motion" in c:
            d.motion = motion(c["motion"])
        if "obstacle" in c:
            d.carrier = obstacles[c["obstacle"]]
        world.add_constraint(d)
    return world


def bits(world):
    """Every sheet's positions and velocities, as raw bytes (so -0.0 and +0.0 differ)."""
    out = []
    for sheet in world.sheets():
        v = world.view(sheet)
        out += [a.tobytes() for a in (v.x, v.y, v.z, v.vx, v.vy, v.vz)]
    return out


# (scene, substeps): long enough that each scene's terms act (the tablecloth reaches the table
# after about 290 substeps; the curtain's corner is pulled along from the first).
SCENES = [("flag_wind.json", 300, None), ("tablecloth.json", 500, None), ("curtain_rail.json", 300, None),
          ("curtain_rail.json", 300, "float32"), ("sewn_box.json", 300, None), ("cape_sphere.json", 300, None)]


@pytest.mark.parametrize("scene_name,substeps,precision", SCENES)
def test_a_world_built_from_python_steps_as_the_scene_loader_s_bit_for_bit(source_dir, scene_name, substeps, precision):
    path = source_dir / "scenes" / scene_name
    doc = json.loads(path.read_text())
    scene = drape.load_scene(path, overrides={"precision": precision} if precision else {})
    world_class = drape.WorldF if precision == "float32" else drape.World
    loaded = scene.make_world(threads=1)
    assert isinstance(loaded, world_class)
    built = world_from_json(doc, 1, world_class)
    split = world_from_json(doc, 2, world_class)  # two threads, the same bits
    assert built.constraint_count == len(scene.constraints) == len(doc.get("constraints", []))
    start = bits(built)
    assert bits(loaded) == start
    for world in (loaded, built, split):
        assert world.step(substeps).ok
    assert bits(built) == bits(loaded)
    assert bits(split) == bits(loaded)
    assert bits(built) != start


# Each new field, taken away, changes the run: the comparison above would catch a field the
# module dropped.
@pytest.mark.parametrize("scene_name,substeps,remove", [
    ("flag_wind.json", 300, ("wind",)),
    ("flag_wind.json", 300, ("sheets", 0, "shear")),
    ("flag_wind.json", 300, ("sheets", 0, "bending")),
    ("flag_wind.json", 300, ("sheets", 0, "air")),
    ("tablecloth.json", 500, ("obstacles", 0, "friction")),
    ("curtain_rail.json", 300, ("constraints", 0)),
    ("curtain_rail.json", 300, ("constraints", 1)),
    ("sewn_box.json", 300, ("constraints", 0)),
    ("cape_sphere.json", 300, ("obstacles", 0, "motion")),
])
def test_every_bound_field_changes_the_run(source_dir, scene_name, substeps, remove):
    doc = json.loads((source_dir / "scenes" / scene_name).read_text())
    less = copy.deepcopy(doc)
    part = less
    for key in remove[:-1]:
        part = part[key]
    del part[remove[-1]]
    full, reduced = world_from_json(doc, 1), world_from_json(less, 1)
    full.step(substeps)
    reduced.step(substeps)
    assert bits(full) != bits(reduced)


def test_a_rail_holds_its_points_and_the_sheet_slides_down_it_at_g_sin_theta():
    # A sheet hangs from its top row, which slides without friction on a straight rail
    # inclined at theta (the sheet turned so that the row starts on it). The rail's forces are
    # normal to it, the springs' sum to zero and nothing damps: along the rail only gravity
    # acts, so the momentum along it is M·g·sin(theta)·t whatever the sheet does, and the
    # centre of mass moves as semi-implicit Euler moves a point under g·sin(theta).
    g, theta, dt, k, mass = 9.81, math.radians(20), 2e-4, 1500, 0.2
    m, n = 6, 8
    u = np.array([math.cos(theta), 0.0, -math.sin(theta)])  # down the rail
    world = drape.World(dt=dt, gravity=(0, 0, -g), threads=1)
    upright = drape.quat_from_axis_angle((1, 0, 0), math.pi / 2)
    sheet = world.add_sheet(m=m, n=n, width=0.4, height=0.3, mass=mass, stiffness=200, center=(0, 0, 0.85),
                            orientation=drape.multiply(drape.quat_from_axis_angle((0, 1, 0), theta), upright))
    top = drape.row_points(m, n, m)
    v = world.view(sheet)

    def positions(points=None):
        x = np.stack([v.x.ravel(), v.y.ravel(), v.z.ravel()], axis=1)
        return x if points is None else x[points]

    p0 = positions(top).mean(axis=0)
    rail = [tuple(p0 - 3 * u), tuple(p0 + 3 * u)]
    com0 = positions().mean(axis=0)
    world.add_constraint(kind=drape.ConstraintKind.Rail, sheet=sheet, points=top, stiffness=5000, rail=rail)
    assert world.step(k).ok
    p_along = mass / drape.point_count(m, n) * (u[0] * v.vx.sum() + u[2] * v.vz.sum())
    assert p_along == pytest.approx(mass * g * math.sin(theta) * k * dt, rel=1e-9)
    travelled = (positions().mean(axis=0) - com0) @ u
    assert travelled == pytest.approx(g * math.sin(theta) * dt * dt * k * (k + 1) / 2, rel=1e-9)
    assert travelled > 0.1  # slid along the rail (15 cm)
    # the rail's points within 2 mm of its line (free, they would have fallen 0.44 m)
    d = positions(top) - np.array(rail[0])
    off = d - np.outer(d @ u, u)
    assert np.linalg.norm(off, axis=1).max() < 2e-3


def test_bending_energy_of_a_parabola_is_the_hand_computed_sum():
    # z = c·j² along every row: each triple of consecutive points along a row has the second
    # difference (0, 0, 2c); along columns it is zero. E = ½·k_b·(m+1)(n−1)·(2c)².
    m, n, k_b, c = 4, 6, 0.3, 0.01
    world = drape.World(threads=1, gravity=(0, 0, 0))
    sheet = world.add_sheet(m=m, n=n, bending=drape.BendingDef(stiffness=k_b))
    s = world.state(sheet)
    s.z[...] = c * np.arange(n + 1, dtype=float) ** 2
    e = world.energies()
    assert e.bending == pytest.approx(0.5 * k_b * (m + 1) * (n - 1) * (2 * c) ** 2, rel=1e-12)
    assert e.total == pytest.approx(e.kinetic + e.spring + e.bending + e.gravity + e.anchor + e.obstacle, rel=1e-15)


def test_constraint_kinds_are_the_engine_s_names():
    assert list(drape.ConstraintKind.__members__) == ["PointToPoint", "Path", "Frame", "Rail"]
    for kind in drape.ConstraintKind.__members__.values():
        assert drape.ConstraintKind(kind.label) == kind
    assert drape.ConstraintDef(kind="point_to_point").kind == drape.ConstraintKind.PointToPoint
    with pytest.raises(ValueError, match="unknown constraint kind"):
        drape.ConstraintKind("glue")


def test_integrators_come_from_the_engine_s_table():
    names = drape.Integrator.__members__
    assert "LocalGlobal" in names and "RK4" in names
    for name, integrator in names.items():
        assert drape.Integrator(integrator.label) == integrator, name
        assert integrator.order >= 1 and integrator.stability
    assert drape.Integrator("local_global") == drape.Integrator.LocalGlobal
    assert not drape.Integrator.LocalGlobal.is_explicit
    assert "local_global_iterations" in drape.Integrator.LocalGlobal.knobs


def test_local_global_drops_a_free_sheet_as_backward_euler_does():
    # A free sheet with springs at rest under gravity: backward Euler gives v_k = −g·k·dt and
    # z_k = z0 − g·dt²·k(k+1)/2, the springs staying at rest (a rigid translation).
    g, dt, k = 9.81, 1e-3, 50
    world = drape.World(dt=dt, integrator="local_global", local_global_iterations=4, threads=1)
    sheet = world.add_sheet(m=3, n=3, center=(0, 0, 1.0))
    assert world.definition.local_global_iterations == 4
    assert world.step(k).ok
    v = world.view(sheet)
    assert np.allclose(v.vz, -g * k * dt, rtol=0, atol=1e-9)
    assert np.allclose(v.z, 1.0 - g * dt * dt * k * (k + 1) / 2, rtol=0, atol=1e-9)
    stats = world.solver_stats(sheet)
    assert stats.converged and stats.unconverged_solves == 0 and stats.iterations >= 1


def test_vertex_block_descent_iterations_are_a_knob():
    # The budget set in Python is the one the step spends: solver_stats counts it per step.
    assert "vertex_block_iterations" in drape.Integrator.VertexBlockDescent.knobs
    for budget in (1, 3):
        world = drape.World(dt=1 / 60, integrator="vertex_block_descent", vertex_block_iterations=budget, threads=1)
        assert world.definition.vertex_block_iterations == budget
        sheet = world.add_sheet(m=5, n=5, stiffness=1e3, pins=drape.corner_points(5, 5))
        assert world.step(2).ok
        assert world.solver_stats(sheet).iterations == budget


def test_implicit_euler_preconditioner_is_a_knob_and_cholesky_converges_on_a_stiff_sheet():
    assert drape.Preconditioner("cholesky") == drape.Preconditioner.Cholesky
    with pytest.raises(ValueError, match="unknown preconditioner"):
        drape.Preconditioner("ilu")
    runs = {}
    for name in ("block_jacobi", "cholesky"):
        world = drape.World(dt=1 / 60, integrator="implicit_euler", cg_preconditioner=name, cg_max_iterations=50,
                            threads=1)
        assert world.definition.cg_preconditioner == drape.Preconditioner(name)
        sheet = world.add_sheet(m=15, n=15, stiffness=1e5, pins=drape.corner_points(15, 15))
        assert world.step(10).ok
        runs[name] = world.solver_stats(sheet)
    # k = 1e5 N/m at a frame step: block Jacobi stops at a cap of 50, the factor converges at once
    assert runs["block_jacobi"].unconverged_solves > 0
    assert runs["cholesky"].unconverged_solves == 0 and runs["cholesky"].iterations == 1


def circle(period=0.5):
    return drape.Motion(kind=drape.Motion.Kind.Circle,
                        circle=drape.CirclePath(center=(0, 0, 0.5), axis=(0, 0, 1), start=(0.3, 0, 0.5), period=period))


def test_poses_of_a_circle_and_of_a_moving_obstacle_by_hand():
    # a quarter period turns the start point (0.3, 0, 0.5) about the z axis to (0, 0.3, 0.5)
    pose = drape.pose_at(circle(), 0.125)
    assert np.allclose(drape.apply(pose, (0.3, 0, 0.5)), (0, 0.3, 0.5), atol=1e-15)
    assert drape.validate(circle()) == ""
    moved = drape.obstacle_at(drape.ObstacleDef(center=(0.3, 0, 0.5), motion=circle()), 0.25)
    assert moved.motion is None and np.allclose(moved.center, (-0.3, 0, 0.5), atol=1e-15)
    p = drape.Pose(rotation=drape.quat_from_axis_angle((0, 0, 1), 0.7), translation=(1, 2, 3))
    assert np.allclose(drape.apply(drape.compose(drape.inverse(p), p), (4, 5, 6)), (4, 5, 6), atol=1e-14)


def path_world(motion, threads=1, obstacle_motion=None):
    world = drape.World(dt=5e-4, threads=threads)
    sheet = world.add_sheet(m=5, n=5, width=0.3, height=0.3, center=(0.3, 0, 0.5), stiffness=150, damping=0.01)
    world.add_constraint(kind=drape.ConstraintKind.Path, sheet=sheet, points=[drape.center_point(5, 5)],
                         stiffness=2000, motion=motion)
    world.add_obstacle(shape=drape.ObstacleShape.Sphere, size=(0.05, 0, 0), center=(0.3, 0, 0.3), c=0.01, xi=0.005,
                       motion=obstacle_motion)
    return world


def test_a_python_callback_motion_drives_a_path_as_the_motion_it_returns():
    # The callback is called by step() (GIL released) from the engine's host stage; it must
    # give the same bits as the engine evaluating the motion itself, on one or two threads.
    calls = []

    def poses(t):
        calls.append(t)
        return drape.pose_at(circle(), t)

    by_callback = drape.Motion(kind=drape.Motion.Kind.Callback, callback=poses)
    reference = path_world(circle(), obstacle_motion=circle())
    reference.step(200)
    for threads in (1, 2):
        world = path_world(by_callback, threads, obstacle_motion=by_callback)
        assert world.step(200).ok
        assert bits(world) == bits(reference)
    assert len(calls) > 400 and max(calls) == pytest.approx(199 * 5e-4)
    back = world.constraint(world.constraints()[0]).motion
    assert back.kind == drape.Motion.Kind.Callback
    assert back.callback(0.1).translation == drape.pose_at(circle(), 0.1).translation


def test_a_callback_motion_steps_from_python_threads_and_its_errors_arrive():
    # Worlds with callbacks stepped by several Python threads at once: no deadlock (step
    # releases the GIL, the callback takes it), the one-thread result.
    motion = drape.Motion(kind=drape.Motion.Kind.Callback, callback=lambda t: drape.pose_at(circle(), t))
    worlds = [path_world(motion) for _ in range(3)]
    threads = [threading.Thread(target=w.step, args=(150,)) for w in worlds]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    serial = path_world(circle())
    serial.step(150)
    for w in worlds:
        assert bits(w) == bits(serial)

    def broken(t):
        if t > 0.0102:
            raise RuntimeError("motion failed")
        return drape.Pose()

    world = path_world(drape.Motion(kind=drape.Motion.Kind.Callback, callback=broken))
    with pytest.raises(RuntimeError, match="motion failed"):
        world.step(100)
    assert world.step_count == 21 and world.all_finite()  # the substeps before the failing one
    with pytest.raises(RuntimeError, match="motion failed"):
        world.add_obstacle(motion=drape.Motion(kind=drape.Motion.Kind.Callback, callback=broken))
    assert world.obstacle_count == 1  # path_world's sphere; the failed one left nothing behind
    assert world.add_obstacle().index == 1


def test_bad_constraints_are_value_errors_naming_the_field_and_unknown_keywords_type_errors():
    world = drape.World(threads=1)
    sheet = world.add_sheet(m=4, n=4)
    with pytest.raises(ValueError, match=r"points\[1\]"):
        world.add_constraint(kind=drape.ConstraintKind.Path, sheet=sheet, points=[0, 99], motion=circle())
    with pytest.raises(ValueError, match="rail"):
        world.add_constraint(kind=drape.ConstraintKind.Rail, sheet=sheet, points=[0], rail=[(0, 0, 0)])
    with pytest.raises(ValueError, match="other_points"):
        world.add_constraint(kind=drape.ConstraintKind.PointToPoint, sheet=sheet, points=[0, 1],
                             other_sheet=sheet, other_points=[2])
    with pytest.raises(ValueError, match="keyframes"):
        world.add_obstacle(motion=drape.Motion())
    with pytest.raises(ValueError, match="shear"):
        world.add_sheet(shear=drape.ShearDef(stiffness=-1))
    assert world.constraint_count == 0 and world.obstacle_count == 0
    with pytest.raises(TypeError, match="ConstraintDef has no field 'stifness'"):
        world.add_constraint(stifness=3)
    with pytest.raises(TypeError, match="Wind has no field 'speed'"):
        drape.Wind(speed=3)
    with pytest.raises(TypeError, match="Motion has no field 'keys'"):
        drape.Motion(keys=[])
    c = world.add_constraint(kind=drape.ConstraintKind.Rail, sheet=sheet, points=drape.row_points(4, 4, 4),
                             rail=[(-1, 0.5, 0), (1, 0.5, 0)])
    assert world.contains(c) and world.constraints() == [c]
    world.remove_constraint(c)
    assert not world.contains(c)
    with pytest.raises(ValueError, match="ConstraintId"):
        world.remove_constraint(c)


def test_new_definition_fields_are_keywords_with_the_engine_s_defaults():
    w = drape.WorldDef(wind=drape.Wind(velocity=(6, 1, 0)))
    assert w.wind.velocity == (6.0, 1.0, 0.0) and w.wind.density == 1.2
    d = drape.SheetDef(air=drape.AirDef(friction=0.05))
    assert d.air.drag == 1.0 and d.shear is None and d.bending is None and d.friction == 0.0
    assert "air=AirDef(drag=1.0, friction=0.05)" in repr(d)
    assert drape.ShearDef(stiffness=90).rest_length is None
    assert drape.ObstacleDef().motion is None
    assert drape.row_points(2, 3, 1) == [4, 5, 6, 7] and drape.column_points(2, 3, 1) == [1, 5, 9]
    scene = drape.parse_scene('{"frames": 1, "wind": {"velocity": [2, 0, 0]}, "sheets": [{"grid": [2, 2], '
                              '"size": [1, 1], "stiffness": 10, "air": {}}]}')
    assert scene.world.wind.velocity == (2.0, 0.0, 0.0) and scene.sheets[0].air.drag == 1.0
