"""The Python module against the C++ engine: same bits as `drape run`, arrays that view the
engine's buffers, the GIL released while stepping, and errors as Python exceptions."""
import gc
import json
import re
import subprocess
import threading
import time
import weakref

import numpy as np
import pytest

import drape


def read_vtu(path, dtype):
    """Per sheet: positions and velocities, each (points, 3), as drape run wrote them (exact form)."""
    text = path.read_text()
    blocks = re.findall(r'NumberOfComponents="3" format="ascii">\n(.*?)</DataArray>', text, re.S)
    arrays = [np.array([[dtype(float(v)) for v in line.split()] for line in b.splitlines()], dtype=dtype) for b in blocks]
    return [(arrays[k], arrays[k + 1]) for k in range(0, len(arrays), 2)]


def state_of(world, sheet):
    v = world.view(sheet)
    return (np.stack([v.x.ravel(), v.y.ravel(), v.z.ravel()], axis=1),
            np.stack([v.vx.ravel(), v.vy.ravel(), v.vz.ravel()], axis=1))


@pytest.mark.parametrize("scene_name,frames,precision", [
    ("fig09.json", 3, None),           # an ellipsoid obstacle (eq 9)
    ("fig05.json", 2, "float32"),      # five anchored sheets, in float32
    ("stack_sphere.json", 2, None),    # 24 sheets in contact over a sphere
])
def test_bindings_agree_with_drape_run_bit_for_bit(tmp_path, source_dir, drape_bin, scene_name, frames, precision):
    scene_file = source_dir / "scenes" / scene_name
    if precision:
        doc = json.loads(scene_file.read_text())
        doc["precision"] = precision
        scene_file = tmp_path / scene_name
        scene_file.write_text(json.dumps(doc))
    out = tmp_path / "out"
    subprocess.run([drape_bin, "run", str(scene_file), "--frames", str(frames), "--format", "vtk", "--threads", "2",
                    "--out", str(out)], check=True, capture_output=True)

    scene = drape.load_scene(scene_file)
    world = scene.make_world(threads=1)
    assert isinstance(world, drape.WorldF if precision == "float32" else drape.World)
    dtype = np.float32 if precision == "float32" else np.float64
    sheets = world.sheets()
    assert len(sheets) == len(scene.sheets)
    for frame in range(frames + 1):
        if frame:
            assert world.step(scene.substeps).ok
        written = read_vtu(out / f"frame_{frame:05d}.vtu", dtype)
        assert len(written) == len(sheets)
        for k, sheet in enumerate(sheets):
            x, v = state_of(world, sheet)
            assert x.dtype == dtype
            # bit for bit: equal as numbers and no -0.0/+0.0 swaps
            assert np.array_equal(x.view(np.uint8), written[k][0].view(np.uint8)), f"frame {frame} sheet {k} x"
            assert np.array_equal(v.view(np.uint8), written[k][1].view(np.uint8)), f"frame {frame} sheet {k} v"


def hanging_world(**world_fields):
    world = drape.World(dt=5e-4, threads=1, **world_fields)
    sheet = world.add_sheet(m=6, n=9, stiffness=250, damping=0.02, pins=drape.corner_points(6, 9))
    return world, sheet


def address(a):
    return a.__array_interface__["data"][0]


def test_arrays_are_views_of_the_engine_buffers():
    world, sheet = hanging_world()
    v = world.view(sheet)
    assert v.x.shape == (7, 10) and v.vz.shape == (7, 10)
    assert v.x.dtype == np.float64
    assert not v.x.flags.owndata and not v.x.flags.writeable
    s = world.state(sheet)
    assert s.x.flags.writeable
    for name in ("x", "y", "z", "vx", "vy", "vz"):
        assert address(getattr(v, name)) == address(getattr(s, name)), name  # one buffer, no copy
    before = v.z.copy()
    world.step(20)
    again = world.view(sheet)
    assert address(again.z) == address(v.z)  # stepping does not move the buffers
    assert not np.array_equal(v.z, before)   # the old array sees the new state: it is the buffer
    assert np.array_equal(v.z, again.z)
    # row-major grid: point (i, j) is x[i, j]; the sheet spans 1 m along columns, centred on 0
    flat_index = drape.point_index(9, 2, 3)
    assert v.x.ravel()[flat_index] == v.x[2, 3]


