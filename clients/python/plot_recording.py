#!/usr/bin/python3
"""Plots a probe recording (conica-probe or probe.py CSV): force versus depth and force versus
time, one line per probe.

    /usr/bin/python3 clients/python/plot_recording.py press.csv --out press   # press-depth.png, press-time.png

Depth is measured along --axis (default -z) from where the probe first touched (first row with
contact = 1); the force plotted is the normal force, -F . axis (N, positive when the tissue pushes
back)."""
import argparse
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def parse_axis(text):
    sign = -1.0 if text.startswith("-") else 1.0
    name = text.lstrip("+-")
    if name in AXES:
        return sign * np.array(AXES[name], dtype=float)
    v = np.array([float(c) for c in text.split(",")])
    return v / np.linalg.norm(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--axis", default="-z", help="pressing direction")
    ap.add_argument("--out", default=None, help="prefix of the PNGs (default: the CSV name)")
    args = ap.parse_args()
    axis = parse_axis(args.axis)
    prefix = args.out or args.csv.rsplit(".", 1)[0]

    rows = {}
    with open(args.csv) as f:
        for r in csv.DictReader(f):
            rows.setdefault(int(r["probe"]), []).append(r)
    if not rows:
        sys.exit(f"plot_recording: {args.csv}: no rows")

    fig_d, ax_d = plt.subplots(figsize=(6, 4.5))
    fig_t, ax_t = plt.subplots(figsize=(7, 4.5))
    for probe, rs in sorted(rows.items()):
        rs.sort(key=lambda r: float(r["t"]))
        t = np.array([float(r["t"]) for r in rs])
        x = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rs])
        f = np.array([[float(r["fx"]), float(r["fy"]), float(r["fz"])] for r in rs])
        contact = np.array([int(r["contact"]) for r in rs])
        fn = -f @ axis
        touched = np.flatnonzero(contact)
        ref = x[touched[0]] if len(touched) else x[0]
        depth_mm = (x - ref) @ axis * 1e3
        ax_d.plot(depth_mm, fn, label=f"probe {probe}")
        ax_t.plot(t, fn, label=f"probe {probe}")
    ax_d.set_xlabel("depth from first contact (mm)")
    ax_d.set_ylabel("normal force (N)")
    ax_d.set_title("force versus depth")
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel("normal force (N)")
    ax_t.set_title("force versus time")
    for ax in (ax_d, ax_t):
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig_d.tight_layout()
    fig_t.tight_layout()
    fig_d.savefig(prefix + "-depth.png", dpi=110)
    fig_t.savefig(prefix + "-time.png", dpi=110)
    print(f"plot_recording: wrote {prefix}-depth.png, {prefix}-time.png")


if __name__ == "__main__":
    main()
