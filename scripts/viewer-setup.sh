#!/usr/bin/env bash
# Installs what the browser viewer and its test need: Debian's chromium, nodejs and npm, and
# python3-websockets for the bridge (apt-get), then three.js and playwright-core into
# viewer/node_modules from viewer/package-lock.json. Safe to rerun.
#   scripts/viewer-setup.sh            # Debian packages + npm
#   scripts/viewer-setup.sh --no-apt   # npm only
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" != "--no-apt" ]]; then
  PACKAGES=(chromium nodejs npm python3-websockets python3-zmq python3-protobuf)
  wanted=()
  for p in "${PACKAGES[@]}"; do
    # node and npm may come from elsewhere than Debian: keep them if they work
    if [[ $p == nodejs ]] && command -v node >/dev/null; then continue; fi
    if [[ $p == npm ]] && command -v npm >/dev/null; then continue; fi
    wanted+=("$p")
  done
  source scripts/apt-ensure.sh
  apt_ensure viewer-setup "${wanted[@]}"
fi

cd viewer
if [[ -f node_modules/.package-lock.json && node_modules/.package-lock.json -nt package-lock.json ]] \
   && [[ -d node_modules/three && -d node_modules/playwright-core ]]; then
  exit 0  # already installed from this lock file
fi
echo "viewer-setup: npm ci in viewer/"
npm ci --no-audit --no-fund --loglevel=error
