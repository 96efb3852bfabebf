#!/usr/bin/env bash
# CTest entry of the browser viewer test (viewer/test/viewer.test.mjs): installs viewer/'s npm
# packages when npm is there and they are missing, then runs the test in headless Chromium.
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
if [[ "${UPDATE_FIGURES:-0}" == 1 ]]; then shot="$root/docs/figures/viewer.png"; fi
exec node "$root/viewer/test/viewer.test.mjs" --server "$server" --probe "$probe" --gen "$gen" \
  --chromium "$CHROMIUM" --screenshot "$shot" ${VIEWER_TEST_ARGS:-}
