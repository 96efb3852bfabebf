#!/usr/bin/python3
"""The liver press of `conica-lab tradeoff` run headless with several integrators, compared tick by
tick with symplectic Euler x64: RMS error, RMS error of moving means (10 and 30 ms) and the median
per-tick difference, as a Markdown table (docs/speed-vs-accuracy.md).

    /usr/bin/python3 scripts/liver_press_integrators.py [--bin build/bin] [--out out/liver-press]

The scenes are configs/liver.pbtxt with the node penalty of the tradeoff sweep (100 N/m per node)
and the solver settings below, written to --out; the probe is pressed 10 mm along -y in 0.2 s at
the sweep's press point and held to 0.3 s (300 ticks at 1 kHz).
"""
import argparse
import csv
import math
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PRESS = (-0.0485, 0.0716, -0.0093)  # m, first contact (lab_tradeoff.cc, kPressAt)
DEPTH = 0.010                       # m
TICKS = 300
SETTINGS = [  # name, solver lines added to the scene
    ("symplectic x64 (reference)", "  substeps: 64"),
    ("symplectic x1", ""),
    ("implicit x1", "  integrator: IMPLICIT_EULER\n  newton_iterations: 2\n  cg_iterations: 40"),
    ("implicit x4",
     "  integrator: IMPLICIT_EULER\n  newton_iterations: 2\n  cg_iterations: 40\n  substeps: 4"),
]


def scene_text(extra):
    text = open(os.path.join(ROOT, "configs", "liver.pbtxt")).read()
    mesh = re.search(r'path: "([^"]+)"', text).group(1)
    text = text.replace(mesh, os.path.normpath(os.path.join(ROOT, "configs", mesh)))
    text = text.replace('probe { name: "tool" radius: 0.01 }',
                        'probe { name: "tool" radius: 0.01 stiffness: 100 contact: NODES }')
    assert "contact: NODES" in text, "configs/liver.pbtxt's probe line changed"
    if "integrator: IMPLICIT_EULER" in extra:
        text = text.replace("  integrator: SYMPLECTIC_EULER\n", "")
    return text.replace("  mass_damping: 5\n", "  mass_damping: 5\n" + (extra + "\n" if extra else ""))


def forces(path):
    by_tick = {}
    for row in csv.DictReader(open(path)):
        f = [float(row[k]) for k in ("fx", "fy", "fz")]
        by_tick[int(row["tick"])] = math.sqrt(sum(v * v for v in f))
    return [by_tick[t] for t in sorted(by_tick)]


def moving_mean(values, window):
    out, total = [], 0.0
    for t, v in enumerate(values):
        total += v
        if t >= window:
            total -= values[t - window]
        out.append(total / min(t + 1, window))
    return out


def rms(values):
    return math.sqrt(sum(v * v for v in values) / len(values))


def relative_rms(run, ref):
    return rms([a - b for a, b in zip(run, ref)]) / rms(ref)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "liver-press"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    script = os.path.join(args.out, "press.csv")
    with open(script, "w") as f:
        x, y, z = PRESS
        f.write("t,probe,x,y,z\n")
        f.write(f"0,0,{x},{y},{z}\n0.2,0,{x},{y - DEPTH},{z}\n0.3,0,{x},{y - DEPTH},{z}\n")
    runs = []
    for k, (name, extra) in enumerate(SETTINGS):
        scene = os.path.join(args.out, f"liver-{k}.pbtxt")
        with open(scene, "w") as f:
            f.write(scene_text(extra))
        out = os.path.join(args.out, f"forces-{k}.csv")
        subprocess.run([os.path.join(args.bin, "conica-lab"), "run", "--scene", scene,
                        "--probe-script", script, "--ticks", str(TICKS), "--out", out],
                       check=True, stdout=subprocess.DEVNULL)
        runs.append((name, forces(out)))
    ref = runs[0][1]
    median = sorted(ref)[len(ref) // 2]
    print(f"reference: peak {max(ref):.3f} N, RMS {rms(ref):.3f} N, "
          f"{sum(1 for v in ref if v > 2 * median)} ticks above twice its median\n")
    print("| setting | RMS | RMS of 10 ms means | RMS of 30 ms means | median per-tick difference |")
    print("|---|---:|---:|---:|---:|")
    for name, run in runs[1:]:
        cols = [relative_rms(run, ref)]
        cols += [relative_rms(moving_mean(run, w), moving_mean(ref, w)) for w in (10, 30)]
        diffs = sorted(abs(a - b) / max(b, 1e-12) for a, b in zip(run[50:], ref[50:]))
        cols.append(diffs[len(diffs) // 2])
        print(f"| {name} | " + " | ".join(f"{100 * c:.1f} %" for c in cols) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
