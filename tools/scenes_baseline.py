#!/usr/bin/env python3
"""Records what the shipped scenes cost with an older commit's engine: docs/scenes-baseline.json.

Issue 13 asks for the many-sheet scenes "at least 10x faster than today"; today has to be
measured, not remembered. This script checks COMMIT out in a scratch git worktree, copies
today's bench/bench_scenes.cpp into it, builds its drape_bench as tools/bench.sh builds
(Release, -march=native, no tests, no Python module), runs the BM_Scene benchmarks on
today's scene files (DRAPE_SCENES_DIR), and writes their results with the commit, the
machine, the compiler and flags, and the load average around the run. tools/bench_report.py
divides each scene's rate in a later run by the one recorded here. The worktree is removed
afterwards.

Because today's bench/bench_scenes.cpp is the one built, the baseline is timed exactly as a later
run is: each scene's span repeated from a fresh world until at least a second is timed (since
issue 13's third step; a baseline recorded before timed each span once, and its short scenes
are noise). Record it again after such a change to the benchmark, with the same commit:

    tools/scenes_baseline.py --commit 0598513 --out docs/scenes-baseline.json

With --current BENCH (tools/bench.sh passes its own drape_bench), today's engine runs the same
scenes in rounds alternating with the baseline's (--rounds, one repetition each), and both sides'
runs go into the record: the report then divides figures measured side by side, round by
round (the median of the ratios within rounds). A scene file with a key newer than the
baseline's loader (NEWER_KEYS) runs on the baseline's side without it; with --current, today's
engine also runs those scenes without it in the same rounds, so the report can divide like for
like (the same physics) beside the scene as shipped (which pays for the newer feature).

Usage: tools/scenes_baseline.py [--commit 0598513] [--current BENCH] [--rounds 5] [--out docs/scenes-baseline.json]
tools/bench.sh runs it before its own measurements; it waits for a quiet machine (load < 0.5)
before it measures.
"""

import argparse
import datetime
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from baseline import Recorder  # noqa: E402
from bench_report import compiler_and_flags  # noqa: E402
from machine import cpu_model  # noqa: E402

# As tools/bench.sh configures its build, so the baseline and a report's run differ only in
# the engine's code.
CMAKE_OPTIONS = ["-DCMAKE_BUILD_TYPE=Release", "-DDRAPE_NATIVE=ON", "-DDRAPE_WERROR=ON", "-DDRAPE_BUILD_TESTS=OFF",
                 "-DDRAPE_BUILD_APPS=ON", "-DDRAPE_BUILD_PYTHON=OFF", "-DDRAPE_BUILD_TOOLS=OFF"]
BENCH_SOURCE = "bench/bench_scenes.cpp"
# Top-level scene keys added after the baseline commit, which its loader refuses: the baseline
# runs each scene without them (the engine then had no such feature), today's build with them,
# and, for the scenes that had any, once more without them in the same rounds (like for like).
NEWER_KEYS = ("contact_rims",)


def scenes_without_newer_keys(scenes_dir, out_dir):
    """Copies of the scene files with NEWER_KEYS removed, in out_dir; returns out_dir and, per scene
    that had any, the keys removed from it."""
    os.makedirs(out_dir)
    removed = {}
    for name in os.listdir(scenes_dir):
        path = os.path.join(scenes_dir, name)
        if not name.endswith(".json"):
            shutil.copy(path, out_dir)
            continue
        with open(path) as f:
            scene = json.load(f)
        keys = [key for key in NEWER_KEYS if key in scene]
        for key in keys:
            del scene[key]
        if keys:
            removed[name[:-len(".json")]] = keys
        with open(os.path.join(out_dir, name), "w") as f:
            json.dump(scene, f, indent=2)
    return out_dir, removed


