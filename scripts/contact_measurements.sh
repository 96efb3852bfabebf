#!/usr/bin/env bash
# Runs the surface-contact measurement suite (conica-lab contact --suite) and writes
# docs/contact-measurements.md with its tables. Builds conica-lab into BUILD_DIR (default
# build-lab) unless it is there. CSVs of every case go to out/contact (one per case).
set -euo pipefail
cd "$(dirname "$0")/.."
build="${BUILD_DIR:-build-lab}"
if [ ! -x "$build/bin/conica-lab" ]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCONICA_BUILD_BENCH=OFF
  cmake --build "$build" -j2 --target conica-lab
fi
cmd=(conica-lab contact --suite --out-dir out/contact)
mkdir -p out/contact
start=$(date +%s)
"$build/bin/${cmd[0]}" "${cmd[@]:1}" >out/contact/tables.md
secs=$(( $(date +%s) - start ))
# The source the binary was built from: the commit, and whether server/core had local changes.
rev="${CONICA_COMMIT:-$(git rev-parse --short HEAD 2>/dev/null || echo unknown)}"
if git rev-parse --git-dir >/dev/null 2>&1 && ! git diff --quiet HEAD -- server/core 2>/dev/null; then
  rev="$rev with local changes in server/core"
fi
{
  cat <<HEAD
# Surface contact: measurements

Written by \`scripts/contact_measurements.sh\`: \`${cmd[*]}\` (Release build of ${rev},
2-core machine, ${secs} s for the whole suite). Scenes: \`configs/paper-cube.pbtxt\`, \`configs/paper-cube-hooke.pbtxt\`,
\`configs/anisotropic-block.pbtxt\` for press and drag; the paper cube for hold and the quasi-static
check; the paper cube's card for the Hertz block. Every probe uses \`contact: SURFACE\`
(\`core/contact.h\`). Forces are on the device, N, along +z (pushing the tool out); depths from the rest
surface at the press point. \`s\` is the top surface's lattice spacing (median of its triangles'
shorter edges). Press columns: "drops > 1 %" counts press ticks (tool deeper than 0.1 mm) whose force
is more than 1 % below its running maximum, "max drop" the largest such shortfall, "last drop at"
the tool depth of the last one. Hold statistics: the hold's second half (press), its last second
(hold). CSVs per case (tick,t,tool_depth_mm,proxy_depth_mm,fx,fy,fz,contacts,penetration_mm):
\`out/contact/\`.
HEAD
  cat out/contact/tables.md
  if [ -f docs/contact-measurements-notes.md ]; then
    echo
    cat docs/contact-measurements-notes.md
  fi
} >docs/contact-measurements.md
echo "wrote docs/contact-measurements.md (${secs} s)"
