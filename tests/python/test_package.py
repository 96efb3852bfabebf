"""The installed Python package conica against a real conica-server (`--builtin cube` on ports
the OS picks; $CONICA_SERVER is the binary). Run with the venv's interpreter after
install_package.py:

    CONICA_SERVER=build/bin/conica-server build/python/venv/bin/python -m pytest tests/python

The built-in cube: 0.04 m on a side, min corner at the origin, a 7 x 7 x 4 cell lattice
(8 x 8 x 5 = 320 nodes), bottom face fixed, one probe of radius 5 mm touching the surface
through a proxy (contact SURFACE): a reply depends on where the proxy was, so tests that compare
replies first let it settle at a position (`settled`).
"""
import asyncio
import os
import re
import sys
import threading
import time

import numpy as np
import pytest
import zmq

import conica
import conica.aio
from conica.v1 import messages_pb2 as pb

SIZE = 0.04                 # m, the cube's side
CELLS = (7, 7, 4)           # lattice cells along x, y, z
NUM_NODES = (CELLS[0] + 1) * (CELLS[1] + 1) * (CELLS[2] + 1)
RADIUS = 5e-3               # m, the probe
DX = SIZE / CELLS[0]        # m, node spacing in x and y
TOP = SIZE                  # m, z of the top face
CENTRE_XY = (3 * DX, 3 * DX)  # m, a node column near the middle of the top face
FAR = (0.02, 0.02, TOP + 0.02)  # m, 15 mm clear of the top face


def pressed(depth, x=CENTRE_XY[0], y=CENTRE_XY[1]):
    """The probe centre `depth` m into the top face above (x, y)."""
    return np.array((x, y, TOP + RADIUS - depth))


def settled(client, x):
    """The reply at x once the proxy has settled there (the server paused): a proxy sinks at most
    0.02 R per update, so a probe placed millimetres deep at once takes some updates."""
    r = client.probe(x)
    for _ in range(200):
        nxt = client.probe(x)
        if np.array_equal(nxt.force, r.force):
            return nxt
        r = nxt
    raise AssertionError(f"the replies at {x} did not settle: {nxt.force}, before {r.force}")


@pytest.fixture(scope="module")
def server():
    with conica.LocalServer(builtin="cube", seconds=120) as s:
        yield s


@pytest.fixture
def client(server):
    c = server.client(timeout=5.0)
    yield c
    # Leave the server as the next test expects it: running, the probe away, the body at rest.
    c.resume()
    c.probe(FAR)
    c.reset()
    c.close()


def test_imported_from_the_venv_not_the_source_tree():
    assert sys.prefix != sys.base_prefix, "the tests run in the venv the package is installed in"
    here = os.path.dirname(conica.__file__)
    assert here.startswith(sys.prefix), here
    assert os.path.isfile(os.path.join(here, "py.typed"))
    for name in ("messages_pb2.py", "messages_pb2.pyi", "scene_pb2.py", "scene_pb2.pyi"):
        assert os.path.isfile(os.path.join(here, "v1", name)), name
    assert os.path.dirname(pb.__file__) == os.path.join(here, "v1")


def test_far_from_the_body_the_force_is_zero(client):
    r = client.probe(FAR)
    assert r.force.shape == (3,) and r.force.dtype == np.float64
    assert r.stiffness.shape == (3, 3) and r.stiffness.dtype == np.float64
    assert not r.contact
    assert np.array_equal(r.force, np.zeros(3))
    assert np.array_equal(r.stiffness, np.zeros((3, 3)))
    np.testing.assert_allclose(r.position, FAR, rtol=0, atol=1e-12)
    assert 0 < r.round_trip_s < 5.0
    assert r.server_recv_time_ns <= r.server_reply_time_ns


