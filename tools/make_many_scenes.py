#!/usr/bin/env python3
"""Writes the two many-sheet scenes of issue 4: scenes/stack_sphere.json (sheets dropped
onto a sphere settle into layers) and scenes/rain_torus.json (sheets rain over a torus and
a plane; since issue 12 they are cloth: shear springs and bending). The JSON files are
committed; rerun this after changing a parameter here.

    tools/make_many_scenes.py
"""
import json
import math
import pathlib

SCENES = pathlib.Path(__file__).resolve().parent.parent / "scenes"


def rounded(v, digits=6):
    return [round(x, digits) for x in v] if isinstance(v, (list, tuple)) else round(v, digits)


def stack_sphere():
    sheets = []
    for k in range(24):
        big = k % 2 == 0
        cells = 10 if big else 8
        side = 1.2 if big else 0.9
        sheets.append({
            "name": f"layer{k:02d}",
            "grid": [cells, cells],
            "size": [side, side],
            "center": rounded([0.02 * ((7 * k) % 5 - 2), 0.02 * ((3 * k) % 5 - 2), 0.58 + 0.03 * k]),
            # turned about z so the layers' grids and corners do not line up
            "orientation": {"axis": [0, 0, 1], "degrees": rounded(math.degrees(0.12 * k), 4)},
            "mass": 0.2,
            "stiffness": [200.0, 500.0, 1000.0][k % 3],
            # damping that settles the layers' bouncing on their contacts, which without it
            # lets the pile creep off the sphere within 5 s despite friction
            "damping": 0.05,
            "friction": FRICTION_STACK,
        })
    return {
        "description": "Beyond the paper (issues 4, 13): 24 sheets of two sizes (1.2 m 10x10 cells, 0.9 m 8x8 "
                       "cells) and three stiffnesses (200, 500, 1000 N/m), 0.2 kg each, dropped onto a sphere of "
                       "radius 0.5 m; sheet-sheet contacts keep them apart, friction (0.8 between sheets and on "
                       "the sphere) holds them, and they settle into layers that stay on the sphere.",
        "dt": DT_STACK,
        "fps": 30,
        "duration": DURATION_STACK,
        **CONTACTS,
        "sheets": sheets,
        "obstacles": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "c": 0.01, "xi": 0.01, "friction": 0.8}],
        "output": {"dir": "out/stack_sphere", "formats": ["obj"]},
        "camera": {"eye": [2.3, -2.9, 1.7], "target": [0.0, 0.0, 0.25]},
    }


def cloth_bending(mass, side, cells, length=None):
    """k_b giving the sheet a bending length (D / (rho_A g))^(1/3) of `length`: a strip of
    cloth that long sticks out straight, a longer one droops. D = k_b h^2 per unit width
    (one grid line of EI = k_b h^3 every h)."""
    h = side / cells
    areal_density = mass / (side * side)
    length = BENDING_LENGTH if length is None else length
    return rounded(areal_density * 9.81 * length ** 3 / h ** 2, 6)


def rotated(v, axis, angle):
    """v turned by angle (radians) about the unit axis (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    dot = sum(a * b for a, b in zip(axis, v))
    cross = [axis[1] * v[2] - axis[2] * v[1], axis[2] * v[0] - axis[0] * v[2], axis[0] * v[1] - axis[1] * v[0]]
    return [v[i] * c + cross[i] * s + axis[i] * dot * (1 - c) for i in range(3)]


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def sheet_corners(center, side, axis, tilt):
    """The corners, in order around it, of a flat square sheet of the given side turned by tilt about axis."""
    return [[center[i] + d for i, d in enumerate(rotated([sx * side / 2, sy * side / 2, 0], axis, tilt))]
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]


def segment_distance(p, q, a, b):
    """Distance between segments pq and ab (the closest pair of parameters, clamped)."""
    d1, d2, r = sub(q, p), sub(b, a), sub(p, a)
    a11, a22, a12, b1, b2 = dot(d1, d1), dot(d2, d2), dot(d1, d2), dot(d1, r), dot(d2, r)
    det = a11 * a22 - a12 * a12
    s = min(max((a12 * b2 - a22 * b1) / det, 0.0), 1.0) if det > 1e-18 else 0.0
    t = min(max((a12 * s + b2) / a22, 0.0), 1.0)
    s = min(max((a12 * t - b1) / a11, 0.0), 1.0)
    return math.dist([p[i] + s * d1[i] for i in range(3)], [a[i] + t * d2[i] for i in range(3)])


def segment_to_square(p, q, square):
    """Distance from segment pq to a flat convex quad: 0 where pq passes through it."""
    u, v = sub(square[1], square[0]), sub(square[3], square[0])
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    norm = math.sqrt(dot(n, n))
    n = [x / norm for x in n]

    def inside(x):  # x on the quad's plane: within all four edges
        return all(dot(n, cross3(sub(square[(k + 1) % 4], square[k]), sub(x, square[k]))) >= 0 for k in range(4))

    hp, hq = dot(n, sub(p, square[0])), dot(n, sub(q, square[0]))
    best = min(segment_distance(p, q, square[k], square[(k + 1) % 4]) for k in range(4))
    for x, h in ((p, hp), (q, hq)):
        if inside([x[i] - h * n[i] for i in range(3)]):
            best = min(best, abs(h))
    if hp * hq < 0:
        t = hp / (hp - hq)
        if inside([p[i] + t * (q[i] - p[i]) for i in range(3)]):
            return 0.0
    return best


def cross3(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def squares_distance(a, b):
    """Distance between two flat convex quads: each one's edges against the other."""
    return min(min(segment_to_square(x[k], x[(k + 1) % 4], y) for k in range(4)) for x, y in ((a, b), (b, a)))


