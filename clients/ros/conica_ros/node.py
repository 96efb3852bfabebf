"""The conica-ros node: CRTK-style topics on one side, conica-server on the other.

In its namespace (`__ns:=/arm` or ROS_NAMESPACE):
  measured_cp  (sub, geometry_msgs/PoseStamped, m, in ~frame_id): each pose is one probe update;
               the orientation is ignored (the probe is a sphere).
  servo_cf     (pub, geometry_msgs/WrenchStamped, N): the force on the probe, the force to render,
               one per pose, stamped with the pose's stamp and frame; torque zero.
  stiffness    (pub, std_msgs/Float64MultiArray, N/m): the 3 x 3 d force / d position of the same
               reply, row-major (layout dims "row", "col"), in ~frame_id.
  surface      (pub, visualization_msgs/Marker TRIANGLE_LIST, m, ~frame_id): the deformed
               surface at ~surface_rate_hz, for RViz.

Private parameters: ~endpoint (tcp://127.0.0.1:5555), ~state_endpoint and ~control_endpoint
(default: the probe port + 1 and + 2), ~probe (0), ~radius (m, 0: the scene's), ~timeout (s per
reply, 0.1), ~frame_id ("world"), ~scene_translation ([x, y, z] m) and ~scene_rotation
([x, y, z, w]): where the scene frame sits in ~frame_id (conica_ros/frames.py; default identity),
~surface_rate_hz (10; 0: none), ~pipeline (true: updates are pipelined, conica_ros/link.py
ProbeStream; false: each waits for its reply), ~link (auto, package, zmq: for GET_MESH, the state
stream and unpipelined probes)."""
import sys
import threading
import time

import numpy as np
import rospy
from geometry_msgs.msg import Point, PoseStamped, WrenchStamped
from std_msgs.msg import ColorRGBA, Float64MultiArray, MultiArrayDimension
from visualization_msgs.msg import Marker

from .frames import SceneFrame
from .link import LinkError, LinkTimeout, ProbeStream, open_link


