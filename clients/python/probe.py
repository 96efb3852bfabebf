#!/usr/bin/python3
"""A minimal conica probe client: press a probe into the scene and record the forces.

Connects a DEALER to the server's probe ROUTER, sends one ProbeUpdate per step (positions in
metres), waits for the ForceReply and writes t,probe,seq,x,y,z,fx,fy,fz,contact,rtt_us.

    PYTHONPATH=build/proto/gen /usr/bin/python3 clients/python/probe.py --out press.csv
"""
import argparse
import csv
import sys
import time

import zmq

from conica.v1 import messages_pb2 as pb


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--endpoint", default="tcp://127.0.0.1:5555")
    ap.add_argument("--probe", type=int, default=0)
    ap.add_argument("--at", default="0.02,0.02,0.045", help="m, probe centre at depth 0 (top of the builtin cube)")
    ap.add_argument("--depth", type=float, default=0.005, help="m, how far to press along -z")
    ap.add_argument("--approach", type=float, default=0.005, help="m, start this far above")
    ap.add_argument("--steps", type=int, default=500, help="updates from start to full depth")
    ap.add_argument("--hold", type=int, default=200, help="updates held at full depth")
    ap.add_argument("--timeout-ms", type=int, default=2000)
    ap.add_argument("--out", default="-", help="CSV file ('-': stdout)")
    args = ap.parse_args()
    x0, y0, z0 = (float(v) for v in args.at.split(","))

    ctx = zmq.Context()
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.connect(args.endpoint)

    out = sys.stdout if args.out == "-" else open(args.out, "w", newline="")
    w = csv.writer(out)
    w.writerow(["t", "probe", "seq", "x", "y", "z", "fx", "fy", "fz", "contact", "rtt_us"])
    msg = pb.ClientMessage(protocol_version=1)
    reply = pb.ServerMessage()
    dt = 1e-3  # s of script time per update
    total = args.steps + args.hold
    for seq in range(total + 1):
        d = -args.approach + (args.approach + args.depth) * min(seq, args.steps) / args.steps
        z = z0 - d
        p = msg.probe
        p.client_id, p.probe_id, p.sequence = 1, args.probe, seq
        p.send_time_ns = time.monotonic_ns()
        p.position.x, p.position.y, p.position.z = x0, y0, z
        sock.send(msg.SerializeToString())
        while True:  # one outstanding update: wait for its reply
            if not sock.poll(args.timeout_ms):
                sys.exit(f"probe.py: no reply from {args.endpoint} within {args.timeout_ms} ms")
            reply.ParseFromString(sock.recv())
            if reply.HasField("error"):
                sys.exit(f"probe.py: server error: {reply.error.message}")
            if reply.HasField("force") and reply.force.sequence == seq:
                break
        f = reply.force
        rtt_us = (time.monotonic_ns() - f.client_send_time_ns) / 1e3
        w.writerow([f"{seq * dt:.6f}", args.probe, seq, x0, y0, f"{z:.9g}", f"{f.force.x:.9g}",
                    f"{f.force.y:.9g}", f"{f.force.z:.9g}", int(f.contact), f"{rtt_us:.1f}"])
    if out is not sys.stdout:
        out.close()
    sock.close()
    ctx.term()


if __name__ == "__main__":
    main()
