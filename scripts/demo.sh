#!/usr/bin/env bash
# Sets up, then runs the main job on the built-in default and shows the results.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
mkdir -p out
echo "== The conical spring law, paper Figure 6 card (n = 3): deflection,force,stiffness,phase"
build/bin/conica-lab law --G 50 --d 1 --D1 2 --D2 8 --L0 90 --na 3 --from 0 --to 89 --steps 12 \
  --plot out/law.png
echo "== wrote out/law.png"