def test_pressed_in_the_force_points_out_of_the_body(client):
    client.pause()  # the body holds still: the proxy settles at each probe position
    top = settled(client, pressed(2e-3))
    assert top.contact
    assert top.force[2] > 0  # the top face pushes the probe up (+z)
    assert abs(top.force[0]) + abs(top.force[1]) < 1e-3 * top.force[2]
    deeper = settled(client, pressed(3e-3))
    assert deeper.force[2] > top.force[2]  # deeper presses harder
    # Into the face x = 0 at mid height (the proxy moved around, not through, the body): pushed
    # towards -x.
    for waypoint in (FAR, (-RADIUS - 5e-3, 0.02, FAR[2]), (-RADIUS - 5e-3, 0.02, 0.02)):
        client.probe(waypoint)
    side = settled(client, (-RADIUS + 2e-3, 0.02, 0.02))
    assert side.contact
    assert side.force[0] < 0
    assert abs(side.force[1]) + abs(side.force[2]) < 1e-3 * -side.force[0]


def test_stiffness_is_the_derivative_of_the_force(client):
    """K = dF/dx from the reply against central differences of six further replies."""
    client.pause()
    # Over the edge x = 0 of the top face, the sphere touching the side face too: K has
    # off-diagonal terms (on a flat face a frictionless tool's K is its normal entry alone).
    x0 = np.array((0.0, 0.0185, TOP + RADIUS - 1.5e-3))
    k = settled(client, x0).stiffness
    h = 1e-6  # m
    fd = np.column_stack([(client.probe(x0 + h * e).force - client.probe(x0 - h * e).force) / (2 * h)
                          for e in np.eye(3)])
    scale = np.abs(k).max()
    assert k[2, 2] < 0  # pressing deeper pushes back harder
    assert np.abs(k[0, 2]) > 0.05 * scale  # a test of more than one entry
    # 1e-3: each reply ends the proxy solve at its own tolerance.
    np.testing.assert_allclose(fd, k, rtol=0, atol=1e-3 * scale)
    # The reply's local model F0 + K dx predicts the force 0.1 mm away ten times better than
    # F0 alone (what is left is the law's curvature).
    r0, step = client.probe(x0), np.array((1e-4, -1e-4, -1e-4))
    actual = client.probe(x0 + step).force
    error = np.linalg.norm(r0.force_at(x0 + step) - actual)
    assert error < 0.1 * np.linalg.norm(r0.force - actual), (error, r0.force, actual)


def test_position_frames_hold_every_node_as_a_float32_view(client):
    mesh = client.mesh()
    assert mesh.num_nodes == NUM_NODES
    rest = mesh.rest_positions
    assert rest.shape == (NUM_NODES, 3)
    for axis, cells in enumerate(CELLS):  # a lattice: cells + 1 distinct coordinates per axis
        np.testing.assert_allclose(np.unique(rest[:, axis].round(6)),
                                   np.linspace(0, SIZE, cells + 1), atol=1e-6)
    # The surface of a 7 x 7 x 4 box of cells: two triangles per face quad.
    assert mesh.triangles.shape == (2 * 2 * (7 * 7 + 7 * 4 + 7 * 4), 3)
    assert mesh.triangles.max() < NUM_NODES

    with client.subscribe(forces=False) as sub:
        frame = sub.recv()
        assert frame.topic == "S"
        assert frame.num_nodes == NUM_NODES
        p = frame.positions
        assert p is not None and p.shape == (NUM_NODES, 3) and p.dtype == np.float32
        assert not p.flags.owndata and not p.flags.writeable  # a view of the message bytes
        base = p
        while isinstance(base, np.ndarray):
            base = base.base
        assert isinstance(base, memoryview), type(base)  # the received message
        assert np.shares_memory(p, np.frombuffer(base, dtype=np.uint8))
        assert base.nbytes > p.nbytes  # the whole message, positions inside it
        np.testing.assert_allclose(p, rest, atol=1e-4)  # at rest (reset after each test)

        # Pressed 3 mm for 0.3 s: the node under the probe goes down by about the press (a
        # little more while the lattice rings), a top corner far away moves much less, and the
        # fixed bottom face not at all.
        client.probe(pressed(3e-3))
        time.sleep(0.3)
        moved = sub.latest()
        dz = moved.positions[:, 2] - rest[:, 2]
        under = int(np.argmin(np.linalg.norm(rest - (CENTRE_XY[0], CENTRE_XY[1], TOP), axis=1)))
        corner = int(np.argmin(np.linalg.norm(rest - (SIZE, SIZE, TOP), axis=1)))
        assert -4e-3 < dz[under] < -2e-3, dz[under]
        # (the corner rings by up to ~11 % of the press in the lightly damped lattice)
        assert abs(dz[corner]) < 0.25 * abs(dz[under]), (dz[corner], dz[under])
        bottom = rest[:, 2] == 0
        np.testing.assert_array_equal(moved.positions[bottom], rest[bottom])
        assert moved.tick > frame.tick


