#!/usr/bin/python3
"""conica_ros.frames (clients/ros): the scene frame placed in a ROS frame, against rotations and
values worked out by hand. No ROS needed (numpy only).

    /usr/bin/python3 tests/ros/test_frames.py --module-dir clients/ros
"""
import argparse
import math
import sys
import unittest

frames = None
S = math.sqrt(0.5)


def close(a, b, tol=1e-12):
    return all(abs(x - y) <= tol for x, y in zip(list(a), list(b))) and len(list(a)) == len(list(b))


class Frames(unittest.TestCase):
    def test_identity_is_the_default_the_scene_already_follows_rep103(self):
        f = frames.SceneFrame()
        self.assertTrue(close(f.position_to_scene((0.1, -0.2, 0.3)), (0.1, -0.2, 0.3)))
        self.assertTrue(close(f.vector_to_ros((1.0, 2.0, 3.0)), (1.0, 2.0, 3.0)))
        k = [[-3.0, 0.5, 0.2], [0.5, -2.0, 0.1], [0.2, 0.1, -1.0]]
        self.assertEqual(f.stiffness_to_ros(k), [v for row in k for v in row])

    def test_quarter_turn_about_z_and_shift(self):
        # The scene's x axis along world +y, its y along world -x; origin at (1, 2, 0) m.
        f = frames.SceneFrame((1.0, 2.0, 0.0), (0.0, 0.0, S, S))
        self.assertTrue(close(f.position_to_ros((0.04, 0.0, 0.0)), (1.0, 2.04, 0.0)))
        self.assertTrue(close(f.position_to_ros((0.0, 0.04, 0.01)), (0.96, 2.0, 0.01)))
        self.assertTrue(close(f.position_to_scene((0.96, 2.0, 0.01)), (0.0, 0.04, 0.01)))
        # Forces rotate, never shift: 1 N along scene x is 1 N along world y.
        self.assertTrue(close(f.vector_to_ros((1.0, 0.0, 0.0)), (0.0, 1.0, 0.0)))
        self.assertTrue(close(f.vector_to_scene((0.0, 1.0, 0.0)), (1.0, 0.0, 0.0)))

    def test_scene_upside_down_maps_up_to_down(self):
        # Half a turn about x: scene z (up) is world -z, scene y is world -y.
        f = frames.SceneFrame((0.0, 0.0, 0.5), (1.0, 0.0, 0.0, 0.0))
        self.assertTrue(close(f.vector_to_ros((0.0, 0.0, 2.0)), (0.0, 0.0, -2.0)))
        self.assertTrue(close(f.position_to_ros((0.0, 0.1, 0.1)), (0.0, -0.1, 0.4)))

    def test_stiffness_rotates_as_a_tensor(self):
        # A wall pushing along scene x with 100 N/m: K = -100 e_x e_x^T. After a quarter turn
        # about z the wall pushes along world y: K_ros = -100 e_y e_y^T (row-major, 9 values).
        f = frames.SceneFrame((0.3, 0.0, 0.0), (0.0, 0.0, S, S))
        k = f.stiffness_to_ros([[-100.0, 0, 0], [0, 0, 0], [0, 0, 0]])
        self.assertTrue(close(k, [0, 0, 0, 0, -100.0, 0, 0, 0, 0], 1e-10), k)
        # A general symmetric K keeps its eigenvalues (trace and Frobenius norm).
        ks = [[-3.0, 0.5, 0.2], [0.5, -2.0, 0.1], [0.2, 0.1, -1.0]]
        f = frames.SceneFrame((0, 0, 0), (0.1, -0.4, 0.3, 0.8))
        kr = f.stiffness_to_ros(ks)
        self.assertAlmostEqual(kr[0] + kr[4] + kr[8], -6.0, places=12)
        self.assertAlmostEqual(sum(v * v for v in kr), sum(v * v for r in ks for v in r), places=12)
        self.assertAlmostEqual(kr[1], kr[3], places=12)

    def test_unnormalised_quaternion_is_normalised_and_bad_ones_refused(self):
        a = frames.SceneFrame((0, 0, 0), (0.0, 0.0, 2.0, 2.0))
        self.assertTrue(close(a.vector_to_ros((1.0, 0.0, 0.0)), (0.0, 1.0, 0.0)))
        with self.assertRaises(ValueError):
            frames.SceneFrame((0, 0, 0), (0, 0, 0, 0))
        with self.assertRaises(ValueError):
            frames.SceneFrame((0, float("nan"), 0))

    def test_points_match_the_single_position_conversion(self):
        f = frames.SceneFrame((1.0, 2.0, 3.0), (0.2, 0.1, -0.3, 0.9))
        pts = [(0.0, 0.0, 0.0), (0.04, 0.01, 0.02), (-0.1, 0.2, 0.3)]
        many = f.points_to_ros(pts).tolist()
        for p, q in zip(pts, many):
            self.assertTrue(close(f.position_to_ros(p), q))
            self.assertTrue(close(f.position_to_scene(q), p, 1e-12))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--module-dir", required=True, help="clients/ros")
    args, rest = ap.parse_known_args()
    sys.path.insert(0, args.module_dir)
    from conica_ros import frames as _frames
    frames = _frames
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
