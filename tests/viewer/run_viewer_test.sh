#!/usr/bin/env bash
# CTest entry of the browser viewer test (viewer/test/viewer.test.mjs): installs viewer/'s npm
# packages when npm is there and they are missing, then runs the test in headless Chromium twice:
# on the default scene (the cube, or VIEWER_TEST_ARGS), and on a body too large for the page to
# draw every frame (configs/block-20k.pbtxt, 21,952 nodes, its loop at 30 Hz), where frames must
# be dropped and the frame age must stay bounded. VIEWER_TEST_LARGE=0 skips the second run.
# Exits 77 (CTest: skipped) with a message only when chromium, node or npm is not installed;
# scripts/viewer-setup.sh installs them, and .ci/run calls it.
#   tests/viewer/run_viewer_test.sh SERVER PROBE PROTO_GEN_DIR SCREENSHOT
# UPDATE_FIGURES=1 writes the screenshot to docs/figures/viewer.png instead of SCREENSHOT.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
server=$1 probe=$2 gen=$3 shot=$4
CHROMIUM=${CHROMIUM:-/usr/bin/chromium}

for need in "$CHROMIUM" node npm; do
  if ! command -v "$need" >/dev/null; then
    echo "SKIPPED: $need is not installed (scripts/viewer-setup.sh installs it)"
    exit 77
  fi
done
if ! /usr/bin/python3 -c "import websockets" 2>/dev/null; then
  echo "SKIPPED: python3-websockets is not installed (scripts/viewer-setup.sh installs it)"
  exit 77
fi
"$root/scripts/viewer-setup.sh" --no-apt
large=${VIEWER_TEST_LARGE:-1}
if [[ "${UPDATE_FIGURES:-0}" == 1 ]]; then shot="$root/docs/figures/viewer.png" large=0; fi
node "$root/viewer/test/viewer.test.mjs" --server "$server" --probe "$probe" --gen "$gen" \
  --chromium "$CHROMIUM" --screenshot "$shot" ${VIEWER_TEST_ARGS:-}
if [[ "$large" == 1 ]]; then
  echo "== a large body: configs/block-20k.pbtxt"
  node "$root/viewer/test/viewer.test.mjs" --server "$server" --probe "$probe" --gen "$gen" \
    --chromium "$CHROMIUM" --screenshot "${shot%.png}-large.png" \
    --scene "$root/configs/block-20k.pbtxt" --server-args "--rate-hz 30" --probe-radius 0.008
fi
