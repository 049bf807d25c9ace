#!/usr/bin/env bash
# Installs the Debian packages drape builds against, only those that are missing.
# Idempotent; prints nothing when everything is already present.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
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

# Packages whose command may come from another package: nodejs from NodeSource carries npm,
# and Debian's npm package then conflicts with it. The command being there is enough.
declare -A command_of=([npm]=npm [nodejs]=node)

missing=()
for p in "${packages[@]}"; do
  if [[ -n "${command_of[$p]:-}" ]] && command -v "${command_of[$p]}" >/dev/null 2>&1; then
    continue
  fi
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
