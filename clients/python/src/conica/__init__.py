"""conica: the Python client of the conica soft-tissue simulation server.

    import conica
    with conica.Client("tcp://127.0.0.1:5555") as c:
        r = c.probe((0.02, 0.02, 0.043))   # probe centre, m
        r.force                            # (3,) float64, N on the probe
        r.stiffness                        # (3, 3) float64, N/m
        with c.subscribe() as sub:
            frame = sub.recv()             # frame.positions: (N, 3) float32, m (or None)

Units are SI throughout: metres, newtons, N/m, seconds. conica.aio holds the asyncio twins; the
protocol messages themselves are conica.v1.messages_pb2 (generated from proto/ when the package is
built)."""
from ._sockets import DEFAULT_CONTROL_ENDPOINT, DEFAULT_ENDPOINT, DEFAULT_STATE_ENDPOINT
from .client import Client, Subscriber
from .curve import CurveKeys, curve_keys, read_key_file
from .errors import (ConicaError, EndpointError, KeyFileError, ProtocolError, ServerError,
                     Timeout)
from .server import LocalServer, ServerStartError
from .types import ControlResult, Mesh, ProbeForce, ProbeReply, StateFrame
from .v1 import messages_pb2
from . import aio  # noqa: E402  (conica.aio.Client)

__version__ = "0.1.0"

__all__ = [
    "Client", "Subscriber", "aio", "LocalServer", "ProbeReply", "ProbeForce", "StateFrame",
    "ControlResult", "Mesh", "ConicaError", "EndpointError", "Timeout", "ServerError",
    "ProtocolError", "KeyFileError", "ServerStartError", "CurveKeys", "curve_keys",
    "read_key_file", "messages_pb2", "DEFAULT_ENDPOINT", "DEFAULT_STATE_ENDPOINT",
    "DEFAULT_CONTROL_ENDPOINT", "__version__",
]
