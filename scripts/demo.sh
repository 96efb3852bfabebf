#!/usr/bin/env bash
# Sets up, then runs the main job on the built-in default and shows the results:
#   1. conica-server serves the built-in 320-node conical cube at 1 kHz on the default endpoints
#      (tcp://127.0.0.1:5555 probes, :5556 state, :5557 control);
#   2. conica-probe presses a spherical probe 6 mm into its top face in real time and records the
#      replies (out/press.csv), plotted as force versus depth and time (out/press-*.png);
#   3. conica-latency measures probe-to-force round trips for 3 s, open loop at 1 kHz;
#   4. conica-lab law prints the conical spring law of the paper's Figure 6 card.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
mkdir -p out

build/bin/conica-server --builtin cube --seconds 60 --stats-seconds 0 >out/server.log 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true; wait $server 2>/dev/null || true' EXIT
for _ in $(seq 50); do grep -q "serving" out/server.log 2>/dev/null && break; sleep 0.1; done
echo "== conica-server: $(grep -m1 serving out/server.log | sed 's/.*\] //')"

echo "== conica-probe: press 6 mm into the top of the cube, hold, release (real time)"
build/bin/conica-probe --script press --depth 0.006 --hold 0.5 --realtime -o out/press.csv
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
         { fz = $col["fz"]; if (fz > peak) { peak = fz; z = $col["z"] } ++n }
         END { printf "   %d replies, peak force %.4f N (pushing the probe out) at probe z = %.4f m\n", n, peak, z }' \
  out/press.csv
/usr/bin/python3 clients/python/plot_recording.py out/press.csv --out out/press
echo "   plots: out/press-depth.png, out/press-time.png"

echo "== conica-latency: 3 s of probe updates at 1 kHz, open loop"
build/bin/conica-latency --seconds 3 --csv out/latency.csv | tail -n 4

echo "== conica-lab law: the paper's Figure 6 card (n = 3), deflection,force,stiffness,phase"
build/bin/conica-lab law --G 50 --d 1 --D1 2 --D2 8 --L0 90 --na 3 --from 0 --to 88 --steps 9
