#!/usr/bin/env python3
"""Measures the portable build beside the native one: docs/benchmarks-portable.json.

Issue 15 asks that a build without -march=native (what a distribution or a Python wheel ships)
run within 10 % of the native build. Run one after the other, minutes apart, the two differ by
as much as a virtual machine's slow spell (25-35 % on the machine of docs/BENCHMARKS.md) however
alike their code is; so this script runs the two drape_bench binaries in alternating rounds of
one repetition each (tools/baseline.py), the order turning every round, and writes the portable
side's runs as a drape_bench JSON with the native side's runs beside them under "native".
tools/bench_report.py judges by the median over the rounds of the ratio within a round.

Usage: tools/portable_pair.py --native BENCH --portable BENCH [--rounds 5] [--out docs/benchmarks-portable.json]
                              [-- drape_bench arguments, e.g. --benchmark_filter=... --benchmark_min_time=0.2]
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from baseline import Recorder  # noqa: E402

recorder = Recorder("portable_pair")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--native", required=True, help="drape_bench of the -DDRAPE_NATIVE=ON build")
    ap.add_argument("--portable", required=True, help="drape_bench of the -DDRAPE_NATIVE=OFF build")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default="docs/benchmarks-portable.json")
    ap.add_argument("bench_args", nargs="*", help="arguments for both binaries (after --)")
    args = ap.parse_args()
    recorder.check_sides(args.rounds, args.native, args.portable)
    sides = {name: ([os.path.abspath(path), *args.bench_args], {})
             for name, path in (("native", args.native), ("portable", args.portable))}
    measured, paired = recorder.pair(sides, args.rounds,
                                     "each round ran the native and the portable drape_bench one after the other, "
                                     "the order turning every round; `native` holds the native side's runs")
    record = measured["portable"]
    record["paired"] = paired
    record["native"] = measured["native"]
    recorder.write(record, args.out)


if __name__ == "__main__":
    main()