# Sheets start this far apart at least, beyond the contact range (h + 6 xi = 17 mm): none
# starts through another, and all fall alike until they land.
RAIN_CLEARANCE = 0.03


def rain_torus():
    sheets, placed = [], []
    for k in range(36):
        i, j = k % 6, k // 6
        tilt = 0.5 * (k % 7) / 6
        cells, side, mass = 8 + k % 6, rounded(0.3 + 0.06 * (k % 6)), rounded(0.05 + 0.03 * (k % 5))
        stiffness = [100.0, 200.0, 400.0, 800.0][k % 4]
        axis = rounded([math.cos(k), math.sin(k), 0])
        center = [-0.75 + 0.3 * i, -0.75 + 0.3 * j, 1.0 + 0.15 * ((7 * k) % 12)]
        # tilted neighbours at the same or the next height would start through each other:
        # such a sheet starts higher, in steps of a tenth of the height pitch
        while any(squares_distance(sheet_corners(center, side, axis, tilt), b) < RAIN_CLEARANCE for b in placed):
            center[2] += 0.015
        placed.append(sheet_corners(center, side, axis, tilt))
        sheet = {
            "name": f"drop{k:02d}",
            "grid": [cells, cells],
            "size": [side, side],
            "center": rounded(center),
            "velocity": [0, 0, -0.5],
            "mass": mass,
            "stiffness": stiffness,
            "damping": 0.005,
            # cloth (issue 12): shear springs at SHEAR_RATIO of the grid's stiffness, and bending
            "shear": {"stiffness": rounded(SHEAR_RATIO * stiffness)},
            "bending": {"stiffness": cloth_bending(mass, side, cells)},
        }
        if tilt > 0:
            sheet["orientation"] = {"axis": axis, "degrees": rounded(math.degrees(tilt), 4)}
        if k % 9 == 0:
            sheet["self_collision"] = True
        sheets.append(sheet)
    return {
        "description": "Beyond the paper (issue 4): 36 sheets of six sizes (0.3-0.6 m, 8x8-13x13 cells), five masses "
                       "and four stiffnesses (100-800 N/m) rain onto a torus (R = 0.6 m, r = 0.2 m) lying on a plane; "
                       "every ninth sheet also collides with itself. Since issue 12 the sheets are cloth: shear "
                       "springs at 0.3 of the grid stiffness and bending with a bending length of 6 cm.",
        "dt": DT_RAIN,
        "fps": 30,
        "duration": DURATION_RAIN,
        **CONTACTS,
        "sheets": sheets,
        # the torus's c as the plane's: the points reach it at up to about 5.4 m/s, and at
        # c = 0.01 the fastest came within 0.2 mm of its surface (0.5 mm inside once contacts
        # between sheets were damped, which stops the sheets above harder); at 0.02, 2 mm
        "obstacles": [
            {"type": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "c": 0.02, "xi": 0.01, "full_gradient": True},
            {"type": "torus", "center": [0, 0, 0.2], "major_radius": 0.6, "minor_radius": 0.2, "c": 0.02, "xi": 0.005,
             "full_gradient": True},
        ],
        "output": {"dir": "out/rain_torus", "formats": ["obj"]},
        "camera": {"eye": [3.6, -4.8, 3.4], "target": [0.0, 0.0, 0.8]},
    }


DT_STACK, DURATION_STACK, FRICTION_STACK = 4e-4, 5.0, 0.8
DT_RAIN, DURATION_RAIN = 3e-4, 2.5
SHEAR_RATIO, BENDING_LENGTH = 0.3, 0.06
# Rims on: the sheets' cells (4-18 cm) are long against the contact range (17 mm), and
# without the rims' edge contacts their rims hooked through each other while landing and
# settling (World::sheet_crossings found it in both scenes), for about half as much time again.
CONTACTS = {"contact_thickness": 0.005, "contact_xi": 0.002, "contact_strength": 2e-3, "contact_rims": True}

if __name__ == "__main__":
    for name, scene in (("stack_sphere", stack_sphere()), ("rain_torus", rain_torus())):
        (SCENES / f"{name}.json").write_text(json.dumps(scene, indent=2) + "\n")
        print(f"wrote scenes/{name}.json ({len(scene['sheets'])} sheets)")
