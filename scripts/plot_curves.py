#!/usr/bin/python3
"""Draw curves from CSV files with a header line: x is the first column, y the named columns
(default: the second column). One curve per file and column, labelled in that order.

Example: plot_curves.py --out fig.png --columns data_N,full_N --labels data,model fit.csv
A file given as PATH::COL1,COL2 takes its own columns.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv", nargs="+")
    ap.add_argument("--out", required=True, help="PNG to write")
    ap.add_argument("--columns", default="", help="comma-separated y columns (default: 2nd)")
    ap.add_argument("--labels", default="", help="comma-separated legend labels")
    ap.add_argument("--styles", default="", help="comma-separated matplotlib format strings")
    ap.add_argument("--title", default="")
    ap.add_argument("--xlabel", default="")
    ap.add_argument("--ylabel", default="")
    ap.add_argument("--logy", action="store_true")
    a = ap.parse_args()
    labels = a.labels.split(",") if a.labels else []
    styles = a.styles.split(",") if a.styles else []
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    n = 0
    for arg in a.csv:
        path, _, own = arg.partition("::")
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        head, body = rows[0], rows[1:]
        cols = (own or a.columns).split(",") if (own or a.columns) else [head[1]]
        x = [float(r[0]) for r in body]
        for c in cols:
            j = head.index(c)
            y = [float(r[j]) for r in body]
            if all(math.isnan(v) for v in y):
                n += 1
                continue
            label = labels[n] if n < len(labels) else (c if len(a.csv) == 1 else path)
            style = styles[n] if n < len(styles) else "-"
            ax.plot(x, y, style, label=label, lw=1.6, ms=4)
            n += 1
    ax.set_title(a.title)
    ax.set_xlabel(a.xlabel)
    ax.set_ylabel(a.ylabel)
    if a.logy:
        ax.set_yscale("log")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)


if __name__ == "__main__":
    main()
