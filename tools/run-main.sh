#!/usr/bin/env bash
# The main job: set up a fresh Debian machine, build drape (Release), simulate every paper
# scene (scenes/fig*.json), the many-sheet scenes (scenes/stack_sphere.json,
# scenes/rain_torus.json), the cloth scene (scenes/flag_wind.json) and the friction scene
# (scenes/tablecloth.json) and draw one PNG per scene into figures/ (git-ignored).
#
#   tools/run-main.sh          figures/figNN.png, figures/stack_sphere.png, figures/rain_torus.png,
#                              figures/flag_wind.png, figures/tablecloth.png
#   tools/run-main.sh --docs   also the smaller copies shown in docs/figures.md (docs/img/figures/)
#
# Constraints (issue 14): scenes/flag_pole.json, cape_sphere.json, curtain_rail.json and
# sewn_box.json, each a strip of frames.
#
# Figures the paper shows as an animation get a strip of frames, left to right, all seen by
# the scene's camera; the frames are chosen where the motion shows (30 frames per second).
# Each picture comes twice: as the paper draws it (wireframe, NAME.png) and shaded
# (NAME_shaded.png: the sheets' uniform B-spline surfaces, lit, front and back in two colours).
set -euo pipefail
cd "$(dirname "$0")/.."

docs=0
case "${1:-}" in
  "") ;;
  --docs) docs=1 ;;
  *) echo "usage: tools/run-main.sh [--docs]" >&2; exit 2 ;;
esac

tools/setup.sh
build=${DRAPE_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)" --target drape >/dev/null
drape="$build/apps/drape"

# figure  frames (empty: the last)  panel size
figures=(
  "fig05 -            960x420"
  "fig06 8,14,91      640x300"
  "fig07 0,8,16,91    400x400"
  "fig08 0,6,12,24,91 400x400"
  "fig09 0,8,14,91    400x380"
  "fig10 0,8,14,91    440x380"
  "fig11 0,8,14,91    440x380"
  "fig12 0,9,11,13,16 400x400"
  "flag_pole    0,8,15,30,45  400x400"
  "cape_sphere  0,15,30,45,90 400x400"
  "curtain_rail 0,20,45,68,90 400x400"
  "sewn_box     0,8,16,30,60  400x400"
)

# Beyond the paper: many sheets with contacts (issue 4), a flag in the wind (issue 12), a
# tablecloth held by friction (issue 13). These take seconds to tens of seconds each, so
# each is simulated once (drape run) and both
# pictures are drawn from its frames.
# scene  frames  panel size
many=(
  "stack_sphere 0,15,45,150 400x400"
  "rain_torus   0,15,30,75 400x400"
  "flag_wind    0,15,45,91 400x400"
  "tablecloth   0,5,10,90  400x400"
)

out=figures
mkdir -p "$out"

# pictures NAME WxH RENDER_ARGS...: the wireframe and the shaded picture, and their half-size
# copies for docs/figures.md with --docs.
pictures() {
  local name=$1 size=$2
  shift 2
  local w=${size%x*} h=${size#*x}
  "$drape" render "$@" --size "$size" -o "$out/$name.png"
  "$drape" render "$@" --size "$size" --style shaded --surface bspline -o "$out/${name}_shaded.png"
  if [[ $docs -eq 1 ]]; then
    "$drape" render "$@" --size "$((w / 2))x$((h / 2))" -o "docs/img/figures/$name.png"
    "$drape" render "$@" --size "$((w / 2))x$((h / 2))" --style shaded --surface bspline \
      -o "docs/img/figures/${name}_shaded.png"
  fi
}
[[ $docs -eq 1 ]] && mkdir -p docs/img/figures
start=$SECONDS
for line in "${figures[@]}"; do
  read -r name frames size <<<"$line"
  args=("scenes/$name.json")
  [[ $frames != - ]] && args+=(--frame "$frames")
  pictures "$name" "$size" "${args[@]}"
done
for line in "${many[@]}"; do
  read -r name frames size <<<"$line"
  frames_dir="$build/many/$name"
  t0=$SECONDS
  if ! log=$("$drape" run "scenes/$name.json" --out "$frames_dir" --threads "$(nproc)" 2>&1); then
    echo "$log" >&2
    exit 1
  fi
  echo "main job: $name simulated in $((SECONDS - t0)) s"
  pictures "$name" "$size" "$frames_dir" --frame "$frames"
done
echo "main job: $(ls "$out"/*.png | wc -l) pictures in $(cd "$out" && pwd)/ ($((SECONDS - start)) s)"
[[ $docs -eq 1 ]] && echo "main job: small copies in $(pwd)/docs/img/figures/"
exit 0
