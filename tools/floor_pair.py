#!/usr/bin/env python3
"""Measures the floor against the bare world in alternating rounds: docs/benchmarks-floor.json.

Issue 13 asks that a floor (eq 9) under every point cost at most 40 % more per substep than the
bare world (BM_Feature_bare and BM_Feature_obstacle in bench/bench_features.cpp, 48 sheets of
64×64 on one thread). In the main run of tools/bench.sh the two are separate repetitions minutes
apart, and a slow spell of the machine during one of them (25-35 % on the machine of
docs/BENCHMARKS.md) decides the verdict: two reports in a row read +11 % and +41 %. So this
script runs each of the benchmarks (the bare world, the floor, the floor with friction, with
damping) as its own side, one repetition per round, the order turning every round (tools/baseline.py), all from
the same drape_bench binary, and writes every side's runs into one drape_bench JSON.
tools/bench_report.py shows the fastest of each benchmark's rounds and judges the floor by the median
over the rounds of the price within a round. The stacked sheets in contact with friction and
damping between them (issue 13's pricing of the contact terms) are paired the same way against
the plain stack, and the same floor in the machine ceiling (bench/bench_ceiling.cpp) against the
ceiling's bare step, which prices the floor's own arithmetic with no engine around it. The bare
world is paired with the bare kernel (BM_Feature_kernel_only) too, for issue 6's overhead of the
World around the kernel, which the report judges from these rounds as well.

Usage: tools/floor_pair.py --bench BENCH [--rounds 5] [--out docs/benchmarks-floor.json]
                           [--benchmarks BM_Feature_bare BM_Feature_obstacle ...]
                           [-- drape_bench arguments, e.g. --benchmark_min_time=0.2]
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from baseline import Recorder  # noqa: E402

recorder = Recorder("floor_pair")
BENCHMARKS = ["BM_Feature_bare", "BM_Feature_obstacle", "BM_Feature_obstacle_friction", "BM_Feature_obstacle_damping",
              "BM_CeilingSheets48", "BM_CeilingSheets48Floor/full_gradient:0", "BM_CeilingSheets48Floor/full_gradient:1",
              "BM_World48SheetsInContact/1/real_time", "BM_World48SheetsInContactDissipative/0/real_time",
              "BM_World48SheetsInContactDissipative/1/real_time", "BM_World48SheetsInContactDissipative/2/real_time",
              "BM_Feature_kernel_only"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", required=True, help="drape_bench (tools/bench.sh's native build)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default="docs/benchmarks-floor.json")
    ap.add_argument("--benchmarks", nargs="+", default=BENCHMARKS, help="the benchmarks paired, one side each")
    ap.add_argument("bench_args", nargs="*", help="arguments for every run (after --)")
    args = ap.parse_args()
    recorder.check_sides(args.rounds, args.bench)
    bench = os.path.abspath(args.bench)
    # a side's name names its files: no "/" of a benchmark's arguments in it
    side = {name: name.replace("/", "_") for name in args.benchmarks}
    sides = {side[name]: ([bench, f"--benchmark_filter=^{name}$", *args.bench_args], {}) for name in args.benchmarks}
    measured, paired = recorder.pair(sides, args.rounds,
                                     "each round ran every benchmark once, one drape_bench process each, one after "
                                     "the other, the order turning every round; `benchmarks` holds every round's run")
    record = measured[side[args.benchmarks[0]]]
    for name in args.benchmarks[1:]:
        record["benchmarks"] += measured[side[name]]["benchmarks"]
    record["paired"] = paired
    recorder.write(record, args.out)


if __name__ == "__main__":
    main()
