"""A real conica-server for Python tests: `--builtin cube` on ephemeral loopback ports, read back
from its "serving: probes ..., state ..., control ... at" log line; every log line kept in .lines.
"""
import re
import signal
import subprocess
import threading


class ServerProcess:
    def __init__(self, path, extra_args=()):
        any_port = "tcp://127.0.0.1:*"
        self.proc = subprocess.Popen(
            [path, "--builtin", "cube", "--probe-endpoint", any_port, "--state-endpoint", any_port,
             "--control-endpoint", any_port, "--seconds", "120", "--no-realtime",
             "--stats-seconds", "0", *extra_args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines = []
        found = threading.Event()
        self.endpoints = None  # (probe, state, control)

        def read():
            pattern = re.compile(r"serving: probes (\S+), state (\S+), control (\S+) at")
            for line in self.proc.stdout:
                self.lines.append(line)
                m = pattern.search(line)
                if m and not found.is_set():
                    self.endpoints = m.groups()
                    found.set()
            found.set()

        threading.Thread(target=read, daemon=True).start()
        if not found.wait(30) or self.endpoints is None:
            self.proc.kill()
            raise RuntimeError("server did not start:\n" + "".join(self.lines))

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=10)
