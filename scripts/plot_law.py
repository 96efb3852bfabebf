#!/usr/bin/python3
"""Draw load-deflection curves from `conica-lab law` CSV files (one curve per file).

With --second, a second panel beside the load: `stiffness` (tangent stiffness, log scale) or
`normalized` (each load divided by its value at the last deflection, to compare shapes).
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    x = [float(r["deflection"]) for r in rows]
    y = [float(r["force"]) for r in rows]
    k = [float(r["stiffness"]) for r in rows]
    return x, y, k


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv", nargs="+", help="CSV with deflection,force,stiffness,phase")
    ap.add_argument("--out", required=True, help="PNG to write")
    ap.add_argument("--labels", default="", help="comma-separated legend labels")
    ap.add_argument("--title", default="Conical spring load-deflection")
    ap.add_argument("--xlabel", default="deflection")
    ap.add_argument("--ylabel", default="load")
    ap.add_argument("--logy", action="store_true", help="log scale for the load")
    ap.add_argument("--second", choices=["none", "stiffness", "normalized"], default="none",
                    help="second panel")
    a = ap.parse_args()
    labels = a.labels.split(",") if a.labels else [None] * len(a.csv)
    if len(labels) != len(a.csv):
        ap.error(f"{len(a.csv)} CSV files but {len(labels)} labels")
    two = a.second != "none"
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11 if two else 6, 4.2), dpi=120)
    ax = axes[0] if two else axes
    curves = [read(p) for p in a.csv]
    for (x, y, _), label in zip(curves, labels):
        ax.plot(x, y, label=label)
    ax.set_xlabel(a.xlabel)
    ax.set_ylabel(a.ylabel)
    ax.set_title(a.title)
    if a.logy:
        ax.set_yscale("log")
    ax.grid(alpha=0.3)
    if any(labels):
        ax.legend()
    if two:
        bx = axes[1]
        for (x, y, k), label in zip(curves, labels):
            if a.second == "stiffness":
                pts = [(xi, ki) for xi, ki in zip(x, k) if math.isfinite(ki) and ki > 0]
                bx.plot([p[0] for p in pts], [p[1] for p in pts], label=label)
            else:
                bx.plot(x, [yi / y[-1] for yi in y], label=label)
        bx.set_xlabel(a.xlabel)
        if a.second == "stiffness":
            bx.set_yscale("log")
            bx.set_ylabel("tangent stiffness")
            bx.set_title("Tangent stiffness dP/d(deflection)")
        else:
            bx.set_ylabel("load / load at last deflection")
            bx.set_title("Shape: normalised load")
        bx.grid(alpha=0.3, which="both")
        if any(labels):
            bx.legend()
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