def test_arrays_of_a_removed_sheet_keep_its_last_state():
    # Before, remove_sheet freed the buffers under live arrays: they read freed memory
    # (denormal garbage in the first values), silently.
    world, sheet = hanging_world()
    world.step(20)
    v, s = world.view(sheet), world.state(sheet)
    last = {name: getattr(v, name).copy() for name in ("x", "y", "z", "vx", "vy", "vz")}
    kept_at = address(v.z)
    world.remove_sheet(sheet)
    with pytest.raises(ValueError):
        world.view(sheet)
    # the world goes on with other sheets in the freed slot; the arrays keep the sheet's last state
    other = world.add_sheet(m=6, n=9, mass=1.0, stiffness=100.0, center=(0.0, 0.0, 2.0))
    world.step(20)
    assert address(v.z) == kept_at and address(world.view(other).z) != kept_at
    for name, values in last.items():
        assert np.array_equal(getattr(v, name), values), name
        assert np.array_equal(getattr(s, name), values), name
    # they hold the world until they go (as any view does), then both are freed
    gone = weakref.ref(world)
    del world
    gc.collect()
    assert gone() is not None
    del v, s
    gc.collect()
    assert gone() is None


def test_integrator_memory_is_a_copy_that_outlives_the_sheet():
    # It viewed the engine's vector, which a removal freed (and an integrator change may move).
    world = drape.World(dt=1e-3, integrator="rk4")
    sheet = world.add_sheet(m=4, n=4, pins=drape.corner_points(4, 4))
    world.step(2)
    memory = world.integrator_memory(sheet)
    assert memory.size > 0 and memory.flags.owndata
    kept = memory.copy()
    world.remove_sheet(sheet)
    for _ in range(3):
        world.add_sheet(m=20, n=20)
    assert np.array_equal(memory, kept)


def test_threads_sharing_one_world_take_turns():
    # Two threads stepping one world while a third adds and removes sheets crashed the
    # interpreter (segmentation fault): the world's calls now run one at a time.
    world = drape.World(dt=1e-4, threads=1)
    for k in range(3):
        world.add_sheet(m=20, n=20, center=(0.0, 0.0, 0.01 * k))

    def stepper():
        for _ in range(20):
            world.step(5)

    def changer():
        for k in range(40):
            extra = world.add_sheet(m=10, n=10, center=(0.0, 0.0, 1.0 + k))
            world.view(extra)
            world.remove_sheet(extra)

    threads = [threading.Thread(target=stepper) for _ in range(2)] + [threading.Thread(target=changer)]
    for t in threads:
        t.start()
    # a run_frames callback may call its own world while another thread waits for it
    frames = world.run_frames(5, 2, lambda frame: world.view(world.sheets()[0]) is not None)
    for t in threads:
        t.join()
    assert frames == 5
    assert world.step_count == 2 * 20 * 5 + 5 * 2  # no substep lost to a race
    assert world.sheet_count == 3 and world.check().ok


def test_pinned_corners_stay_and_grid_spacing_is_the_definition():
    world, sheet = hanging_world()
    v = world.view(sheet)
    # h1 = Lh/n, h2 = Lv/m (paper §2): the initial grid, independent of any step
    assert np.allclose(np.diff(v.x, axis=1), 1.0 / 9, rtol=0, atol=1e-15)
    assert np.allclose(np.diff(v.y, axis=0), 1.0 / 6, rtol=0, atol=1e-15)
    corners = v.x[[0, 0, -1, -1], [0, -1, 0, -1]].copy(), v.z[[0, 0, -1, -1], [0, -1, 0, -1]].copy()
    world.step(100)
    assert np.array_equal(v.x[[0, 0, -1, -1], [0, -1, 0, -1]], corners[0])
    assert np.array_equal(v.z[[0, 0, -1, -1], [0, -1, 0, -1]], corners[1])
    assert v.z[3, 4] < -1e-3  # the middle sags under gravity


