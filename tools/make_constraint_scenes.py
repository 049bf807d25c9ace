#!/usr/bin/env python3
"""Writes the four constraint scenes of issue 14: scenes/flag_pole.json, cape_sphere.json,
curtain_rail.json and sewn_box.json. The sewn cover's seams are found by position: every
pair of points of two panels that start at the same place is welded. The JSON files are
committed; rerun this after changing a parameter here.

    tools/make_constraint_scenes.py
"""
import json
import math
import pathlib
import re
S = str(pathlib.Path(__file__).resolve().parent.parent / 'scenes') + '/'
def rot_x90(): return {"axis": [1, 0, 0], "degrees": 90}
def dump(name, d):
    open(S + name, 'w').write(json.dumps(d, indent=2) + "\n")

# 1. flag on a swaying pole
dump('flag_pole.json', {
  "description": "Constraints (issue 14): a flag, 0.9 m x 0.6 m, carried along its left edge by a pole that sways 12 degrees to either side about its base (a box obstacle with a repeating keyframed motion; a frame constraint with the pole as carrier).",
  "dt": 0.0004, "fps": 30, "duration": 3.0,
  "sheets": [{"name": "flag", "grid": [16, 24], "size": [0.9, 0.6], "center": [0.47, 0, 1.6],
              "orientation": rot_x90(), "mass": 0.3, "stiffness": 300.0, "damping": 0.002}],
  "obstacles": [{"type": "box", "center": [0, 0, 1.0], "half_extents": [0.01, 0.01, 1.0], "c": 0.001, "xi": 0.002,
                 "motion": {"pivot": [0, 0, 0], "repeat": True, "keyframes": [
                    {"time": 0.0},
                    {"time": 0.5, "rotation": {"axis": [1, 0, 0], "degrees": 12}},
                    {"time": 1.0},
                    {"time": 1.5, "rotation": {"axis": [1, 0, 0], "degrees": -12}},
                    {"time": 2.0}]}}],
  "constraints": [{"type": "frame", "sheet": "flag", "points": {"column": 0}, "stiffness": 3000, "obstacle": 0}],
  "output": {"dir": "out/flag_pole", "formats": ["obj"]},
  "camera": {"eye": [3.0, -2.4, 1.8], "target": [0.3, 0, 1.2]}})

# 2. cape on a moving sphere
dump('cape_sphere.json', {
  "description": "Constraints (issue 14): a cape, 0.6 m x 0.8 m, hangs from the equator of a sphere of radius 0.2 m that walks forward and turns left (keyframed translation and rotation); the cape's top edge rides on the sphere (a frame constraint with the sphere as carrier) and the sphere's potential (eq 9) keeps the cape off it.",
  "dt": 0.0004, "fps": 30, "duration": 3.0,
  "sheets": [{"name": "cape", "grid": [16, 12], "size": [0.6, 0.8], "center": [0, -0.23, 0.6],
              "orientation": rot_x90(), "mass": 0.2, "stiffness": 150.0, "damping": 0.002}],
  "obstacles": [{"type": "sphere", "center": [0, 0, 1.0], "radius": 0.2, "c": 0.005, "xi": 0.01,
                 "motion": {"pivot": [0, 0, 1.0], "keyframes": [
                    {"time": 0.0},
                    {"time": 1.2, "translation": [0, 0.9, 0]},
                    {"time": 2.4, "translation": [-0.7, 1.5, 0], "rotation": {"axis": [0, 0, 1], "degrees": 90}}]}}],
  "constraints": [{"type": "frame", "sheet": "cape", "points": {"row": 16}, "stiffness": 3000, "obstacle": 0}],
  "output": {"dir": "out/cape_sphere", "formats": ["obj"]},
  "camera": {"eye": [2.4, -2.2, 1.8], "target": [-0.2, 0.7, 0.7]}})

# 3. curtain pulled along a rail with a corner
rail = [[-1.7, 0, 2.0], [0.5, 0, 2.0], [1.2, 0.7, 2.0]]
dump('curtain_rail.json', {
  "description": "Constraints (issue 14): a curtain, 1 m x 1 m, hangs from a rail with a corner (a bay window); its top row slides along the rail without friction (a rail constraint) while its leading corner is pulled along the rail and round the corner (a path constraint with keyframes).",
  "dt": 0.0005, "fps": 30, "duration": 3.0,
  "sheets": [{"name": "curtain", "grid": [20, 20], "size": [1.0, 1.0], "center": [-1.0, 0, 1.5],
              "orientation": rot_x90(), "mass": 0.5, "stiffness": 200.0, "damping": 0.005}],
  "constraints": [
    {"type": "rail", "sheet": "curtain", "points": [[20, j] for j in range(20)], "stiffness": 3000, "rail": rail},
    {"type": "path", "sheet": "curtain", "points": [[20, 20]], "stiffness": 3000,
     "motion": {"pivot": [-0.5, 0, 2.0], "keyframes": [
        {"time": 0.0}, {"time": 1.5, "translation": [1.0, 0, 0]}, {"time": 2.5, "translation": [1.7, 0.7, 0]}]}}],
  "output": {"dir": "out/curtain_rail", "formats": ["obj"]},
  "camera": {"eye": [-0.3, -4.2, 3.0], "target": [-0.1, 0.3, 1.4]}})

