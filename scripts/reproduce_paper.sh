#!/usr/bin/env bash
# Reproduces the paper's experiments that this repository can run (docs/paper-reproduction.md):
# writes docs/figures/repro-*.png and docs/figures/repro-*.csv.
#   scripts/reproduce_paper.sh        (uses build/; BUILD_DIR=... for another build;
#                                      DATA=... for the phantom data, default ../shared/data/phantoms)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${BUILD_DIR:-build}"
LAB="$BUILD/bin/conica-lab"
DATA="${DATA:-../shared/data/phantoms}"
PY=/usr/bin/python3  # the interpreter with matplotlib
FIG=docs/figures
if [[ ! -x "$LAB" ]]; then
  echo "reproduce_paper: $LAB not found; build the conica-lab target first" >&2
  exit 1
fi
mkdir -p "$FIG"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Figures 6 and 7: the law itself.
BUILD_DIR="$BUILD" scripts/make_law_figures.sh

# Figure 8 / Table 1 style fits and Figure 13: the two phantom recipes, all ten tests each,
# averaged. The cell surrogate is fitted up to 50 % strain; the full body (the phantom cylinder
# between plates) is run at the fitted card and refitted up to 25 % strain, where it is stable.
for recipe in EF30_0T EF10_0T; do
  data=()
  for f in "$DATA/$recipe"/*.csv; do data+=(--data "$f"); done
  "$LAB" calibrate --scene configs/phantom-cylinder-springs.pbtxt "${data[@]}" --max-strain 0.5 \
    --no-precompression --full-iterations 0 --out "$FIG/repro-fit-$recipe.card" --curves "$FIG/repro-fit-$recipe.csv" \
    | tee "$tmp/fit-$recipe.log" | tail -4
  "$LAB" calibrate --scene configs/phantom-cylinder-springs.pbtxt "${data[@]}" --max-strain 0.25 \
    --no-precompression --full-iterations 2 --out "$FIG/repro-fit25-$recipe.card" \
    --curves "$FIG/repro-fit25-$recipe.csv" | tee "$tmp/fit25-$recipe.log" | tail -4
  "$PY" scripts/plot_curves.py --out "$FIG/repro-fit-$recipe.png" \
    --title "$recipe: conical card fitted to the mean of 10 tests" \
    --xlabel "plate travel (mm)" --ylabel "force (N)" \
    --labels "measured (mean of 10),homogenised lattice (fit to 50 %),full body at that card,full body (fit to 25 %)" \
    --styles "k-,b-,r--,g-." "$FIG/repro-fit-$recipe.csv::data_N,surrogate_N,full_N" \
    "$FIG/repro-fit25-$recipe.csv::full_N"
done
# A card per spring family (2: edges | diagonals, 3: edges | face | body diagonals, moduli tied by
# isotropy), fitted through the full body up to 50 % strain (a few minutes per fit).
for recipe in EF30_0T EF10_0T; do
  data=()
  for f in "$DATA/$recipe"/*.csv; do data+=(--data "$f"); done
  for k in 2 3; do
    "$LAB" calibrate --scene configs/phantom-cylinder-springs.pbtxt "${data[@]}" --max-strain 0.5 \
      --cards $k --no-precompression --full-iterations 3 --out "$FIG/repro-fitk$k-$recipe.card" \
      --curves "$FIG/repro-fitk$k-$recipe.csv" | tee "$tmp/fitk$k-$recipe.log" | tail -2
  done
  "$PY" scripts/plot_curves.py --out "$FIG/repro-fitk-$recipe.png" \
    --title "$recipe: cards per spring family, full body to 50 % strain" \
    --xlabel "plate travel (mm)" --ylabel "force (N)" \
    --labels "measured (mean of 10),2 cards: lattice,2 cards: full body,3 cards: lattice,3 cards: full body" \
    --styles "k-,b-,b--,r-,r--" "$FIG/repro-fitk2-$recipe.csv::data_N,surrogate_N,full_N" \
    "$FIG/repro-fitk3-$recipe.csv::surrogate_N,full_N"
done

# The phantom with volume, spread and shear stiffness (configs/phantom-cylinder.pbtxt): the
# issue's command, fitted through the full body to 50 % strain with the body's Poisson ratio on
# the full-body grid (0.49, 0.45, 0.41) and bodies that leave the homogeneous state rejected
# (about 7 minutes each on two threads).
for recipe in EF30_0T EF10_0T; do
  data=()
  for f in "$DATA/$recipe"/*.csv; do data+=(--data "$f"); done
  "$LAB" calibrate --scene configs/phantom-cylinder.pbtxt "${data[@]}" --max-strain 0.5 \
    --out "$FIG/repro-fitvol-$recipe.card" --curves "$FIG/repro-fitvol-$recipe.csv" \
    | tee "$tmp/fitvol-$recipe.log" | tail -1
  nu=$(sed -n 's/.*body Poisson \([0-9.]*\)\..*/\1/p' "$FIG/repro-fitvol-$recipe.card")
  "$PY" scripts/plot_curves.py --out "$FIG/repro-fitvol-$recipe.png" \
    --title "$recipe: homogeneous full body (shear stiffness, nu fitted $nu), fitted to 50 % strain" \
    --xlabel "plate travel (mm)" --ylabel "force (N)" \
    --labels "measured (mean of 10),homogenised lattice,full body" \
    --styles "k-,b--,r-" "$FIG/repro-fitvol-$recipe.csv::data_N,surrogate_N,full_N"