class ConicaRosNode:
    def __init__(self):
        self.endpoint = rospy.get_param("~endpoint", "tcp://127.0.0.1:5555")
        self.probe_id = int(rospy.get_param("~probe", 0))
        radius = float(rospy.get_param("~radius", 0.0))
        self.radius = radius if radius > 0 else None
        self.frame_id = str(rospy.get_param("~frame_id", "world"))
        self.frame = SceneFrame(rospy.get_param("~scene_translation", [0.0, 0.0, 0.0]),
                                rospy.get_param("~scene_rotation", [0.0, 0.0, 0.0, 1.0]))
        self.surface_rate_hz = float(rospy.get_param("~surface_rate_hz", 10.0))
        args = dict(endpoint=self.endpoint,
                    state_endpoint=rospy.get_param("~state_endpoint", "") or None,
                    control_endpoint=rospy.get_param("~control_endpoint", "") or None,
                    timeout=float(rospy.get_param("~timeout", 0.1)),
                    kind=str(rospy.get_param("~link", "auto")))
        self._link_args = args
        self.link = open_link(**args)
        self.pipeline = bool(rospy.get_param("~pipeline", True))
        self.rest, self.triangles = self.link.mesh()
        rospy.loginfo("conica-ros: %s via %s, %d nodes, %d surface triangles, frame %s",
                      self.endpoint, self.link.kind, len(self.rest), len(self.triangles),
                      self.frame_id)
        self.replies = self.timeouts = self.errors = self.wrong_frame = 0
        self.pub_wrench = rospy.Publisher("servo_cf", WrenchStamped, queue_size=100)
        self.pub_k = rospy.Publisher("stiffness", Float64MultiArray, queue_size=100)
        self.pub_surface = rospy.Publisher("surface", Marker, queue_size=1, latch=True)
        self._stop = threading.Event()
        self._surface_thread = None
        if self.surface_rate_hz > 0 and len(self.triangles):
            self._surface_thread = threading.Thread(target=self._surface_loop, daemon=True)
            self._surface_thread.start()
        self.stream = None
        if self.pipeline:
            self.stream = ProbeStream(self.endpoint, self._publish, self._timed_out,
                                      timeout=args["timeout"], probe_id=self.probe_id,
                                      radius=self.radius)
        # One thread runs this callback; it alone sends probe updates.
        self.sub = rospy.Subscriber("measured_cp", PoseStamped, self.on_pose, queue_size=100,
                                    tcp_nodelay=True)

    def on_pose(self, msg):
        if msg.header.frame_id and msg.header.frame_id.lstrip("/") != self.frame_id.lstrip("/"):
            self.wrong_frame += 1
            rospy.logerr_throttle(1.0, "conica-ros: measured_cp in frame %r, expected %r (set "
                                  "~frame_id, ~scene_translation, ~scene_rotation); ignored",
                                  msg.header.frame_id, self.frame_id)
            return
        q = msg.pose.position
        p = self.frame.position_to_scene((q.x, q.y, q.z))
        header = (msg.header.stamp, msg.header.frame_id or self.frame_id)
        if self.stream is not None:
            self.stream.send(p, header)
            return
        try:
            r = self.link.probe(p, self.probe_id, self.radius)
        except LinkTimeout as e:
            self.timeouts += 1
            rospy.logwarn_throttle(1.0, "conica-ros: %s", e)
            return
        except LinkError as e:
            self.errors += 1
            rospy.logerr_throttle(1.0, "conica-ros: %s", e)
            return
        self._publish(header, r)

    def _publish(self, header, r):
        """servo_cf and stiffness for one reply, stamped as the pose it answers."""
        f = self.frame.vector_to_ros(r.force)
        w = WrenchStamped()
        w.header.stamp, w.header.frame_id = header
        w.wrench.force.x, w.wrench.force.y, w.wrench.force.z = f
        self.pub_wrench.publish(w)
        k = Float64MultiArray()
        k.layout.dim = [MultiArrayDimension("row", 3, 9), MultiArrayDimension("col", 3, 3)]
        k.data = self.frame.stiffness_to_ros(r.stiffness)
        self.pub_k.publish(k)
        self.replies += 1

    def _timed_out(self, header):
        self.timeouts += 1
        rospy.logwarn_throttle(1.0, "conica-ros: no reply from %s within %g s", self.endpoint,
                               self._link_args["timeout"])

    def _surface_loop(self):
        latest = open_link(**self._link_args).positions_subscriber()
        idx = self.triangles.reshape(-1).astype(np.int64)
        positions = self.rest
        period = 1.0 / self.surface_rate_hz
        while not self._stop.is_set() and not rospy.is_shutdown():
            got = latest(period)
            if got is not None and len(got) == len(self.rest):
                positions = got
            self.pub_surface.publish(self.marker(positions, idx))
            self._stop.wait(period)

    def marker(self, positions, idx):
        m = Marker()
        m.header.stamp = rospy.Time.now()
        m.header.frame_id = self.frame_id
        m.ns, m.id = "conica_surface", 0
        m.type, m.action = Marker.TRIANGLE_LIST, Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = 1.0
        m.color = ColorRGBA(0.85, 0.45, 0.45, 0.9)
        m.points = [Point(*q) for q in self.frame.points_to_ros(positions[idx]).tolist()]
        return m

    def shutdown(self):
        self._stop.set()
        if self.stream is not None:
            self.stream.close()
            self.errors += self.stream.errors
        rospy.loginfo("conica-ros: %d replies, %d timeouts, %d errors, %d poses in another frame",
                      self.replies, self.timeouts, self.errors, self.wrong_frame)


def wait_for_master(poll_s=0.2):
    """Block until the ROS master answers. rospy.init_node retries its registration but not the
    private parameters (``_endpoint:=...``) it sets first, so a node started a moment before
    rosmaster would die with ConnectionRefusedError; roslaunch and rosrun users never see this."""
    import rosgraph
    said = False
    while not rosgraph.is_master_online():
        if not said:
            sys.stderr.write("conica-ros: waiting for the ROS master at %s\n"
                             % rosgraph.get_master_uri())
            said = True
        time.sleep(poll_s)


def main(argv=None):
    wait_for_master()
    rospy.init_node("conica_ros", argv=argv if argv is not None else sys.argv)
    try:
        node = ConicaRosNode()
    except (LinkError, LinkTimeout, ValueError) as e:
        rospy.logfatal("conica-ros: %s (is conica-server running? build/bin/conica-server "
                       "--builtin cube)", e)
        return 1
    rospy.on_shutdown(node.shutdown)
    rospy.spin()
    return 0
