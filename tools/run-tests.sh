#!/usr/bin/env bash
# What CI runs, from a clean clone: sets up a fresh Debian machine, then
#   1. Release build (warnings as errors) and every test, the Python module's pytest suite
#      (Python.Bindings) and the 2-rank MPI tests (Mpi.*) among them;
#   2. the tests again, built with AddressSanitizer + UndefinedBehaviorSanitizer (build-asan;
#      the files compiled per instruction set without the UBSan checks ASan covers there and
#      without ASan's use-after-scope check, see engine/CMakeLists.txt; a few heavy tests run
#      smaller cases of the same code paths under DRAPE_SANITIZED), and with every optional package left out (-DDRAPE_OPTIONAL_PACKAGES=OFF: Bullet, ...), so
#      this stage also proves that a machine with only what tools/setup.sh installs builds
#      the engine, the programs and the tests, whatever else this machine has; it is also the
#      portable build (-DDRAPE_NATIVE=OFF): its baseline is the compiler's default, where
#      stage 1's is this CPU, and both run the same row sweep dispatched at run time;
#   3. a short libFuzzer run of every reader (build-fuzz, clang), seeded with valid files.
# Environment: DRAPE_BUILD_DIR (default build), DRAPE_SKIP_SANITIZE=1, DRAPE_SKIP_FUZZ=1,
# DRAPE_FUZZ_SECONDS (default 15 per target).
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
jobs=$(nproc)
stamp() { echo "run-tests: $1 ($(( SECONDS - started )) s)"; }
started=$SECONDS

# A new build folder is made with Ninja: it compiles a target's objects while the libraries
# it links are still compiling, where Make waits for them, so the row sweep's long files
# (compiled once per instruction set) no longer leave one core idle. A folder configured
# before keeps its generator.
generator() { [[ -f "$1/CMakeCache.txt" ]] || echo "-GNinja"; }

build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" $(generator "$build") -DCMAKE_BUILD_TYPE=Release -DDRAPE_WERROR=ON >/dev/null
cmake --build "$build" -j"$jobs"
ctest --test-dir "$build" --output-on-failure -j"$jobs"
stamp "release build and tests passed"

if [[ "${DRAPE_SKIP_SANITIZE:-0}" != 1 ]]; then
  # -O1 keeps sanitized tests quick while the stack traces stay readable (-g1: line tables, all
  # a trace needs; full debug info made the vector kernels compile 1.8 times longer); the tests, programs
  # and benchmarks themselves are compiled at -O0 there (CMakeLists.txt, drape_keep_optimization),
  # which halves their compile time and leaves the run time as it was. The benchmarks and the
  # report generators in tools/ run no test, so this stage leaves them out (~55 s of CPU):
  # stage 1 builds them, on CI's fresh machine without any optional package, and
  # Build.OptionalPackagesAreGated checks that every optional package is looked for as one.
  # The kernels are compiled here for AVX2 and the scalar target only
  # (HWY_DISABLED_TARGETS = AVX3 | SSE4 on top of engine/src/simd/targets.h's AVX3_DL | SSSE3,
  # bits 8, 11, 7, 12): each target compiles the whole row sweep again, and stage 1 already
  # runs every target this CPU has; dispatch itself is still what runs here. The scalar target
  # is the one a default (x86-64) baseline requires, and it stays: an SSE4 baseline instead
  # (-march=x86-64-v2 -mpclmul -maes, scalar disabled) was measured to compile the row sweep
  # 1.8 times slower under the sanitizers than the scalar target, and would no longer be the
  # compiler's default baseline that this stage promises.
  cmake -S . -B build-asan $(generator build-asan) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
    -DCMAKE_CXX_FLAGS="-DHWY_DISABLED_TARGETS=6528" \
    -DDRAPE_SANITIZE=ON -DDRAPE_WERROR=ON -DDRAPE_OPTIONAL_PACKAGES=OFF -DDRAPE_NATIVE=OFF \
    -DDRAPE_BUILD_BENCH=OFF -DDRAPE_BUILD_TOOLS=OFF | grep "optional packages"
  cmake --build build-asan -j"$jobs"
  ASAN_OPTIONS=abort_on_error=1:detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs"
  stamp "sanitizer build and tests passed"
fi

if [[ "${DRAPE_SKIP_FUZZ:-0}" != 1 ]]; then
  seconds=${DRAPE_FUZZ_SECONDS:-15}
  # The readers are what is fuzzed: the row sweep is compiled for the baseline target only
  # (HWY_DISABLED_TARGETS = AVX3_DL | AVX3 | AVX2 | SSE4 | SSSE3), once instead of four times.
  cmake -S . -B build-fuzz $(generator build-fuzz) -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DDRAPE_FUZZ=ON -DDRAPE_WERROR=ON \
    -DDRAPE_NATIVE=OFF -DCMAKE_CXX_FLAGS="-DHWY_DISABLED_TARGETS=7040" \
    -DDRAPE_BUILD_TESTS=OFF -DDRAPE_BUILD_BENCH=OFF >/dev/null
  # One line per reader: fuzz target, then its seed directories (see tests/fuzz/README.md).
  targets=(
    "checkpoint_fuzz build-fuzz/seeds/checkpoint tests/fuzz/regressions/checkpoint"
    "frame_fuzz tests/fuzz/seeds/frame"
    "scene_fuzz scenes tests/fuzz/regressions/scene"
  )
  cmake --build build-fuzz -j"$jobs" --target checkpoint_seeds $(for t in "${targets[@]}"; do echo "${t%% *}"; done)
  rm -rf build-fuzz/seeds && build-fuzz/tests/fuzz/checkpoint_seeds build-fuzz/seeds/checkpoint
  for entry in "${targets[@]}"; do
    read -r -a words <<<"$entry"
    target=${words[0]}
    corpus=build-fuzz/corpus/$target
    mkdir -p "$corpus" build-fuzz/artifacts
    echo "run-tests: fuzzing $target for $seconds s"
    if ! build-fuzz/tests/fuzz/"$target" -max_total_time="$seconds" -print_final_stats=1 \
        -artifact_prefix=build-fuzz/artifacts/"$target"- "$corpus" "${words[@]:1}" >build-fuzz/"$target".log 2>&1; then
      tail -n 60 build-fuzz/"$target".log
      echo "run-tests: $target found a crash; add the input under build-fuzz/artifacts/ to" \
           "tests/fuzz/regressions/ and fix the reader" >&2
      exit 1
    fi
    grep -E "stat::number_of_executed_units|Done" build-fuzz/"$target".log || true
  done
  stamp "fuzzing found nothing"
fi