def test_force_frames_report_the_probe(client):
    client.probe(pressed(2e-3))
    with client.subscribe(positions=False) as sub:
        frames = [sub.recv() for _ in range(20)]
    assert all(f.topic == "F" and f.positions is None for f in frames)
    ticks = [f.tick for f in frames]
    assert all(b > a for a, b in zip(ticks, ticks[1:])), ticks
    last = frames[-1].probes[0]
    assert last.probe_id == 0 and last.contact and last.force[2] > 0
    np.testing.assert_allclose(last.position, pressed(2e-3), atol=1e-12)
    assert frames[-1].stats.ticks > 0


def test_pause_freezes_the_simulation_and_resume_steps_it(client):
    assert client.pause().message == "paused"
    assert client.stats().paused
    with client.subscribe(positions=False) as sub:
        a = sub.recv()
        time.sleep(0.05)
        b = sub.latest()
        assert b.tick == a.tick and b.time_s == a.time_s
        client.resume()
        assert not client.stats().paused
        time.sleep(0.05)
        c = sub.latest()
        assert c.tick > a.tick and c.time_s > a.time_s
        np.testing.assert_allclose(c.time_s - a.time_s, (c.tick - a.tick) * 1e-3, rtol=1e-6)


def test_set_parameter_and_its_refusals(client):
    client.set_parameter("positions_hz", 0)  # no position frames
    try:
        with client.subscribe(forces=False, timeout=0.3) as sub:
            with pytest.raises(conica.Timeout):
                sub.recv()
    finally:
        client.set_parameter("positions_hz", 60)
    with pytest.raises(conica.ServerError) as e:
        client.set_parameter("stiffness", 1.0)
    assert e.value.code == "CONTROL_REFUSED" and "unknown parameter" in str(e.value)
    with pytest.raises(conica.ServerError, match="damping >= 0"):
        client.set_parameter("damping", -1.0)
    with pytest.raises(ValueError, match="unknown control kind 'EXPLODE'"):
        client.control("EXPLODE")


def test_refused_probe_updates_raise_server_error(client):
    with pytest.raises(conica.ServerError) as e:
        client.probe(FAR, probe_id=3)
    assert e.value.code == "UNKNOWN_PROBE" and client.endpoint in str(e.value)
    with pytest.raises(conica.ServerError) as e:
        client.probe((float("nan"), 0.0, 0.0))
    assert e.value.code == "BAD_VALUE"
    with pytest.raises(ValueError, match=r"position \(m\) must be 3 numbers"):
        client.probe((0.0, 0.0))
    assert not client.probe(FAR).contact  # still served


def test_threads_share_a_client(client):
    """Four threads probe their own positions through one client while a fifth asks for stats:
    every reply is the one to its own update (position echoed, the tool in contact and pushed
    out; the force itself depends on the order the updates moved the shared proxy in)."""
    client.pause()
    depths = [0.5e-3, 1e-3, 1.5e-3, 2e-3]  # m
    failures = []

    def press(d):
        try:
            for _ in range(50):
                r = client.probe(pressed(d))
                if not (np.array_equal(r.position, pressed(d)) and r.contact and r.force[2] > 0):
                    failures.append((d, r.position, r.force))
        except Exception as e:  # noqa: BLE001 - reported below
            failures.append((d, e))

    def stats():
        for _ in range(20):
            if not client.stats().paused:
                failures.append("stats: not paused")

    threads = [threading.Thread(target=press, args=(d,)) for d in depths]
    threads.append(threading.Thread(target=stats))
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert not failures, failures[:3]


