#!/usr/bin/env python3
"""Measures `drape sweep`'s throughput at 1 and 2 MPI ranks x 1 and 2 threads per rank.

mpirun cannot run inside Google Benchmark, so this script runs the drape program itself: the
sweep of bench/bench_sweep.cpp's scene (a 16x16 sheet hung at its corners, 10 frames of 20
substeps) over 1,024 stiffness values, `--repetitions` times per configuration, interleaved.
The rate is the one drape prints (runs / seconds on rank 0, from the first run started to the
last outcome gathered; MPI's start-up and the plan are not in it), and the whole command's
wall time is kept beside it. Every configuration's CSV must equal the 1-rank one, wall times aside.
Writes JSON that tools/bench_report.py turns into the "Sweeps across MPI ranks" section.

    tools/bench_ranks.py --drape build-bench/apps/drape --out docs/sweep_ranks.json

Normally run by tools/bench.sh. Without an MPI launcher, or with a drape built without MPI,
only the 1-rank configurations are measured (and the JSON says why).
"""

import argparse
import csv
import io
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from machine import cpu_model  # noqa: E402

SCENE = {"frames": 10, "dt": 0.001, "substeps": 20,
         "sheets": [{"grid": [16, 16], "size": [1, 1], "stiffness": 100, "mass": 0.3, "damping": 0.02,
                     "anchors": [{"at": "corners", "stiffness": 300}]}]}
RUNS = 1024  # enough that a configuration lasts a good part of a second, and the gather is negligible
CONFIGS = [(1, 1), (1, 2), (2, 1), (2, 2)]  # (ranks, threads per rank)
RATE = re.compile(r"run\(s\) in (\S+) s \((\S+) runs/s\)")


def fail(message):
    print(f"bench_ranks: {message}", file=sys.stderr)
    sys.exit(1)


def rows_without_time(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    at = rows[0].index("wall_time_s")
    return [r[:at] + r[at + 1:] for r in rows]


def mpi_built(drape):
    """Whether this drape was linked with an MPI library (CMake found MPI when it was built)."""
    r = subprocess.run(["ldd", drape], capture_output=True, text=True)
    return "libmpi" in r.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drape", default="build-bench/apps/drape", help="the drape program")
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "", help="MPI launcher (default: mpirun on PATH)")
    ap.add_argument("--repetitions", type=int, default=3)
    ap.add_argument("--out", default="docs/sweep_ranks.json")
    args = ap.parse_args()
    if not os.access(args.drape, os.X_OK):
        fail(f"{args.drape} is not an executable drape program (build the target drape first)")

    note = ""
    configs = CONFIGS
    if not args.mpirun:
        note = "no MPI launcher (mpirun) was found: only one rank was measured"
    elif not mpi_built(args.drape):
        note = f"{args.drape} was built without MPI: only one rank was measured"
    if note:
        configs = [c for c in CONFIGS if c[0] == 1]

    work = tempfile.mkdtemp(prefix="drape_bench_ranks_")
    try:
        scene = os.path.join(work, "sheet.json")
        with open(scene, "w") as f:
            json.dump(SCENE, f)
        values = ",".join(str(50 + k) for k in range(RUNS))
        samples = {c: [] for c in configs}
        reference = None
        for rep in range(args.repetitions):
            for ranks, threads in configs:  # interleaved: a slow spell of a shared machine hits every one
                out = os.path.join(work, f"r{ranks}t{threads}.csv")
                command = [args.drape, "sweep", scene, "--set", f"sheets[*].stiffness={values}", "--threads",
                           str(threads), "--out", out]
                if ranks > 1:
                    command = [args.mpirun, "-np", str(ranks), "--oversubscribe", "--allow-run-as-root"] + command
                start = time.perf_counter()
                r = subprocess.run(command, capture_output=True, text=True, timeout=600)
                wall = time.perf_counter() - start
                if r.returncode != 0:
                    fail(f"{' '.join(command)} failed ({r.returncode}):\n{r.stderr}")
                m = RATE.search(r.stderr)
                if not m:
                    fail(f"no rate in the output of {' '.join(command)}:\n{r.stderr}")
                rows = rows_without_time(out)
                if reference is None:
                    reference = rows
                elif rows != reference:
                    fail(f"{ranks} rank(s) x {threads} thread(s) wrote another CSV than 1 rank x 1 thread")
                samples[(ranks, threads)].append({"sweep_s": float(m.group(1)), "rate": float(m.group(2)),
                                                  "command_s": wall})
    finally:
        shutil.rmtree(work, ignore_errors=True)

    results = []
    for (ranks, threads), s in samples.items():
        rates = [x["rate"] for x in s]
        results.append({"ranks": ranks, "threads_per_rank": threads, "runs": RUNS,
                        "runs_per_s": statistics.median(rates),
                        "cv": statistics.pstdev(rates) / statistics.mean(rates) if len(rates) > 1 else None,
                        "command_s": statistics.median(x["command_s"] for x in s),
                        "samples": s})
    data = {"cpu": cpu_model(), "cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M:%S"),
            "load_avg": list(os.getloadavg()), "scene": SCENE, "runs": RUNS, "repetitions": args.repetitions,
            "csv_identical": True, "note": note, "results": results}
    tmp = args.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, indent=1)
    os.replace(tmp, args.out)
    for r in results:
        print(f"bench_ranks: {r['ranks']} rank(s) x {r['threads_per_rank']} thread(s): {r['runs_per_s']:.1f} runs/s")
    print(f"bench_ranks: wrote {args.out}")


if __name__ == "__main__":
    main()
