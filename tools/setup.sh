#!/usr/bin/env bash
# Installs the Debian packages drape builds against, only those that are missing.
# Idempotent; prints nothing when everything is already present.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libtbb-dev libhwy-dev libgtest-dev libgmock-dev libbenchmark-dev
  nlohmann-json3-dev libcli11-dev libfmt-dev libpng-dev
  python3 python3-matplotlib
  python3-dev python3-numpy python3-pytest pybind11-dev python3-pybind11  # the Python module and its tests
  libopenmpi-dev openmpi-bin  # sweeps and batches across MPI ranks, and their 2-rank test
  clang libclang-rt-dev  # libFuzzer and the sanitizer runtimes (only recommended by clang)
  nodejs npm chromium    # the browser viewer: built with npm (three.js, esbuild), tested in headless Chromium
)
# Extra packages a caller may ask for, e.g. DRAPE_EXTRA_PACKAGES="clang python3-matplotlib".
if [[ -n "${DRAPE_EXTRA_PACKAGES:-}" ]]; then
  read -r -a extra <<<"${DRAPE_EXTRA_PACKAGES}"
  packages+=("${extra[@]}")
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

sudo=""
[[ $(id -u) -ne 0 ]] && sudo="sudo"
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
