"""The node's connection to conica-server: probe updates (force and stiffness back), the body's
surface (GET_MESH) and its deformed node positions (state frames "S").

open_link() uses the Python package conica (clients/python: conica.Client) when it is installed,
else a minimal client on pyzmq and the generated protocol module conica.v1.messages_pb2 (the
build writes it into build/proto/gen; put that on PYTHONPATH). Both give the same Reply and raise
LinkTimeout when the server does not answer in time; a probe() waits for its reply.

ProbeStream pipelines probe updates (the next is sent before the last is answered), which a
1 kHz topic needs once a round trip and the node's own work add up to a period: a producer thread
sends, an I/O thread owns the DEALER socket and hands each reply to a callback. It needs only
pyzmq and conica.v1.messages_pb2 (from the installed package or build/proto/gen).

Positions in m, forces in N, stiffness in N/m, all in the scene frame."""
import itertools
import random
import threading
import time
from collections import namedtuple

import numpy as np

# force (3,) N on the probe, stiffness (3, 3) N/m (row i, column j = dF_i / dx_j), contact
Reply = namedtuple("Reply", "force stiffness contact tick")


class LinkTimeout(Exception):
    """No answer from the server within the timeout."""


class LinkError(Exception):
    """The server refused a request, or its answer made no sense."""


def sibling(endpoint, offset):
    """tcp://host:P -> tcp://host:P+offset (the server's state and control sockets)."""
    head, _, port = endpoint.rpartition(":")
    if not port.isdigit():
        raise LinkError(f"endpoint {endpoint!r} has no port; give the state and control "
                        "endpoints explicitly")
    return f"{head}:{int(port) + offset}"


class PackageLink:
    """Through conica.Client (the installed package)."""
    kind = "conica package"

    def __init__(self, endpoint, state_endpoint, control_endpoint, timeout):
        import conica
        self._conica = conica
        self._client = conica.Client(endpoint, state_endpoint=state_endpoint,
                                     control_endpoint=control_endpoint, timeout=timeout)
        self._state_endpoint = state_endpoint
        self._timeout = timeout

    def probe(self, position, probe_id=0, radius=None):
        try:
            r = self._client.probe(position, probe_id=probe_id, radius=radius)
        except self._conica.Timeout as e:
            raise LinkTimeout(str(e)) from None
        except self._conica.ConicaError as e:
            raise LinkError(str(e)) from None
        return Reply(r.force, r.stiffness, r.contact, r.tick)

    def mesh(self):
        """(rest positions (n, 3) float32 m, triangles (t, 3) uint32)."""
        try:
            m = self._client.mesh()
        except self._conica.Timeout as e:
            raise LinkTimeout(str(e)) from None
        return np.asarray(m.rest_positions), np.asarray(m.triangles)

    def positions_subscriber(self):
        """A callable latest(timeout) -> (n, 3) float32 node positions (m) or None; use it from
        one thread only."""
        sub = self._conica.Subscriber(self._state_endpoint, forces=False, positions=True,
                                      timeout=self._timeout)

        def latest(timeout):
            try:
                f = sub.latest(timeout)
            except self._conica.Timeout:
                return None
            return None if f.positions is None else np.array(f.positions)
        return latest

    def close(self):
        self._client.close()


