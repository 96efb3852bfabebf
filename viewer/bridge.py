#!/usr/bin/python3
"""conica viewer bridge: ZeroMQ state frames -> WebSocket, and the viewer's static page.

Subscribes to the server's state PUB (topic "S": node positions, probe forces, loop statistics),
asks the control ROUTER for the surface mesh (GET_MESH) at start, whenever the node count changes
and after the server was silent (a restart), and serves on one HTTP port:
  /            the page (viewer/index.html and its modules, three.js from viewer/node_modules)
  /ws          a WebSocket; each client gets
                 binary  mesh       [u32 2][u32 num_nodes][u32 num_triangles][u32 mesh_id]
                                    float32 rest_positions[3 n], uint32 triangles[3 t]
                 binary  positions  [u32 1][u32 num_nodes][f64 tick][f64 time][f64 received]
                                    float32[3 n]; received: ms since the epoch when the bridge
                                    took the frame off the state socket (the page's frame age)
                 text    JSON       {"type": "state", tick, time, probes, stats, bridge}
                                    {"type": "status", server: "connected" | "waiting", ...}
                 the page answers each positions message with the text "ack"
All little-endian. Conflating: the bridge keeps only the newest frame, and each client is sent the
newest frame when it has acknowledged the previous one, so at most one frame is on its way to a
page: a slow page or a large body drops frames and never lags behind the simulation.

    PYTHONPATH=build/proto/gen /usr/bin/python3 viewer/bridge.py            # default endpoints
    ... --state tcp://127.0.0.1:5556 --control tcp://127.0.0.1:5557 --port 8080
"""
import argparse
import asyncio
import http
import json
import mimetypes
import os
import struct
import sys
import time

import websockets
import zmq
import zmq.asyncio

from conica.v1 import messages_pb2 as pb

HERE = os.path.dirname(os.path.abspath(__file__))
POSITIONS, MESH = 1, 2
STALE_S = 1.5  # no state frame for this long: the server is gone (or paused)
ACK_TIMEOUT_S = 1.0  # a page that does not acknowledge positions frames still gets one a second

STAT_FIELDS = ("ticks", "missed_ticks", "rate_hz", "lateness_p50_us", "lateness_p99_us",
               "lateness_max_us", "step_p50_us", "step_p99_us", "step_max_us", "rollbacks",
               "errors", "probes_received", "nan_events", "speed_events", "hard_stops", "paused",
               "window")


def read_varint(buf, i):
    shift = result = 0
    while True:
        b = buf[i]
        i += 1
        result |= (b & 0x7F) << shift
        if b < 0x80:
            return result, i
        shift += 7


