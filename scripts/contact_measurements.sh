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
if [ -n "${CONICA_TABLES:-}" ]; then  # tables from an earlier run of the same command
  cp "$CONICA_TABLES" out/contact/tables.md
else
  "$build/bin/${cmd[0]}" "${cmd[@]:1}" >out/contact/tables.md
fi
secs="${CONICA_SECONDS:-$(( $(date +%s) - start ))}"
# The source the binary was built from: the commit, and whether server/core had local changes.
rev="${CONICA_COMMIT:-$(git rev-parse --short HEAD 2>/dev/null || echo unknown)}"
if [ -z "${CONICA_COMMIT:-}" ] && git rev-parse --git-dir >/dev/null 2>&1 &&
   ! git diff --quiet HEAD -- server/core 2>/dev/null; then
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
fell by more than 1 % of its running maximum since the tick before, "max drop" the largest such
fall, "last drop at" the tool depth of the last one; "max shortfall" is the largest (running
maximum - force) / running maximum over the press and "at" the tool depth where it is reached. Hold statistics: the hold's second half (press), its last second
(hold). CSVs per case (tick,t,tool_depth_mm,proxy_depth_mm,fx,fy,fz,contacts,penetration_mm):
\`out/contact/\`.
HEAD
  cat out/contact/tables.md
  cat <<'NOTES'

## Reading the tables (measured at the commit named above)
- **Felt from the start.** Every press feels force from the first tick of motion (0.005 mm).
  Force > 0 at every tick from 0.1 mm holds in 22 of 24 presses; it fails for the 10 mm sphere
  (1 x s) at the quad centre of both cubes: between 13.8 and 14.4 mm of tool depth the tool loses
  the surface (0 faces, proxy depth = tool depth, force 0 for 132 ticks) while the cell under it
  gives way, then finds it again.
- **Not monotone.** Every press falls far below its running maximum somewhere (the "max
  shortfall" column: 39-92 %, at 8.6-18.4 mm): the lattice under the tool gives way (pair springs
  lose shear stability under large compression, README). Tick to tick the falls are gradual (at
  most 5.7 % of the running maximum in one tick). The barrier holds: the deepest penetration is
  0.19 R (barrier 0.25 R); no rollbacks with the scenes' integrators.
- **Holds.** std/mean over the hold's second half is below 0.5 % in 17 of 24 presses; the
  others: paper-cube-hooke, 5 mm sphere at the node, 19.8 %; the 20 mm sphere at the quad centre
  of both cubes, 3.4 %; anisotropic-block 0.9-2.9 % (5 mm and 10 mm at the quad centre, 20 mm at
  both positions).
- **Hertz (sphere).** The plate compression gives E = 1031.9 Pa, equal to the homogenised cell's,
  and nu = 0.183 at both spacings, so E* = 1067.7 Pa (the model's own contact_modulus, from the
  network's nu = 1/4 estimate, is 871.5 Pa, 18 % lower). Against Hertz with that E*: +35 % at
  0.1 R on the 5 mm lattice, +5.1 % on the 2.5 mm lattice; over d in [0.02 R, 0.1 R] the mean
  error falls from 42 % to 12.8 % and the largest (at the shallow end, where the contact radius
  sqrt(R d) = 1.4 mm is below the spacing) from 64 % to 20 %. Converging under refinement; the
  10 % goal is met at 0.1 R on the 2.5 mm lattice only, not over the range. The contact radius is
  0.105 of the 30 mm thickness at 0.1 R; no finite-thickness correction is applied.
- **Sneddon (flat punch): failed, not measured.** The punch's proxy never enters the surface:
  its reference point for the swept move is its face centre, which has to go below the rest
  surface to press it, and the sweep stops it short of that surface. Proxy depth stays 0, no face
  is touched, the body gets no force, and the device force is the coupling spring alone
  (k_vc d: 0.436 N at 1 mm). A core limitation of update_proxy (core/contact.cc) for the punch;
  the unit tests cover tool_contact for the punch, not its proxy.
- **Drag.** The normal-force ripple over the middle three spacings is 30-102 %, at constant
  target height across a lattice whose cells under the tool are far from homogeneous at these
  depths. At 1 R depth the frictionless tool also feels a mean force against the motion (up to
  0.043 N, anisotropic block, 10 mm sphere).
- **Integrators.** Symplectic and implicit Euler hold steady (std/mean 0.007 % and 0.002 %).
  Explicit Euler blows up on the paper cube at 1 kHz (42 rollbacks, the tool at R penetration);
  the same press with the node contact blows up too (22 rollbacks), so the integrator, not the
  surface contact, is what fails there.
- **Quasi-static.** The press at 5 mm/s and at 2.5 mm/s (paper cube, 2.5 mm sphere at the node)
  agree within 0.1 % at 12.5, 25, 37.5, 75, 87.5 and 100 % of the depth and within 0.6 % at
  62.5 %; at 50 % (10 mm), in the middle of the collapse, they differ by 16 %: the collapse itself
  is rate dependent. The Hertz presses are static solves (implicit steps of 1 s); reading each
  depth level after 5 or after 10 held steps changes the 5 mm lattice's errors by less than 0.1 %
  (41.98 / 64.17 / +35.16 % against 42.07 / 64.31 / +35.23 %). Without the held steps the reading
  depends on the increment: a 50-step ramp read +105 % at 0.1 R and a 100-step ramp +68 %, since
  each proxy stage presses into the surface the body had before its step.
NOTES
} >docs/contact-measurements.md
echo "wrote docs/contact-measurements.md (${secs} s)"