def test_a_write_through_state_is_seen_by_the_next_step():
    # No gravity, springs at rest: a uniform velocity written through the arrays is a rigid
    # translation, x(t) = x0 + vx·t exactly up to rounding.
    world = drape.World(dt=1e-3, gravity=(0, 0, 0), threads=1)
    sheet = world.add_sheet(m=4, n=5)
    s = world.state(sheet)
    x0 = s.x.copy()
    s.vx[...] = 0.5
    world.step(10)
    assert np.allclose(s.x, x0 + 0.5 * 10 * 1e-3, rtol=0, atol=1e-12)
    assert np.allclose(s.vx, 0.5, rtol=0, atol=1e-12)
    with pytest.raises(ValueError):
        world.view(sheet).x[0, 0] = 1.0  # views are read-only


def test_free_fall_matches_the_closed_form_of_semi_implicit_euler():
    # One unconstrained sheet with springs at rest falls as a rigid body. Semi-implicit Euler
    # gives v_k = -g·k·dt, z_k = z0 - g·dt²·k(k+1)/2 exactly (up to rounding).
    g, dt, k = 9.81, 1e-3, 200
    world = drape.World(dt=dt, gravity=(0, 0, -g), integrator="semi_implicit_euler", threads=1)
    sheet = world.add_sheet(m=3, n=3, center=(0, 0, 2.0))
    report = world.step(k)
    assert report.ok and bool(report)
    v = world.view(sheet)
    assert np.allclose(v.z, 2.0 - g * dt * dt * k * (k + 1) / 2, rtol=0, atol=1e-12)
    assert np.allclose(v.vz, -g * k * dt, rtol=0, atol=1e-12)
    assert world.step_count == k and world.time == pytest.approx(k * dt, rel=1e-15)
    e = world.energies()
    assert e.kinetic == pytest.approx(0.5 * 1.0 * (g * k * dt) ** 2, rel=1e-12)


def test_contact_energy_is_the_potential_of_two_stacked_sheets():
    # Two equal 5x5-point sheets 6 mm apart: each point's nearest triangle is straight across,
    # so the potential is 2 * 25 * E(6 mm), E written out here from docs/api.md's formula.
    c, h, xi, reach = 1e-3, 0.005, 0.002, 6.0
    world = drape.World(gravity=(0, 0, 0), contact_strength=c, contact_thickness=h, contact_xi=xi,
                        contact_range=reach, threads=1)
    world.add_sheet(m=4, n=4)
    world.add_sheet(m=4, n=4, center=(0, 0, 0.006))
    d, t = 0.006, np.exp(-reach)
    energy = c * (np.exp((h - d) / xi) - t) - c * t * (h + reach * xi - d) / xi
    assert world.contact_energy() == pytest.approx(2 * 25 * energy, rel=1e-12)
    assert world.energies().total == pytest.approx(0.0, abs=1e-12)  # not in energies()


def test_step_releases_the_gil():
    # While one thread is inside step(), the main thread keeps running Python. With the GIL
    # held through the step, no main-thread iteration could fall in the middle of it.
    world = drape.World(dt=1e-4, threads=1)
    world.add_sheet(m=60, n=60, stiffness=10, damping=0.01)
    substeps, took = 10, 0.0
    while took < 0.1:  # until a step() call lasts long enough to time
        substeps *= 2
        start = time.perf_counter()
        world.step(substeps)
        took = time.perf_counter() - start
    substeps = int(substeps * 0.4 / took)  # about 0.4 s of stepping
    window = {}

    def stepper():
        window["t0"] = time.perf_counter()
        world.step(substeps)
        window["t1"] = time.perf_counter()

    ticks = []
    t = threading.Thread(target=stepper)
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
    t.join()
    t0, t1 = window["t0"], window["t1"]
    middle = [x for x in ticks if t0 + 0.25 * (t1 - t0) < x < t1 - 0.25 * (t1 - t0)]
    assert t1 - t0 > 0.05
    assert middle, "the main thread did not run while step() ran: the GIL is held"


def test_python_threads_step_worlds_like_one_thread():
    def run(world):
        world.step(300)

    worlds = [hanging_world()[0] for _ in range(3)]
    threads = [threading.Thread(target=run, args=(w,)) for w in worlds]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    serial, sheet = hanging_world()
    run(serial)
    for w in worlds:
        for name in ("x", "y", "z", "vx", "vy", "vz"):
            assert np.array_equal(getattr(w.view(w.sheets()[0]), name), getattr(serial.view(sheet), name))