def test_pipelined_updates_are_answered_in_order(client):
    """send_probe() 40 updates before reading any reply: each reply is the one to its update
    (the force of its depth, as probe() gives it one at a time from the same start)."""
    client.pause()
    depths = np.linspace(0.2e-3, 3e-3, 40)  # m
    client.probe(FAR)  # the proxy free, at FAR: both runs start from it
    expected = [client.probe(pressed(d)).force for d in depths]
    client.probe(FAR)
    seqs = [client.send_probe(pressed(d)) for d in depths]
    assert client.outstanding == len(depths)
    got = [client.recv_reply() for _ in depths]
    assert [r.sequence for r in got] == seqs
    for r, d, f in zip(got, depths, expected):
        np.testing.assert_array_equal(r.position, pressed(d))
        np.testing.assert_array_equal(r.force, f)
    assert client.outstanding == 0
    with pytest.raises(ValueError, match="no probe update is awaited"):
        client.recv_reply()

    # A refusal among them is raised with its sequence; a probe() in between keeps the others.
    a = client.send_probe(FAR)
    b = client.send_probe(FAR, probe_id=3)
    c = client.send_probe(FAR)
    r = client.probe(pressed(1e-3))
    assert r.sequence == c + 1 and r.contact
    assert [x.sequence for x in client.replies()] == [a]
    with pytest.raises(conica.ServerError) as e:
        client.replies()
    assert e.value.sequence == b and e.value.code == "UNKNOWN_PROBE"
    assert [x.sequence for x in client.replies()] == [c]
    assert client.outstanding == 0


def test_bad_endpoint_and_silence_raise_the_right_exceptions():
    with pytest.raises(conica.EndpointError, match="'tcp://127.0.0.1:notaport'"):
        conica.Client("tcp://127.0.0.1:notaport")
    with pytest.raises(conica.EndpointError, match="cannot derive the state endpoint"):
        conica.Client("ipc:///tmp/conica-none").subscribe()
    with zmq.Context.instance().socket(zmq.ROUTER) as silent:  # takes requests, never answers
        port = silent.bind_to_random_port("tcp://127.0.0.1")
        endpoint = f"tcp://127.0.0.1:{port}"
        with conica.Client(endpoint, timeout=0.2) as c:
            t0 = time.monotonic()
            with pytest.raises(conica.Timeout) as e:
                c.probe(FAR)
            waited = time.monotonic() - t0
        assert 0.2 <= waited < 2.0
        assert isinstance(e.value, TimeoutError)
        assert e.value.endpoint == endpoint and e.value.timeout_s == 0.2
        assert f"no reply to probe update 1 from {endpoint} within 0.2 s" in str(e.value)
        with conica.Client(endpoint, timeout=0.2) as c:
            c.send_probe(FAR)
            c.send_probe(FAR)
            with pytest.raises(conica.Timeout, match="no reply to any of 2 probe updates"):
                c.recv_reply()
            assert c.replies() == [] and c.outstanding == 2


def _fake_server(reply):
    """A ROUTER on a free port answering one request with reply(request bytes)."""
    sock = zmq.Context.instance().socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    port = sock.bind_to_random_port("tcp://127.0.0.1")

    def serve():
        if sock.poll(5000):
            route, request = sock.recv_multipart()
            sock.send_multipart([route, reply(request)])
        sock.close()

    threading.Thread(target=serve, daemon=True).start()
    return f"tcp://127.0.0.1:{port}"


def test_malformed_replies_raise_protocol_error():
    with conica.Client(_fake_server(lambda _: b"\xff\xff\xff"), timeout=2) as c:
        with pytest.raises(conica.ProtocolError, match="unparseable ServerMessage"):
            c.probe(FAR)

    def short_stiffness(request):
        p = pb.ClientMessage.FromString(request).probe
        m = pb.ServerMessage(protocol_version=1)
        m.force.client_id, m.force.sequence = p.client_id, p.sequence
        m.force.force.z = 1.0
        m.force.stiffness.m.extend([0.0] * 4)
        return m.SerializeToString()

    with conica.Client(_fake_server(short_stiffness), timeout=2) as c:
        with pytest.raises(conica.ProtocolError, match=r"ForceReply.stiffness has 4 values, expected 9"):
            c.probe(FAR)
    with conica.Client(_fake_server(lambda _: pb.ServerMessage(protocol_version=2).SerializeToString()),
                       timeout=2) as c:
        with pytest.raises(conica.ProtocolError, match="protocol_version is 2"):
            c.probe(FAR)


