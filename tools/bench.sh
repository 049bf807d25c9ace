#!/usr/bin/env bash
# Runs drape's benchmark suite and regenerates docs/BENCHMARKS.md and docs/img/*.png.
#
# Build: Release (-O3 -DNDEBUG) with -march=native and -fno-math-errno (see the top-level
# CMakeLists.txt, drape_flags), in its own build directory so a Debug or sanitizer build in
# build/ is never measured. Run: one drape_bench process, every benchmark --benchmark_repetitions
# times for --benchmark_min_time seconds each, repetitions of different benchmarks randomly
# interleaved so a slow spell of a shared machine does not land on one benchmark; the report
# uses the medians.
#
# Environment (all optional):
#   DRAPE_BENCH_BUILD_DIR   build directory              (build-bench)
#   DRAPE_BENCH_MIN_TIME    seconds per repetition        (0.2)
#   DRAPE_BENCH_REPETITIONS repetitions per benchmark     (3)
#   DRAPE_BENCH_ROUNDS      alternating rounds of a baseline and today's binary (5)
#   DRAPE_BENCH_SETTLE      most seconds to wait for a quiet machine before each run (300)
#   DRAPE_BENCH_BASELINES   1: record the two baselines again in this run (default); 0: use
#                           docs/simd-baseline.json and docs/scenes-baseline.json as they are
#                           (with the runs of today's binary recorded beside them then)
#   PYTHON                  interpreter with matplotlib   (/usr/bin/python3, Debian's)
# Extra arguments go to drape_bench, e.g. --benchmark_filter=Fig13 for a partial report.
set -euo pipefail
cd "$(dirname "$0")/.."
# libbullet-dev: the comparison with Bullet's soft bodies (bench/bench_bullet.cpp), which
# only the benchmarks need.
DRAPE_EXTRA_PACKAGES="${DRAPE_EXTRA_PACKAGES:-} libbullet-dev" tools/setup.sh
build=${DRAPE_BENCH_BUILD_DIR:-build-bench}
min_time=${DRAPE_BENCH_MIN_TIME:-0.2}
repetitions=${DRAPE_BENCH_REPETITIONS:-3}
rounds=${DRAPE_BENCH_ROUNDS:-5}
python=${PYTHON:-/usr/bin/python3}
json=docs/benchmarks.json

# Without the Python module, whose shared object would make the engine position-independent:
# the engine is measured as a program links it.
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DDRAPE_NATIVE=ON -DDRAPE_WERROR=ON \
  -DDRAPE_BUILD_TESTS=OFF -DDRAPE_BUILD_APPS=ON -DDRAPE_BUILD_PYTHON=OFF >/dev/null
cmake --build "$build" --target drape_bench drape -j"$(nproc)"
# The portable build (issue 15): no -march=native, as a distribution ships drape; its kernels
# pick their instruction set at run time. Built now, before anything is measured, so that no
# compile shares the CPU with a benchmark (the report compares it with the native run).
cmake -S . -B "$build-portable" -DCMAKE_BUILD_TYPE=Release -DDRAPE_NATIVE=OFF -DDRAPE_WERROR=ON \
  -DDRAPE_BUILD_TESTS=OFF -DDRAPE_BUILD_APPS=OFF -DDRAPE_BUILD_PYTHON=OFF -DDRAPE_BUILD_TOOLS=OFF >/dev/null
cmake --build "$build-portable" --target drape_bench -j"$(nproc)"

# Waits (at most DRAPE_BENCH_SETTLE seconds, default 300) until the 1-minute load average is
# below 0.5: the builds above, or anything else running, would otherwise share the cores
# with the first benchmarks. The report prints the load each run started at.
settle() {
  local waited=0 limit=${DRAPE_BENCH_SETTLE:-300}
  while awk '{exit !($1 >= 0.5)}' /proc/loadavg && (( waited < limit )); do
    sleep 10
    waited=$(( waited + 10 ))
  done
  echo "bench: starting $1 at load $(cut -d' ' -f1-3 /proc/loadavg) (waited ${waited} s)"
}

