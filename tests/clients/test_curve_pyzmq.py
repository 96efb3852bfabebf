#!/usr/bin/python3
"""conica's CURVE certificates against pyzmq's (Debian's python3-zmq), end to end: a real
conica-server on ephemeral loopback ports and plain pyzmq CURVE clients, no conica code on the
client side.

- Certificates made by zmq.auth.create_certificates serve as they are: the server takes pyzmq's
  server.key_secret and a folder of pyzmq public certificates; a pyzmq client whose public
  certificate is listed gets force replies, one whose certificate is not gets nothing.
- Certificates made by conica (conica-keygen, conica-server --generate-keys) load in
  zmq.auth.load_certificate / load_certificates with the keys conica printed, and a pyzmq
  client using them is served by a server on conica's keys.
- An old conica key folder is refused by the server with what it is and the conversion command;
  after `conica-keygen --convert` the same keys serve, and pyzmq reads the converted files.

    PYTHONPATH=build/proto/gen /usr/bin/python3 tests/clients/test_curve_pyzmq.py \\
        --server build/bin/conica-server --keygen build/bin/conica-keygen
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from server_process import ServerProcess  # noqa: E402

import zmq  # noqa: E402
import zmq.auth  # noqa: E402
from conica.v1 import messages_pb2 as pb  # noqa: E402

SERVER = KEYGEN = None
TOP = 0.04               # m, top face of the built-in cube
NODE_XY = 3 * 0.04 / 7   # m, a lattice column under the probe
RADIUS = 5e-3            # m, the cube's probe


def run(cmd, timeout=60):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def probe_message(seq, depth):
    m = pb.ClientMessage(protocol_version=1)
    p = m.probe
    p.client_id, p.probe_id, p.sequence = 9, 0, seq
    p.send_time_ns = time.monotonic_ns()
    p.position.x, p.position.y, p.position.z = NODE_XY, NODE_XY, TOP + RADIUS - depth
    return m.SerializeToString()


class CurvePyzmqTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="conica-curve-pyzmq-")
        self.ctx = zmq.Context()
        self.servers = []

    def tearDown(self):
        self.ctx.destroy(linger=0)
        for s in self.servers:
            rc = s.stop()
            self.assertEqual(rc, 0, "server exit code %d:\n%s" % (rc, "".join(s.lines)))
        shutil.rmtree(self.dir, ignore_errors=True)

    def path(self, *parts):
        return os.path.join(self.dir, *parts)

    def serve(self, server_secret, clients):
        s = ServerProcess(SERVER, ("--curve-server-key", server_secret, "--curve-clients", clients))
        self.servers.append(s)
        return s

    def client(self, endpoint, server_public_file, client_secret_file):
        """A DEALER with pyzmq's own reading of the certificates."""
        server_public, _ = zmq.auth.load_certificate(server_public_file)
        public, secret = zmq.auth.load_certificate(client_secret_file)
        self.assertIsNotNone(secret, client_secret_file)
        s = self.ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.curve_serverkey, s.curve_publickey, s.curve_secretkey = server_public, public, secret
        s.connect(endpoint)
        return s

    def ask(self, sock, seq, depth, timeout_ms):
        sock.send(probe_message(seq, depth))
        if not sock.poll(timeout_ms):
            return None
        reply = pb.ServerMessage()
        reply.ParseFromString(sock.recv())
        return reply

    def expect_served(self, server, server_public_file, client_secret_file):
        sock = self.client(server.endpoints[0], server_public_file, client_secret_file)
        far = self.ask(sock, 1, -0.01, 5000)
        self.assertIsNotNone(far, "a listed client got no reply:\n" + "".join(server.lines))
        self.assertEqual(far.force.sequence, 1)
        self.assertFalse(far.force.contact)
        self.assertEqual(far.force.force.z, 0.0)
        # Pressed 2 mm in over about 80 ms and held 100 ms: the body pushes the probe up (a real
        # reply, not an error). Read at once after a fast press, a reply can fall in the moment the
        # dented face swings back below the probe (-1 mN once under the sanitizer build's load).
        for seq in range(2, 90):
            time.sleep(0.002)
            pressed = self.ask(sock, seq, 0.002 * min(1.0, (seq - 1) / 40), 5000)
            self.assertIsNotNone(pressed)
        self.assertTrue(pressed.force.contact)
        self.assertGreater(pressed.force.force.z, 0.0)
        sock.close()

    def expect_refused(self, server, server_public_file, client_secret_file):
        sock = self.client(server.endpoints[0], server_public_file, client_secret_file)
        self.assertIsNone(self.ask(sock, 1, 0.001, 1500), "an unlisted client was served")
        sock.close()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and not any("CURVE: refused" in l for l in server.lines):
            time.sleep(0.05)
        self.assertTrue(any("CURVE: refused" in l for l in server.lines), "".join(server.lines))

    def test_pyzmq_certificates_serve_as_they_are(self):
        os.makedirs(self.path("clients"))
        os.makedirs(self.path("other"))
        server_pub, server_secret = zmq.auth.create_certificates(self.dir, "server")
        alice_pub, alice_secret = zmq.auth.create_certificates(self.path("clients"), "alice")
        _, mallory_secret = zmq.auth.create_certificates(self.path("other"), "mallory",
                                                         metadata={"name": "mallory"})
        self.assertEqual((server_pub, server_secret),
                         (self.path("server.key"), self.path("server.key_secret")))
        # pyzmq leaves alice.key_secret in the clients folder: the server skips it.
        server = self.serve(server_secret, self.path("clients"))
        self.assertTrue(any("1 authorised client keys" in l for l in server.lines),
                        "".join(server.lines))
        self.expect_served(server, server_pub, alice_secret)
        self.expect_refused(server, server_pub, mallory_secret)

    def test_conica_certificates_load_in_pyzmq(self):
        r = run([KEYGEN, self.dir, "server"])
        self.assertEqual(r.returncode, 0, r.stderr)
        printed = r.stdout.split("public-key ")[1].strip().encode()
        public, secret = zmq.auth.load_certificate(self.path("server.key_secret"))
        self.assertEqual(public, printed)
        self.assertEqual(zmq.curve_public(secret), public)
        self.assertEqual(zmq.auth.load_certificate(self.path("server.key")), (public, None))
        self.assertEqual(os.stat(self.path("server.key_secret")).st_mode & 0o077, 0)
        r = run([SERVER, "--generate-keys", self.path("clients"), "--key-name", "alice"])
        self.assertEqual(r.returncode, 0, r.stderr)
        alice = r.stdout.split("public-key ")[1].strip().encode()
        # The server's own folder reading and pyzmq's agree: one client, alice.
        self.assertEqual(zmq.auth.load_certificates(self.path("clients")), {alice: True})
        server = self.serve(self.path("server.key_secret"), self.path("clients"))
        self.expect_served(server, self.path("server.key"), self.path("clients", "alice.key_secret"))

    def test_old_key_files_are_refused_then_converted(self):
        # The files conica wrote before: NAME.key the key pair, NAME.pub the public key.
        pub, sec = zmq.curve_keypair()
        cpub, csec = zmq.curve_keypair()
        os.makedirs(self.path("clients"))
        with open(self.path("server.key"), "w") as f:
            f.write(f"# conica CURVE key pair: keep this file private\npublic {pub.decode()}\n"
                    f"secret {sec.decode()}\n")
        with open(self.path("server.pub"), "w") as f:
            f.write(f"# conica CURVE public key\npublic {pub.decode()}\n")
        with open(self.path("clients", "alice.key"), "w") as f:
            f.write(f"public {cpub.decode()}\nsecret {csec.decode()}\n")
        with open(self.path("clients", "alice.pub"), "w") as f:
            f.write(f"public {cpub.decode()}\n")
        r = run([SERVER, "--builtin", "cube", "--seconds", "5", "--no-realtime",
                 "--probe-endpoint", "tcp://127.0.0.1:*", "--state-endpoint", "tcp://127.0.0.1:*",
                 "--control-endpoint", "tcp://127.0.0.1:*",
                 "--curve-server-key", self.path("server.key"),
                 "--curve-clients", self.path("clients")])
        self.assertNotEqual(r.returncode, 0)
        out = r.stdout + r.stderr
        self.assertIn(self.path("server.key") + ": an old conica key file", out)
        self.assertIn("`conica-keygen --convert " + self.path("server.key") + "`", out)

        r = run([KEYGEN, "--convert", self.path("server.key"), self.path("server.pub"),
                 self.path("clients")])
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertFalse(os.path.exists(self.path("server.pub")))
        self.assertFalse(os.path.exists(self.path("clients", "alice.pub")))
        # pyzmq reads the converted certificates with the old keys.
        self.assertEqual(zmq.auth.load_certificate(self.path("server.key_secret")), (pub, sec))
        self.assertEqual(zmq.auth.load_certificate(self.path("server.key")), (pub, None))
        self.assertEqual(zmq.auth.load_certificate(self.path("clients", "alice.key_secret")),
                         (cpub, csec))
        self.assertEqual(zmq.auth.load_certificates(self.path("clients")), {cpub: True})
        server = self.serve(self.path("server.key_secret"), self.path("clients"))
        self.expect_served(server, self.path("server.key"), self.path("clients", "alice.key_secret"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--keygen", required=True)
    args, rest = parser.parse_known_args()
    SERVER = os.path.abspath(args.server)
    KEYGEN = os.path.abspath(args.keygen)
    unittest.main(argv=[sys.argv[0]] + rest)
