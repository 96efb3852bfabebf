#!/usr/bin/python3
"""Plots conica-latency runs: the latency CDF of every run and, when the runs have different
mesh sizes (num_nodes in their CSV header), p50/p99 latency versus mesh size.

    /usr/bin/python3 scripts/plot_latency.py --out latency.png run1.csv [run2.csv ...]

Each CSV: a header comment '# conica-latency ... num_nodes=N label=NAME ...', then
seq,scheduled_us,latency_us (latency -1: lost)."""
import argparse
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_run(path):
    meta = {}
    lat = []
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                for part in line[1:].split():
                    if "=" in part:
                        k, v = part.split("=", 1)
                        meta[k] = v
                continue
            if line.startswith("seq"):
                continue
            fields = line.strip().split(",")
            if len(fields) == 3:
                lat.append(float(fields[2]))
    lat = np.array(lat)
    return meta, lat[lat >= 0], int(np.sum(lat < 0))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="PNG to write")
    ap.add_argument("csv", nargs="+")
    args = ap.parse_args()
    runs = [(p,) + read_run(p) for p in args.csv]
    nodes = sorted({int(m.get("num_nodes", 0)) for _, m, _, _ in runs})
    by_size = len(nodes) > 1 and all(n > 0 for n in nodes)
    fig, axes = plt.subplots(1, 2 if by_size else 1, figsize=(11 if by_size else 6.5, 4.5))
    ax = axes[0] if by_size else axes
    for path, meta, lat, lost in runs:
        if len(lat) == 0:
            print(f"plot_latency: {path}: no answered requests", file=sys.stderr)
            continue
        x = np.sort(lat)
        y = np.arange(1, len(x) + 1) / (len(x) + lost)
        label = f"{meta.get('label', path)} ({meta.get('num_nodes', '?')} nodes, p50 {np.median(x):.0f} us, lost {lost})"
        ax.plot(x, y, label=label)
    ax.set_xscale("log")
    ax.set_xlabel("round trip from scheduled send (us)")
    ax.set_ylabel("fraction of requests")
    ax.set_title("probe -> force latency CDF")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    if by_size:
        ax2 = axes[1]
        pts = []
        for _, meta, lat, _ in runs:
            if len(lat):
                pts.append((int(meta["num_nodes"]), np.percentile(lat, 50), np.percentile(lat, 99)))
        pts.sort()
        n, p50, p99 = zip(*pts)
        ax2.plot(n, p50, "o-", label="p50")
        ax2.plot(n, p99, "s--", label="p99")
        ax2.set_xlabel("mesh nodes")
        ax2.set_ylabel("round trip (us)")
        ax2.set_yscale("log")
        ax2.set_title("latency versus mesh size")
        ax2.grid(True, which="both", alpha=0.3)
        ax2.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"plot_latency: wrote {args.out}")


if __name__ == "__main__":
    main()
