#!/usr/bin/python3
"""conica-ros end to end: conica-server --builtin cube and rosmaster on loopback (free ports),
the node clients/ros/conica-ros in namespace /probe0, and this test as a second ROS node.

The scene is placed in the ROS frame "world" rotated 90 degrees about z and shifted by (1, 2, 0)
m, so every position and force crosses a real transform (worked out by hand below, not with the
node's code). A publisher sends measured_cp (PoseStamped) at 1000 Hz for 3 s: 1 s with the probe
5 mm above the cube's top face, 0.5 s pressing 2 mm in, 1.5 s held. Checks: one servo_cf per pose
(loss), latency from the pose's stamp to the receipt of its servo_cf (p50 / p99), zero wrench off
the body, a wrench pushing out of the top face (+z) when pressed, the stiffness pushing back
(d Fz / d z < 0), the surface marker inside the transformed cube, poses in another frame ignored.
Before ROS starts, the node's server links (the conica package when installed, pyzmq) are checked
against each other.

Exit 0: passed; 1: failed; 77: ROS 1 (rospy, rosmaster) is not installed (skipped)."""
import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

SKIP = 77


def free_ports(n):
    socks, ports = [], []
    for _ in range(n):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        socks.append(s)
        ports.append(s.getsockname()[1])
    for s in socks:
        s.close()
    return ports


failures = []


def check(cond, what):
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    if not cond:
        failures.append(what)