done

# Figure 9: relaxation, creep (load-controlled plate) and hysteresis with a Maxwell branch.
"$LAB" viscoelastic --scene configs/viscoelastic-cube.pbtxt --out "$FIG/repro-fig9" --plot

# Table 2 anisotropy: the Table 2 block pressed along x and along z, and the white-only block.
for b in anisotropic-block-x anisotropic-block-z isotropic-block-x isotropic-block-z; do
  "$LAB" compress --scene "configs/$b.pbtxt" --to-strain 0.05 --rate-mm-per-min 60 --samples 10 \
    --out "$FIG/repro-table2-$b.csv" 2> /dev/null
done
awk -F, 'FNR == 12 { f[FILENAME] = $2 }
  END {
    ax = f["'"$FIG"'/repro-table2-anisotropic-block-x.csv"] / 1.8e-3 / 0.05
    az = f["'"$FIG"'/repro-table2-anisotropic-block-z.csv"] / 3.6e-3 / 0.05
    ix = f["'"$FIG"'/repro-table2-isotropic-block-x.csv"] / 1.8e-3 / 0.05
    iz = f["'"$FIG"'/repro-table2-isotropic-block-z.csv"] / 3.6e-3 / 0.05
    printf "Table 2: E_x %.4g Pa, E_z %.4g Pa, ratio %.3f; white only %.4g / %.4g = %.3f\n", ax, az, ax / az, ix, iz, ix / iz
  }' "$FIG"/repro-table2-*.csv

# Cross-validation: fit on A1-A5 (surrogate), error on B1-B5 is printed by the unit test
# calibration_test (FitOnHalfOfThePhantomTestsPredictsTheOtherHalf).

# Figure 14 / Table 4: conical cube vs linear Hooke cube under compression (their own
# symplectic integrator at 1 kHz), and the time per step of each, same machine, same run.
for s in paper-cube paper-cube-hooke; do
  best=""
  for rep in 1 2 3; do
    "$LAB" compress --scene "configs/$s.pbtxt" --to-strain 0.2 --rate-mm-per-min 600 \
      --out "$FIG/repro-fig14-$s.csv" 2> "$tmp/$s.log"
    t=$(sed -n 's/.*step time \([0-9.e+-]*\) us.*/\1/p' "$tmp/$s.log")
    if [[ -z "$best" ]] || awk "BEGIN{exit !($t < $best)}"; then best=$t; fi
  done
  echo "$s: best of 3 mean step time $best us"
  echo "$best" > "$tmp/$s.t"
done
ratio=$(awk "BEGIN{printf \"%.3f\", $(cat "$tmp/paper-cube.t") / $(cat "$tmp/paper-cube-hooke.t")}")
echo "scene,step_time_us" > "$FIG/repro-table4.csv"
echo "paper-cube,$(cat "$tmp/paper-cube.t")" >> "$FIG/repro-table4.csv"
echo "paper-cube-hooke,$(cat "$tmp/paper-cube-hooke.t")" >> "$FIG/repro-table4.csv"
echo "ratio,$ratio" >> "$FIG/repro-table4.csv"
echo "Table 4: conical / Hooke time per step = $ratio (paper: 0.090 s / 0.083 s = 1.08)"
"$PY" scripts/plot_curves.py --out "$FIG/repro-fig14.png" \
  --title "Figure 14: 320-node cube compressed by a plate" \
  --xlabel "plate travel (mm)" --ylabel "force (N)" --labels "conical,linear (Hooke, K0)" \
  --styles "r-,b--" "$FIG/repro-fig14-paper-cube.csv" "$FIG/repro-fig14-paper-cube-hooke.csv"
