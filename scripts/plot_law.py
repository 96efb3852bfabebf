#!/usr/bin/python3
"""Draw load-deflection curves from `conica-lab law` CSV files (one curve per file)."""
import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv", nargs="+", help="CSV with deflection,force,stiffness,phase")
    ap.add_argument("--out", required=True, help="PNG to write")
    ap.add_argument("--labels", default="", help="comma-separated legend labels")
    ap.add_argument("--title", default="Conical spring load-deflection")
    ap.add_argument("--xlabel", default="deflection")
    ap.add_argument("--ylabel", default="load")
    a = ap.parse_args()
    labels = a.labels.split(",") if a.labels else [None] * len(a.csv)
    fig, ax = plt.subplots(figsize=(6, 4.2), dpi=120)
    for path, label in zip(a.csv, labels):
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        x = [float(r["deflection"]) for r in rows]
        y = [float(r["force"]) for r in rows]
        ax.plot(x, y, label=label)
    ax.set_xlabel(a.xlabel)
    ax.set_ylabel(a.ylabel)
    ax.set_title(a.title)
    ax.grid(alpha=0.3)
    if any(labels):
        ax.legend()
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
