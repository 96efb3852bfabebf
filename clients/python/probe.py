#!/usr/bin/python3
"""A minimal conica probe client: press a probe into the scene and record the forces.

Connects a DEALER to the server's probe ROUTER, sends one ProbeUpdate per step (positions in
metres), waits for the ForceReply and writes t,probe,seq,x,y,z,fx,fy,fz,contact,rtt_us.

    PYTHONPATH=build/proto/gen /usr/bin/python3 clients/python/probe.py --out press.csv

Against a CURVE server (conica-server --curve-server-key K --curve-clients DIR) give the
server's public key file and this client's key pair file, both as written by
conica-server --generate-keys DIR --key-name NAME (the server lists NAME.pub):

    ... probe.py --curve-server-pub keys/server.pub --curve-key keys/alice.key
"""
import argparse
import csv
import sys
import time

import zmq
from zmq.utils import z85

from conica.v1 import messages_pb2 as pb


class KeyFileError(Exception):
    pass


def read_key_file(path):
    """The keys of a conica key file ("public <z85>" / "secret <z85>" lines, '#' comments) as
    {"public": ..., "secret": ...} (bytes, z85); KeyFileError names the file, line and problem."""
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise KeyFileError(f"{path}: cannot open key file ({e.strerror})")
    keys = {}
    for n, line in enumerate(lines[:100], start=1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        ok = len(words) >= 2 and words[0] in ("public", "secret") and len(words[1]) == 40
        if ok:
            try:
                ok = len(z85.decode(words[1].encode())) == 32
            except (ValueError, KeyError, TypeError):
                ok = False
        if not ok:
            raise KeyFileError(f"{path}:{n}: expected 'public <z85 key>' or 'secret <z85 key>'")
        keys[words[0]] = words[1].encode()
    if not keys:
        raise KeyFileError(f"{path}: no key in the file")
    if "secret" in keys:
        public = zmq.curve_public(keys["secret"])
        if keys.setdefault("public", public) != public:
            raise KeyFileError(f"{path}: public and secret keys do not match")
    return keys


def curve_client_keys(server_pub_file, key_file):
    """(server public, client public, client secret) from --curve-server-pub / --curve-key."""
    if not zmq.has("curve"):
        raise KeyFileError("CURVE requested but this libzmq has no CURVE support")
    try:
        server = read_key_file(server_pub_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-server-pub: the server's .pub file)")
    if "secret" in server:
        raise KeyFileError(f"{server_pub_file}: holds the server's secret key; "
                           "give the client the server's .pub file")
    try:
        mine = read_key_file(key_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-key: this client's .key file)")
    if "secret" not in mine:
        raise KeyFileError(f"{key_file}: no secret key; give this client's .key file "
                           "(public and secret), not its .pub")
    return server["public"], mine["public"], mine["secret"]


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
    ap.add_argument("--curve-server-pub", metavar="FILE",
                    help="CURVE: the server's public key file (its .pub from conica-server --generate-keys)")
    ap.add_argument("--curve-key", metavar="FILE",
                    help="CURVE: this client's key pair file (its .key; the server lists its .pub)")
    args = ap.parse_args()
    curve = None
    if args.curve_server_pub or args.curve_key:
        if not (args.curve_server_pub and args.curve_key):
            sys.exit("probe.py: --curve-server-pub and --curve-key go together")
        try:
            curve = curve_client_keys(args.curve_server_pub, args.curve_key)
        except KeyFileError as e:
            sys.exit(f"probe.py: {e}")
    x0, y0, z0 = (float(v) for v in args.at.split(","))

    ctx = zmq.Context()
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    if curve:
        sock.curve_serverkey, sock.curve_publickey, sock.curve_secretkey = curve
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
