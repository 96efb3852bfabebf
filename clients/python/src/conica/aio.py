"""The asyncio twin of conica.Client and conica.Subscriber (zmq.asyncio): the same arguments,
replies and exceptions, with coroutines.

    async with conica.aio.Client("tcp://127.0.0.1:5555") as c:
        r = await c.probe((0.02, 0.02, 0.043))     # m; r.force in N, r.stiffness in N/m
        async with c.subscribe(forces=False) as sub:
            async for frame in sub:                 # frame.positions: (N, 3) float32, m
                ...

Units are SI: positions in m, forces in N, stiffness in N/m, timeouts in s."""
from __future__ import annotations

import asyncio
import math
import time
from types import TracebackType
from typing import AsyncIterator, List, Optional, Type

import zmq
import zmq.asyncio

from . import _sockets, _wire
from ._book import Item, ProbeBook
from ._pb import pb
from ._sockets import (DEFAULT_ENDPOINT, DEFAULT_STATE_ENDPOINT, DEFAULT_TIMEOUT_S, TOPIC_FORCES,
                       TOPIC_POSITIONS)
from ._wire import Vector
from .client import ControlKind, control_kind
from .curve import CurveKeys
from .errors import ProtocolError, ServerError, Timeout
from .types import ControlResult, Mesh, ProbeReply, StateFrame

__all__ = ["Client", "Subscriber"]

_context: Optional[zmq.asyncio.Context] = None


def _default_context() -> zmq.asyncio.Context:
    global _context
    if _context is None or _context.closed:
        _context = zmq.asyncio.Context()
    return _context


async def _recv(sock: zmq.asyncio.Socket, endpoint: str, t: float, deadline: float,
                what: str, multipart: bool = False) -> object:
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            raise Timeout(endpoint, t, what)
        if await sock.poll(math.ceil(left * 1e3)):
            break
    if multipart:
        return await sock.recv_multipart(copy=False)
    return await sock.recv()


async def _send(sock: zmq.asyncio.Socket, payload: bytes, endpoint: str, t: float,
                deadline: float) -> None:
    left = deadline - time.monotonic()
    try:
        await asyncio.wait_for(sock.send(payload), max(left, 1e-3))
    except asyncio.TimeoutError:
        raise Timeout(endpoint, t, "room to send (queue full)") from None


class Subscriber:
    """conica.Subscriber with `await recv()`, `await latest()` and `async for`."""

    def __init__(self, endpoint: str = DEFAULT_STATE_ENDPOINT, *, forces: bool = True,
                 positions: bool = True, timeout: float = DEFAULT_TIMEOUT_S,
                 curve: Optional[CurveKeys] = None,
                 context: Optional[zmq.asyncio.Context] = None) -> None:
        if not (forces or positions):
            raise ValueError("subscribe to forces, positions or both")
        self.endpoint = endpoint
        self.timeout = _sockets.check_timeout(timeout, DEFAULT_TIMEOUT_S)
        ctx = context if context is not None else _default_context()
        self._sock: zmq.asyncio.Socket = ctx.socket(zmq.SUB)
        _sockets.setup(self._sock, endpoint, curve)
        if forces:
            self._sock.setsockopt(zmq.SUBSCRIBE, TOPIC_FORCES)
        if positions:
            self._sock.setsockopt(zmq.SUBSCRIBE, TOPIC_POSITIONS)

    async def recv(self, timeout: Optional[float] = None) -> StateFrame:
        """The next frame; conica.Timeout when none arrives within `timeout` s."""
        t = _sockets.check_timeout(timeout, self.timeout)
        parts = await _recv(self._sock, self.endpoint, t, time.monotonic() + t, "state frame",
                            multipart=True)
        return self._decode(parts)  # type: ignore[arg-type]

    async def latest(self, timeout: Optional[float] = None) -> StateFrame:
        """The newest frame already received (older queued frames are dropped), or the next one
        when none is queued; conica.Timeout after `timeout` s without any."""
        newest = None
        while await self._sock.poll(0):
            newest = await self._sock.recv_multipart(copy=False)
        if newest is None:
            return await self.recv(timeout)
        return self._decode(newest)

    def _decode(self, parts: List[zmq.Frame]) -> StateFrame:
        if len(parts) != 2:
            raise ProtocolError(self.endpoint, f"state message with {len(parts)} frames, "
                                               "expected 2 ([topic][payload])")
        return _wire.decode_state(self.endpoint, parts[0].bytes, parts[1].buffer)

    def __aiter__(self) -> AsyncIterator[StateFrame]:
        return self._frames()

    async def _frames(self) -> AsyncIterator[StateFrame]:
        while True:
            yield await self.recv()

    def close(self) -> None:
        self._sock.close(linger=0)

    async def __aenter__(self) -> "Subscriber":
        return self

    async def __aexit__(self, t: Optional[Type[BaseException]], e: Optional[BaseException],
                        tb: Optional[TracebackType]) -> None:
        self.close()


