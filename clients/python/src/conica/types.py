"""What the server sends back, as plain immutable objects with numpy arrays.

Units are SI throughout: positions in metres (m), forces in newtons (N), stiffness in newtons per
metre (N/m), times in seconds (s) unless a name ends in `_ns` (nanoseconds, CLOCK_MONOTONIC)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
import numpy.typing as npt

from ._pb import pb

Float64Array = npt.NDArray[np.float64]
Float32Array = npt.NDArray[np.float32]
UInt32Array = npt.NDArray[np.uint32]


@dataclass(frozen=True)
class ProbeReply:
    """The server's answer to one probe update (conica.v1.ForceReply).

    force:      (3,) float64, N: the force ON the probe (what a haptic device renders); it points
                out of the body when the probe is pressed in.
    stiffness:  (3, 3) float64, N/m: d force / d probe position (row i, column j = dF_i/dx_j),
                for rendering F0 + K (x - x0) between replies; negative definite in contact.
    position:   (3,) float64, m: the probe centre the force was computed at (scene frame).
    contact:    the probe touches the body.
    tick:       the simulation tick the force belongs to.
    round_trip_s: s, from this client's send to its receipt of the reply.
    """

    force: Float64Array
    stiffness: Float64Array
    position: Float64Array
    contact: bool
    probe_id: int
    sequence: int
    tick: int
    client_send_time_ns: int
    server_recv_time_ns: int
    server_reply_time_ns: int
    round_trip_s: float

    def force_at(self, position: "npt.ArrayLike") -> Float64Array:
        """N: the local model F0 + K (x - x0) of this reply at probe position x (m), what a
        haptic loop renders between replies (x0 = self.position)."""
        x = np.asarray(position, dtype=np.float64)
        if x.shape != (3,):
            raise ValueError(f"position (m) must be 3 numbers (x, y, z), got shape {x.shape}")
        out: Float64Array = self.force + self.stiffness @ (x - self.position)
        return out


@dataclass(frozen=True)
class ProbeForce:
    """One probe in a state frame: position (3,) m, force (3,) N on the probe, contact."""

    probe_id: int
    position: Float64Array
    force: Float64Array
    contact: bool


@dataclass(frozen=True)
class StateFrame:
    """One frame from the state socket (conica.v1.StateFrame).

    topic:      "F" (forces, every tick) or "S" (forces and node positions, 60 Hz by default).
    time_s:     s, simulation time.
    positions:  (num_nodes, 3) float32, m, node positions: a read-only view of the received
                message bytes (no copy), or None in force frames. Copy it (np.array(...)) to keep
                it beyond the frame or to modify it.
    probes:     every probe's position, force and contact.
    stats:      the loop statistics (conica.v1.LoopStats: ticks, missed_ticks, lateness_p99_us,
                ...).
    """

    topic: str
    tick: int
    time_s: float
    num_nodes: int
    positions: Optional[Float32Array]
    probes: Tuple[ProbeForce, ...]
    stats: "pb.LoopStats"


@dataclass(frozen=True)
class ControlResult:
    """The answer to a control request (conica.v1.ControlReply): ok is always True here (a refusal
    raises conica.ServerError), message says what was done, num_nodes is the scene's node count,
    stats the loop statistics (conica.v1.LoopStats)."""

    sequence: int
    ok: bool
    message: str
    num_nodes: int
    stats: "pb.LoopStats"


@dataclass(frozen=True)
class Mesh:
    """The body's surface for viewers (GET_MESH): rest_positions (num_nodes, 3) float32 in m,
    triangles (T, 3) uint32 node indices."""

    num_nodes: int
    rest_positions: Float32Array
    triangles: UInt32Array
    stats: "pb.LoopStats"
