#!/usr/bin/env bash
# Sets up a fresh Debian machine, builds drape (Release, warnings as errors) and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DDRAPE_WERROR=ON >/dev/null
cmake --build "$build" -j"$(nproc)"
ctest --test-dir "$build" --output-on-failure -j"$(nproc)"
