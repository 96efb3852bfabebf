#!/usr/bin/env bash
# Serves a scene with conica-server and presses it in real time with conica-probe, as the served
# tables of docs/performance.md ("Multi-rate serving", "Surface contact, multi-rate") were made:
# 1 mm approach, 4 mm press at 10 mm/s, 1.5 s hold, the probe at 1 kHz. Prints the server's loop
# and body statistics (one line a second) and the press peak, the hold's mean force and its std
# (the hold's last second). --surface serves a copy of the scene with `contact: SURFACE` in its
# probe block instead of what it says (written next to it, for the mesh paths, and removed after).
#   scripts/serve_press.sh configs/liver-ef30.pbtxt -0.0739,0.0753,-0.0149 -y [--surface]
#   scripts/serve_press.sh configs/phantom-ef30.pbtxt 0,0,0.035 -z --surface
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 3 ] || { echo "usage: $0 SCENE AT AXIS [--surface]" >&2; exit 2; }
scene=$1 at=$2 axis=$3
bin=${BUILD_DIR:-build}/bin
out=$(mktemp -d)
if [ "${4:-}" = --surface ]; then
  copy="$(dirname "$scene")/.surface-$(basename "$scene")"
  sed -E -e '/^probe \{/s/ contact: [A-Z_]+//' -e 's/^(probe \{[^}]*)\}/\1contact: SURFACE }/' "$scene" >"$copy"
  grep -q 'contact: SURFACE' "$copy" || { echo "$scene: no one-line probe block to switch" >&2; rm -f "$copy"; exit 2; }
  trap 'rm -f "$copy"' EXIT
  scene=$copy
fi
"$bin/conica-server" --scene "$scene" --seconds 12 --stats-seconds 1 >"$out/server.log" 2>&1 &
server=$!
sleep 3
"$bin/conica-probe" --script press --at "$at" --axis "$axis" --depth 0.004 --approach 0.001 \
  --speed 0.01 --hold 1.5 --rate-hz 1000 --realtime -o "$out/press.csv" >"$out/probe.log" 2>&1
wait "$server"
grep -E "loop:|body:" "$out/server.log" | cut -c 33-
tail -1 "$out/probe.log"
/usr/bin/python3 - "$out/press.csv" <<'PY'
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
t = [float(r["t"]) for r in rows]
f = [math.sqrt(sum(float(r[c]) ** 2 for c in ("fx", "fy", "fz"))) for r in rows]
hold = [fi for ti, fi in zip(t, f) if 1.0 <= ti <= 1.99]  # press ends at 0.5 s, hold to 2.0 s
mean = sum(hold) / len(hold)
std = math.sqrt(sum((h - mean) ** 2 for h in hold) / len(hold))
print(f"press peak {max(f):.3f} N, hold {mean:.3f} N, hold std {100 * std / mean:.3f} %")
PY
echo "replies: $out/press.csv"
