#!/usr/bin/env bash
# Regenerates the README's figures in docs/figures/ in one command:
#   - the conical law (paper Figures 6 and 7)          scripts/make_law_figures.sh
#   - the phantom fits, Figure 14 and Table 4          scripts/reproduce_paper.sh (minutes)
#   - the browser viewer during a press                 tests/viewer/run_viewer_test.sh
#   - the integrator stability map                      conica-lab stability
#   - the speed / accuracy trade-off                    conica-lab tradeoff
# A step whose program or script is missing is skipped with a message; any other failure stops.
#   scripts/make_figures.sh                 (uses build/; BUILD_DIR=... for another build)
#   scripts/make_figures.sh --no-paper      (skip the phantom fits, the slow part)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${BUILD_DIR:-build}"
BIN="$BUILD/bin"
FIG=docs/figures
paper=1
[[ "${1:-}" == "--no-paper" ]] && paper=0
mkdir -p "$FIG"
skipped=()
skip() { echo "make_figures: skipping $1: $2"; skipped+=("$1"); }
has_subcommand() { [[ -x "$BIN/conica-lab" ]] && "$BIN/conica-lab" --help 2>/dev/null | grep -qE "^ +$1 "; }

# 1. the law, and the paper reproduction (which redraws the law figures itself)
if ((paper)) && [[ -x scripts/reproduce_paper.sh ]]; then
  echo "== paper reproduction (law, phantom fits, Figure 14, Table 4)"
  BUILD_DIR="$BUILD" scripts/reproduce_paper.sh
elif [[ -x scripts/make_law_figures.sh ]]; then
  ((paper)) && skip "paper reproduction" "scripts/reproduce_paper.sh not found"
  echo "== law figures"
  BUILD_DIR="$BUILD" scripts/make_law_figures.sh
else
  skip "law figures" "scripts/make_law_figures.sh not found"
fi

# 2. the viewer: server + bridge + headless Chromium, screenshot during a scripted press
if [[ -x "$BIN/conica-server" && -x "$BIN/conica-probe" && -d "$BUILD/proto/gen" ]]; then
  echo "== viewer screenshot"
  # the liver of the paper's Figure 15 when its mesh is there, pressed from the top; else the cube
  liver_args=""
  if [[ -f ../shared/data/meshes/liver2.msh ]]; then
    liver_args="--scene configs/liver.pbtxt --at -0.0485,0.0716,-0.0093 --axis -y --depth 0.01"
    liver_args+=" --probe-radius 0.01 --up y"
  fi
  set +e
  VIEWER_TEST_ARGS="$liver_args" UPDATE_FIGURES=1 tests/viewer/run_viewer_test.sh "$BIN/conica-server" "$BIN/conica-probe" \
    "$BUILD/proto/gen" "$FIG/viewer.png"
  rc=$?
  set -e
  if ((rc == 77)); then
    skip "viewer screenshot" "chromium, node or npm missing (scripts/viewer-setup.sh)"
  elif ((rc != 0)); then
    echo "make_figures: the viewer test failed" >&2
    exit "$rc"
  fi
else
  skip "viewer screenshot" "$BIN/conica-server, conica-probe or $BUILD/proto/gen not built"
fi

# 3. integrator stability map
if has_subcommand stability; then
  echo "== stability map"
  "$BIN/conica-lab" stability --out "$FIG/stability"
else
  skip "stability map" "conica-lab has no 'stability' subcommand in $BIN"
fi

# 4. speed / accuracy trade-off
if has_subcommand tradeoff; then
  echo "== speed / accuracy trade-off"
  "$BIN/conica-lab" tradeoff --out "$FIG/tradeoff"
else
  skip "speed/accuracy chart" "conica-lab has no 'tradeoff' subcommand in $BIN"
fi

echo "make_figures: figures in $FIG/:"
ls "$FIG"/*.png | sed 's/^/  /'
if ((${#skipped[@]})); then
  echo "make_figures: skipped: ${skipped[*]}"
fi
