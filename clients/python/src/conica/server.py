"""Starts a local conica-server on ports the OS picks, for scripts and tests.

    with conica.LocalServer("build/bin/conica-server", builtin="cube") as server:
        with server.client() as c:
            print(c.probe((0.02, 0.02, 0.043)).force)   # N
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import threading
from types import TracebackType
from typing import List, Optional, Sequence, Type

from .client import Client, Subscriber
from .errors import ConicaError

_SERVING = re.compile(r"serving: probes (\S+), state (\S+), control (\S+) at")


class ServerStartError(ConicaError):
    """conica-server exited or did not report its endpoints in time (its log is in the message)."""


def find_server(binary: Optional[str] = None) -> str:
    """`binary`, else $CONICA_SERVER, else conica-server on PATH."""
    found = binary or os.environ.get("CONICA_SERVER") or shutil.which("conica-server")
    if not found:
        raise ServerStartError("conica-server not found: pass its path, set CONICA_SERVER or put "
                               "it on PATH (it is built into build/bin/)")
    return found


class LocalServer:
    """A conica-server child process serving loopback ports the OS picks (read back from its
    "serving: probes ..., state ..., control ..." log line; every log line is kept in .lines).

    builtin:  "cube", "block" or "liver" (no files); or scene: a scene file path.
    seconds:  s, the server stops by itself after this long (a safety net for scripts).
    realtime: False adds --no-realtime (no SCHED_FIFO loop thread).
    args:     further conica-server options, e.g. ("--busy-poll",).
    """

    def __init__(self, binary: Optional[str] = None, *, builtin: Optional[str] = "cube",
                 scene: Optional[str] = None, args: Sequence[str] = (), seconds: float = 600,
                 realtime: bool = False, start_timeout: float = 30.0) -> None:
        self.binary = find_server(binary)
        any_port = "tcp://127.0.0.1:*"
        cmd = [self.binary]
        if scene is not None:
            cmd += ["--scene", scene]
        elif builtin is not None:
            cmd += ["--builtin", builtin]
        cmd += ["--probe-endpoint", any_port, "--state-endpoint", any_port,
                "--control-endpoint", any_port, "--seconds", f"{seconds:g}",
                "--stats-seconds", "0"]
        if not realtime:
            cmd.append("--no-realtime")
        cmd += list(args)
        self.command = cmd
        self.lines: List[str] = []
        self.probe_endpoint = self.state_endpoint = self.control_endpoint = ""
        self._proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      text=True)
        found = threading.Event()

        def read() -> None:
            assert self._proc.stdout is not None
            for line in self._proc.stdout:
                self.lines.append(line)
                m = _SERVING.search(line)
                if m and not found.is_set():
                    self.probe_endpoint, self.state_endpoint, self.control_endpoint = m.groups()
                    found.set()
            found.set()

        threading.Thread(target=read, daemon=True).start()
        if not found.wait(start_timeout) or not self.probe_endpoint:
            self._proc.kill()
            self._proc.wait()
            raise ServerStartError(f"{' '.join(cmd)}: did not start within {start_timeout:g} s:\n"
                                   + "".join(self.lines))

    @property
    def pid(self) -> int:
        return self._proc.pid

    def running(self) -> bool:
        return self._proc.poll() is None

    def client(self, **kwargs: object) -> Client:
        """A conica.Client of this server (keyword arguments go to Client)."""
        return Client(self.probe_endpoint, state_endpoint=self.state_endpoint,
                      control_endpoint=self.control_endpoint, **kwargs)  # type: ignore[arg-type]

    def subscriber(self, **kwargs: object) -> Subscriber:
        """A conica.Subscriber of this server's state socket."""
        return Subscriber(self.state_endpoint, **kwargs)  # type: ignore[arg-type]

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM, then the exit code (killed after `timeout` s)."""
        if self._proc.poll() is None:
            self._proc.send_signal(signal.SIGTERM)
        try:
            return self._proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            return self._proc.wait()

    def __enter__(self) -> "LocalServer":
        return self

    def __exit__(self, t: Optional[Type[BaseException]], e: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        self.stop()