def test_errors_arrive_as_python_exceptions_with_the_engine_message(tmp_path):
    world = drape.World(threads=1)
    with pytest.raises(ValueError, match="stiffness must be positive"):
        world.add_sheet(stiffness=-3)
    with pytest.raises(ValueError, match="WorldDef"):
        drape.World(dt=0)
    with pytest.raises(TypeError, match="SheetDef has no field 'stifness'"):
        drape.SheetDef(stifness=3)
    sheet = world.add_sheet()
    world.remove_sheet(sheet)
    with pytest.raises(ValueError, match="unknown or removed SheetId"):
        world.view(sheet)
    other = world.add_sheet(m=2, n=2)
    with pytest.raises(ValueError, match="needs"):
        world.set_state(other, *(np.zeros(3) for _ in range(6)))
    with pytest.raises(ValueError, match="unknown integrator"):
        drape.Integrator("leapfrog")
    # a name wherever an enum is taken says which name, not pybind11's "incompatible arguments"
    with pytest.raises(ValueError, match='unknown integrator "leapfrog"'):
        drape.World(integrator="leapfrog")
    with pytest.raises(ValueError, match='unknown integrator "leapfrog"'):
        drape.World().set_integrator("leapfrog")
    with pytest.raises(ValueError, match='unknown constraint kind "join"'):
        drape.ConstraintDef(kind="join")
    with pytest.raises(TypeError, match="expected a ConstraintKind or its name, got float"):
        drape.ConstraintDef(kind=3.5)
    # obstacle shapes by the scene format's type too
    assert [s.label for s in drape.ObstacleShape.__members__.values()] == ["plane", "sphere", "ellipsoid", "torus", "box"]
    assert drape.ObstacleDef(shape="torus").shape == drape.ObstacleShape.Torus
    with pytest.raises(ValueError, match='unknown obstacle shape "cube"'):
        drape.World().add_obstacle(shape="cube")
    assert drape.WorldDef(cg_preconditioner="cholesky").cg_preconditioner == drape.Preconditioner.Cholesky
    with pytest.raises(ValueError, match="advance"):
        world.advance(-1.0)
    missing = tmp_path / "missing.json"
    with pytest.raises(drape.SceneError, match="missing.json"):
        drape.load_scene(missing)
    assert issubclass(drape.SceneError, ValueError)
    bad = tmp_path / "bad.json"
    bad.write_text('{"frames": 1, "sheets": [{"grid": [4, 4], "size": [1, 1], "stiffness": 10}]}')
    with pytest.raises(drape.SceneError, match=r"sheets\[0\]\.stiffness: must be positive"):
        drape.load_scene(bad, overrides={"sheets[*].stiffness": -1})
    assert drape.validate(drape.SheetDef(mass=0)) != ""
    assert drape.validate(drape.SheetDef()) == ""
    far = drape.SheetDef(m=10, n=10, width=0.01, height=0.01, center=(1000, 0, 0))  # 1 mm cells 1 km out
    assert drape.validate(far) == ""
    assert "float" in drape.validate_float(far)


def test_unstable_world_reports_instead_of_raising():
    world = drape.World(dt=0.05, gravity=(0, 0, 0), integrator=drape.Integrator.ForwardEuler, threads=1)
    sheet = world.add_sheet(m=4, n=4, stiffness=1000)
    world.state(sheet).vz[2, 2] = 1.0
    report = world.step(200)
    assert not report.ok and report.status != drape.StabilityStatus.Stable
    assert report.sheet == sheet and world.halted
    assert "forward_euler" in str(report)
    assert report.step_limit == drape.StepLimit.Springs and report.stable_dt < report.dt
    with pytest.raises(ValueError, match="non-negative number of substeps"):
        world.step(-1)


