"""The scene frame of conica-server and a ROS frame, and the conversions between them.

The server works in its scene frame: right-handed, metres, newtons, z up (the scene files'
frame). REP-103 asks the same of ROS frames (right-handed, SI units, z up for frames fixed to the
world), so with the scene placed at the origin of the ROS frame the conversion is the identity.
In general the scene sits in the ROS frame (`~frame_id`, e.g. a robot's base) at a translation t
(m) with a rotation R (unit quaternion x, y, z, w: the scene's axes expressed in the ROS frame):

    p_ros = R p_scene + t          p_scene = R^T (p_ros - t)       positions, m
    f_ros = R f_scene                                              forces, N (no translation)
    K_ros = R K_scene R^T                                          stiffness dF/dx, N/m

No ROS import here, so the conversions are tested without ROS (tests/ros/test_frames.py)."""
import math

import numpy as np


def quaternion_matrix(q):
    """The rotation matrix (3, 3) of a quaternion (x, y, z, w); normalised first. ValueError for a
    zero or non-finite quaternion."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-12:
        raise ValueError(f"scene rotation {tuple(q)} is not a usable quaternion (x, y, z, w)")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


class SceneFrame:
    """Where the scene sits in a ROS frame: translation (m) and rotation (quaternion x, y, z, w).

    The per-message conversions work on plain tuples (a 1 kHz topic: numpy's per-call cost on
    3-vectors is larger than the arithmetic); points_to_ros takes arrays."""

    def __init__(self, translation=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0, 1.0)):
        t = np.asarray(translation, dtype=float)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"scene translation {translation!r} must be three finite numbers (m)")
        self.t = t
        self.R = quaternion_matrix(rotation)
        self._t = tuple(float(v) for v in t)
        self._R = tuple(tuple(float(v) for v in row) for row in self.R)
        self._identity = bool(np.array_equal(self.R, np.eye(3)))

    def position_to_scene(self, p_ros):
        """m, ROS frame -> m, scene frame: R^T (p - t)."""
        R, t = self._R, self._t
        d = (p_ros[0] - t[0], p_ros[1] - t[1], p_ros[2] - t[2])
        return tuple(R[0][i] * d[0] + R[1][i] * d[1] + R[2][i] * d[2] for i in range(3))

    def position_to_ros(self, p_scene):
        """m, scene frame -> m, ROS frame: R p + t."""
        R, t = self._R, self._t
        return tuple(R[i][0] * p_scene[0] + R[i][1] * p_scene[1] + R[i][2] * p_scene[2] + t[i]
                     for i in range(3))

    def vector_to_ros(self, v_scene):
        """A force (N) or other free vector, scene -> ROS frame: R v."""
        R = self._R
        return tuple(R[i][0] * v_scene[0] + R[i][1] * v_scene[1] + R[i][2] * v_scene[2]
                     for i in range(3))

    def vector_to_scene(self, v_ros):
        R = self._R
        return tuple(R[0][i] * v_ros[0] + R[1][i] * v_ros[1] + R[2][i] * v_ros[2] for i in range(3))

    def stiffness_to_ros(self, k_scene):
        """(3, 3) N/m, d force / d position in the scene -> the same in the ROS frame: R K R^T,
        as 9 values row-major."""
        k0, k1, k2 = k_scene
        if self._identity:
            return [k0[0], k0[1], k0[2], k1[0], k1[1], k1[2], k2[0], k2[1], k2[2]]
        R = self._R
        rk = [(r[0] * k0[0] + r[1] * k1[0] + r[2] * k2[0], r[0] * k0[1] + r[1] * k1[1] + r[2] * k2[1],
               r[0] * k0[2] + r[1] * k1[2] + r[2] * k2[2]) for r in R]
        return [a[0] * r[0] + a[1] * r[1] + a[2] * r[2] for a in rk for r in R]

    def points_to_ros(self, pts_scene):
        """(n, 3) m, scene -> (n, 3) m, ROS frame."""
        return np.asarray(pts_scene, dtype=float) @ self.R.T + self.t
