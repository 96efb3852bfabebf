"""The blocking conica client: probes, the state stream and control requests.

Units are SI: positions in m, forces in N, stiffness in N/m, timeouts in s. A Client may be
shared by threads: its probe and control requests are each served one after another under a
lock (a probe never waits for a control request). A Subscriber belongs to one thread."""
from __future__ import annotations

import math
import threading
import time
from types import TracebackType
from typing import Iterator, List, Optional, Type, Union

import zmq

from . import _sockets, _wire
from ._book import Item, ProbeBook
from ._pb import pb
from ._sockets import (DEFAULT_ENDPOINT, DEFAULT_STATE_ENDPOINT, DEFAULT_TIMEOUT_S, TOPIC_FORCES,
                       TOPIC_POSITIONS)
from ._wire import Vector
from .curve import CurveKeys
from .errors import ProtocolError, ServerError, Timeout
from .types import ControlResult, Mesh, ProbeReply, StateFrame

ControlKind = Union[str, int]


def control_kind(kind: ControlKind) -> int:
    """A ControlRequest.Kind from its name ("RESET", "reset") or number; ValueError otherwise."""
    if isinstance(kind, str):
        try:
            return pb.ControlRequest.Kind.Value(kind.upper())
        except ValueError:
            names = [n for n in pb.ControlRequest.Kind.keys() if n != "KIND_UNSPECIFIED"]
            raise ValueError(f"unknown control kind {kind!r} (one of {', '.join(names)})") from None
    return int(kind)