def raise_priority():
    """SCHED_FIFO priority 10 where permitted, else nice -10, else nothing; the node and rosmaster
    inherit it (conica-server sets its own). The test measures the node at 1 kHz, not the CPU share
    left by whatever else the machine runs. Returns what it got."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        return "SCHED_FIFO 10"
    except (OSError, AttributeError):
        pass
    try:
        os.nice(-10)
        return "nice -10"
    except OSError:
        return "default priority"


def percentile(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q / 100 * (len(v) - 1))))]


# The scene in the ROS frame, by hand: rotated +90 degrees about z, then shifted by (1, 2, 0) m.
# A scene point (x, y, z) is the ROS point (1 - y, 2 + x, z); a scene vector (x, y, z) is (-y, x, z).
def scene_to_ros(p):
    return (1.0 - p[1], 2.0 + p[0], p[2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", required=True, help="conica-server")
    ap.add_argument("--node", required=True, help="clients/ros/conica-ros")
    ap.add_argument("--python", default=sys.executable, help="interpreter for the node")
    ap.add_argument("--seconds", type=float, default=3.0, help="streaming time at 1 kHz")
    args = ap.parse_args()

    try:
        import rospy
        from geometry_msgs.msg import PoseStamped, WrenchStamped
        from std_msgs.msg import Float64MultiArray
        from visualization_msgs.msg import Marker
    except ImportError as e:
        print(f"SKIP: ROS 1 is not installed ({e}); Debian: apt-get install python3-rospy "
              "python3-rosmaster python3-geometry-msgs python3-std-msgs python3-visualization-msgs")
        return SKIP
    rosmaster = shutil.which("rosmaster")
    if rosmaster is None:
        print("SKIP: rosmaster is not installed (Debian: apt-get install python3-rosmaster)")
        return SKIP

    sys.path.insert(0, os.path.dirname(os.path.realpath(args.node)))
    from conica_ros import link as links

    priority = raise_priority()  # this process; the node and rosmaster inherit it
    p_port, s_port, c_port, m_port = free_ports(4)
    ep = lambda port: f"tcp://127.0.0.1:{port}"  # noqa: E731
    tmp = tempfile.mkdtemp(prefix="conica-ros-test-")
    procs = []
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{m_port}", ROS_IP="127.0.0.1",
               ROS_HOME=tmp, ROS_LOG_DIR=tmp)
    env.pop("ROS_HOSTNAME", None)
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR")})
    os.environ.pop("ROS_HOSTNAME", None)
    try:
        server = subprocess.Popen([args.server, "--builtin", "cube", "--probe-endpoint", ep(p_port),
                                   "--state-endpoint", ep(s_port), "--control-endpoint", ep(c_port),
                                   "--seconds", "120"], stdout=subprocess.DEVNULL,
                                  stderr=open(os.path.join(tmp, "server.log"), "w"))
        procs.append(server)

        # ---- the server links, before ROS --------------------------------------------------
        # Cube top z = 0.04, r = 5 mm. 2 mm in: deeper, the paper's card under a tool at a quad
        # centre drifts sideways in a hold (the compressed cells lose their stability, docs/contact.md).
        above, pressed = (0.02, 0.02, 0.050), (0.02, 0.02, 0.043)
        kinds = ["zmq"]
        try:
            from conica import Client  # noqa: F401
            kinds.insert(0, "package")
        except ImportError:
            print("note: the conica package is not installed; the node uses pyzmq + protobuf")
        deadline = time.monotonic() + 10
        link = None
        while link is None:
            try:
                link = links.open_link(ep(p_port), ep(s_port), ep(c_port), timeout=0.5, kind=kinds[-1])
                link.probe(above)
            except links.LinkTimeout:
                link = None
                if time.monotonic() > deadline or server.poll() is not None:
                    check(False, "conica-server answers a probe update")
                    return 1
        forces = {}
        opened = {kind: (link if kind == kinds[-1] else
                         links.open_link(ep(p_port), ep(s_port), ep(c_port), timeout=0.5, kind=kind))
                  for kind in kinds}
        for kind, lk in opened.items():
            check(lk.probe(above).force.tolist() == [0.0, 0.0, 0.0], f"{lk.kind}: no force off the body")
            mesh_pos, tris = lk.mesh()
            check(len(tris) > 0 and len(mesh_pos) == 320, f"{lk.kind}: GET_MESH gives the 320-node cube "
                  f"({len(mesh_pos)} nodes, {len(tris)} triangles)")
        # Press 2 mm in over 0.2 s (a device does not jump 7 mm: a surface probe placed deep at once
        # sets the lightly damped cube ringing) and hold 0.6 s until the body settles.
        t0 = time.monotonic()
        while (t := time.monotonic() - t0) < 0.8:
            s = min(1.0, t / 0.2)
            link.probe((0.02, 0.02, above[2] + s * (pressed[2] - above[2])))
            time.sleep(0.001)
        for kind, lk in opened.items():  # then each link in turn, a millisecond apart
            r = lk.probe(pressed)
            forces[kind] = r.force[2]
            check(r.force[2] > 0.02 and r.stiffness[2][2] < 0,
                  f"{lk.kind}: pressed 2 mm in, Fz = {r.force[2]:.4f} N > 0.02, "
                  f"dFz/dz = {r.stiffness[2][2]:.1f} N/m < 0")
        if len(kinds) == 2:
            a, b = forces["package"], forces["zmq"]
            check(abs(a - b) <= 0.02 * max(a, b), f"both links agree pressed in ({a:.5f} / {b:.5f} N)")
        link.probe(above)

        # ---- ROS ------------------------------------------------------------------------------
        master = subprocess.Popen([rosmaster, "--core", "-p", str(m_port)], env=env,
                                  stdout=open(os.path.join(tmp, "rosmaster.log"), "w"),
                                  stderr=subprocess.STDOUT)
        procs.append(master)
        node = subprocess.Popen([args.python, args.node, "__ns:=/probe0", f"_endpoint:={ep(p_port)}",
                                 f"_state_endpoint:={ep(s_port)}", f"_control_endpoint:={ep(c_port)}",
                                 "_frame_id:=world", "_scene_translation:=[1.0, 2.0, 0.0]",
                                 "_scene_rotation:=[0.0, 0.0, 0.7071067811865476, 0.7071067811865476]",
                                 "_surface_rate_hz:=10"], env=env,
                                stdout=open(os.path.join(tmp, "node.log"), "w"), stderr=subprocess.STDOUT)
        procs.append(node)

        deadline = time.monotonic() + 15
        while True:  # the master takes a moment to listen
            try:
                rospy.init_node("conica_ros_test", disable_signals=True)
                break
            except Exception:  # rospy raises several kinds while the master is not up
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

        lock = threading.Lock()
        wrenches, markers = {}, []
        k_seq = []

        def on_wrench(w):
            t = time.time()
            with lock:
                wrenches[(w.header.stamp.secs, w.header.stamp.nsecs)] = (t, w)

        def on_k(k):
            with lock:
                k_seq.append(list(k.data))

        def on_marker(m):
            with lock:
                markers.append(m)

        pub = rospy.Publisher("/probe0/measured_cp", PoseStamped, queue_size=1000, tcp_nodelay=True)
        rospy.Subscriber("/probe0/servo_cf", WrenchStamped, on_wrench, queue_size=10000, tcp_nodelay=True)
        rospy.Subscriber("/probe0/stiffness", Float64MultiArray, on_k, queue_size=10000, tcp_nodelay=True)
        rospy.Subscriber("/probe0/surface", Marker, on_marker, queue_size=5)

        deadline = time.monotonic() + 20
        while pub.get_num_connections() == 0 or not markers:
            if node.poll() is not None or time.monotonic() > deadline:
                check(False, f"conica-ros subscribed to measured_cp and published its surface "
                      f"(node exit {node.poll()}; log {os.path.join(tmp, 'node.log')}):\n"
                      + open(os.path.join(tmp, "node.log")).read()[-3000:])
                return 1
            time.sleep(0.05)

        def pose(p_scene, frame="world"):
            m = PoseStamped()
            m.header.stamp = rospy.Time.now()
            m.header.frame_id = frame
            m.pose.position.x, m.pose.position.y, m.pose.position.z = scene_to_ros(p_scene)
            m.pose.orientation.w = 1.0
            return m

        # Warm up until replies flow (the servo_cf connection is set up by then).
        deadline = time.monotonic() + 10
        while not wrenches:
            pub.publish(pose(above))
            time.sleep(0.01)
            if time.monotonic() > deadline:
                check(False, "servo_cf answers measured_cp")
                return 1
        time.sleep(0.2)
        with lock:
            wrenches.clear()
            k_seq.clear()

        wrong = []  # poses in another frame: the node must not answer them
        for _ in range(5):
            m = pose(above, frame="some_other_frame")
            wrong.append((m.header.stamp.secs, m.header.stamp.nsecs))
            pub.publish(m)
            time.sleep(0.002)

        # ---- 1 kHz ------------------------------------------------------------------------------
        n = int(args.seconds * 1000)
        n_off, n_ramp = n // 3, n // 6
        sent = []  # (stamp key, phase)
        dt = 1e-3
        t0 = time.monotonic() + 0.01
        late = 0
        for k in range(n):
            target = t0 + k * dt
            while True:
                left = target - time.monotonic()
                if left <= 0:
                    break
                if left > 3e-4:
                    time.sleep(left - 2e-4)
            if time.monotonic() - target > 2e-3:
                late += 1
            if k < n_off:
                p, phase = above, "off"
            elif k < n_off + n_ramp:
                s = (k - n_off + 1) / n_ramp
                p, phase = (0.02, 0.02, above[2] + s * (pressed[2] - above[2])), "ramp"
            else:
                p, phase = pressed, "hold"
            m = pose(p)
            sent.append(((m.header.stamp.secs, m.header.stamp.nsecs), phase))
            pub.publish(m)
        elapsed = time.monotonic() - t0
        time.sleep(0.5)
        pub.publish(pose(above))  # leave the probe off the body

        with lock:
            got = dict(wrenches)
            ks = list(k_seq)
            mk = markers[-1]
        received = [(key, phase) for key, phase in sent if key in got]
        lost = len(sent) - len(received)
        lat_us = [(got[key][0] - (key[0] + key[1] * 1e-9)) * 1e6 for key, _ in received]
        p50, p99, pmax = percentile(lat_us, 50), percentile(lat_us, 99), max(lat_us)
        print(f"ros_e2e: {priority}, sent={len(sent)} in {elapsed:.3f} s ({len(sent) / elapsed:.0f} Hz, {late} "
              f"sends > 2 ms late) received={len(received)} lost={lost} ({100 * lost / len(sent):.2f} %) "
              f"latency p50_us={p50:.0f} p99_us={p99:.0f} max_us={pmax:.0f}", flush=True)
        check(len(sent) / elapsed > 950, f"poses sent at 1 kHz ({len(sent) / elapsed:.0f} Hz)")
        check(lost <= 0.01 * len(sent), f"loss {lost} of {len(sent)} <= 1 %")
        check(p99 < 100000, f"latency p99 {p99:.0f} us < 100 ms")
        check(not any(key in got for key in wrong), "poses in another frame get no servo_cf")

        off = [got[key][1].wrench for key, phase in received if phase == "off"]
        check(len(off) > 0 and all(w.force.x == 0 and w.force.y == 0 and w.force.z == 0 for w in off),
              f"zero wrench off the body ({len(off)} replies)")
        hold = [got[key][1] for key, phase in received if phase == "hold"][-500:]
        fz = [w.wrench.force.z for w in hold]
        fxy = max(abs(w.wrench.force.x) + abs(w.wrench.force.y) for w in hold)
        check(len(hold) > 100 and min(fz) > 0.02,
              f"pressed 2 mm in, the wrench pushes out of the top face: Fz min {min(fz):.4f} N > 0.02")
        check(fxy < 0.2 * min(fz), f"and along the face normal (|Fx| + |Fy| max {fxy:.2e} N)")
        check(all(w.header.frame_id == "world" for w in hold), "servo_cf in the pose's frame")
        check(len(ks) >= len(received) and all(len(k) == 9 for k in ks), "a 3 x 3 stiffness per reply")
        kzz = [k[8] for k in ks[-500:]]
        check(max(kzz) < 0, f"stiffness pushes back pressed in: dFz/dz max {max(kzz):.1f} N/m < 0")
        check(all(abs(k[1] - k[3]) <= 1e-6 * (1 + abs(k[8])) for k in ks[-500:]),
              "stiffness symmetric (K_xy = K_yx)")

        pts = [(q.x, q.y, q.z) for q in mk.points]
        check(mk.type == Marker.TRIANGLE_LIST and mk.header.frame_id == "world" and len(pts) % 3 == 0
              and len(pts) > 0, f"surface: a TRIANGLE_LIST in world ({len(pts) // 3} triangles)")
        xs, ys, zs = zip(*pts)
        # The cube [0, 0.04]^3 in the scene is x in [0.96, 1], y in [2, 2.04] in world.
        e = 0.003
        check(0.96 - e <= min(xs) and max(xs) <= 1 + e and 2 - e <= min(ys) and max(ys) <= 2.04 + e
              and -e <= min(zs) and max(zs) <= 0.04 + e,
              f"surface inside the transformed cube: x [{min(xs):.4f}, {max(xs):.4f}], "
              f"y [{min(ys):.4f}, {max(ys):.4f}], z [{min(zs):.4f}, {max(zs):.4f}]")
        check(max(xs) - min(xs) > 0.035 and max(ys) - min(ys) > 0.035, "and spanning it")
        check(node.poll() is None, "conica-ros still running")

        # ---- unpipelined (~pipeline false: each pose waits for its reply), 200 Hz, 0.5 s -------
        node.terminate()
        node.wait(timeout=5)
        node2 = subprocess.Popen([args.python, args.node, "__ns:=/probe0", "__name:=conica_ros_wait",
                                  f"_endpoint:={ep(p_port)}", f"_state_endpoint:={ep(s_port)}",
                                  f"_control_endpoint:={ep(c_port)}", "_pipeline:=false",
                                  "_surface_rate_hz:=0", "_scene_translation:=[1.0, 2.0, 0.0]",
                                  "_scene_rotation:=[0.0, 0.0, 0.7071067811865476, 0.7071067811865476]"],
                                 env=env, stdout=open(os.path.join(tmp, "node2.log"), "w"),
                                 stderr=subprocess.STDOUT)
        procs.append(node2)
        with lock:
            wrenches.clear()
        deadline = time.monotonic() + 20
        while not wrenches and time.monotonic() < deadline and node2.poll() is None:
            pub.publish(pose(above))  # until the new node answers
            time.sleep(0.01)
        time.sleep(0.2)
        with lock:
            wrenches.clear()
        keys = []
        for k in range(100):  # pressed in over the first 40 poses (0.2 s), then held
            s = min(1.0, (k + 1) / 40)
            m = pose((0.02, 0.02, above[2] + s * (pressed[2] - above[2])))
            keys.append((m.header.stamp.secs, m.header.stamp.nsecs))
            pub.publish(m)
            time.sleep(0.005)
        time.sleep(0.5)
        with lock:
            got2 = {key: wrenches[key][1] for key in keys if key in wrenches}
        pub.publish(pose(above))
        fz2 = [got2[key].wrench.force.z for key in keys[60:] if key in got2]  # held 0.1 s and more
        check(len(got2) >= 95 and min(fz2) > 0.02,
              f"~pipeline false: {len(got2)} of 100 poses answered, pressed in Fz min "
              f"{min(fz2) if fz2 else float('nan'):.4f} N > 0.02")
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
        if failures:
            for name in ("node.log", "rosmaster.log", "server.log"):
                path = os.path.join(tmp, name)
                if os.path.exists(path):
                    print(f"---- {name} (tail)\n" + open(path).read()[-2000:])
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
