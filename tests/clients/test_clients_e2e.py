#!/usr/bin/python3
"""End to end: conica-server --builtin cube on free ports, then conica-probe (press script),
clients/python/probe.py (run with this interpreter, which must have the package conica) and
conica-latency --seconds 2 against it.

Checks: the press recording has one reply per sample, the normal force is ~0 before contact and
rises with depth (deeper thirds of the contact phase press harder), conica-latency ends with
'p50_us=A p99_us=B p999_us=C max_us=D lost=E sent=F' with sent = 2000 and few lost replies."""
import argparse
import csv
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time


def free_ports(n):
    socks, ports = [], []
    for _ in range(n):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        socks.append(s)
        ports.append(s.getsockname()[1])
    for s in socks:
        s.close()
    return ports


def check(cond, what):
    if not cond:
        print("FAIL:", what)
        sys.exit(1)
    print("ok:", what)


def press_forces(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    depth = [0.045 - float(r["z"]) for r in rows]  # builtin cube: top face + 5 mm probe radius
    fn = [float(r["fz"]) for r in rows]            # -F . axis with axis -z
    return rows, depth, fn


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--server", required=True)
    ap.add_argument("--probe", required=True)
    ap.add_argument("--latency", required=True)
    ap.add_argument("--python-client", required=True,
                    help="clients/python/probe.py, run with this interpreter (which has conica)")
    args = ap.parse_args()
    p, s, c = free_ports(3)
    ep = lambda port: f"tcp://127.0.0.1:{port}"  # noqa: E731
    tmp = tempfile.mkdtemp(prefix="conica-clients-")
    server = subprocess.Popen([args.server, "--builtin", "cube", "--probe-endpoint", ep(p),
                               "--state-endpoint", ep(s), "--control-endpoint", ep(c),
                               "--seconds", "90"], stdout=subprocess.DEVNULL,
                              stderr=open(os.path.join(tmp, "server.log"), "w"))
    try:
        time.sleep(1.0)
        check(server.poll() is None, "server is running")

        # Paced at the script clock (1 kHz): unpaced, the 601 samples go out in ~40 ms, the cube
        # steps ~40 times meanwhile, and which depth each reply's force belongs to depends on the
        # machine's load (a busy run read band means 0.63, 1.58, 1.25 N).
        rec = os.path.join(tmp, "press.csv")
        r = subprocess.run([args.probe, "--endpoint", ep(p), "--script", "press", "--depth", "0.006",
                            "--approach", "0.004", "--speed", "0.02", "--hold", "0.1", "--realtime",
                            "-o", rec],
                           capture_output=True, text=True, timeout=60)
        check(r.returncode == 0, f"conica-probe press exits 0 ({r.stderr.strip()})")
        rows, depth, fn = press_forces(rec)
        check(len(rows) == 601, f"one reply per sample (601 expected, got {len(rows)})")
        before = [f for d, f in zip(depth, fn) if d < -0.001]
        check(before and max(abs(f) for f in before) < 1e-9, "no force 1 mm above the surface")
        inside = [(d, f) for d, f in zip(depth, fn) if f > 0]
        check(len(inside) > 50, f"contact during the press ({len(inside)} samples)")
        d0, d1 = inside[0][0], max(depth)
        third = (d1 - d0) / 3
        mean = lambda xs: sum(xs) / len(xs)  # noqa: E731
        bands = [mean([f for d, f in inside if d0 + i * third <= d <= d0 + (i + 1) * third + 1e-12])
                 for i in range(3)]
        check(bands[0] < bands[1] < bands[2], f"force rises with depth (band means {bands} N)")

        # The body back at rest: the press above released the cube, which rings for about a
        # second (mass damping 5 /s) and would meet probe.py's paced press on its way up.
        import conica  # this interpreter has the package (--python-client)
        with conica.Client(ep(p), control_endpoint=ep(c)) as ctl:
            ctl.probe((0.02, 0.02, 0.1))  # the probe well clear of the body
            ctl.reset()

        pyrec = os.path.join(tmp, "py.csv")
        r = subprocess.run([sys.executable, args.python_client, "--endpoint", ep(p),
                            "--steps", "400", "--hold", "20", "--out", pyrec],
                           capture_output=True, text=True, timeout=60)
        check(r.returncode == 0, f"probe.py exits 0 ({r.stderr.strip()})")
        _, pdepth, pfn = press_forces(pyrec)
        # A press of 10 mm in 0.4 s paced at 1 kHz: the force rises with depth while pressing (the
        # means of three depth bands of the contact) and stays on the tool while held.
        pin = [(d, f) for d, f in zip(pdepth, pfn) if f > 0]
        pbands = []
        if len(pin) > 30:
            p0, p1 = pin[0][0], max(pdepth)
            pthird = (p1 - p0) / 3
            pbands = [mean([f for d, f in pin if p0 + i * pthird <= d <= p0 + (i + 1) * pthird + 1e-12])
                      for i in range(3)]
        check(pfn[-1] > 0 and abs(pfn[0]) < 1e-12 and len(pbands) == 3 and
              pbands[0] < pbands[1] < pbands[2],
              f"probe.py: force at full depth {pfn[-1]:.4f} N, band means {pbands} N")

        r = subprocess.run([args.latency, "--endpoint", ep(p), "--control-endpoint", ep(c),
                            "--seconds", "2", "--csv", os.path.join(tmp, "lat.csv")],
                           capture_output=True, text=True, timeout=60)
        print(r.stdout)
        check(r.returncode == 0, "conica-latency exits 0")
        last = r.stdout.strip().splitlines()[-1]
        m = re.fullmatch(r"p50_us=([\d.]+) p99_us=([\d.]+) p999_us=([\d.]+) max_us=([\d.]+) "
                         r"lost=(\d+) sent=(\d+)", last)
        check(m is not None, f"final line format: {last!r}")
        p50, p99, p999, mx = (float(m.group(i)) for i in range(1, 5))
        lost, sent = int(m.group(5)), int(m.group(6))
        check(sent == 2000, "2000 updates sent at 1 kHz for 2 s")
        check(0 < p50 <= p99 <= p999 <= mx, "percentiles ordered")
        check(lost <= sent // 100, f"lost replies {lost} <= 1 %")
        check("tick lateness" in r.stdout and "missed ticks" in r.stdout, "server loop statistics printed")
    finally:
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
    print("all end-to-end checks passed")
    shutil.rmtree(tmp, ignore_errors=True)  # kept after a failure (check exits before this)


if __name__ == "__main__":
    main()