class Subscriber:
    """The server's state stream (PUB socket, default tcp://127.0.0.1:5556).

    forces:     receive force frames ("F", every tick: every probe's position in m, force in N,
                contact, and the loop statistics).
    positions:  receive position frames ("S", 60 Hz by default): the same plus the node positions
                as a (num_nodes, 3) float32 array in m, a view of the message bytes (no copy).

        with conica.Subscriber("tcp://127.0.0.1:5556", forces=False) as sub:
            for frame in sub:            # raises conica.Timeout after `timeout` s of silence
                print(frame.tick, frame.positions.shape)
    """

    def __init__(self, endpoint: str = DEFAULT_STATE_ENDPOINT, *, forces: bool = True,
                 positions: bool = True, timeout: float = DEFAULT_TIMEOUT_S,
                 curve: Optional[CurveKeys] = None,
                 context: Optional[zmq.Context] = None) -> None:
        if not (forces or positions):
            raise ValueError("subscribe to forces, positions or both")
        self.endpoint = endpoint
        self.timeout = _sockets.check_timeout(timeout, DEFAULT_TIMEOUT_S)
        ctx = context if context is not None else zmq.Context.instance()
        self._sock: zmq.Socket = ctx.socket(zmq.SUB)
        _sockets.setup(self._sock, endpoint, curve)
        if forces:
            self._sock.setsockopt(zmq.SUBSCRIBE, TOPIC_FORCES)
        if positions:
            self._sock.setsockopt(zmq.SUBSCRIBE, TOPIC_POSITIONS)

    def recv(self, timeout: Optional[float] = None) -> StateFrame:
        """The next frame; conica.Timeout when none arrives within `timeout` s."""
        t = _sockets.check_timeout(timeout, self.timeout)
        deadline = time.monotonic() + t
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout(self.endpoint, t, "state frame")
            if self._sock.poll(math.ceil(left * 1e3)):
                return self._decode(self._sock.recv_multipart(copy=False))

    def latest(self, timeout: Optional[float] = None) -> StateFrame:
        """The newest frame already received (older queued frames are dropped), or the next one
        when none is queued; conica.Timeout after `timeout` s without any."""
        newest = None
        while True:
            try:
                newest = self._sock.recv_multipart(zmq.NOBLOCK, copy=False)
            except zmq.Again:
                break
        if newest is None:
            return self.recv(timeout)
        return self._decode(newest)

    def _decode(self, parts: list) -> StateFrame:
        if len(parts) != 2:
            raise ProtocolError(self.endpoint, f"state message with {len(parts)} frames, "
                                                     "expected 2 ([topic][payload])")
        return _wire.decode_state(self.endpoint, parts[0].bytes, parts[1].buffer)

    def __iter__(self) -> Iterator[StateFrame]:
        while True:
            yield self.recv()

    def close(self) -> None:
        self._sock.close(linger=0)

    def __enter__(self) -> "Subscriber":
        return self

    def __exit__(self, t: Optional[Type[BaseException]], e: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        self.close()


class Client:
    """A client of one conica-server: probe updates on its probe socket (ROUTER, default
    tcp://127.0.0.1:5555), control requests on its control socket (default: the probe port + 2)
    and state subscriptions (default: the probe port + 1).

        with conica.Client("tcp://127.0.0.1:5555") as c:
            r = c.probe((0.02, 0.02, 0.043))   # probe centre in m
            r.force        # (3,) float64, N on the probe
            r.stiffness    # (3, 3) float64, N/m, d force / d position

    timeout:  s, how long each request waits for its answer (conica.Timeout after that).
    curve:    conica.curve_keys(server_pub_file, key_file) for a CURVE server.
    client_id: echoed by the server; random when not given.
    """

    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, *, state_endpoint: Optional[str] = None,
                 control_endpoint: Optional[str] = None, timeout: float = DEFAULT_TIMEOUT_S,
                 curve: Optional[CurveKeys] = None, client_id: Optional[int] = None,
                 context: Optional[zmq.Context] = None) -> None:
        self.endpoint = endpoint
        self._state_endpoint = state_endpoint
        self._control_endpoint = control_endpoint
        self.timeout = _sockets.check_timeout(timeout, DEFAULT_TIMEOUT_S)
        self.client_id = _sockets.new_client_id() if client_id is None else int(client_id)
        self._curve = curve
        self._ctx = context if context is not None else zmq.Context.instance()
        self._sock: zmq.Socket = self._ctx.socket(zmq.DEALER)
        _sockets.setup(self._sock, endpoint, curve)
        self._control: Optional[zmq.Socket] = None
        self._control_sequence = 0
        self._probe_lock = threading.Lock()
        self._book = ProbeBook(endpoint, self.client_id)
        self._control_lock = threading.Lock()

    @property
    def state_endpoint(self) -> str:
        """The state socket: as given, else the probe port + 1."""
        if self._state_endpoint is None:
            self._state_endpoint = _sockets.sibling_endpoint(self.endpoint, 1, "state")
        return self._state_endpoint

    @property
    def control_endpoint(self) -> str:
        """The control socket: as given, else the probe port + 2."""
        if self._control_endpoint is None:
            self._control_endpoint = _sockets.sibling_endpoint(self.endpoint, 2, "control")
        return self._control_endpoint

    # ---- probes ------------------------------------------------------------------------------
    def probe(self, position: Vector, *, probe_id: int = 0, velocity: Optional[Vector] = None,
              radius: Optional[float] = None, timeout: Optional[float] = None) -> ProbeReply:
        """Moves probe `probe_id` to `position` (its centre, m, scene frame) and returns the
        server's reply: the force on the probe (N) and its stiffness (N/m) at that position.

        velocity: m/s, optional; radius: m, optional (None keeps the scene's radius).
        Raises conica.Timeout (no reply within `timeout` s), conica.ServerError (the update was
        refused, e.g. code "UNKNOWN_PROBE" or "BAD_VALUE"), conica.ProtocolError. Replies to
        updates sent with send_probe() that arrive meanwhile are kept for recv_reply()."""
        t = _sockets.check_timeout(timeout, self.timeout)
        with self._probe_lock:
            seq = self._send_probe(position, probe_id, velocity, radius, t)
            try:
                deadline = time.monotonic() + t
                while True:
                    item = self._read_probe(t, deadline, f"reply to probe update {seq}")
                    if item.sequence == seq or item.sequence is None:
                        if isinstance(item, ServerError):
                            raise item
                        return item
                    self._book.arrived.append(item)
            finally:
                self._book.pending.pop(seq, None)

    def send_probe(self, position: Vector, *, probe_id: int = 0,
                   velocity: Optional[Vector] = None, radius: Optional[float] = None,
                   timeout: Optional[float] = None) -> int:
        """Sends a probe update (position in m, as probe()) without waiting for its reply and
        returns its sequence number; recv_reply() and replies() return the replies. Pipelining
        keeps a fixed-rate loop (a 1 kHz haptic loop) from waiting a round trip per update. At
        most `max_outstanding` (1000) updates are awaited; older ones are given up (late replies
        to them are dropped)."""
        t = _sockets.check_timeout(timeout, self.timeout)
        with self._probe_lock:
            seq = self._send_probe(position, probe_id, velocity, radius, t)
            self._book.trim()
            return seq

    def recv_reply(self, timeout: Optional[float] = None) -> ProbeReply:
        """The next reply to an update sent with send_probe(), in the order they arrive (each
        has its .sequence). conica.Timeout after `timeout` s; conica.ServerError for a refused
        update (its .sequence names it); ValueError when no update is awaited."""
        t = _sockets.check_timeout(timeout, self.timeout)
        with self._probe_lock:
            book = self._book
            if book.arrived:
                item = book.arrived.popleft()
            elif book.pending:
                item = self._read_probe(t, time.monotonic() + t,
                                        f"reply to any of {len(book.pending)} probe updates")
            else:
                raise ValueError("no probe update is awaited (send one with send_probe())")
            if isinstance(item, ServerError):
                raise item
            return item

    def replies(self) -> List[ProbeReply]:
        """Every reply to send_probe() updates received so far, oldest first, without waiting
        (a refused update raises conica.ServerError; the replies before it come first)."""
        with self._probe_lock:
            book = self._book
            while book.pending:
                try:
                    data = self._sock.recv(zmq.NOBLOCK)
                except zmq.Again:
                    break
                item = book.decode(data)
                if item is not None:
                    book.arrived.append(item)
            return book.take_arrived()

    @property
    def outstanding(self) -> int:
        """Probe updates sent with send_probe() whose replies have not been returned yet."""
        return self._book.outstanding

    @property
    def max_outstanding(self) -> int:
        """How many send_probe() updates are awaited at most (older ones are given up)."""
        return self._book.max_outstanding

    @max_outstanding.setter
    def max_outstanding(self, n: int) -> None:
        if n < 1:
            raise ValueError(f"max_outstanding must be >= 1, got {n}")
        self._book.max_outstanding = int(n)

    def _send_probe(self, position: Vector, probe_id: int, velocity: Optional[Vector],
                    radius: Optional[float], t: float) -> int:
        seq = self._book.sequence + 1
        payload = _wire.encode_probe(self.client_id, probe_id, seq, _wire.now_ns(), position,
                                     velocity, radius)
        self._send(self._sock, payload, self.endpoint, t, time.monotonic() + t)
        return self._book.next_sequence()

    def _read_probe(self, t: float, deadline: float, what: str) -> Item:
        while True:
            data = self._wait(self._sock, self.endpoint, t, deadline, what)
            item = self._book.decode(data)
            if item is not None:
                return item

    # ---- state -------------------------------------------------------------------------------
    def subscribe(self, *, forces: bool = True, positions: bool = True,
                  timeout: Optional[float] = None) -> Subscriber:
        """A Subscriber to this server's state socket (close it, or use it in a `with`)."""
        return Subscriber(self.state_endpoint, forces=forces, positions=positions,
                          timeout=self.timeout if timeout is None else timeout, curve=self._curve,
                          context=self._ctx)

    # ---- control -----------------------------------------------------------------------------
    def control(self, kind: ControlKind, *, text: str = "", name: str = "", value: float = 0.0,
                timeout: Optional[float] = None) -> "pb.ControlReply":
        """One control request (kind: "RESET", "PAUSE", "RESUME", "SET_PARAMETER", "GET_STATS",
        "GET_MESH", "LOAD_SCENE" or a ControlRequest.Kind) and its raw ControlReply; a refusal
        raises conica.ServerError with the server's reason."""
        t = _sockets.check_timeout(timeout, self.timeout)
        k = control_kind(kind)
        with self._control_lock:
            if self._control is None:
                sock = self._ctx.socket(zmq.DEALER)
                _sockets.setup(sock, self.control_endpoint, self._curve)
                self._control = sock
            self._control_sequence += 1
            seq = self._control_sequence
            deadline = time.monotonic() + t
            self._send(self._control, _wire.encode_control(k, seq, text, name, value),
                       self.control_endpoint, t, deadline)
            what = f"reply to control request {pb.ControlRequest.Kind.Name(k)} ({seq})"
            while True:
                data = self._wait(self._control, self.control_endpoint, t, deadline, what)
                reply = _wire.decode_control_reply(self.control_endpoint, data, seq)
                if reply is not None:
                    return reply

    def reset(self) -> ControlResult:
        """Puts the body back in its rest state."""
        return _wire.control_result(self.control("RESET"))

    def pause(self) -> ControlResult:
        """Stops stepping the simulation; probe updates are still answered (at the frozen body)."""
        return _wire.control_result(self.control("PAUSE"))

    def resume(self) -> ControlResult:
        """Steps the simulation again after pause()."""
        return _wire.control_result(self.control("RESUME"))

    def set_parameter(self, name: str, value: float) -> ControlResult:
        """Sets a model parameter: "damping" (mass damping, 1/s, >= 0), "gravity_x",
        "gravity_y", "gravity_z" (m/s^2) or "positions_hz" (rate of position frames, Hz, >= 0;
        0: none). A refused name or value raises conica.ServerError."""
        return _wire.control_result(self.control("SET_PARAMETER", name=name, value=value))

    def stats(self) -> "pb.LoopStats":
        """The loop statistics (ticks, missed_ticks, lateness_p99_us, errors, paused, ...)."""
        return self.control("GET_STATS").stats

    def mesh(self) -> Mesh:
        """The body's rest positions (num_nodes, 3) in m and its surface triangles."""
        return _wire.mesh_result(self.control_endpoint, self.control("GET_MESH"))

    def load_scene(self, path: str, *, timeout: float = 60.0) -> ControlResult:
        """Loads a scene file (a path as the server sees it) and swaps it in at a tick boundary;
        waits up to `timeout` s for the server to prepare it. A bad scene raises
        conica.ServerError with the server's file:line:column reason."""
        return _wire.control_result(self.control("LOAD_SCENE", text=path, timeout=timeout))

    # ---- plumbing ------------------------------------------------------------------------------
    @staticmethod
    def _send(sock: zmq.Socket, payload: bytes, endpoint: str, t: float, deadline: float) -> None:
        while True:
            try:
                sock.send(payload, zmq.NOBLOCK)
                return
            except zmq.Again:
                left = deadline - time.monotonic()
                if left <= 0 or not sock.poll(math.ceil(left * 1e3), zmq.POLLOUT):
                    raise Timeout(endpoint, t, "room to send (queue full)") from None

    @staticmethod
    def _wait(sock: zmq.Socket, endpoint: str, t: float, deadline: float, what: str) -> bytes:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout(endpoint, t, what)
            if sock.poll(math.ceil(left * 1e3)):
                return sock.recv(zmq.NOBLOCK)

    def close(self) -> None:
        """Closes the sockets (pending requests are dropped)."""
        with self._probe_lock, self._control_lock:
            self._sock.close(linger=0)
            if self._control is not None:
                self._control.close(linger=0)

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, t: Optional[Type[BaseException]], e: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        self.close()