# 4. a cover sewn from five panels drops over a box
half, lid_z, side_h = 0.2, 1.0, 0.3
sheets = [{"name": "lid", "grid": [8, 8], "size": [0.4, 0.4], "center": [0, 0, lid_z], "mass": 0.08,
           "stiffness": 300.0, "damping": 0.003}]
# sides: vertical, rows go up (row 6 at the lid), columns along the edge
sides = [("front", [0, -half, lid_z - side_h / 2], {"axis": [1, 0, 0], "degrees": 90}),
         ("right", [half, 0, lid_z - side_h / 2], [0.5, 0.5, 0.5, 0.5]),
         ("back", [0, half, lid_z - side_h / 2], [0, 0, 0.7071067811865476, 0.7071067811865476]),
         ("left", [-half, 0, lid_z - side_h / 2], [0.5, 0.5, -0.5, -0.5])]
for name, c, o in sides:
    sheets.append({"name": name, "grid": [6, 8], "size": [0.4, side_h], "center": c, "orientation": o,
                   "mass": 0.06, "stiffness": 300.0, "damping": 0.003})
sewn = {
  "description": "Constraints (issue 14): a cover sewn from five panels (a lid and four sides, welded along their eight shared edges by point-to-point constraints of rest length 0) drops over a box and settles on it. Contacts are off: welded points coincide, and sheet contacts would push the seams apart.",
  "dt": 0.0003, "fps": 30, "duration": 2.0, "contact_strength": 0,
  "sheets": sheets,
  "obstacles": [{"type": "box", "center": [0, 0, 0.45], "half_extents": [0.17, 0.17, 0.3], "c": 0.005, "xi": 0.005},
                {"type": "plane", "center": [0, 0, 0.15], "c": 0.005, "xi": 0.005}],
  "constraints": [],  # below: every pair of panel points that start at one place is welded
  "output": {"dir": "out/sewn_box", "formats": ["obj"]},
  "camera": {"eye": [1.6, -2.0, 1.6], "target": [0, 0, 0.6]}}

def quat(o):
    if isinstance(o, list): return o
    ax = o["axis"]; n = math.sqrt(sum(a * a for a in ax)); a = math.radians(o["degrees"])
    s = math.sin(a / 2) / n
    return [math.cos(a / 2), ax[0] * s, ax[1] * s, ax[2] * s]
def rotate(q, v):
    w, x, y, z = q
    u = (x, y, z)
    t = (2 * (u[1] * v[2] - u[2] * v[1]), 2 * (u[2] * v[0] - u[0] * v[2]), 2 * (u[0] * v[1] - u[1] * v[0]))
    return (v[0] + w * t[0] + (u[1] * t[2] - u[2] * t[1]), v[1] + w * t[1] + (u[2] * t[0] - u[0] * t[2]),
            v[2] + w * t[2] + (u[0] * t[1] - u[1] * t[0]))
def points(s):
    m, n = s["grid"]; w, h = s["size"]; q = quat(s.get("orientation", [1, 0, 0, 0])); c = s["center"]
    out = []
    for i in range(m + 1):
        for j in range(n + 1):
            l = (-w / 2 + j * w / n, -h / 2 + i * h / m, 0)
            r = rotate(q, l)
            out.append((i, j, tuple(r[k] + c[k] for k in range(3))))
    return out
P = [points(s) for s in sheets]
constraints = []
for a in range(len(sheets)):
    for b in range(a + 1, len(sheets)):
        pa, pb = [], []
        for (i, j, x) in P[a]:
            for (k, l, y) in P[b]:
                if sum((x[d] - y[d]) ** 2 for d in range(3)) < 1e-12:
                    pa.append([i, j]); pb.append([k, l])
        if pa:
            constraints.append({"type": "point_to_point", "sheet": sheets[a]["name"], "points": pa, "stiffness": 3000,
                                "other_sheet": sheets[b]["name"], "other_points": pb})
sewn["constraints"] = constraints
dump('sewn_box.json', sewn)

for f in ['flag_pole.json', 'cape_sphere.json', 'curtain_rail.json', 'sewn_box.json']:
    t = open(S + f).read()
    # short arrays of numbers (and of [row, column] pairs) on one line
    t = re.sub(r'\[\s*(-?[\d.e-]+(?:,\s*-?[\d.e-]+)*)\s*\]', lambda m: '[' + ', '.join(x.strip() for x in m.group(1).split(',')) + ']', t)
    t = re.sub(r'\[\s*((?:\[[^\[\]]*\],?\s*)+)\]', lambda m: '[' + ', '.join(re.findall(r'\[[^\[\]]*\]', m.group(1))) + ']', t)
    open(S + f, 'w').write(t)