# The baselines the report divides by (issue 13's scenes before the contact work, issue 15's
# engine before the vector kernels on AVX2), recorded again here so that the ratios come from
# one run on one machine: recorded at another time, a virtual machine's slow spell (quiet
# or not) moves a ratio as much as a change does. Each script builds its old commit (its
# default) in a scratch folder, waits for a quiet machine, runs the old binary and today's
# (the builds above) in alternating rounds, one repetition each, and writes both sides'
# runs to its docs/*-baseline.json; the report judges by the median of the ratios within rounds.
if [[ "${DRAPE_BENCH_BASELINES:-1}" != 0 ]]; then
  "$python" tools/simd_baseline.py --current "$build-portable/bench/drape_bench" --rounds "$rounds"
  "$python" tools/scenes_baseline.py --current "$build/bench/drape_bench" --rounds "$rounds"
fi

mkdir -p docs/img
command=("$build/bench/drape_bench" "--benchmark_min_time=$min_time" "--benchmark_repetitions=$repetitions"
  --benchmark_enable_random_interleaving=true --benchmark_report_aggregates_only=true "$@")
# Written next to the report only when the run completes, so a failed run leaves the old one.
settle "the native run"
"${command[@]}" --benchmark_out="$json.tmp" --benchmark_out_format=json
mv "$json.tmp" "$json"
# drape sweep at 1 and 2 MPI ranks × 1 and 2 threads: mpirun cannot run inside Google Benchmark,
# so a script times the program (docs/sweep_ranks.json, read by the report).
settle "the MPI sweep"
"$python" tools/bench_ranks.py --drape "$build/apps/drape" --out docs/sweep_ranks.json
# The portable build against the native one (docs/benchmarks-portable.json): the figures the
# report compares, the two binaries in alternating rounds of one repetition each, so that both
# see the same slow spells of the machine (tools/portable_pair.py).
portable_json=docs/benchmarks-portable.json
settle "the portable run"
"$python" tools/portable_pair.py --native "$build/bench/drape_bench" --portable "$build-portable/bench/drape_bench" \
  --rounds "$rounds" --out "$portable_json" -- "--benchmark_min_time=$min_time" \
  "--benchmark_filter=^BM_(Sheets48_f|HugeSheet|Fig13/semi_implicit_euler/f64/|Paper1000Points|CeilingSheets48($|Frames)|ArithmeticBound)"
# Issue 13's floor against the bare world (docs/benchmarks-floor.json): BM_Feature_bare,
# BM_Feature_obstacle and its friction and damping variants, the bare kernel (issue 6's overhead of
# the World around it, judged from these rounds too), and the stacked sheets with and
# without friction and damping between them, from the native binary in alternating rounds of one
# repetition each (tools/floor_pair.py). In the main run they are repetitions minutes apart,
# and a slow spell during one of them once moved the floor's price from +11 % to +41 %; the report
# judges the floor by the median over these rounds of the price within a round.
floor_json=docs/benchmarks-floor.json
settle "the floor paired with the bare world"
"$python" tools/floor_pair.py --bench "$build/bench/drape_bench" --rounds "$rounds" --out "$floor_json" \
  -- "--benchmark_min_time=$min_time"
# The same binary held to lower instruction sets (DRAPE_SIMD_TARGET, read by bench_simd.cpp):
# how it runs on a CPU with AVX2 but no AVX-512, or SSE4 only (docs/benchmarks-<set>.json).
forced_json=()
for set in AVX2 SSE4; do
  out="docs/benchmarks-$set.json"
  settle "the portable run held to $set"
  DRAPE_SIMD_TARGET=$set "$build-portable/bench/drape_bench" "--benchmark_min_time=$min_time" \
    "--benchmark_repetitions=$repetitions" --benchmark_enable_random_interleaving=true \
    --benchmark_report_aggregates_only=true \
    "--benchmark_filter=^BM_(Sheets48_f|Fig13/semi_implicit_euler/f64/1024|Paper1000Points|CeilingSheets48$|ArithmeticBound)" \
    --benchmark_out="$out.tmp" --benchmark_out_format=json >/dev/null
  mv "$out.tmp" "$out"
  forced_json+=("$out")
done
"$python" tools/bench_report.py --json "$json" --build-dir "$build" --out docs/BENCHMARKS.md --img docs/img \
  --portable-json "$portable_json" --floor-json "$floor_json" --forced-json "${forced_json[@]}" --command "tools/bench.sh (${command[*]:1})"
