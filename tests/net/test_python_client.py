#!/usr/bin/python3
"""Drives a real conica-server from Python: proves the wire protocol is usable outside C++.

Starts `conica-server --builtin cube` on ephemeral loopback ports (read back from its log line),
sends probe updates on a DEALER, reads state frames on a SUB, asks for the mesh on the control
socket, then stops it with SIGTERM.

    PYTHONPATH=build/proto/gen /usr/bin/python3 tests/net/test_python_client.py --server build/bin/conica-server
"""
import argparse
import os
import sys
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from server_process import ServerProcess  # noqa: E402

import zmq
from conica.v1 import messages_pb2 as pb

SERVER = None
TOP = 0.04               # m, top face of the built-in cube
NODE_XY = 3 * 0.04 / 7   # m, a lattice column under the probe
RADIUS = 5e-3            # m, the cube's probe

def probe_message(seq, z, x=NODE_XY, y=NODE_XY, probe_id=0, version=1):
    m = pb.ClientMessage(protocol_version=version)
    p = m.probe
    p.client_id = 7
    p.probe_id = probe_id
    p.sequence = seq
    p.send_time_ns = time.monotonic_ns()
    p.position.x, p.position.y, p.position.z = x, y, z
    return m.SerializeToString()


class PythonClientTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = ServerProcess(SERVER)
        cls.ctx = zmq.Context()

    @classmethod
    def tearDownClass(cls):
        cls.ctx.destroy(linger=0)
        rc = cls.server.stop()
        assert rc == 0, "server exit code %d:\n%s" % (rc, "".join(cls.server.lines))

    def dealer(self, endpoint):
        s = self.ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.RCVTIMEO, 5000)
        s.connect(endpoint)
        return s

    def ask(self, sock, payload):
        sock.send(payload)
        reply = pb.ServerMessage()
        reply.ParseFromString(sock.recv())
        self.assertEqual(reply.protocol_version, 1)
        return reply

    def test_probe_replies_echo_sequence_and_push_up(self):
        s = self.dealer(self.server.endpoints[0])
        try:
            far = self.ask(s, probe_message(1, TOP + 0.02))
            self.assertEqual(far.WhichOneof("body"), "force")
            self.assertEqual(far.force.sequence, 1)
            self.assertEqual(far.force.client_id, 7)
            self.assertFalse(far.force.contact)
            self.assertEqual((far.force.force.x, far.force.force.y, far.force.force.z), (0, 0, 0))

            pressed = self.ask(s, probe_message(2, TOP + RADIUS - 2e-3))
            self.assertEqual(pressed.force.sequence, 2)
            self.assertTrue(pressed.force.contact)
            self.assertGreater(pressed.force.force.z, 0)  # the body pushes the probe up
            self.assertEqual(len(pressed.force.stiffness.m), 9)
            self.assertLess(pressed.force.stiffness.m[8], 0)  # dFz/dz < 0: pressing deeper pushes harder
            self.assertGreaterEqual(pressed.force.server_reply_time_ns, pressed.force.server_recv_time_ns)

            bad = self.ask(s, probe_message(3, float("nan")))
            self.assertEqual(bad.WhichOneof("body"), "error")
            self.assertEqual(bad.error.code, pb.Error.BAD_VALUE)
            self.assertEqual(bad.error.sequence, 3)
            unknown = self.ask(s, probe_message(4, TOP, probe_id=9))
            self.assertEqual(unknown.error.code, pb.Error.UNKNOWN_PROBE)

            again = self.ask(s, probe_message(5, TOP + 0.02))  # still served
            self.assertEqual(again.force.sequence, 5)
        finally:
            s.close()

    def test_state_frames_arrive_with_increasing_ticks(self):
        sub = self.ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.RCVTIMEO, 5000)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(self.server.endpoints[1])
        try:
            ticks, topics = [], set()
            deadline = time.monotonic() + 10
            while (len(ticks) < 50 or "S" not in topics) and time.monotonic() < deadline:
                topic, payload = sub.recv_multipart()
                msg = pb.ServerMessage()
                msg.ParseFromString(payload)
                self.assertEqual(msg.WhichOneof("body"), "state")
                topics.add(topic.decode())
                if topic == b"F":
                    ticks.append(msg.state.tick)
                    self.assertEqual(len(msg.state.positions), 0)
                    self.assertEqual(len(msg.state.probes), 1)
                else:
                    self.assertEqual(len(msg.state.positions), 3 * 320)
            self.assertGreaterEqual(len(ticks), 50)
            self.assertIn("S", topics)
            self.assertTrue(all(b > a for a, b in zip(ticks, ticks[1:])), ticks)
        finally:
            sub.close()

    def test_control_get_mesh(self):
        s = self.dealer(self.server.endpoints[2])
        try:
            m = pb.ClientMessage(protocol_version=1)
            m.control.kind = pb.ControlRequest.GET_MESH
            m.control.sequence = 11
            r = self.ask(s, m.SerializeToString())
            self.assertEqual(r.WhichOneof("body"), "control_reply")
            self.assertTrue(r.control_reply.ok)
            self.assertEqual(r.control_reply.sequence, 11)
            self.assertEqual(r.control_reply.num_nodes, 320)
            self.assertEqual(len(r.control_reply.rest_positions), 3 * 320)
            self.assertEqual(len(r.control_reply.triangles) % 3, 0)
            # The loop is running: its tick count grows (the first reply may come before the
            # first tick on a loaded machine, so ask again for up to 5 s).
            deadline = time.monotonic() + 5
            while r.control_reply.stats.ticks == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
                m.control.sequence += 1
                r = self.ask(s, m.SerializeToString())
            self.assertGreater(r.control_reply.stats.ticks, 0)
        finally:
            s.close()


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    args, rest = parser.parse_known_args()
    SERVER = os.path.abspath(args.server)
    unittest.main(argv=[sys.argv[0]] + rest)
