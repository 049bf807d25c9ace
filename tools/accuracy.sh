#!/usr/bin/env bash
# Measures accuracy against speed for every integrator and precision and writes
# docs/accuracy.md, docs/img/accuracy_*.png and the raw CSV files in docs/data/.
# Usage: tools/accuracy.sh [--quick]   (a few minutes on 2 cores, most of it the stiff sheets; --quick: a smoke run into build/)
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh
build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target drape-accuracy -j"$(nproc)"
# Debian's python3 has python3-matplotlib; a python3 earlier on PATH may not.
python=python3
for candidate in python3 /usr/bin/python3; do
  if "$candidate" -c "import matplotlib" 2>/dev/null; then python=$candidate; break; fi
done
if [[ "${1:-}" == "--quick" ]]; then
  out="$build/accuracy-quick"
  mkdir -p "$out/data"
  "$build/tools/accuracy/drape-accuracy" "$out/data" --quick
  "$python" tools/accuracy_report.py "$out/data" "$out"
  echo "accuracy: quick report in $out/accuracy.md"
else
  mkdir -p docs/data docs/img
  "$build/tools/accuracy/drape-accuracy" docs/data
  "$python" tools/accuracy_report.py docs/data docs
  echo "accuracy: wrote docs/accuracy.md, docs/img/accuracy_*.png, docs/data/accuracy_*.csv"
fi
