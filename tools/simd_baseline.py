#!/usr/bin/env python3
"""Records issue 15's "today" on an AVX2 machine: docs/simd-baseline.json.

Issue 15 asks, on a CPU with AVX2 and no AVX-512, for the 1024-point sheet step and the 48
sheets at least 3x faster than "today": the engine before the Highway kernels (cf9ea80),
built with -march=native on such a CPU, whose loops the compiler left scalar. This script
extracts COMMIT's tree (git archive, no worktree) into a scratch folder, builds its own
drape_bench as tools/bench.sh builds (Release, no tests, apps or Python module), with
-march=MARCH instead of -march=native (x86-64-v3 is AVX2 without AVX-512, what such a CPU's
-march=native gives the vectoriser), runs the benchmarks the issue names, and writes their
results with the commit, the CPU, the compiler and flags and the load average around the
run. tools/bench_report.py divides the portable build's rates held to AVX2 by these: those
measured beside them (below), else those of docs/benchmarks-AVX2.json.

With --current BENCH (tools/bench.sh passes its portable build's drape_bench), that binary held
to AVX2 (DRAPE_SIMD_TARGET=AVX2) runs the same benchmarks in alternating rounds with the old one
(--rounds, one repetition each), and both sides' runs go into the record: the report then
divides figures measured side by side, round by round (the median of the ratios within rounds).

Usage: tools/simd_baseline.py [--commit cf9ea80] [--march x86-64-v3] [--current BENCH] [--rounds 5]
                              [--out docs/simd-baseline.json]
tools/bench.sh runs it before its own measurements; it waits for a quiet machine (load < 0.5)
before it measures.
"""

import argparse
import datetime
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from baseline import Recorder  # noqa: E402
from bench_report import compiler_and_flags  # noqa: E402
from machine import cpu_model  # noqa: E402

# The benchmarks of issue 15's targets, under the names they had then and have now.
FILTER = "^BM_(Paper1000Points/32|Sheets48_f(64|32)/threads:1/real_time)$"


recorder = Recorder("simd_baseline")
fail, git, run = recorder.fail, recorder.git, recorder.run


def cpu_flags():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", default="cf9ea80", help="the engine before the Highway kernels")
    ap.add_argument("--march", default="x86-64-v3", help="what -march=native gives on an AVX2 CPU")
    ap.add_argument("--out", default="docs/simd-baseline.json")
    ap.add_argument("--current", default=None,
                    help="today's portable drape_bench, run held to AVX2 in rounds alternating with the baseline's")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of one repetition each (the fastest is reported)")
    ap.add_argument("--scratch", default=None,
                    help="folder for the tree and its build (must not exist; default: a new one under $TMPDIR)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel build jobs")
    args = ap.parse_args()

    if args.rounds < 1:
        fail(f"--rounds {args.rounds}: give at least 1")
    if args.current and not os.access(args.current, os.X_OK):
        fail(f"--current {args.current}: not an executable drape_bench")
    if "avx2" not in cpu_flags():
        fail("this CPU has no AVX2: the baseline would not run")
    repo = git(os.path.dirname(os.path.abspath(__file__)), "rev-parse", "--show-toplevel")
    commit = git(repo, "rev-parse", "--verify", args.commit + "^{commit}")
    subject = git(repo, "log", "-1", "--format=%s", commit)
    if args.scratch and os.path.exists(args.scratch):
        fail(f"--scratch {args.scratch} exists; give a new folder")
    scratch = os.path.abspath(args.scratch) if args.scratch else tempfile.mkdtemp(prefix=f"drape-simd-{commit[:7]}-")
    os.makedirs(scratch, exist_ok=True)
    cmake_options = ["-DCMAKE_BUILD_TYPE=Release", "-DDRAPE_NATIVE=OFF", f"-DCMAKE_CXX_FLAGS=-march={args.march}",
                     "-DDRAPE_BUILD_TESTS=OFF", "-DDRAPE_BUILD_APPS=OFF", "-DDRAPE_BUILD_PYTHON=OFF",
                     "-DDRAPE_BUILD_TOOLS=OFF"]
    try:
        tree = os.path.join(scratch, "src")
        os.makedirs(tree)
        archive = subprocess.Popen(["git", "-C", repo, "archive", commit], stdout=subprocess.PIPE)
        run(["tar", "-x", "-C", tree], stdin=archive.stdout)
        if archive.wait() != 0:
            fail(f"git archive {commit} failed")
        build = os.path.join(scratch, "build")
        launcher = ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"] if shutil.which("ccache") else []
        run(["cmake", "-S", tree, "-B", build, *cmake_options, *launcher], stdout=subprocess.DEVNULL)
        run(["nice", "-n", "5", "cmake", "--build", build, "--target", "drape_bench", f"-j{args.jobs}"],
            stdout=subprocess.DEVNULL)
        command = [os.path.join(build, "bench", "drape_bench"), f"--benchmark_filter={FILTER}"]
        sides = {"baseline": (command, {})}
        if args.current:
            sides["current"] = ([os.path.abspath(args.current), f"--benchmark_filter={FILTER}"],
                                {"DRAPE_SIMD_TARGET": "AVX2"})
        load_before = recorder.settle()
        measured = recorder.alternate(sides, args.rounds)
        load_after = list(os.getloadavg())
        results = measured["baseline"]
        compiler, flags = compiler_and_flags(build)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)

    if not results.get("benchmarks"):
        fail("the run produced no results")
    record = {
        "what": "issue 15's 'today': drape_bench of `commit` (before the Highway kernels) built for an AVX2 CPU "
                "(-march=`march`); tools/bench_report.py divides the AVX2-held portable run's rates by these",
        "commit": commit,
        "commit_subject": subject,
        "march": args.march,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpu": cpu_model(), "logical_cores": os.cpu_count(), "avx512f": "avx512f" in cpu_flags()},
        "compiler": compiler,
        "flags": flags,
        "cmake_options": cmake_options,
        "command": [os.path.relpath(command[0], scratch), *command[1:]],
        "rounds": args.rounds,
        "load_avg_before": load_before,
        "load_avg_after": load_after,
        "note": "the load averages say how busy the machine was",
        "results": results,
    }
    if args.current:
        record["current"] = {"what": "today's portable drape_bench held to AVX2 (DRAPE_SIMD_TARGET=AVX2), "
                                     "each round run right before or after the baseline's",
                             "binary": os.path.abspath(args.current), "results": measured["current"]}
    recorder.write(record, args.out)


if __name__ == "__main__":
    main()
