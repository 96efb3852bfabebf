#!/usr/bin/python3
"""The figure of docs/validation.md: the three transfer tests (conica against the CalculiX
reference, force against travel) and the punch's surface profile against Boussinesq's.

Every input is a CSV with a header line (displacement_mm,force_N for the curves, r_mm,w_over_d,
boussinesq for the profile), as written by conica-lab compress / indent / fem-reference and
conica-lab validate. Example (docs/validation.md lists the commands that write them):
  plot_validation.py --out docs/figures/validation.png \
    --case "bonded cylinder" cyl.csv cyl-fem.csv --case "bonded cube" cube.csv cube-fem.csv \
    --case "flat punch" punch.csv punch-fem.csv --profile boussinesq-24.csv
"""
import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], [r for r in rows[1:] if r]
    return head, [[float(v) for v in r] for r in body]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", required=True, help="PNG to write")
    ap.add_argument("--case", nargs=3, action="append", default=[],
                    metavar=("TITLE", "CONICA_CSV", "REFERENCE_CSV"),
                    help="a reference of - draws conica alone")
    ap.add_argument("--profile", default="", help="surface profile CSV of conica-lab validate")
    a = ap.parse_args()
    n = len(a.case) + (1 if a.profile else 0)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.6), squeeze=False)
    for ax, (title, conica, ref) in zip(axes[0], a.case):
        for path, label, style in ((ref, "CalculiX (Yeoh)", "k-"), (conica, "conica", "o--")):
            if path == "-":  # no reference
                continue
            _, rows = read(path)
            ax.plot([r[0] for r in rows], [r[1] for r in rows], style, label=label, ms=4)
        ax.set_title(title)
        ax.set_xlabel("travel (mm)")
        ax.set_ylabel("force (N)")
        ax.grid(alpha=0.3)
        ax.legend()
    if a.profile:
        ax = axes[0][-1]
        _, rows = read(a.profile)
        ax.plot([r[0] for r in rows], [r[2] for r in rows], "k-", label="Boussinesq (half-space)")
        ax.plot([r[0] for r in rows], [r[1] for r in rows], "o--", ms=4, label="conica")
        ax.set_title("surface under a flat punch, a = 5 mm")
        ax.set_xlabel("distance from the axis (mm)")
        ax.set_ylabel("w / d")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


if __name__ == "__main__":
    main()
