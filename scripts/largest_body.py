#!/usr/bin/python3
"""The largest body conica-server holds at 1 kHz, with and without the active region.

For each lattice of n x n x n cells of 5 mm (the conical card and solver of
configs/block-20k.pbtxt), starts conica-server on private loopback ports for --seconds, presses
the top centre with conica-probe's press script (8 mm probe, 5 mm deep at 10 mm/s, held), and
reads the server's own count of ticks and missed ticks and its last loop statistics (tick
lateness and step time percentiles over its rolling window). A body is held when missed ticks
stay <= --max-missed (fraction, default 0.5 %: on a shared 2-core machine the smallest bodies
already miss 0.1-0.4 % of an 8 s run to the machine, while a body the loop cannot hold misses
several per cent). Prints one table row per run; the scenes live in a temporary
folder.

    /usr/bin/python3 scripts/largest_body.py --cells 10 16 20 24 27 30 --seconds 8
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CELL = 0.005  # m

SCENE = """name: "block-{n}"
lattice {{ size {{ x: {L} y: {L} z: {L} }} cells: [{n}, {n}, {n}] }}
density: 1000
group {{
  name: "tissue"
  card {{
    conical {{ G: 2e8 d: 1e-3 D1: 2e-3 D2: 8e-3 L0: 10e-3 n_a: 3 }}
    stiffness_cap: 20
    damping: 0.01
  }}
}}
fixed {{ plane {{ normal {{ z: 1 }} offset: 0 }} }}
probe {{ name: "tool" radius: 0.008 }}
solver {{
  integrator: SYMPLECTIC_EULER
  rate_hz: 1000
  mass_damping: 5
  {active}
}}
"""


def run(binary_dir, scene_path, L, seconds, port, extra):
    """Serves scene_path (a block L m across) and presses its top centre."""
    server = subprocess.Popen(
        [os.path.join(binary_dir, "conica-server"), "--scene", scene_path, "--seconds", str(seconds),
         "--stats-seconds", "1", "--probe-endpoint", f"tcp://127.0.0.1:{port}",
         "--state-endpoint", f"tcp://127.0.0.1:{port + 1}",
         "--control-endpoint", f"tcp://127.0.0.1:{port + 2}"] + extra,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    start = time.monotonic()
    # Wait for "serving" (the load measures the step and may build a large body first).
    while True:
        line = server.stdout.readline()
        if not line:
            break
        lines.append(line)
        if "serving:" in line or time.monotonic() - start > 120:
            break
    probe = subprocess.run(
        [os.path.join(binary_dir, "conica-probe"), "--endpoint", f"tcp://127.0.0.1:{port}",
         "--script", "press", "--at", f"{L / 2},{L / 2},{L + 0.008}", "--axis", "-z",
         "--depth", "0.005", "--approach", "0.003", "--speed", "0.01",
         "--hold", str(max(0.5, seconds - 3)), "--realtime", "-o", os.devnull],
        capture_output=True, text=True)
    rest, _ = server.communicate(timeout=seconds + 120)
    lines += rest.splitlines()
    text = "\n".join(lines)
    step = re.search(r"step ([0-9.]+) us \(median of 50\)", text)
    stopped = re.search(r"stopped after (\d+) ticks \((\d+) missed\)", text)
    loops = re.findall(r"lateness p50/p99/max (\d+)/(\d+)/(\d+) us; step p50/p99 (\d+)/(\d+) us", text)
    refused = re.search(r"the step costs .* period at .*", text)
    if refused and not stopped:
        return {"refused": refused.group(0)}
    if not stopped:
        sys.stderr.write(text + "\n" + probe.stdout + probe.stderr)
        return None
    force = re.search(r"max \|F\| ([0-9.e-]+) N", probe.stdout + probe.stderr)
    last = loops[-1] if loops else ("-",) * 5
    return {"load_step_us": float(step.group(1)) if step else float("nan"),
            "ticks": int(stopped.group(1)), "missed": int(stopped.group(2)),
            "late_p99": last[1], "step_p50": last[3], "step_p99": last[4],
            "force": force.group(1) if force else "-"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", type=int, nargs="+", default=[10, 16, 20, 24, 27, 30])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--tolerance", type=float, default=3e-4, help="m, active region tolerance")
    ap.add_argument("--max-missed", type=float, default=0.005)
    ap.add_argument("--binary-dir", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--port", type=int, default=6755)
    ap.add_argument("--server-args", default="", help="extra conica-server flags")
    args = ap.parse_args()
    print("| cells | nodes | active region | step at load | step p50 / p99 (loop) | tick lateness p99 "
          "| missed ticks | peak force | held at 1 kHz |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.cells:
            for active in (False, True):
                L = n * CELL
                path = os.path.join(tmp, f"block-{n}-{int(active)}.pbtxt")
                with open(path, "w") as f:
                    f.write(SCENE.format(n=n, L=f"{L:.6g}",
                                         active=f"active_region {{ tolerance: {args.tolerance} }}"
                                         if active else ""))
                r = run(args.binary_dir, path, L, args.seconds, args.port, args.server_args.split())
                nodes = (n + 1) ** 3
                label = f"{args.tolerance:g} m" if active else "off"
                if r is None:
                    print(f"| {n} | {nodes:,} | {label} | (server failed) | | | | | |")
                elif "refused" in r:
                    print(f"| {n} | {nodes:,} | {label} | refused: {r['refused']} | | | | | no |")
                else:
                    frac = r["missed"] / max(1, r["ticks"] + r["missed"])
                    held = "yes" if frac <= args.max_missed else "no"
                    print(f"| {n} | {nodes:,} | {label} | {r['load_step_us']:.0f} us | "
                          f"{r['step_p50']} / {r['step_p99']} us | {r['late_p99']} us | "
                          f"{r['missed']} / {r['ticks'] + r['missed']} ({100 * frac:.2f} %) | "
                          f"{r['force']} N | {held} |")
                sys.stdout.flush()


if __name__ == "__main__":
    main()
