#!/usr/bin/env python3
"""A minimal conica probe client: press a probe into the scene and record the forces.

Sends one probe update per step (positions in metres) with conica.Client, waits for each reply
and writes t,probe,seq,x,y,z,fx,fy,fz,contact,rtt_us (s, m, N, us). Needs the package conica
(clients/README.md: pip install --no-build-isolation clients/python into a venv):

    .venv/bin/python clients/python/probe.py --out press.csv

Against a CURVE server (conica-server --curve-server-key K --curve-clients DIR) give the
server's public certificate and this client's secret certificate, ZeroMQ certificates as
conica-keygen DIR NAME (or pyzmq's zmq.auth.create_certificates) writes them (the server lists
NAME.key):

    ... probe.py --curve-server-pub keys/server.key --curve-key keys/alice.key_secret
"""
import argparse
import csv
import sys
import time

try:
    import conica
    conica.Client
except (ImportError, AttributeError):  # not installed (or only the generated modules on the path)
    sys.exit("probe.py: needs the Python package conica: /usr/bin/python3 -m venv "
             "--system-site-packages .venv && .venv/bin/pip install --no-build-isolation "
             "clients/python, then run this with .venv/bin/python (clients/python/README.md)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--endpoint", default=conica.DEFAULT_ENDPOINT)
    ap.add_argument("--probe", type=int, default=0)
    ap.add_argument("--at", default="0.02,0.02,0.045", help="m, probe centre at depth 0 (top of the builtin cube)")
    ap.add_argument("--depth", type=float, default=0.005, help="m, how far to press along -z")
    ap.add_argument("--approach", type=float, default=0.005, help="m, start this far above")
    ap.add_argument("--steps", type=int, default=500, help="updates from start to full depth")
    ap.add_argument("--hold", type=int, default=200, help="updates held at full depth")
    ap.add_argument("--rate-hz", type=float, default=1000,
                    help="updates per second, paced as a haptic device would (0: each as soon as the "
                         "last reply is back)")
    ap.add_argument("--timeout-ms", type=int, default=2000)
    ap.add_argument("--out", default="-", help="CSV file ('-': stdout)")
    ap.add_argument("--curve-server-pub", metavar="FILE",
                    help="CURVE: the server's public certificate (its NAME.key, not NAME.key_secret)")
    ap.add_argument("--curve-key", metavar="FILE",
                    help="CURVE: this client's secret certificate NAME.key_secret (the server lists its NAME.key)")
    args = ap.parse_args()
    curve = None
    if args.curve_server_pub or args.curve_key:
        if not (args.curve_server_pub and args.curve_key):
            sys.exit("probe.py: --curve-server-pub and --curve-key go together")
        try:
            curve = conica.curve_keys(args.curve_server_pub, args.curve_key)
        except conica.KeyFileError as e:
            sys.exit(f"probe.py: {e}")
    x0, y0, z0 = (float(v) for v in args.at.split(","))

    out = sys.stdout if args.out == "-" else open(args.out, "w", newline="")
    w = csv.writer(out)
    w.writerow(["t", "probe", "seq", "x", "y", "z", "fx", "fy", "fz", "contact", "rtt_us"])
    dt = 1e-3 if args.rate_hz <= 0 else 1 / args.rate_hz  # s of script time per update
    total = args.steps + args.hold
    try:
        with conica.Client(args.endpoint, timeout=args.timeout_ms / 1e3, curve=curve) as client:
            start = time.monotonic()
            for seq in range(total + 1):
                if args.rate_hz > 0:  # on schedule: a late update is sent at once, not skipped
                    time.sleep(max(0.0, start + seq * dt - time.monotonic()))
                d = -args.approach + (args.approach + args.depth) * min(seq, args.steps) / args.steps
                z = z0 - d
                r = client.probe((x0, y0, z), probe_id=args.probe)
                f = r.force
                w.writerow([f"{seq * dt:.6f}", args.probe, seq, x0, y0, f"{z:.9g}", f"{f[0]:.9g}",
                            f"{f[1]:.9g}", f"{f[2]:.9g}", int(r.contact), f"{r.round_trip_s * 1e6:.1f}"])
    except conica.Timeout:
        sys.exit(f"probe.py: no reply from {args.endpoint} within {args.timeout_ms} ms")
    except conica.ConicaError as e:
        sys.exit(f"probe.py: {e}")
    finally:
        if out is not sys.stdout:
            out.close()


if __name__ == "__main__":
    main()