def field_spans(buf, start, end):
    """Yields (field_number, wire_type, value_start, value_end) of one protobuf message."""
    i = start
    while i < end:
        key, i = read_varint(buf, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            _, j = read_varint(buf, i)
        elif wt == 1:
            j = i + 8
        elif wt == 2:
            n, i = read_varint(buf, i)
            j = i + n
        elif wt == 5:
            j = i + 4
        else:
            raise ValueError(f"unsupported wire type {wt}")
        yield num, wt, i, j
        i = j


def packed_positions(raw):
    """The packed float32 bytes of ServerMessage.state.positions, without copying them through
    Python floats (a large body would make the bridge the bottleneck). None if absent."""
    for num, wt, a, b in field_spans(raw, 0, len(raw)):
        if num == 3 and wt == 2:  # ServerMessage.state
            for n2, w2, a2, b2 in field_spans(raw, a, b):
                if n2 == 3 and w2 == 2:  # StateFrame.positions, packed
                    return raw[a2:b2]
    return None


class Hub:
    """The newest frame and mesh, and a version counter clients wait on."""

    def __init__(self):
        self.version = 0
        self.mesh = None        # bytes of the mesh message
        self.mesh_id = 0
        self.positions = None   # bytes of the positions message
        self.info = None        # JSON text of the state message
        self.status = {"type": "status", "server": "waiting"}
        self._changed = asyncio.Event()

    def publish(self):
        self.version += 1
        self._changed.set()
        self._changed = asyncio.Event()

    async def wait_newer(self, version, timeout=1.0):
        if self.version > version:
            return
        try:
            await asyncio.wait_for(self._changed.wait(), timeout)
        except asyncio.TimeoutError:
            pass


class Bridge:
    def __init__(self, args):
        self.args = args
        self.hub = Hub()
        self.ctx = zmq.asyncio.Context()
        self.frames_in = 0        # "S" frames received
        self.frames_parsed = 0    # frames actually decoded (the newest of each batch)
        self.frames_sent = 0      # position messages sent to all clients
        self.clients = 0
        self.last_frame = 0.0
        self.last_tick = None
        self.num_nodes = None
        self.mesh_nodes = None
        self.mesh_wanted = asyncio.Event()
        self.mesh_wanted.set()
        self.control_seq = 0

    # ---- ZeroMQ side --------------------------------------------------------------------------

    async def subscribe(self):
        sub = self.ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.RCVHWM, 8)  # a small queue: old frames are worthless
        sub.setsockopt(zmq.SUBSCRIBE, b"S")
        sub.connect(self.args.state)
        msg = pb.ServerMessage()
        while True:
            if not await sub.poll(int(STALE_S * 1000)):
                self.set_status("waiting", f"no state frames from {self.args.state}")
                continue
            newest = None
            received_ms = 0.0
            while True:  # drain: keep only the newest frame
                try:
                    parts = await sub.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
                if len(parts) == 2 and parts[0] == b"S":
                    newest = parts[1]
                    received_ms = time.time() * 1e3
                    self.frames_in += 1
            if newest is None:
                continue
            try:
                msg.ParseFromString(newest)
            except Exception:  # noqa: BLE001 (a malformed frame is skipped, not fatal)
                continue
            if not msg.HasField("state"):
                continue
            self.on_state(msg.state, newest, received_ms)

    def on_state(self, st, raw, received_ms):
        now = time.monotonic()
        restarted = self.last_tick is not None and (
            now - self.last_frame > STALE_S or st.tick < self.last_tick)
        self.last_frame, self.last_tick = now, st.tick
        self.frames_parsed += 1
        if restarted and self.mesh_nodes is not None:
            self.mesh_wanted.set()  # a new server (or a resumed one): fetch its mesh again
        if st.num_nodes != self.mesh_nodes:
            self.mesh_wanted.set()
        self.num_nodes = st.num_nodes
        if self.hub.status.get("server") != "connected":
            self.set_status("connected", f"state {self.args.state}", publish=False)
        pos = packed_positions(raw)
        if pos is not None and len(pos) == 12 * st.num_nodes and st.num_nodes > 0:
            self.hub.positions = struct.pack("<IIddd", POSITIONS, st.num_nodes, float(st.tick),
                                             st.time, received_ms) + pos
        s = st.stats
        self.hub.info = json.dumps({
            "type": "state", "tick": st.tick, "time": st.time, "num_nodes": st.num_nodes,
            "probes": [{"id": p.probe_id, "position": [p.position.x, p.position.y, p.position.z],
                        "force": [p.force.x, p.force.y, p.force.z], "contact": p.contact}
                       for p in st.probes],
            "stats": {k: getattr(s, k) for k in STAT_FIELDS},
            "bridge": {"frames_in": self.frames_in, "frames_parsed": self.frames_parsed,
                       "clients": self.clients, "probe_radius": self.args.probe_radius},
        })
        self.hub.publish()

    def set_status(self, server, detail, publish=True):
        if self.hub.status.get("server") == server:
            return
        self.hub.status = {"type": "status", "server": server, "detail": detail}
        print(f"bridge: server {server} ({detail})", file=sys.stderr, flush=True)
        if publish:
            self.hub.publish()

    async def fetch_meshes(self):
        sock = None
        while True:
            await self.mesh_wanted.wait()
            if sock is None:
                sock = self.ctx.socket(zmq.DEALER)
                sock.setsockopt(zmq.LINGER, 0)
                sock.connect(self.args.control)
            self.control_seq += 1
            req = pb.ClientMessage(protocol_version=1)
            req.control.kind = pb.ControlRequest.GET_MESH
            req.control.sequence = self.control_seq
            await sock.send(req.SerializeToString())
            reply = None
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                if not await sock.poll(int(max(1, (deadline - time.monotonic()) * 1000))):
                    break
                m = pb.ServerMessage()
                m.ParseFromString(await sock.recv())
                if m.HasField("control_reply") and m.control_reply.sequence == self.control_seq:
                    reply = m.control_reply
                    break
            if reply is None or not reply.ok:
                # no answer: drop the socket (its queued request would be answered late) and retry
                sock.close()
                sock = None
                await asyncio.sleep(0.5)
                continue
            n, tris = reply.num_nodes, reply.triangles
            rest = struct.pack(f"<{3 * n}f", *reply.rest_positions)
            tri = struct.pack(f"<{len(tris)}I", *tris)
            self.mesh_nodes = n
            self.mesh_wanted.clear()
            if self.hub.mesh is not None and self.hub.mesh[16:] == rest + tri:
                continue  # the same body (a restarted or resumed server): clients keep theirs
            self.hub.mesh_id += 1
            self.hub.mesh = struct.pack("<IIII", MESH, n, len(tris) // 3, self.hub.mesh_id) + rest + tri
            print(f"bridge: mesh {n} nodes, {len(tris) // 3} surface triangles", file=sys.stderr,
                  flush=True)
            self.hub.publish()

    # ---- browser side -------------------------------------------------------------------------

    async def client(self, ws, path=None):
        """Sends each client the newest state, one positions frame in flight at a time: the next
        goes when the page has acknowledged the previous (text "ack") or after ACK_TIMEOUT_S.
        Without that, the sockets' buffers between here and the page's script (megabytes on
        loopback) would queue seconds of large frames whenever the page draws slower than the
        server publishes; with it, frames published meanwhile are skipped and the page gets the
        newest."""
        self.clients += 1
        sent_version, sent_mesh, sent_status = -1, 0, None
        acked = asyncio.Event()
        acked.set()

        async def read_acks():
            try:
                async for m in ws:
                    if m == "ack":
                        acked.set()
            except websockets.ConnectionClosed:
                pass

        reader = asyncio.create_task(read_acks())
        try:
            while True:
                await self.hub.wait_newer(sent_version)
                hub = self.hub
                if hub.version == sent_version:
                    continue
                if hub.status is not sent_status:
                    sent_status = hub.status
                    await ws.send(json.dumps(hub.status))
                if hub.mesh is not None and hub.mesh_id != sent_mesh:
                    sent_mesh = hub.mesh_id
                    await ws.send(hub.mesh)
                if sent_mesh and hub.positions is not None:
                    try:
                        await asyncio.wait_for(acked.wait(), ACK_TIMEOUT_S)
                    except asyncio.TimeoutError:
                        pass
                    if reader.done():
                        break  # the page has gone
                    hub = self.hub  # newer frames may have come while waiting: send the newest
                    acked.clear()
                    await ws.send(hub.positions)
                    self.frames_sent += 1
                if hub.info is not None:
                    await ws.send(hub.info)
                sent_version = hub.version
        except websockets.ConnectionClosed:
            pass
        finally:
            reader.cancel()
            self.clients -= 1

    def static(self, path, headers):
        path = path.split("?", 1)[0]
        if path == "/ws":
            return None  # the WebSocket handshake
        if path.endswith("/"):
            path += "index.html"
        full = os.path.realpath(os.path.join(HERE, path.lstrip("/")))
        if not (full == HERE or full.startswith(HERE + os.sep)) or not os.path.isfile(full):
            return (http.HTTPStatus.NOT_FOUND, [("Content-Type", "text/plain")], b"not found\n")
        ctype = mimetypes.guess_type(full)[0] or "application/octet-stream"
        if full.endswith((".js", ".mjs")):
            ctype = "text/javascript"
        with open(full, "rb") as f:
            body = f.read()
        return (http.HTTPStatus.OK, [("Content-Type", ctype), ("Cache-Control", "no-cache")], body)

    async def run(self):
        async with websockets.serve(self.client, self.args.host, self.args.port,
                                    process_request=self.static, max_size=2 ** 20,
                                    compression=None):
            print(f"bridge: serving http://{self.args.host}:{self.args.port}/ "
                  f"(state {self.args.state}, control {self.args.control})", file=sys.stderr,
                  flush=True)
            tasks = [asyncio.create_task(self.subscribe()), asyncio.create_task(self.fetch_meshes())]
            if self.args.seconds > 0:
                await asyncio.sleep(self.args.seconds)
            else:
                await asyncio.Future()
            for t in tasks:
                t.cancel()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--state", default="tcp://127.0.0.1:5556", help="server's state PUB")
    ap.add_argument("--control", default="tcp://127.0.0.1:5557", help="server's control ROUTER")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--probe-radius", type=float, default=0.005,
                    help="m, radius the page draws probes with (not on the wire)")
    ap.add_argument("--seconds", type=float, default=0, help="exit after this long (0: never)")
    args = ap.parse_args()
    if not os.path.isdir(os.path.join(HERE, "node_modules", "three")):
        print("bridge: viewer/node_modules/three missing; run scripts/viewer-setup.sh",
              file=sys.stderr)
    bridge = Bridge(args)
    try:
        asyncio.run(bridge.run())
    except KeyboardInterrupt:
        pass
    finally:
        bridge.ctx.destroy(linger=0)


if __name__ == "__main__":
    main()
