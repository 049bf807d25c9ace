#!/usr/bin/env bash
# Sets up a fresh Debian machine, builds drape and runs the small engine demo (one sheet
# pinned at its corners; prints the sag and energies per frame). The main job is run-main.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target drape-demo
"$build"/apps/drape-demo "$@"
