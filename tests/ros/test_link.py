#!/usr/bin/python3
"""conica_ros.link.ProbeStream (clients/ros) against a scripted server in this process (a ZeroMQ
ROUTER speaking the conica protocol): updates pipelined without waiting, replies matched to their
tokens, the reply's force and stiffness passed through, refused updates counted, updates left
unanswered reported as timed out and their late replies dropped. No ROS needed.

    PYTHONPATH=build/proto/gen /usr/bin/python3 tests/ros/test_link.py --module-dir clients/ros
"""
import argparse
import sys
import threading
import time
import unittest

links = None
pb = None
zmq = None


class ScriptedServer:
    """Answers each probe update with force = (x, y, z) * 10 N/m and stiffness = -10 I, after
    `delay` s; updates whose sequence is in `ignore` get no answer, those in `refuse` an error."""

    def __init__(self, ignore=(), refuse=(), delay=0.0, hold_first=0):
        self.ctx = zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.ROUTER)
        self.sock.setsockopt(zmq.LINGER, 0)
        port = self.sock.bind_to_random_port("tcp://127.0.0.1")
        self.endpoint = f"tcp://127.0.0.1:{port}"
        self.ignore, self.refuse, self.delay = set(ignore), set(refuse), delay
        self.hold_first = hold_first  # answer nothing until this many updates have arrived
        self.received = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _answer(self, peer, u):
        out = pb.ServerMessage(protocol_version=1)
        if u.sequence in self.refuse:
            out.error.code = pb.Error.BAD_VALUE
            out.error.message = "refused by the script"
            out.error.sequence = u.sequence
        else:
            f = out.force
            f.client_id, f.probe_id, f.sequence = u.client_id, u.probe_id, u.sequence
            f.force.x, f.force.y, f.force.z = (10 * u.position.x, 10 * u.position.y,
                                               10 * u.position.z)
            f.stiffness.m.extend([-10, 0, 0, 0, -10, 0, 0, 0, -10])
            f.contact = True
            f.tick = u.sequence
        self.sock.send_multipart([peer, out.SerializeToString()])

    def _run(self):
        held = []
        while not self._stop.is_set():
            if not self.sock.poll(10):
                continue
            peer, data = self.sock.recv_multipart()
            m = pb.ClientMessage()
            m.ParseFromString(data)
            u = m.probe
            self.received.append((u.sequence, time.monotonic()))
            if u.sequence in self.ignore:
                continue
            if self.delay:
                time.sleep(self.delay)
            held.append((peer, pb.ProbeUpdate.FromString(u.SerializeToString())))
            if len(self.received) >= self.hold_first:
                for p, x in held:
                    self._answer(p, x)
                held.clear()

    def close(self):
        self._stop.set()
        self._thread.join(timeout=1)
        self.sock.close()


class Collect:
    def __init__(self):
        self.replies, self.timeouts = [], []
        self.lock = threading.Lock()

    def on_reply(self, token, r):
        with self.lock:
            self.replies.append((token, r))

    def on_timeout(self, token):
        with self.lock:
            self.timeouts.append(token)

    def wait(self, n, seconds=2.0):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            with self.lock:
                if len(self.replies) + len(self.timeouts) >= n:
                    return True
            time.sleep(0.005)
        return False


class ProbeStreamTest(unittest.TestCase):
    def test_pipelined_updates_come_back_with_their_tokens_and_values(self):
        # The server answers nothing until all 20 updates have arrived: the stream must have sent
        # them all without waiting for a reply.
        srv = ScriptedServer(hold_first=20)
        c = Collect()
        s = links.ProbeStream(srv.endpoint, c.on_reply, c.on_timeout, timeout=1.0)
        try:
            for i in range(20):
                s.send((0.001 * i, 0.002, 0.003), token=("pose", i))
            self.assertTrue(c.wait(20), f"{len(c.replies)} replies")
            self.assertEqual(len(srv.received), 20)
            self.assertEqual([t for t, _ in c.replies], [("pose", i) for i in range(20)])
            tok, r = c.replies[7]
            self.assertAlmostEqual(r.force[0], 10 * 0.007, places=12)
            self.assertAlmostEqual(r.force[2], 10 * 0.003, places=12)
            self.assertEqual([list(row) for row in r.stiffness],
                             [[-10, 0, 0], [0, -10, 0], [0, 0, -10]])
            self.assertEqual((s.sent, s.replies, s.timeouts, s.errors), (20, 20, 0, 0))
        finally:
            s.close()
            srv.close()

    def test_unanswered_updates_time_out_and_refused_ones_are_counted(self):
        srv = ScriptedServer(ignore={2, 5}, refuse={4})
        c = Collect()
        s = links.ProbeStream(srv.endpoint, c.on_reply, c.on_timeout, timeout=0.1)
        try:
            for i in range(1, 7):
                s.send((0.0, 0.0, 0.01), token=i)
                time.sleep(0.002)
            self.assertTrue(c.wait(5, seconds=1.0))
            time.sleep(0.2)  # past the timeout: no more callbacks for 2 and 5 after this
            self.assertEqual(sorted(t for t, _ in c.replies), [1, 3, 6])
            self.assertEqual(sorted(c.timeouts), [2, 5])
            self.assertEqual(s.errors, 1)
            self.assertIn("refused by the script", s.last_error)
        finally:
            s.close()
            srv.close()

    def test_late_replies_are_dropped(self):
        srv = ScriptedServer(delay=0.15)  # every answer after the stream's 0.05 s timeout
        c = Collect()
        s = links.ProbeStream(srv.endpoint, c.on_reply, c.on_timeout, timeout=0.05)
        try:
            s.send((0.0, 0.0, 0.0), token="late")
            time.sleep(0.4)
            self.assertEqual(c.timeouts, ["late"])
            self.assertEqual(c.replies, [])
        finally:
            s.close()
            srv.close()


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--module-dir", required=True, help="clients/ros")
    args, rest = ap.parse_known_args()
    sys.path.insert(0, args.module_dir)
    import zmq as _zmq
    from conica.v1 import messages_pb2 as _pb
    from conica_ros import link as _link
    zmq, pb, links = _zmq, _pb, _link
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
