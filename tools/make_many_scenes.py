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


def rain_torus():
    sheets = []
    for k in range(36):
        i, j = k % 6, k // 6
        tilt = 0.5 * (k % 7) / 6
        cells, side, mass = 8 + k % 6, rounded(0.3 + 0.06 * (k % 6)), rounded(0.05 + 0.03 * (k % 5))
        stiffness = [100.0, 200.0, 400.0, 800.0][k % 4]
        sheet = {
            "name": f"drop{k:02d}",
            "grid": [cells, cells],
            "size": [side, side],
            "center": rounded([-0.75 + 0.3 * i, -0.75 + 0.3 * j, 1.0 + 0.15 * ((7 * k) % 12)]),
            "velocity": [0, 0, -0.5],
            "mass": mass,
            "stiffness": stiffness,
            "damping": 0.005,
            # cloth (issue 12): shear springs at SHEAR_RATIO of the grid's stiffness, and bending
            "shear": {"stiffness": rounded(SHEAR_RATIO * stiffness)},
            "bending": {"stiffness": cloth_bending(mass, side, cells)},
        }
        if tilt > 0:
            sheet["orientation"] = {"axis": rounded([math.cos(k), math.sin(k), 0]), "degrees": rounded(math.degrees(tilt), 4)}
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
CONTACTS = {"contact_thickness": 0.005, "contact_xi": 0.002, "contact_strength": 2e-3}

if __name__ == "__main__":
    for name, scene in (("stack_sphere", stack_sphere()), ("rain_torus", rain_torus())):
        (SCENES / f"{name}.json").write_text(json.dumps(scene, indent=2) + "\n")
        print(f"wrote scenes/{name}.json ({len(scene['sheets'])} sheets)")
