#!/usr/bin/env bash
# Regenerates docs/figures/law-fig6.png and law-fig7.png (paper Figures 6 and 7) from the law as
# implemented: `conica-lab law` writes one CSV per card, scripts/plot_law.py draws them.
#   scripts/make_law_figures.sh            (uses build/; BUILD_DIR=... to use another build)
set -euo pipefail
cd "$(dirname "$0")/.."
LAB="${BUILD_DIR:-build}/bin/conica-lab"
PY=/usr/bin/python3  # the interpreter with matplotlib
if [[ ! -x "$LAB" ]]; then
  echo "make_law_figures: $LAB not found; build the conica-lab target first" >&2
  exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p docs/figures

# Figure 6: n_a = 3, d = 1, G = 50, D1 = 2, D2 = 8; displacement range 90 = delta_emax and
# L0 = 90 n_a / n + Ls (eq. 24, Ls = 0 for this card) for n = 0.5, 1, 2, 3. The exact law
# (no stiffness cap); the last sample stops short of the solid height of n = 3 (S = 90).
csvs=()
for n in 0.5 1 2 3; do
  L0=$("$PY" -c "print(90 * 3 / $n)")
  "$LAB" law --G 50 --d 1 --D1 2 --D2 8 --na 3 --L0 "$L0" --from 0 --to 89.9 --steps 600 \
    >"$tmp/fig6-$n.csv"
  csvs+=("$tmp/fig6-$n.csv")
done
"$PY" scripts/plot_law.py "${csvs[@]}" --out docs/figures/law-fig6.png \
  --labels "n = 0.5 (L0 = 540),n = 1 (L0 = 270),n = 2 (L0 = 135),n = 3 (L0 = 90)" \
  --title "Figure 6: n_a = 3, d = 1, G = 50, D1 = 2, D2 = 8" --second normalized

# Figure 7: the n = 3 card of Figure 6 with several shear moduli.
csvs=()
for G in 25 50 100 200; do
  "$LAB" law --G "$G" --d 1 --D1 2 --D2 8 --na 3 --L0 90 --from 0 --to 89.9 --steps 600 \
    >"$tmp/fig7-$G.csv"
  csvs+=("$tmp/fig7-$G.csv")
done
"$PY" scripts/plot_law.py "${csvs[@]}" --out docs/figures/law-fig7.png \
  --labels "G = 25,G = 50,G = 100,G = 200" \
  --title "Figure 7: n = 3 card of Figure 6, several G" --second normalized
echo "wrote docs/figures/law-fig6.png docs/figures/law-fig7.png"