def test_repr_says_what_the_world_holds_and_what_the_guard_found():
    world = drape.WorldF(dt=0.002, threads=1)
    assert repr(world).startswith("<drape.WorldF: 0 sheet(s), 0 obstacle(s), t = 0 s after 0 substep(s)")
    world.add_sheet(m=4, n=4)
    world.add_obstacle(shape="plane", center=(0, 0, -1))
    report = world.step(5)
    assert repr(world) == ("<drape.WorldF: 1 sheet(s), 1 obstacle(s), t = 0.01 s after 5 substep(s) of "
                           "semi_implicit_euler at dt = 0.002 s>")
    assert repr(report) == "<drape.StabilityReport: " + str(report) + ">"
    blown = drape.World(dt=0.05, gravity=(0, 0, 0), integrator="forward_euler", threads=1)
    sheet = blown.add_sheet(m=4, n=4, stiffness=1000)
    blown.state(sheet).vz[2, 2] = 1.0
    report = blown.step(200)
    assert not report.ok and repr(blown).endswith(", halted by the stability guard>")
    assert "forward_euler" in repr(report)
    # results list their fields as the attributes give them
    energies = world.energies()
    assert repr(energies) == "Energies(" + ", ".join(
        f"{k}={getattr(energies, k)!r}" for k in ("kinetic", "spring", "bending", "gravity", "anchor", "obstacle", "total")) + ")"
    assert repr(world.solver_stats(world.sheets()[0])).startswith("SolverStats(iterations=0, ")
    penetration = world.obstacle_penetration(world.sheets()[0])
    assert repr(penetration) == f"ObstaclePenetration(depth=0.0, obstacle=ObstacleId(invalid), point={penetration.point})"


def test_obstacle_penetration_is_the_depth_inside_a_sphere():
    world = drape.World(threads=1)
    ball = world.add_obstacle(shape=drape.ObstacleShape.Sphere, center=(0, 0, 0), size=(0.3, 0, 0))
    sheet = world.add_sheet(m=2, n=2, width=0.2, height=0.2, center=(0, 0, 0.1))  # centre point 0.2 inside
    deepest = world.obstacle_penetration(sheet)
    assert deepest.obstacle == ball and deepest.point == 4 and abs(deepest.depth - 0.2) < 1e-12


def test_sheet_crossings_name_a_point_pushed_through_another_sheet():
    world = drape.World(threads=1)
    lower = world.add_sheet(m=4, n=4, width=0.2, height=0.2)
    upper = world.add_sheet(m=4, n=4, width=0.2, height=0.2, center=(0.011, 0.013, 0.004))
    assert world.sheet_crossings() == []
    world.state(upper).z[2, 2] = -0.002  # the middle point, 2 mm under the lower sheet
    (crossing,) = world.sheet_crossings()
    assert (crossing.a, crossing.b, crossing.point_b) == (lower, upper, 12)
    assert crossing.edges >= 6  # its edges along the row, the column and the diagonal


def test_contact_rims_add_the_potential_of_edges_passing_a_rim():
    # a sheet over another's edge, turned 0.5 rad about z: its edges pass the lower sheet's
    # rim 4 mm above it, so the rims add their potential to the points' (contact_energy)
    energies = []
    for rims in (False, True):
        world = drape.World(threads=1, gravity=(0, 0, 0), contact_rims=rims)
        world.add_sheet(m=2, n=2, width=0.2, height=0.2)
        world.add_sheet(m=2, n=2, width=0.2, height=0.2, center=(0.1, 0.0, 0.004),
                        orientation=drape.quat_from_axis_angle((0, 0, 1), 0.5))
        energies.append(world.contact_energy())
    assert energies[1] > energies[0]


def test_a_contact_too_stiff_for_the_step_is_named():
    # c/ξ² about 300 times m/dt² for the 1 g points (stability_test.cpp has the C++ case)
    world = drape.World(dt=1e-3, gravity=(0, 0, 0), contact_strength=1e-2, contact_xi=1e-4, threads=1)
    world.add_sheet(m=10, n=10, mass=0.121, stiffness=40, pins=drape.corner_points(10, 10))
    world.add_sheet(m=10, n=10, mass=0.121, stiffness=40, width=0.8, height=0.8, center=(0, 0, 0.05),
                    initial_velocity=(0, 0, -1))
    report = world.advance(0.2)
    assert not report.ok and report.step_limit == drape.StepLimit.Contact
    assert report.stable_dt < report.dt and "contact_strength" in str(report)


