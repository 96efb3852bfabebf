"""Endpoint arithmetic and socket set-up shared by the sync and asyncio clients."""
from __future__ import annotations

import random
import re
from typing import Optional

import zmq

from .curve import CurveKeys
from .errors import EndpointError

DEFAULT_ENDPOINT = "tcp://127.0.0.1:5555"
DEFAULT_STATE_ENDPOINT = "tcp://127.0.0.1:5556"
DEFAULT_CONTROL_ENDPOINT = "tcp://127.0.0.1:5557"
DEFAULT_TIMEOUT_S = 2.0
TOPIC_FORCES = b"F"
TOPIC_POSITIONS = b"S"

_TCP = re.compile(r"^(tcp://.*:)(\d+)$")


def sibling_endpoint(probe_endpoint: str, offset: int, what: str) -> str:
    """The server's default layout: state on the probe port + 1, control on + 2."""
    m = _TCP.match(probe_endpoint)
    if not m:
        raise EndpointError(probe_endpoint, f"cannot derive the {what} endpoint from it (only "
                                            f"tcp://HOST:PORT gives PORT + {offset}); pass "
                                            f"{what}_endpoint=")
    return f"{m.group(1)}{int(m.group(2)) + offset}"


def new_client_id() -> int:
    return random.getrandbits(31) | 1


def check_timeout(timeout_s: Optional[float], default: float) -> float:
    t = default if timeout_s is None else float(timeout_s)
    if not t > 0:
        raise ValueError(f"timeout must be > 0 s, got {timeout_s!r}")
    return t


def setup(sock: zmq.Socket, endpoint: str, curve: Optional[CurveKeys]) -> None:
    """LINGER 0, CURVE keys when given, then connect; EndpointError when ZeroMQ refuses the
    endpoint. The socket is closed on failure."""
    try:
        sock.setsockopt(zmq.LINGER, 0)
        if curve is not None:
            sock.curve_serverkey = curve.server_public
            sock.curve_publickey = curve.public
            sock.curve_secretkey = curve.secret
        sock.connect(endpoint)
    except zmq.ZMQError as e:
        sock.close(linger=0)
        raise EndpointError(endpoint, e.strerror) from None
    except (TypeError, ValueError) as e:
        sock.close(linger=0)
        raise EndpointError(endpoint, str(e)) from None
