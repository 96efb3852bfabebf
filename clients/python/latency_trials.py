#!/usr/bin/env python3
"""Interleaved latency trials: several server/client option variants measured in one run.

For every trial and every variant (the order rotates from trial to trial) a fresh conica-server
(conica.LocalServer) serves the scene on ports the OS picks and conica-latency sends at --rate-hz
for --seconds; the summary line (p50_us, p99_us, ...) and the legs are collected. Prints a
Markdown table with the median p50 / p99 per variant and their ratios to the first variant (the
default), and the load average seen before each trial (the machine may be shared).

    .venv/bin/python clients/python/latency_trials.py --bin build/bin --scene configs/liver.pbtxt \\
        --trials 5 --seconds 10      # a venv with the package conica (clients/README.md)
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

try:
    import conica
    conica.Client
except (ImportError, AttributeError):  # not installed (or only the generated modules on the path)
    sys.exit("latency_trials.py: needs the Python package conica: /usr/bin/python3 -m venv "
             "--system-site-packages .venv && .venv/bin/pip install --no-build-isolation "
             "clients/python, then run this with .venv/bin/python (clients/python/README.md)")

# name, server options, conica-latency options
VARIANTS = [
    ("default", [], []),
    ("client spin + busy poll", [], ["--spin-us", "100", "--busy-poll-us", "500"]),
    ("server busy poll", ["--busy-poll"], []),
    ("server + client busy poll", ["--busy-poll"], ["--spin-us", "100", "--busy-poll-us", "500"]),
    ("server I/O threads FIFO", ["--realtime-io"], []),
    ("client FIFO", [], ["--realtime"]),
    ("server I/O FIFO + client FIFO", ["--realtime-io"], ["--realtime"]),
    ("all of the above", ["--realtime-io", "--busy-poll"],
     ["--realtime", "--spin-us", "100", "--busy-poll-us", "500"]),
    ("server I/O FIFO + client FIFO, spin 100 us", ["--realtime-io"], ["--realtime", "--spin-us", "100"]),
    ("server I/O FIFO + busy poll, client FIFO", ["--realtime-io", "--busy-poll"], ["--realtime"]),
    ("server I/O FIFO + busy poll in a normal-priority loop, client FIFO",
     ["--realtime-io", "--busy-poll", "--no-realtime"], ["--realtime"]),
    ("server I/O FIFO + busy poll resting 10 % of a period after each probe, client FIFO",
     ["--realtime-io", "--busy-poll", "--busy-poll-fraction", "0.9"], ["--realtime"]),
    ("server I/O FIFO + busy poll resting 25 % of a period after each probe, client FIFO",
     ["--realtime-io", "--busy-poll", "--busy-poll-fraction", "0.75"], ["--realtime"]),
]


def one_trial(args, server_extra, client_extra):
    try:
        server = conica.LocalServer(os.path.join(args.bin, "conica-server"), scene=args.scene,
                                    seconds=args.seconds + 30, realtime=True, args=server_extra,
                                    start_timeout=60)
    except conica.ServerStartError as e:
        sys.exit(f"latency_trials.py: {e}")
    with server:
        r = subprocess.run([os.path.join(args.bin, "conica-latency"), "--endpoint",
                            server.probe_endpoint, "--control-endpoint", server.control_endpoint,
                            "--rate-hz", str(args.rate_hz), "--seconds", str(args.seconds),
                            *client_extra],
                           capture_output=True, text=True, timeout=args.seconds + 60)
    m = re.search(r"p50_us=(\S+) p99_us=(\S+) p999_us=(\S+) max_us=(\S+) lost=(\d+) sent=(\d+)", r.stdout)
    if not m:
        sys.exit("latency_trials.py: no summary line from conica-latency:\n" + r.stdout + r.stderr)
    legs = re.search(r"scheduled -> server recv (\S+) / (\S+), in server (\S+) / (\S+), "
                     r"server reply -> client read (\S+) / (\S+)", r.stdout)
    return {"p50": float(m.group(1)), "p99": float(m.group(2)), "lost": int(m.group(5)),
            "to_server_p50": float(legs.group(1)) if legs else float("nan"),
            "to_client_p50": float(legs.group(5)) if legs else float("nan")}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/bin", help="folder with conica-server and conica-latency")
    ap.add_argument("--scene", default="configs/liver.pbtxt")
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=10)
    ap.add_argument("--rate-hz", type=float, default=1000)
    ap.add_argument("--only", help="comma-separated indices into VARIANTS to run (the first is the "
                                   "reference of the ratios; 0 is the default)")
    args = ap.parse_args()
    variants = VARIANTS
    if args.only:
        variants = [VARIANTS[int(i)] for i in args.only.split(",")]
    results = {v[0]: [] for v in variants}
    loads = []
    for t in range(args.trials):
        order = variants[t % len(variants):] + variants[:t % len(variants)]
        for name, server_extra, client_extra in order:
            loads.append(os.getloadavg()[0])
            r = one_trial(args, server_extra, client_extra)
            results[name].append(r)
            print(f"trial {t + 1} {name}: p50 {r['p50']:.1f} us p99 {r['p99']:.1f} us lost {r['lost']} "
                  f"(load {loads[-1]:.2f})", file=sys.stderr, flush=True)
    base = results[variants[0][0]]
    b50 = statistics.median(r["p50"] for r in base)
    b99 = statistics.median(r["p99"] for r in base)
    print(f"\n{args.trials} x {args.seconds:g} s per variant at {args.rate_hz:g} Hz, {args.scene}; "
          f"load average (1 min) before the trials: median {statistics.median(loads):.2f}, "
          f"range {min(loads):.2f}-{max(loads):.2f}\n")
    print("| variant | server | conica-latency | p50 (median) | p99 (median) | p50 / default | "
          "p99 / default | sched -> server recv p50 | reply -> client read p50 | lost |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, server_extra, client_extra in variants:
        rs = results[name]
        p50 = statistics.median(r["p50"] for r in rs)
        p99 = statistics.median(r["p99"] for r in rs)
        ts = statistics.median(r["to_server_p50"] for r in rs)
        tc = statistics.median(r["to_client_p50"] for r in rs)
        lost = sum(r["lost"] for r in rs)
        print(f"| {name} | `{' '.join(server_extra) or '-'}` | `{' '.join(client_extra) or '-'}` | "
              f"{p50:.0f} us | {p99:.0f} us | {p50 / b50:.2f} | {p99 / b99:.2f} | {ts:.0f} us | "
              f"{tc:.0f} us | {lost} |")
    print("\nper trial p50 / p99 (us):")
    for name, _, _ in variants:
        print(f"  {name}: " + ", ".join(f"{r['p50']:.0f}/{r['p99']:.0f}" for r in results[name]))


if __name__ == "__main__":
    main()
