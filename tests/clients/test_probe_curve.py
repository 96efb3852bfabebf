#!/usr/bin/python3
"""clients/python/probe.py against a CURVE server: certificates from conica-server
--generate-keys (NAME.key public, NAME.key_secret secret), the server started with
--curve-server-key and --curve-clients on ephemeral loopback ports.

A listed client key presses the built-in cube and records an upward force growing with depth;
an unknown key gets no reply (probe.py gives up after its timeout, the server logs the refusal);
damaged, swapped or old-format key files are refused naming the file.

    build/python/venv/bin/python tests/clients/test_probe_curve.py \\
        --server build/bin/conica-server --probe-py clients/python/probe.py

(probe.py runs with the same interpreter, which must have the package conica: ctest installs it
into build/python/venv, tests/python/install_package.py)
"""
import argparse
import csv
import io
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

import conica

SERVER = PROBE_PY = None
TOP = 0.04               # m, top face of the built-in cube
NODE_XY = 3 * 0.04 / 7   # m, a lattice column under the probe
RADIUS = 5e-3            # m, the cube's probe


def run(cmd, timeout=60):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)

class ProbeCurveTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="conica-probe-curve-")
        for d, name in ((cls.dir, "server"), (os.path.join(cls.dir, "clients"), "alice"),
                        (os.path.join(cls.dir, "other"), "mallory")):
            r = run([SERVER, "--generate-keys", d, "--key-name", name])
            assert r.returncode == 0, r.stdout + r.stderr
        cls.server = conica.LocalServer(
            SERVER, builtin="cube", seconds=120,
            args=("--curve-server-key", os.path.join(cls.dir, "server.key_secret"),
                  "--curve-clients", os.path.join(cls.dir, "clients")))

    @classmethod
    def tearDownClass(cls):
        rc = cls.server.stop()
        shutil.rmtree(cls.dir, ignore_errors=True)
        assert rc == 0, "server exit code %d:\n%s" % (rc, "".join(cls.server.lines))

    def path(self, name):
        return os.path.join(self.dir, name)

    def probe(self, key, server_pub="server.key", extra=()):
        return run([sys.executable, PROBE_PY, "--endpoint", self.server.probe_endpoint,
                    "--at", f"{NODE_XY},{NODE_XY},{TOP + RADIUS}", "--depth", "0.002",
                    "--approach", "0.002", "--steps", "200", "--hold", "20",
                    "--curve-server-pub", self.path(server_pub), "--curve-key", self.path(key),
                    *extra])

    def test_listed_key_presses_and_feels_the_body(self):
        r = self.probe("clients/alice.key_secret")
        self.assertEqual(r.returncode, 0, r.stderr)
        rows = list(csv.DictReader(io.StringIO(r.stdout)))
        self.assertEqual(len(rows), 221)
        first, last = rows[0], rows[-1]
        self.assertEqual(first["contact"], "0")  # starts 2 mm above the surface
        self.assertEqual(float(first["fz"]), 0.0)
        self.assertEqual(last["contact"], "1")   # 2 mm deep
        self.assertGreater(float(last["fz"]), 0.0)  # the body pushes the probe up
        # Deeper is harder: the force at 2 mm exceeds the force at 1 mm (row 150 of 200 steps, a
        # press at 20 mm/s paced at 1 kHz).
        self.assertGreater(float(last["fz"]), float(rows[150]["fz"]))
        self.assertGreater(float(rows[150]["fz"]), 0.0)
        self.assertLess(abs(float(last["fx"])) + abs(float(last["fy"])), 0.05 * float(last["fz"]))

    def test_unknown_key_gets_no_reply(self):
        t0 = time.monotonic()
        r = self.probe("other/mallory.key_secret", extra=("--timeout-ms", "1000"))
        self.assertLess(time.monotonic() - t0, 20)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("no reply", r.stderr)
        self.assertEqual(r.stdout.count("\n"), 1, r.stdout)  # the CSV header only
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and not any("CURVE: refused" in l for l in self.server.lines):
            time.sleep(0.05)
        self.assertTrue(any("CURVE: refused" in l for l in self.server.lines), "".join(self.server.lines))

    def test_bad_key_files_are_named(self):
        r = self.probe("clients/alice.key")  # the public certificate
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(self.path("clients/alice.key") + ": a public certificate (no secret key)",
                      r.stderr)
        r = self.probe("clients/alice.key_secret", server_pub="server.key_secret")
        self.assertIn(self.path("server.key_secret") + ": holds the server's secret key", r.stderr)
        with open(self.path("bad.key_secret"), "w") as f:
            f.write("# damaged\ncurve\n    public-key = \"abc\"\n")
        r = self.probe("bad.key_secret")
        self.assertIn(self.path("bad.key_secret") + ":3: public-key is not a z85 CURVE key",
                      r.stderr)
        r = self.probe("missing.key_secret")
        self.assertIn(self.path("missing.key_secret") + ": cannot open key file", r.stderr)

    def test_old_key_file_is_refused_with_the_conversion(self):
        with open(self.path("clients/alice.key_secret")) as f:
            keys = {w[0]: w[2].strip('"') for w in (l.split() for l in f) if len(w) == 3}
        with open(self.path("old.key"), "w") as f:
            f.write("# conica CURVE key pair: keep this file private\n"
                    f"public {keys['public-key']}\nsecret {keys['secret-key']}\n")
        r = self.probe("old.key")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(self.path("old.key") + ": an old conica key file", r.stderr)
        self.assertIn("`conica-keygen --convert " + self.path("old.key") + "`", r.stderr)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--probe-py", required=True)
    args, rest = parser.parse_known_args()
    SERVER = os.path.abspath(args.server)
    PROBE_PY = os.path.abspath(args.probe_py)
    unittest.main(argv=[sys.argv[0]] + rest)
