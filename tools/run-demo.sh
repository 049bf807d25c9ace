#!/usr/bin/env bash
# Sets up a fresh Debian machine, builds drape and runs the main job.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target drape-demo
"$build"/apps/drape-demo "$@"
