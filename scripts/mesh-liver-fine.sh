#!/usr/bin/env bash
# Writes the finer liver mesh that configs/liver-fine-ef30.pbtxt loads: the boundary of
# ../shared/data/meshes/liver2.msh tetrahedralised by TetGen (Debian tetgen), into
# build/meshes/liver-fine.msh (or OUT). Run by scripts/setup.sh; safe to rerun.
#   scripts/mesh-liver-fine.sh [OUT] [VOLUME]     # VOLUME: TetGen's volume bound (liver units^3)
set -euo pipefail
cd "$(dirname "$0")/.."
src=../shared/data/meshes/liver2.msh
out=${1:-build/meshes/liver-fine.msh}
volume=${2:-7e-4}
if [ ! -f "$src" ]; then
  echo "mesh-liver-fine: $src not found: configs/liver-fine-ef30.pbtxt will not load" >&2
  exit 0
fi
/usr/bin/python3 scripts/mesh-liver-fine.py --volume "$volume" "$src" "$out"
