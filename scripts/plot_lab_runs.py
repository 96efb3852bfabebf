#!/usr/bin/python3
"""Plots the probe force of `conica-lab run` CSVs against time, one line per file.

    /usr/bin/python3 scripts/plot_lab_runs.py nodes=out/a.csv surface=out/b.csv --out fig.png
"""
import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="LABEL=FILE.csv (conica-lab run --out)")
    ap.add_argument("--out", required=True, help="PNG to write")
    a = ap.parse_args()
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for run in a.runs:
        label, _, path = run.partition("=")
        if not path:
            ap.error(f"{run}: expected LABEL=FILE.csv")
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        t = [float(r["t"]) for r in rows]
        axes[0].plot(t, [float(r["fz"]) for r in rows], label=label)
        axes[1].plot(t, [float(r["fx"]) for r in rows], label=label)
    axes[0].set_ylabel("force z (N)")
    axes[1].set_ylabel("force x (N)")
    axes[1].set_xlabel("t (s)")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(a.out, dpi=80)


if __name__ == "__main__":
    main()
