"""The exceptions of the conica client: one base class and a few kinds, each message saying what
went wrong and where (endpoint, timeout, message field)."""
from __future__ import annotations

from typing import Optional


class ConicaError(Exception):
    """Base class of every error the conica client raises."""


class EndpointError(ConicaError, ValueError):
    """An endpoint ZeroMQ cannot connect to (bad syntax, unknown transport, unresolvable host)."""

    def __init__(self, endpoint: str, reason: str) -> None:
        super().__init__(f"cannot connect to {endpoint!r}: {reason}")
        self.endpoint = endpoint
        self.reason = reason


class Timeout(ConicaError, TimeoutError):
    """No answer from the server within the timeout (is a conica-server serving that endpoint?)."""

    def __init__(self, endpoint: str, timeout_s: float, what: str) -> None:
        super().__init__(f"no {what} from {endpoint} within {timeout_s:g} s "
                         f"(is conica-server serving that endpoint?)")
        self.endpoint = endpoint
        self.timeout_s = timeout_s
        self.what = what


class ServerError(ConicaError):
    """The server refused a request: an Error reply on the probe socket (`code` is the
    conica.v1.Error.Code name, e.g. "BAD_VALUE", "UNKNOWN_PROBE"), or a control reply with
    ok = false (code "CONTROL_REFUSED")."""

    def __init__(self, endpoint: str, code: str, message: str,
                 sequence: Optional[int] = None) -> None:
        where = f" (sequence {sequence})" if sequence is not None else ""
        super().__init__(f"{endpoint}: server refused the request{where}: {code}: {message}")
        self.endpoint = endpoint
        self.code = code
        self.server_message = message
        self.sequence = sequence


class ProtocolError(ConicaError):
    """A message that does not follow the conica.v1 protocol (unparseable, wrong protocol version,
    wrong message type, a field missing or of the wrong size)."""

    def __init__(self, endpoint: str, problem: str) -> None:
        super().__init__(f"{endpoint}: protocol error: {problem}")
        self.endpoint = endpoint
        self.problem = problem


class KeyFileError(ConicaError):
    """A CURVE key file that cannot be read or does not hold the keys expected (the message names
    the file and, where it applies, the line)."""