class Client:
    """conica.Client with coroutines: `await probe(...)`, `await reset()`, ...; the same
    arguments (endpoints, timeout in s, curve, client_id) and the same replies."""

    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, *, state_endpoint: Optional[str] = None,
                 control_endpoint: Optional[str] = None, timeout: float = DEFAULT_TIMEOUT_S,
                 curve: Optional[CurveKeys] = None, client_id: Optional[int] = None,
                 context: Optional[zmq.asyncio.Context] = None) -> None:
        self.endpoint = endpoint
        self._state_endpoint = state_endpoint
        self._control_endpoint = control_endpoint
        self.timeout = _sockets.check_timeout(timeout, DEFAULT_TIMEOUT_S)
        self.client_id = _sockets.new_client_id() if client_id is None else int(client_id)
        self._curve = curve
        self._ctx = context if context is not None else _default_context()
        self._sock: zmq.asyncio.Socket = self._ctx.socket(zmq.DEALER)
        _sockets.setup(self._sock, endpoint, curve)
        self._control: Optional[zmq.asyncio.Socket] = None
        self._book = ProbeBook(endpoint, self.client_id)
        self._control_sequence = 0
        self._probe_lock = asyncio.Lock()
        self._control_lock = asyncio.Lock()

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

    async def probe(self, position: Vector, *, probe_id: int = 0,
                    velocity: Optional[Vector] = None, radius: Optional[float] = None,
                    timeout: Optional[float] = None) -> ProbeReply:
        """As conica.Client.probe: position (m) in, force (N) and stiffness (N/m) out. Concurrent
        calls on one client are served one after the other."""
        t = _sockets.check_timeout(timeout, self.timeout)
        async with self._probe_lock:
            seq = await self._send_probe(position, probe_id, velocity, radius, t)
            try:
                deadline = time.monotonic() + t
                while True:
                    item = await self._read_probe(t, deadline, f"reply to probe update {seq}")
                    if item.sequence == seq or item.sequence is None:
                        if isinstance(item, ServerError):
                            raise item
                        return item
                    self._book.arrived.append(item)
            finally:
                self._book.pending.pop(seq, None)

    async def send_probe(self, position: Vector, *, probe_id: int = 0,
                         velocity: Optional[Vector] = None, radius: Optional[float] = None,
                         timeout: Optional[float] = None) -> int:
        """As conica.Client.send_probe: sends without waiting for the reply, returns the
        sequence number."""
        t = _sockets.check_timeout(timeout, self.timeout)
        async with self._probe_lock:
            seq = await self._send_probe(position, probe_id, velocity, radius, t)
            self._book.trim()
            return seq

    async def recv_reply(self, timeout: Optional[float] = None) -> ProbeReply:
        """As conica.Client.recv_reply: the next reply to a send_probe() update."""
        t = _sockets.check_timeout(timeout, self.timeout)
        async with self._probe_lock:
            book = self._book
            if book.arrived:
                item = book.arrived.popleft()
            elif book.pending:
                item = await self._read_probe(t, time.monotonic() + t,
                                              f"reply to any of {len(book.pending)} probe updates")
            else:
                raise ValueError("no probe update is awaited (send one with send_probe())")
            if isinstance(item, ServerError):
                raise item
            return item

    @property
    def outstanding(self) -> int:
        """Probe updates sent with send_probe() whose replies have not been returned yet."""
        return self._book.outstanding

    async def _send_probe(self, position: Vector, probe_id: int, velocity: Optional[Vector],
                          radius: Optional[float], t: float) -> int:
        seq = self._book.sequence + 1
        payload = _wire.encode_probe(self.client_id, probe_id, seq, _wire.now_ns(), position,
                                     velocity, radius)
        await _send(self._sock, payload, self.endpoint, t, time.monotonic() + t)
        return self._book.next_sequence()

    async def _read_probe(self, t: float, deadline: float, what: str) -> Item:
        while True:
            data = await _recv(self._sock, self.endpoint, t, deadline, what)
            item = self._book.decode(data)  # type: ignore[arg-type]
            if item is not None:
                return item

    def subscribe(self, *, forces: bool = True, positions: bool = True,
                  timeout: Optional[float] = None) -> Subscriber:
        """An asyncio Subscriber to this server's state socket."""
        return Subscriber(self.state_endpoint, forces=forces, positions=positions,
                          timeout=self.timeout if timeout is None else timeout, curve=self._curve,
                          context=self._ctx)

    async def control(self, kind: ControlKind, *, text: str = "", name: str = "",
                      value: float = 0.0, timeout: Optional[float] = None) -> "pb.ControlReply":
        """As conica.Client.control."""
        t = _sockets.check_timeout(timeout, self.timeout)
        k = control_kind(kind)
        async with self._control_lock:
            if self._control is None:
                sock = self._ctx.socket(zmq.DEALER)
                _sockets.setup(sock, self.control_endpoint, self._curve)
                self._control = sock
            self._control_sequence += 1
            seq = self._control_sequence
            deadline = time.monotonic() + t
            await _send(self._control, _wire.encode_control(k, seq, text, name, value),
                        self.control_endpoint, t, deadline)
            what = f"reply to control request {pb.ControlRequest.Kind.Name(k)} ({seq})"
            while True:
                data = await _recv(self._control, self.control_endpoint, t, deadline, what)
                reply = _wire.decode_control_reply(self.control_endpoint, data, seq)  # type: ignore[arg-type]
                if reply is not None:
                    return reply

    async def reset(self) -> ControlResult:
        """Puts the body back in its rest state."""
        return _wire.control_result(await self.control("RESET"))

    async def pause(self) -> ControlResult:
        """Stops stepping the simulation; probe updates are still answered."""
        return _wire.control_result(await self.control("PAUSE"))

    async def resume(self) -> ControlResult:
        """Steps the simulation again after pause()."""
        return _wire.control_result(await self.control("RESUME"))

    async def set_parameter(self, name: str, value: float) -> ControlResult:
        """As conica.Client.set_parameter ("damping" 1/s, "gravity_x|y|z" m/s^2,
        "positions_hz" Hz)."""
        return _wire.control_result(await self.control("SET_PARAMETER", name=name, value=value))

    async def stats(self) -> "pb.LoopStats":
        """The loop statistics."""
        return (await self.control("GET_STATS")).stats

    async def mesh(self) -> Mesh:
        """The body's rest positions (num_nodes, 3) in m and its surface triangles."""
        return _wire.mesh_result(self.control_endpoint, await self.control("GET_MESH"))

    async def load_scene(self, path: str, *, timeout: float = 60.0) -> ControlResult:
        """Loads a scene file (a path as the server sees it), waiting up to `timeout` s."""
        return _wire.control_result(await self.control("LOAD_SCENE", text=path, timeout=timeout))

    def close(self) -> None:
        """Closes the sockets (pending requests are dropped)."""
        self._sock.close(linger=0)
        if self._control is not None:
            self._control.close(linger=0)

    async def __aenter__(self) -> "Client":
        return self

    async def __aexit__(self, t: Optional[Type[BaseException]], e: Optional[BaseException],
                        tb: Optional[TracebackType]) -> None:
        self.close()
