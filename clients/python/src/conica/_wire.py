"""Encoding requests and decoding replies of the conica.v1 protocol; no I/O here, so the sync and
asyncio clients share it."""
from __future__ import annotations

import time
from typing import Container, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt
from google.protobuf.message import DecodeError

from ._pb import pb
from .errors import ProtocolError, ServerError
from .types import ControlResult, Mesh, ProbeForce, ProbeReply, StateFrame

PROTOCOL_VERSION = 1
Vector = Union[Sequence[float], npt.NDArray[np.floating]]
Buffer = Union[bytes, bytearray, memoryview]


def vec3(value: Vector, what: str) -> Tuple[float, float, float]:
    """Three finite floats from a sequence or array; ValueError naming `what` otherwise."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{what} must be 3 numbers (x, y, z), got shape {a.shape}")
    return float(a[0]), float(a[1]), float(a[2])


def encode_probe(client_id: int, probe_id: int, sequence: int, send_ns: int, position: Vector,
                 velocity: Optional[Vector] = None, radius: Optional[float] = None) -> bytes:
    msg = pb.ClientMessage(protocol_version=PROTOCOL_VERSION)
    p = msg.probe
    p.client_id, p.probe_id, p.sequence, p.send_time_ns = client_id, probe_id, sequence, send_ns
    p.position.x, p.position.y, p.position.z = vec3(position, "position (m)")
    if velocity is not None:
        p.velocity.x, p.velocity.y, p.velocity.z = vec3(velocity, "velocity (m/s)")
    if radius is not None:
        if not radius > 0:
            raise ValueError(f"radius must be > 0 m (None keeps the scene's), got {radius!r}")
        p.radius = float(radius)
    return msg.SerializeToString()


def encode_control(kind: int, sequence: int, text: str = "",
                   name: str = "", value: float = 0.0) -> bytes:
    msg = pb.ClientMessage(protocol_version=PROTOCOL_VERSION)
    c = msg.control
    c.kind = kind  # type: ignore[assignment]  # an int of the enum (the stubs type it Kind)
    c.sequence, c.text, c.name, c.value = sequence, text, name, float(value)
    return msg.SerializeToString()


def _parse_server_message(endpoint: str, data: Buffer) -> "pb.ServerMessage":
    msg = pb.ServerMessage()
    try:
        msg.ParseFromString(bytes(data))
    except DecodeError as e:
        raise ProtocolError(endpoint, f"unparseable ServerMessage ({len(data)} bytes: {e})") from e
    if msg.protocol_version != PROTOCOL_VERSION:
        raise ProtocolError(endpoint, f"ServerMessage.protocol_version is {msg.protocol_version}, "
                                      f"this client speaks {PROTOCOL_VERSION}")
    return msg


def _error_code_name(code: int) -> str:
    try:
        return pb.Error.Code.Name(code)
    except ValueError:
        return f"code {code}"


def _raise_if_error(endpoint: str, msg: "pb.ServerMessage", awaited: Container[int]) -> bool:
    """Raises ServerError for an Error reply to an awaited sequence (or to an unknown one);
    False for an Error about an older request (to skip); True when the message is not an
    Error."""
    if msg.WhichOneof("body") != "error":
        return True
    e = msg.error
    if e.sequence == 0 or e.sequence in awaited:
        raise ServerError(endpoint, _error_code_name(e.code), e.message, e.sequence or None)
    return False


def _array3(v: "pb.Vec3") -> npt.NDArray[np.float64]:
    return np.array((v.x, v.y, v.z), dtype=np.float64)


def decode_probe_reply(endpoint: str, data: Buffer, client_id: int, awaited: Container[int],
                       recv_ns: int) -> Optional[ProbeReply]:
    """The reply to one of the `awaited` probe updates (sequence numbers), None for a late reply
    to one given up on."""
    msg = _parse_server_message(endpoint, data)
    if not _raise_if_error(endpoint, msg, awaited):
        return None
    body = msg.WhichOneof("body")
    if body != "force":
        raise ProtocolError(endpoint, "expected ServerMessage{force} or {error} on the probe "
                                      f"socket, got {{{body}}}" if body else
                                      "ServerMessage without a body on the probe socket")
    f = msg.force
    if f.client_id != client_id or f.sequence not in awaited:
        return None
    if not f.HasField("force"):
        raise ProtocolError(endpoint, f"ForceReply.force is missing (sequence {f.sequence})")
    if len(f.stiffness.m) != 9:
        raise ProtocolError(endpoint, f"ForceReply.stiffness has {len(f.stiffness.m)} values, "
                                      f"expected 9 (3 x 3, row-major; sequence {f.sequence})")
    return ProbeReply(
        force=_array3(f.force),
        stiffness=np.array(f.stiffness.m, dtype=np.float64).reshape(3, 3),
        position=_array3(f.position),
        contact=f.contact, probe_id=f.probe_id, sequence=f.sequence, tick=f.tick,
        client_send_time_ns=f.client_send_time_ns, server_recv_time_ns=f.server_recv_time_ns,
        server_reply_time_ns=f.server_reply_time_ns,
        round_trip_s=(recv_ns - f.client_send_time_ns) * 1e-9)


def decode_control_reply(endpoint: str, data: Buffer,
                         sequence: int) -> Optional["pb.ControlReply"]:
    """The reply to control request `sequence` (ServerError when refused), None for a late reply
    to an earlier request."""
    msg = _parse_server_message(endpoint, data)
    if not _raise_if_error(endpoint, msg, (sequence,)):
        return None
    body = msg.WhichOneof("body")
    if body != "control_reply":
        raise ProtocolError(endpoint, "expected ServerMessage{control_reply} or {error} on the "
                                      f"control socket, got {{{body}}}" if body else
                                      "ServerMessage without a body on the control socket")
    r = msg.control_reply
    if r.sequence != sequence:
        return None
    if not r.ok:
        raise ServerError(endpoint, "CONTROL_REFUSED", r.message, sequence)
    return r


def control_result(r: "pb.ControlReply") -> ControlResult:
    return ControlResult(sequence=r.sequence, ok=r.ok, message=r.message, num_nodes=r.num_nodes,
                         stats=r.stats)


def mesh_result(endpoint: str, r: "pb.ControlReply") -> Mesh:
    n = r.num_nodes
    rest = np.array(r.rest_positions, dtype=np.float32)
    tri = np.array(r.triangles, dtype=np.uint32)
    if rest.size != 3 * n:
        raise ProtocolError(endpoint, f"ControlReply.rest_positions has {rest.size} values, "
                                      f"expected 3 x num_nodes = {3 * n}")
    if tri.size % 3:
        raise ProtocolError(endpoint, f"ControlReply.triangles has {tri.size} indices, "
                                      "not a multiple of 3")
    if tri.size and int(tri.max()) >= n:
        raise ProtocolError(endpoint, f"ControlReply.triangles refers to node {int(tri.max())} "
                                      f"of {n}")
    return Mesh(num_nodes=n, rest_positions=rest.reshape(n, 3), triangles=tri.reshape(-1, 3),
                stats=r.stats)


# ---- state frames: the positions stay in the received bytes --------------------------------
class _Truncated(Exception):
    pass


def _varint(buf: memoryview, i: int, end: int) -> Tuple[int, int]:
    value = shift = 0
    while True:
        if i >= end or shift > 63:
            raise _Truncated("varint runs past its field")
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        if not b & 0x80:
            return value, i
        shift += 7


def _fields(buf: memoryview, start: int, end: int) -> Iterator[Tuple[int, int, int, int, int]]:
    """(field number, wire type, key start, value start, value end) of each field in
    buf[start:end]."""
    i = start
    while i < end:
        key_start = i
        key, i = _varint(buf, i, end)
        field, wire = key >> 3, key & 7
        if wire == 0:
            _, j = _varint(buf, i, end)
        elif wire == 1:
            j = i + 8
        elif wire == 2:
            n, i = _varint(buf, i, end)
            j = i + n
        elif wire == 5:
            j = i + 4
        else:
            raise _Truncated(f"wire type {wire} of field {field}")
        if j > end:
            raise _Truncated(f"field {field} runs past the end")
        yield field, wire, key_start, i, j
        i = j


_STATE_FIELD = pb.ServerMessage.DESCRIPTOR.fields_by_name["state"].number
_VERSION_FIELD = pb.ServerMessage.DESCRIPTOR.fields_by_name["protocol_version"].number
_POSITIONS_FIELD = pb.StateFrame.DESCRIPTOR.fields_by_name["positions"].number


def decode_state(endpoint: str, topic: bytes, data: Buffer) -> StateFrame:
    """A StateFrame whose positions are a (num_nodes, 3) float32 view into `data` (no copy)."""
    buf = memoryview(data).cast("B")
    try:
        version, state = 0, None
        for field, wire, _, a, b in _fields(buf, 0, len(buf)):
            if field == _VERSION_FIELD and wire == 0:
                version = _varint(buf, a, b)[0]
            elif field == _STATE_FIELD and wire == 2:
                state = (a, b)
            elif field in (2, 4, 5):
                name = pb.ServerMessage.DESCRIPTOR.fields_by_number[field].name
                raise ProtocolError(endpoint, f"expected ServerMessage{{state}} on the state "
                                              f"socket, got {{{name}}}")
        if version != PROTOCOL_VERSION:
            raise ProtocolError(endpoint, f"ServerMessage.protocol_version is {version}, this "
                                          f"client speaks {PROTOCOL_VERSION}")
        if state is None:
            raise ProtocolError(endpoint, "ServerMessage without a state frame on the state socket")
        rest: List[bytes] = []
        chunks: List[Tuple[int, int]] = []
        for field, wire, k, a, b in _fields(buf, state[0], state[1]):
            if field == _POSITIONS_FIELD and wire == 2:
                chunks.append((a, b))
            elif field == _POSITIONS_FIELD and wire == 5:  # unpacked floats: legal, never sent
                chunks.append((a, b))
            else:
                rest.append(bytes(buf[k:b]))
    except _Truncated as e:
        raise ProtocolError(endpoint, f"damaged state frame ({len(buf)} bytes): {e}") from None
    frame = pb.StateFrame()
    try:
        frame.ParseFromString(b"".join(rest))
    except DecodeError as e:
        raise ProtocolError(endpoint, f"unparseable StateFrame ({e})") from e
    positions: Optional[npt.NDArray[np.float32]] = None
    if chunks:
        if any((b - a) % 4 for a, b in chunks):
            raise ProtocolError(endpoint, "StateFrame.positions: a packed chunk is not a whole "
                                          "number of 4-byte floats")
        views = [np.frombuffer(buf, dtype="<f4", count=(b - a) // 4, offset=a) for a, b in chunks]
        flat = views[0] if len(views) == 1 else np.concatenate(views)
        if flat.size != 3 * frame.num_nodes:
            raise ProtocolError(endpoint, f"StateFrame.positions has {flat.size} floats, "
                                          f"expected 3 x num_nodes = {3 * frame.num_nodes}")
        positions = flat.reshape(frame.num_nodes, 3)
        positions.flags.writeable = False
    probes = tuple(ProbeForce(probe_id=p.probe_id, position=_array3(p.position),
                              force=_array3(p.force), contact=p.contact) for p in frame.probes)
    return StateFrame(topic=topic.decode("ascii", "replace"), tick=frame.tick, time_s=frame.time,
                      num_nodes=frame.num_nodes, positions=positions, probes=probes,
                      stats=frame.stats)


def now_ns() -> int:
    return time.monotonic_ns()
