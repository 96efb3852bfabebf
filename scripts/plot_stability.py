#!/usr/bin/python3
"""Draw the stability map written by `conica-lab stability` (CSV) as a PNG."""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    with open(a.csv, newline="") as f:
        rows = list(csv.DictReader(f))
    release = [r for r in rows if r["case"] == "release"]
    others = [r for r in rows if r["case"] != "release"]
    integrators = ["symplectic", "explicit", "implicit"]
    fig = plt.figure(figsize=(15, 10), dpi=100)
    gs = fig.add_gridspec(2, 3, height_ratios=[1, 1.15])
    axes = [fig.add_subplot(gs[0, c]) for c in range(3)] + [fig.add_subplot(gs[1, :])]
    # Theory: symplectic Euler is stable while h omega < 2, i.e. dt < 2 / omega_max(k).
    crit = {}
    for r in release:
        k, dt, hw = float(r["stiffness_n_per_m"]), float(r["dt_ms"]), float(r["h_omega"])
        crit[k] = 2.0 * dt / hw
    ks = sorted(crit)
    for ax, name in zip(axes, integrators):
        for r in release:
            if r["integrator"] != name:
                continue
            dt, k = float(r["dt_ms"]), float(r["stiffness_n_per_m"])
            drift = float(r["energy_drift"])
            if r["bounded"] != "1":
                color, marker = "tab:red", "x"
            elif drift > 0.25:
                color, marker = "tab:orange", "o"
            else:
                color, marker = "tab:green", "o"
            ax.scatter(dt, k, c=color, marker=marker, s=55)
            err = r["error"]
            if r["bounded"] == "1" and err not in ("", "nan"):
                ax.annotate(f"{float(err):.0e}", (dt, k), fontsize=6, xytext=(4, 3),
                            textcoords="offset points")
        ax.plot([crit[k] for k in ks], ks, "k--", lw=1, label="h ω_max = 2")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time step (ms)")
        ax.set_ylabel("spring stiffness k (N/m)")
        ax.set_title(f"{name} Euler")
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="lower left", fontsize=8)
    axes[0].text(0.02, 0.98, "green: bounded, energy gain ≤ 25 %\norange: bounded, gain > 25 %\n"
                 "red: blew up (rolled back)\nlabels: error vs converged",
                 transform=axes[0].transAxes, va="top", fontsize=7,
                 bbox=dict(fc="white", alpha=0.8))
    ax = axes[3]
    ax.axis("off")
    cells = [[r["case"], r["integrator"], "yes" if r["bounded"] == "1" else "NO",
              r["rollbacks"], f"{float(r['max_force_n']):.3g}" if r["max_force_n"] else ""]
             for r in others]
    t = ax.table(cellText=cells, colLabels=["case (1 kHz)", "integrator", "bounded", "rollbacks",
                                           "max |F| (N)"], bbox=[0, 0, 1, 0.93], fontsize=7)
    t.auto_set_font_size(False)
    t.set_fontsize(7)
    t.scale(1, 1.25)
    ax.set_title("bottoming (min length / hard-stop length in 'drift' column of the CSV), "
                 "step loads and teleports")
    fig.suptitle("conica stability map: 4x4x2-cell block released from a 2 % stretch, no damping "
                 "(top); failure cases at 1 kHz (bottom)")
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