class ZmqLink:
    """pyzmq and conica.v1.messages_pb2 directly (the package is not installed)."""
    kind = "pyzmq + protobuf"

    def __init__(self, endpoint, state_endpoint, control_endpoint, timeout):
        import zmq
        from conica.v1 import messages_pb2 as pb
        self._zmq, self._pb = zmq, pb
        self._ctx = zmq.Context.instance()
        self._timeout_ms = timeout * 1e3
        self._client_id = random.randrange(1, 2**31)
        self._seq = 0
        self._sock = self._dealer(endpoint)
        self._control = self._dealer(control_endpoint)
        self._state_endpoint = state_endpoint
        self._endpoint, self._control_endpoint = endpoint, control_endpoint

    def _dealer(self, endpoint):
        s = self._ctx.socket(self._zmq.DEALER)
        s.setsockopt(self._zmq.LINGER, 0)
        s.connect(endpoint)
        return s

    def _wait(self, sock, what, endpoint):
        if not sock.poll(self._timeout_ms):
            raise LinkTimeout(f"{endpoint}: no {what} within {self._timeout_ms / 1e3:g} s")
        reply = self._pb.ServerMessage()
        reply.ParseFromString(sock.recv())
        if reply.HasField("error"):
            raise LinkError(f"{endpoint}: {reply.error.message}")
        return reply

    def probe(self, position, probe_id=0, radius=None):
        self._seq += 1
        m = self._pb.ClientMessage(protocol_version=1)
        p = m.probe
        p.client_id, p.probe_id, p.sequence = self._client_id, probe_id, self._seq
        p.send_time_ns = time.monotonic_ns()
        p.position.x, p.position.y, p.position.z = (float(v) for v in position)
        if radius:
            p.radius = float(radius)
        self._sock.send(m.SerializeToString())
        while True:
            r = self._wait(self._sock, f"reply to probe update {self._seq}", self._endpoint)
            if r.HasField("force") and r.force.sequence == self._seq:
                f = r.force
                k = np.array(f.stiffness.m, dtype=float)
                if k.size != 9:
                    raise LinkError(f"{self._endpoint}: stiffness with {k.size} values, not 9")
                return Reply(np.array([f.force.x, f.force.y, f.force.z]), k.reshape(3, 3),
                             f.contact, f.tick)

    def mesh(self):
        m = self._pb.ClientMessage(protocol_version=1)
        m.control.kind = self._pb.ControlRequest.GET_MESH
        m.control.sequence = 1
        self._control.send(m.SerializeToString())
        r = self._wait(self._control, "reply to GET_MESH", self._control_endpoint).control_reply
        if not r.ok:
            raise LinkError(f"{self._control_endpoint}: GET_MESH refused: {r.message}")
        pos = np.array(r.rest_positions, dtype=np.float32).reshape(-1, 3)
        return pos, np.array(r.triangles, dtype=np.uint32).reshape(-1, 3)

    def positions_subscriber(self):
        zmq, pb = self._zmq, self._pb
        sub = self._ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, b"S")
        sub.connect(self._state_endpoint)

        def latest(timeout):
            parts = None
            while True:
                try:
                    parts = sub.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
            if parts is None:
                if not sub.poll(timeout * 1e3):
                    return None
                parts = sub.recv_multipart()
            msg = pb.ServerMessage()
            msg.ParseFromString(parts[-1])
            pos = np.array(msg.state.positions, dtype=np.float32)
            return pos.reshape(-1, 3) if pos.size else None
        return latest

    def close(self):
        self._sock.close()
        self._control.close()


