#!/usr/bin/env python3
"""A throughput job in Python: randomised drapes of a sheet over an obstacle, saved as one .npz.

Each drape draws a sheet size, a spring stiffness, a drop height and an obstacle (sphere, box
or torus, of random size), drops the sheet from rest onto the obstacle and lets it settle for
--seconds; the data set holds every drape's parameters and final positions. The drapes run on
--threads Python threads, one world each: World.step releases the GIL, so the threads step
in parallel. Prints the rate at the end.

    PYTHONPATH=build/python /usr/bin/python3 tools/drape_dataset.py --count 1000 --out drapes.npz

The .npz arrays (N drapes, a grid of (m+1)x(n+1) points):
  positions      (N, m+1, n+1, 3) float64, m   final positions, row-major grid (eqs 2-3)
  size           (N,) m          the sheet's width = height
  stiffness      (N,) N/m
  drop_height    (N,) m          of the sheet above the obstacle's top at the start
  shape          (N,) int        0 sphere, 1 box, 2 torus (shape_names)
  obstacle_size  (N, 3) m        ObstacleDef.size (sphere radius; box half extents; torus R, r)
  stable         (N,) bool       the stability guard's verdict at the end
"""

import argparse
import concurrent.futures
import os
import sys
import time

import numpy as np

import drape

SHAPES = [drape.ObstacleShape.Sphere, drape.ObstacleShape.Box, drape.ObstacleShape.Torus]
SHAPE_NAMES = ["sphere", "box", "torus"]
CELLS = 16
MASS = 0.3        # kg
DAMPING = 0.002   # N·s/m per point
OBSTACLE_C = 1e-3  # J; rests about 3·xi above the surface under the weight of a point
OBSTACLE_XI = 0.005


def draw(rng, count):
    """Every drape's parameters, drawn up front so a data set depends only on the seed."""
    shape = rng.integers(0, len(SHAPES), count)
    size = np.zeros((count, 3))
    top = np.zeros(count)
    for k in range(count):
        if shape[k] == 0:
            r = rng.uniform(0.2, 0.4)
            size[k] = (r, r, r)
            top[k] = r
        elif shape[k] == 1:
            size[k] = rng.uniform(0.15, 0.35, 3)
            top[k] = size[k][2]
        else:
            size[k] = (rng.uniform(0.15, 0.25), rng.uniform(0.08, 0.12), 0.0)  # inside the smallest sheet
            top[k] = size[k][1]
    return {
        "size": rng.uniform(1.0, 1.4, count),
        "stiffness": np.exp(rng.uniform(np.log(20), np.log(300), count)),
        "drop_height": rng.uniform(0.05, 0.4, count),
        "shape": shape,
        "obstacle_size": size,
        "obstacle_top": top,
    }


def drape_one(params, k, seconds):
    world = drape.World(dt=1e-3, adaptive=True, threads=1)
    world.add_obstacle(shape=SHAPES[params["shape"][k]], size=tuple(params["obstacle_size"][k]), c=OBSTACLE_C,
                       xi=OBSTACLE_XI)
    side = float(params["size"][k])
    sheet = world.add_sheet(m=CELLS, n=CELLS, width=side, height=side, mass=MASS, damping=DAMPING,
                            stiffness=float(params["stiffness"][k]),
                            center=(0.0, 0.0, float(params["obstacle_top"][k] + params["drop_height"][k])))
    report = world.advance(seconds)
    v = world.view(sheet)
    positions = np.stack([v.x, v.y, v.z], axis=-1)  # the one copy: into the data set
    return positions, report.ok, world.step_count


def run(count, seconds, threads, seed):
    params = draw(np.random.default_rng(seed), count)
    positions = np.zeros((count, CELLS + 1, CELLS + 1, 3))
    stable = np.zeros(count, dtype=bool)
    substeps = 0
    start = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(max_workers=threads) as pool:
        for k, (p, ok, steps) in enumerate(pool.map(lambda k: drape_one(params, k, seconds), range(count))):
            positions[k], stable[k] = p, ok
            substeps += steps
    elapsed = time.perf_counter() - start
    del params["obstacle_top"]
    return dict(params, positions=positions, stable=stable, shape_names=np.array(SHAPE_NAMES)), elapsed, substeps


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=1000, help="drapes (default 1000)")
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated seconds per drape (default 1)")
    ap.add_argument("--threads", type=int, default=os.cpu_count(), help="Python threads (default: all cores)")
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--out", required=True, help=".npz file to write")
    args = ap.parse_args(argv)
    if args.count < 1 or args.seconds <= 0 or args.threads < 1:
        ap.error("--count and --threads must be at least 1 and --seconds positive")
    data, elapsed, substeps = run(args.count, args.seconds, args.threads, args.seed)
    tmp = args.out + ".tmp.npz"  # written whole, then renamed: never a half-written data set
    np.savez_compressed(tmp, **data)
    os.replace(tmp, args.out)
    points = (CELLS + 1) ** 2
    print(f"drape_dataset: {args.count} drapes in {elapsed:.2f} s ({args.count / elapsed:.1f} drapes/s, "
          f"{points * substeps / elapsed / 1e6:.1f} M point-steps/s on {args.threads} thread(s)), "
          f"{int(np.count_nonzero(~data['stable']))} unstable; wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