recorder = Recorder("scenes_baseline")
fail, git, run = recorder.fail, recorder.git, recorder.run


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", default="0598513", help="the commit whose engine is the baseline")
    ap.add_argument("--out", default="docs/scenes-baseline.json")
    ap.add_argument("--current", default=None, help="today's drape_bench, run in rounds alternating with the baseline's")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of one repetition each (the fastest is reported)")
    ap.add_argument("--scratch", default=None,
                    help="folder for the worktree and its build (must not exist; default: a new one under $TMPDIR). "
                         "Beside this checkout, with CCACHE_BASEDIR set above both, ccache reuses unchanged objects")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel build jobs")
    args = ap.parse_args()

    if args.rounds < 1:
        fail(f"--rounds {args.rounds}: give at least 1")
    if args.current and not os.access(args.current, os.X_OK):
        fail(f"--current {args.current}: not an executable drape_bench")
    repo = git(os.path.dirname(os.path.abspath(__file__)), "rev-parse", "--show-toplevel")
    commit = git(repo, "rev-parse", "--verify", args.commit + "^{commit}")
    subject = git(repo, "log", "-1", "--format=%s", commit)
    source = os.path.join(repo, BENCH_SOURCE)
    scenes_dir = os.path.join(repo, "scenes")
    if not os.path.isfile(source):
        fail(f"{source} is missing")

    if args.scratch and os.path.exists(args.scratch):
        fail(f"--scratch {args.scratch} exists; give a new folder")
    tree = os.path.abspath(args.scratch) if args.scratch else tempfile.mkdtemp(prefix=f"drape-baseline-{commit[:7]}-")
    git(repo, "worktree", "add", "--detach", tree, commit)
    try:
        shutil.copy(source, os.path.join(tree, BENCH_SOURCE))
        build = os.path.join(tree, "build")
        launcher = ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"] if shutil.which("ccache") else []
        run(["cmake", "-S", tree, "-B", build, *CMAKE_OPTIONS, *launcher], stdout=subprocess.DEVNULL)
        run(["nice", "-n", "5", "cmake", "--build", build, "--target", "drape_bench", f"-j{args.jobs}"],
            stdout=subprocess.DEVNULL)
        command = [os.path.join(build, "bench", "drape_bench"), "--benchmark_filter=^BM_Scene/"]
        env = {"DRAPE_SCENES_DIR": scenes_dir}
        old_scenes, removed = scenes_without_newer_keys(scenes_dir, os.path.join(tree, "scenes-baseline"))
        old_env = {"DRAPE_SCENES_DIR": old_scenes}
        sides = {"baseline": (command, old_env)}
        if args.current:
            sides["current"] = ([os.path.abspath(args.current), *command[1:]], env)
            if removed:  # like for like: today's engine on the files the baseline ran, those scenes only
                sides["current_without_newer_keys"] = (
                    [os.path.abspath(args.current), f"--benchmark_filter=^BM_Scene/({'|'.join(sorted(removed))})/"],
                    old_env)
        load_before = recorder.settle()
        measured = recorder.alternate(sides, args.rounds)
        load_after = list(os.getloadavg())
        results = measured["baseline"]
        compiler, flags = compiler_and_flags(build)
    finally:
        subprocess.run(["git", "-C", repo, "worktree", "remove", "--force", tree], capture_output=True)
        shutil.rmtree(tree, ignore_errors=True)
        subprocess.run(["git", "-C", repo, "worktree", "prune"], capture_output=True)

    names = sorted({m.group(1) for b in results.get("benchmarks", [])
                    if (m := re.match(r"BM_Scene/(\w+)/", b.get("run_name", b["name"])))})
    if not names:
        fail("the run produced no BM_Scene results")
    scene_sha256 = {}
    for name in names:
        with open(os.path.join(scenes_dir, name + ".json"), "rb") as f:
            scene_sha256[name] = hashlib.sha256(f.read()).hexdigest()
    record = {
        "what": "BM_Scene (bench/bench_scenes.cpp) built against the engine of `commit`, run on the scene files "
                "whose hashes are listed; tools/bench_report.py divides later rates by these",
        "commit": commit,
        "commit_subject": subject,
        "scenes_from": git(repo, "rev-parse", "HEAD"),
        "scene_sha256": scene_sha256,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpu": cpu_model(), "logical_cores": os.cpu_count()},
        "compiler": compiler,
        "flags": flags,
        "cmake_options": CMAKE_OPTIONS,
        "command": [os.path.relpath(command[0], tree), *command[1:]],
        "rounds": args.rounds,
        "load_avg_before": load_before,
        "load_avg_after": load_after,
        "note": "measured on a shared 2-core machine; the load averages say how busy it was",
        "results": results,
        "newer_keys_removed": removed,
    }
    if args.current:
        record["current"] = {"what": "today's drape_bench on the same scene files, each round run right before or "
                                     "after the baseline's", "binary": os.path.abspath(args.current),
                             "results": measured["current"]}
    if "current_without_newer_keys" in measured:
        record["current_without_newer_keys"] = {
            "what": "today's drape_bench on the scene files as the baseline ran them (newer_keys_removed taken out), "
                    "in the same rounds: the same physics on both sides",
            "binary": os.path.abspath(args.current), "results": measured["current_without_newer_keys"]}
    recorder.write(record, args.out)


if __name__ == "__main__":
    main()