def test_definitions_take_keywords_and_tuples():
    assert drape.__version__.count(".") == 2
    d = drape.SheetDef(m=3, n=4, center=[1, 2, 3], anchors=[drape.AnchorDef(point=0, stiffness=5)])
    assert d.center == (1.0, 2.0, 3.0) and d.m == 3 and d.anchors[0].target is None
    d.orientation = drape.quat_from_axis_angle((0, 0, 1), 0.5)
    assert len(d.orientation) == 4
    assert "stiffness=100.0" in repr(d)
    w = drape.WorldDef(integrator="rk4", dt=2e-3)
    assert w.integrator == drape.Integrator.RK4
    assert w.contact_damping == 2.0 and drape.WorldDef(contact_damping=2.5).contact_damping == 2.5
    assert drape.ObstacleDef().damping == 0.0 and drape.ObstacleDef(damping=1.5).damping == 1.5
    world = drape.World(w, threads=1)
    assert world.definition.dt == 2e-3 and world.definition.threads == 1
    world.definition.dt = 1.0  # a copy: the world changes only through set_dt
    assert world.definition.dt == 2e-3 and world.substep_dt == 2e-3
    scene = drape.parse_scene('{"frames": 2, "dt": 0.002, "sheets": [{"grid": [3, 5], "size": [1, 2], "stiffness": 10, "mass": 1}]}', overrides={"dt": 0.004})
    assert scene.world.dt == 0.004 and scene.sheets[0].m == 3 and scene.precision == "float64"


def test_run_frames_calls_back_per_frame_and_stops_on_false():
    world, sheet = hanging_world()
    seen = []

    def on_frame(frame):
        seen.append((frame, world.step_count, float(world.view(sheet).z[3, 4])))
        return frame < 3

    assert world.run_frames(10, 25, on_frame) == 3
    assert [(f, s) for f, s, _ in seen] == [(1, 25), (2, 50), (3, 75)]
    # the same states as stepping a frame at a time
    again, other = hanging_world()
    for f, _, z in seen:
        again.step(25)
        assert float(again.view(other).z[3, 4]) == z

    def broken(frame):
        raise RuntimeError("callback failed")

    with pytest.raises(RuntimeError, match="callback failed"):
        world.run_frames(2, 1, broken)


def test_frames_in_groups_of_sheets_in_contact_change_no_bit():
    # two columns of three layers in contact, far apart: each column a group
    def columns(group_points):
        world = drape.World(dt=1e-3, threads=1, group_points=group_points)
        sheets = [world.add_sheet(m=12, n=12, width=0.3, height=0.3, stiffness=50, damping=0.05,
                                  center=(0.6 * c, 0, 0.008 * k), pins=drape.corner_points(12, 12))
                  for c in range(2) for k in range(3)]
        return world, sheets

    framed, sheets = columns(0)
    for _ in range(5):
        framed.step(10)
    assert framed.frame_stats.kept == 5 and framed.frame_stats.undone == 0
    single, same = columns(0)
    for _ in range(50):
        single.step(1)
    assert single.frame_stats.kept == 0  # a single substep is never tried
    for a, b in zip(sheets, same):
        assert np.array_equal(framed.view(a).z.view(np.uint8), single.view(b).z.view(np.uint8))
    small, _ = columns(drape.WorldDef().group_points)  # too small a world for groups by default
    small.step(10)
    assert small.frame_stats.kept + small.frame_stats.undone == 0


def test_contact_memory_makes_a_copied_world_in_contact_continue_bit_for_bit():
    def stack():
        world = drape.World(dt=1e-3, threads=1)
        sheets = [world.add_sheet(m=12, n=12, width=0.3, height=0.3, stiffness=50, damping=0.05,
                                  center=(0.01 * k, 0, 0.008 * k), pins=drape.corner_points(12, 12))
                  for k in range(3)]
        return world, sheets

    first, sheets = stack()
    first.step(50)
    copy, copied = stack()
    copy.step_count = first.step_count
    for a, b in zip(sheets, copied):
        s = first.view(a)
        copy.set_state(b, s.x, s.y, s.z, s.vx, s.vy, s.vz)
    memory = first.contact_memory()
    assert memory.dtype == np.uint64 and memory.size > 0
    copy.set_contact_memory(memory)
    first.step(100)
    copy.step(100)
    for a, b in zip(sheets, copied):
        assert np.array_equal(first.view(a).z.view(np.uint8), copy.view(b).z.view(np.uint8))
    with pytest.raises(ValueError, match="contact memory"):
        copy.set_contact_memory(memory[:-1])