def test_damaged_state_frames_raise_protocol_error():
    ctx = zmq.Context.instance()
    with ctx.socket(zmq.PUB) as pub:
        port = pub.bind_to_random_port("tcp://127.0.0.1")
        with conica.Subscriber(f"tcp://127.0.0.1:{port}", timeout=2) as sub:
            m = pb.ServerMessage(protocol_version=1)
            m.state.num_nodes = 2
            m.state.positions.extend([0.0] * 5)  # 5 floats for 2 nodes
            deadline = time.monotonic() + 5
            while not sub._sock.poll(0) and time.monotonic() < deadline:  # the slow joiner
                pub.send_multipart([b"S", m.SerializeToString()])
                time.sleep(0.02)
            with pytest.raises(conica.ProtocolError, match=r"positions has 5 floats, expected 3 x num_nodes = 6"):
                sub.recv()


def test_asyncio_client_gives_the_same_replies(server, client):
    client.pause()
    x = (0.019, 0.0185, TOP + RADIUS - 1.5e-3)
    sync = settled(client, x)

    async def run():
        async with conica.aio.Client(server.probe_endpoint, state_endpoint=server.state_endpoint,
                                     control_endpoint=server.control_endpoint, timeout=5) as a:
            r = await a.probe(x)
            stats = await a.stats()
            async with a.subscribe(forces=False) as sub:
                frame = await sub.recv()
                async for later in sub:
                    assert later.tick == frame.tick  # paused: the simulation holds its tick
                    break
                await asyncio.sleep(0.05)
                newest = await sub.latest()
                assert newest.topic == "S" and newest.num_nodes == NUM_NODES
            with pytest.raises(conica.ServerError):
                await a.probe(x, probe_id=3)
            seqs = [await a.send_probe(x) for _ in range(10)]
            piped = [await a.recv_reply() for _ in seqs]
            assert [p.sequence for p in piped] == seqs
            assert all(np.array_equal(p.force, r.force) for p in piped)
            return r, stats, frame

    r, stats, frame = asyncio.run(run())
    assert sync.contact and r.contact
    np.testing.assert_array_equal(r.force, sync.force)
    np.testing.assert_array_equal(r.stiffness, sync.stiffness)
    assert r.tick == sync.tick  # paused: the same simulation tick
    assert stats.paused
    assert frame.positions.shape == (NUM_NODES, 3) and frame.positions.dtype == np.float32


def test_asyncio_timeout():
    async def run():
        with zmq.Context.instance().socket(zmq.ROUTER) as silent:
            port = silent.bind_to_random_port("tcp://127.0.0.1")
            async with conica.aio.Client(f"tcp://127.0.0.1:{port}", timeout=0.2) as a:
                await a.probe(FAR)

    with pytest.raises(conica.Timeout, match="within 0.2 s"):
        asyncio.run(run())


def test_load_scene_swaps_the_body_in():
    """LOAD_SCENE on a server of its own: the anisotropic block of configs/ replaces the cube;
    the node count follows from the file's lattice cells."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "configs",
                        "anisotropic-block.pbtxt")
    path = os.path.abspath(path)
    with open(path) as f:
        cells = [int(v) for v in re.search(r"cells:\s*\[(\d+),\s*(\d+),\s*(\d+)\]", f.read()).groups()]
    nodes = (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1)
    with conica.LocalServer(builtin="cube", seconds=60) as s, s.client(timeout=5.0) as c:
        with pytest.raises(conica.ServerError) as e:
            c.load_scene(path + ".missing")
        assert e.value.code == "CONTROL_REFUSED" and "anisotropic-block.pbtxt.missing" in str(e.value)
        assert c.mesh().num_nodes == NUM_NODES  # the cube is still served
        r = c.load_scene(path)
        assert r.num_nodes == nodes and f"loaded {nodes} nodes" in r.message
        assert c.mesh().num_nodes == nodes
        with c.subscribe(forces=False) as sub:
            frame = sub.recv()
            while frame.num_nodes != nodes:  # frames published before the swap
                frame = sub.recv()
            assert frame.positions.shape == (nodes, 3)
