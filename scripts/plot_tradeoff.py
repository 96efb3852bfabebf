#!/usr/bin/python3
"""Draw the speed/accuracy data written by `conica-lab tradeoff` (CSV) as a Pareto chart (PNG).

One panel per experiment and spring law: step time per 1 ms tick against force error (log-log;
the RMS error when the CSV has it),
markers by integrator, colour by resolution, the Pareto front joined, the 1 ms tick budget marked,
unstable settings as red crosses along the top edge.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MARKERS = {"symplectic": "o", "explicit": "s", "implicit": "^"}


def label(r):
    if r["integrator"] == "implicit":
        return f"implicit {r['newton']}x{r['cg']}"
    return r["integrator"]


def err(r):
    """The spike-robust RMS error when the CSV has it, else the largest per-tick error."""
    v = float(r.get("rms_error") or "nan")
    return v if math.isfinite(v) else float(r["error"])


def pareto(rows):
    ok = [r for r in rows if r["stable"] == "1" and math.isfinite(err(r))]
    front = []
    for r in ok:
        t, e = float(r["step_us"]), err(r)
        dominated = any(float(o["step_us"]) <= t and err(o) <= e and
                        (float(o["step_us"]) < t or err(o) < e) for o in ok)
        if not dominated:
            front.append(r)
    return sorted(front, key=lambda r: float(r["step_us"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    with open(a.csv, newline="") as f:
        rows = list(csv.DictReader(f))
    scenes = [s for s in ("compression", "indentation") if any(r["scene"] == s for r in rows)]
    laws = ["conical", "hooke"]
    fig, axes = plt.subplots(len(scenes), 2, figsize=(14, 5.5 * len(scenes)), dpi=100,
                             squeeze=False)
    for i, scene in enumerate(scenes):
        resolutions = []
        for r in rows:
            if r["scene"] == scene and r["resolution"] not in resolutions:
                resolutions.append(r["resolution"])
        cmap = plt.get_cmap("viridis")
        colour = {res: cmap(k / max(1, len(resolutions) - 1)) for k, res in enumerate(resolutions)}
        for j, law in enumerate(laws):
            ax = axes[i][j]
            sub = [r for r in rows if r["scene"] == scene and r["law"] == law]
            stable = [r for r in sub if r["stable"] == "1" and math.isfinite(err(r))]
            errs = [max(err(r), 1e-6) for r in stable] or [1e-3, 1]
            top = max(errs) * 3
            seen = set()
            for r in sub:
                t = float(r["step_us"])
                if r in stable:
                    key = (label(r), r["resolution"])
                    ax.scatter(t, max(err(r), 1e-6), marker=MARKERS[r["integrator"]],
                               facecolors="none" if r["integrator"] == "implicit" and
                               r["newton"] == "1" else colour[r["resolution"]],
                               edgecolors=colour[r["resolution"]], s=30 + 12 * int(r["substeps"]),
                               label=f"{label(r)}, {r['resolution']} ({r['nodes']} nodes)"
                               if key not in seen else None, zorder=3)
                    seen.add(key)
                else:
                    ax.scatter(t, top, marker="x", c="tab:red", s=40, zorder=3,
                               label="unstable (rolled back / blew up)"
                               if "unstable" not in seen else None)
                    seen.add("unstable")
            front = pareto(sub)
            if front:
                ax.plot([float(r["step_us"]) for r in front],
                        [max(err(r), 1e-6) for r in front], "k-", lw=1.5, zorder=2,
                        label="Pareto front")
                for r in front:
                    ax.annotate(f"{label(r)} x{r['substeps']}", (float(r["step_us"]),
                                max(err(r), 1e-6)), fontsize=6, xytext=(4, -8),
                                textcoords="offset points")
            ax.axvline(1000, color="tab:red", ls="--", lw=1, label="1 ms tick budget")
            for e in (0.01, 0.05, 0.10):
                ax.axhline(e, color="grey", ls=":", lw=0.8)
                ax.text(1.005, e, f"{e:.0%}", fontsize=7,
                        color="grey", va="bottom", transform=ax.get_yaxis_transform())
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("step time per 1 ms tick, median (µs)")
            ax.set_ylabel("force error, RMS |F − F_ref| / RMS |F_ref|" if "rms_error" in sub[0]
                          else "force error, max |F − F_ref| / max |F_ref|")
            ax.set_title(f"{scene}, {law} springs")
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=5.5, loc="lower left", ncol=2)
    fig.suptitle("conica speed against accuracy: every integrator × substeps × resolution "
                 "(marker size: substeps; hollow triangles: implicit 1 Newton)")
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