class ProbeStream:
    """Pipelined probe updates. send() from one thread (the producer); on_reply(token, Reply) and
    on_timeout(token) are called from the stream's I/O thread, in the order replies arrive.
    Updates unanswered after `timeout` s count as timed out (their late replies are dropped)."""
    _ids = itertools.count()

    def __init__(self, endpoint, on_reply, on_timeout=None, timeout=0.1, probe_id=0, radius=None):
        import zmq
        from conica.v1 import messages_pb2 as pb
        self._zmq, self._pb = zmq, pb
        self._ctx = zmq.Context.instance()
        self._on_reply, self._on_timeout = on_reply, on_timeout
        self._timeout = timeout
        self._endpoint = endpoint
        self._client_id = random.randrange(1, 2**31)
        self._probe_id, self._radius = probe_id, radius
        self._seq = 0
        self._pending = {}  # sequence -> (token, send time s); written by both threads (GIL)
        self._inproc = f"inproc://conica-ros-probes-{next(self._ids)}"
        self._rx = self._ctx.socket(zmq.PAIR)
        self._rx.bind(self._inproc)
        self._tx = self._ctx.socket(zmq.PAIR)
        self._tx.connect(self._inproc)
        self._stop = threading.Event()
        self._msg = pb.ClientMessage(protocol_version=1)
        self._thread = threading.Thread(target=self._run, name="conica-probes", daemon=True)
        self._thread.start()
        self.sent = self.replies = self.timeouts = self.errors = 0
        self.last_error = ""

    def send(self, position, token):
        """Queues a probe update to `position` (m, scene frame); `token` comes back with it."""
        self._seq += 1
        p = self._msg.probe
        p.client_id, p.probe_id, p.sequence = self._client_id, self._probe_id, self._seq
        p.send_time_ns = time.monotonic_ns()
        p.position.x, p.position.y, p.position.z = (float(v) for v in position)
        if self._radius:
            p.radius = float(self._radius)
        self._pending[self._seq] = (token, time.monotonic())
        self._tx.send(self._msg.SerializeToString())
        self.sent += 1

    def _run(self):
        zmq, pb = self._zmq, self._pb
        dealer = self._ctx.socket(zmq.DEALER)
        dealer.setsockopt(zmq.LINGER, 0)
        dealer.connect(self._endpoint)
        poller = zmq.Poller()
        poller.register(self._rx, zmq.POLLIN)
        poller.register(dealer, zmq.POLLIN)
        reply = pb.ServerMessage()
        next_sweep = time.monotonic() + self._timeout
        try:
            while not self._stop.is_set():
                events = dict(poller.poll(20))
                if self._rx in events:
                    while True:
                        try:
                            dealer.send(self._rx.recv(zmq.NOBLOCK))
                        except zmq.Again:
                            break
                if dealer in events:
                    while True:
                        try:
                            data = dealer.recv(zmq.NOBLOCK)
                        except zmq.Again:
                            break
                        reply.ParseFromString(data)
                        if reply.HasField("error"):
                            self.errors += 1
                            self.last_error = reply.error.message
                            self._pending.pop(reply.error.sequence, None)
                            continue
                        if not reply.HasField("force"):
                            continue
                        f = reply.force
                        entry = self._pending.pop(f.sequence, None)
                        if entry is None:
                            continue  # timed out already
                        k = list(f.stiffness.m)
                        if len(k) != 9:
                            self.errors += 1
                            self.last_error = f"stiffness with {len(k)} values, not 9"
                            continue
                        self.replies += 1
                        self._on_reply(entry[0], Reply((f.force.x, f.force.y, f.force.z),
                                                       (k[0:3], k[3:6], k[6:9]), f.contact, f.tick))
                now = time.monotonic()
                if now >= next_sweep:
                    next_sweep = now + self._timeout / 2
                    old = [s for s, (_, t) in list(self._pending.items()) if now - t > self._timeout]
                    for s in old:
                        entry = self._pending.pop(s, None)
                        if entry is not None:
                            self.timeouts += 1
                            if self._on_timeout:
                                self._on_timeout(entry[0])
        finally:
            dealer.close()
            self._rx.close()

    def close(self):
        self._stop.set()
        self._thread.join(timeout=1)
        self._tx.close()


def open_link(endpoint, state_endpoint=None, control_endpoint=None, timeout=0.1, kind="auto"):
    """kind: "auto" (the conica package when it imports, else pyzmq), "package" or "zmq"."""
    state_endpoint = state_endpoint or sibling(endpoint, 1)
    control_endpoint = control_endpoint or sibling(endpoint, 2)
    if kind not in ("auto", "package", "zmq"):
        raise LinkError(f"link {kind!r}: use auto, package or zmq")
    if kind in ("auto", "package"):
        try:
            from conica import Client  # noqa: F401  (the installed package, not build/proto/gen)
            return PackageLink(endpoint, state_endpoint, control_endpoint, timeout)
        except ImportError as e:
            if kind == "package":
                raise LinkError(f"the Python package conica is not installed ({e}); install it "
                                "into a venv that sees Debian's rospy and run the node with "
                                "that venv's python: /usr/bin/python3 -m venv "
                                "--system-site-packages .venv && .venv/bin/pip install "
                                "--no-build-isolation clients/python, then .venv/bin/python "
                                "clients/ros/conica-ros") from None
    try:
        return ZmqLink(endpoint, state_endpoint, control_endpoint, timeout)
    except ImportError as e:
        raise LinkError(f"cannot talk to the server: {e} (run the node with the python of a "
                        "venv holding the conica package: /usr/bin/python3 -m venv "
                        "--system-site-packages .venv && .venv/bin/pip install "
                        "--no-build-isolation clients/python; or put build/proto/gen on "
                        "PYTHONPATH with python3-zmq and python3-protobuf)") from None


__all__ = ["Reply", "LinkTimeout", "LinkError", "ProbeStream", "open_link", "sibling"]
