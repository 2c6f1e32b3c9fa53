#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""scripts/real_pitch without the footage: its reference pipeline on a ball drawn with OpenCV, its bags read
back, evaluate() on a hand-made CSV, and its messages for paths that are not one of the two repositories."""
import csv
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np
import cv2

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.path.join(os.path.dirname(HERE), "scripts")
sys.path.insert(0, SCRIPTS)
import real_footage as rf  # noqa: E402

FPS = 60.0
BALL_RADIUS = 0.037
GEOMETRY = rf.Geometry(fx=800.0, fy=800.0, cx=320.0, cy=240.0, baseline=0.5, width=640, height=480)


def true_position(t):
    """A pitch towards the cameras: 6 m to about 2 m in 0.5 s, falling under gravity (y is down)."""
    p0, v0, a = np.array([0.3, -0.4, 6.0]), np.array([-0.2, -1.5, -8.0]), np.array([0.0, 9.81, 0.0])
    return p0 + v0 * t + 0.5 * a * t * t


def render(numbers, capture_times, seed=1, distractor_frame=None):
    """Rectified grey pairs: a textured wall (disparity 20 px) and the ball drawn to 1/16 px, with noise."""
    rng = np.random.default_rng(seed)
    wall = cv2.GaussianBlur(rng.uniform(40, 120, (480, 700)).astype(np.float32), (0, 0), 3)
    lefts, rights = [], []
    for k, t in enumerate(capture_times):
        left, right = wall[:, 20:660].copy(), wall[:, 40:680].copy()   # right view: the wall 20 px to the left
        p = true_position(t)
        ul, v, ur = (a[0] for a in GEOMETRY.project(p))
        r = GEOMETRY.fx * BALL_RADIUS / p[2]
        for image, u in ((left, ul), (right, ur)):
            cv2.circle(image, (int(round(u * 16)), int(round(v * 16))), int(round(r * 16)), 210.0, -1,
                       cv2.LINE_AA, 4)
        if k == distractor_frame:   # a bigger blob, same rows in both views, far from the trajectory
            for image, u in ((left, 150.0), (right, 90.0)):
                cv2.circle(image, (int(u), 400), 8, 230.0, -1)
        noise = rng.normal(0, 2.0, (2, 480, 640))
        lefts.append(np.clip(left + noise[0], 0, 255).astype(np.uint8))
        rights.append(np.clip(right + noise[1], 0, 255).astype(np.uint8))
    return lefts, rights


class ReferencePipeline(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # The plain pitch, rendered and searched once for the tests that start from it.
        cls.numbers = list(range(30))
        cls.times = [n / FPS for n in cls.numbers]
        cls.detections = rf.detect(*render(cls.numbers, cls.times), GEOMETRY)

    def check_reference(self, ref, numbers, capture_times, max_rms_m):
        truth = np.array([true_position(capture_times[k]) for k in ref["frames"]])
        err = np.linalg.norm(ref["points"] - truth, axis=1)
        self.assertLess(float(np.sqrt(np.mean(err ** 2))), max_rms_m)
        self.assertAlmostEqual(2.0 * ref["radius_m"], 2.0 * BALL_RADIUS, delta=0.015)  # blur widens the blob
        np.testing.assert_allclose(ref["acceleration"], [0.0, 9.81, 0.0], atol=0.8)

    def test_ball_found_triangulated_and_fitted(self):
        numbers, times, detections = self.numbers, self.times, list(self.detections)
        self.assertEqual(sum(d is not None for d in detections), 30)
        ref = rf.reference_trajectory(numbers, detections, GEOMETRY, FPS)
        self.assertEqual(list(ref["frames"]), numbers)
        self.assertEqual(ref["gaps"], [])
        self.check_reference(ref, numbers, times, 0.01)
        self.assertLess(ref["residual_m"], 0.03)
        np.testing.assert_array_equal(ref["captures"], numbers)

    def test_largest_plausible_blob_not_a_bigger_off_trajectory_one_after_the_fit(self):
        # A bigger plausible blob pair in frame 12 wins the detection; the fit drops it as an outlier and the
        # reference at frame 12 is still the ball.
        numbers = list(range(30))
        times = [n / FPS for n in numbers]
        lefts, rights = render(numbers, times, distractor_frame=12)
        detections = rf.detect(lefts, rights, GEOMETRY)
        self.assertAlmostEqual(detections[12][0], 150.0, delta=1.0)
        ref = rf.reference_trajectory(numbers, detections, GEOMETRY, FPS)
        self.assertNotIn(12, list(ref["kept"]))
        self.assertIn(12, list(ref["frames"]))
        self.check_reference(ref, numbers, times, 0.01)

    def test_gross_outlier_dropped_and_refit(self):
        numbers, detections = self.numbers, list(self.detections)
        clean = rf.reference_trajectory(numbers, detections, GEOMETRY, FPS)
        ul, vl, ur, vr, r = detections[20]
        detections[20] = (ul + 5.0, vl + 3.0, ur, vr + 3.0, r)   # 5 px of disparity and 3 px of row too many
        ref = rf.reference_trajectory(numbers, detections, GEOMETRY, FPS)
        self.assertEqual(list(ref["dropped"]), [20])
        self.assertEqual(list(ref["frames"]), numbers)
        np.testing.assert_allclose(ref["points"], clean["points"], atol=0.01)

    def test_skipped_capture_inferred_from_the_motion(self):
        # Files numbered 0..29, but the camera skipped a capture period after file 14 (a dropped frame).
        numbers = list(range(30))
        captures = [n if n <= 14 else n + 1 for n in numbers]
        times = [c / FPS for c in captures]
        ref = rf.reference_trajectory(numbers, rf.detect(*render(numbers, times), GEOMETRY), GEOMETRY, FPS)
        self.assertEqual(ref["gaps"], [15])
        np.testing.assert_array_equal(ref["captures"], captures)
        self.check_reference(ref, numbers, times, 0.01)

    def test_too_few_detections_is_a_clear_error(self):
        numbers = list(range(10))
        detections = [None] * 10
        detections[3] = (330.0, 200.0, 260.0, 200.0, 5.0)
        with self.assertRaisesRegex(rf.FootageError, "only 1 frames"):
            rf.reference_trajectory(numbers, detections, GEOMETRY, FPS)

    def test_triangulation_inverts_projection(self):
        p = np.array([[0.4, -0.2, 5.0], [-1.0, 0.5, 12.0]])
        ul, v, ur = GEOMETRY.project(p)
        np.testing.assert_allclose(GEOMETRY.triangulate(ul, v, ur, v), p, atol=1e-9)

    def test_row_refinement_removes_offset_and_vertical_baseline(self):
        # Correspondences whose right rows are off by 1.5 px plus 0.03 px per px of disparity.
        rng = np.random.default_rng(3)
        u, v, d = rng.uniform(50, 600, 300), rng.uniform(30, 450, 300), rng.uniform(20, 200, 300)
        points = np.stack([u, v, d, -1.5 - 0.03 * d + rng.normal(0, 0.05, 300)], axis=1)
        before = np.abs(rf.row_mismatch(points, GEOMETRY, (0.0, 0.0, 0.0)))
        self.assertGreater(float(np.median(before)), 2.0)
        correction = rf.refine_rows(points, GEOMETRY)
        after = np.abs(rf.row_mismatch(points, GEOMETRY, correction))
        self.assertLess(float(np.median(after)), 0.1)


class Bags(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="test_real_pitch_")

    def tearDown(self):
        shutil.rmtree(self.dir)

    def write(self):
        lefts = [np.full((24, 32), 10 * k, np.uint8) for k in range(3)]
        rights = [np.full((24, 32), 10 * k + 1, np.uint8) for k in range(3)]
        stamps = rf.stamps_ns([0, 1, 3], FPS)   # a skipped capture before the last frame
        reference = {1: ([0.1, -0.2, 3.0], [10, 5, 6, 6]), 2: ([0.1, -0.1, 2.5], [11, 6, 7, 7])}
        path = os.path.join(self.dir, "t.bag")
        rf.write_bag(path, lefts, rights, GEOMETRY, stamps, reference)
        return path, stamps

    def test_bag_read_back(self):
        import rosbag
        path, stamps = self.write()
        self.assertEqual(stamps, [rf.EPOCH_NS, rf.EPOCH_NS + 16666667, rf.EPOCH_NS + 50000000])
        by_topic = {}
        with rosbag.Bag(path) as bag:
            types = {t: info.msg_type for t, info in bag.get_type_and_topic_info()[1].items()}
            for topic, msg, t in bag.read_messages():
                by_topic.setdefault(topic, []).append((msg, t.to_nsec()))
        self.assertEqual(types, {
            "stereo_camera/left/image_raw": "sensor_msgs/Image", "stereo_camera/right/image_raw": "sensor_msgs/Image",
            "stereo_camera/left/camera_info": "sensor_msgs/CameraInfo",
            "stereo_camera/right/camera_info": "sensor_msgs/CameraInfo",
            "ground_truth/target": "geometry_msgs/PointStamped",
            "ground_truth/target_roi": "sensor_msgs/RegionOfInterest",
            "ground_truth/target_visible": "std_msgs/Bool"})
        for topic in ("stereo_camera/left/image_raw", "stereo_camera/right/image_raw", "stereo_camera/left/camera_info",
                      "stereo_camera/right/camera_info"):
            msgs = by_topic[topic]
            self.assertEqual([m.header.stamp.to_nsec() for m, _ in msgs], stamps)
            self.assertEqual([t for _, t in msgs], stamps)   # bag time = stamp
            self.assertTrue(all(m.header.frame_id == rf.FRAME_ID for m, _ in msgs))
        left = by_topic["stereo_camera/left/image_raw"][2][0]
        self.assertEqual((left.encoding, left.width, left.height, left.step), ("mono8", 32, 24, 32))
        self.assertEqual(bytes(left.data), bytes([20] * (32 * 24)))
        self.assertEqual(bytes(by_topic["stereo_camera/right/image_raw"][0][0].data), bytes([1] * (32 * 24)))
        for topic, right in (("stereo_camera/left/camera_info", False), ("stereo_camera/right/camera_info", True)):
            info = by_topic[topic][0][0]
            self.assertEqual((info.width, info.height), (640, 480))
            self.assertEqual(list(info.D), [0.0] * 5)
            self.assertEqual(list(info.R), [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0])
            self.assertEqual(list(info.K), [info.P[0], info.P[1], info.P[2], info.P[4], info.P[5], info.P[6],
                                            info.P[8], info.P[9], info.P[10]])
            self.assertEqual(info.P[3], -800.0 * 0.5 if right else 0.0)
        self.assertEqual([m.data for m, _ in by_topic["ground_truth/target_visible"]], [False, True, True])
        truth = by_topic["ground_truth/target"]
        self.assertEqual([t for _, t in truth], stamps[1:])
        self.assertEqual((truth[1][0].point.x, truth[1][0].point.y, truth[1][0].point.z), (0.1, -0.1, 2.5))
        roi = by_topic["ground_truth/target_roi"]
        self.assertEqual([t for _, t in roi], stamps[1:])
        self.assertEqual((roi[0][0].x_offset, roi[0][0].y_offset, roi[0][0].width, roi[0][0].height), (10, 5, 6, 6))

    def test_evaluate_against_a_track_bag_csv(self):
        path, stamps = self.write()
        csv_path = os.path.join(self.dir, "t.csv")
        with open(csv_path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow("frame,stamp,x,y,z,sxx,syy,szz,u_left,v_left,u_right,v_right,ess,state,ms".split(","))
            # track_bag prints 9 significant digits; frame 0 has no reference, frame 2 no estimate.
            for k, xyz in ((0, ("0", "0", "1")), (1, ("0.1", "-0.2", "3.03")), (2, ("", "", ""))):
                w.writerow([k, "%.9g" % (stamps[k] * 1e-9)] + list(xyz) + [""] * 8 + ["tracking", "1.0"])
        r = rf.evaluate(path, csv_path)
        self.assertEqual((r["rows"], r["frames"], r["estimated"], r["missing"]), (3, 2, 1, 1))
        self.assertAlmostEqual(r["rms_m"], 0.03, places=9)
        mean_range = 0.5 * (math.sqrt(0.01 + 0.04 + 9.0) + math.sqrt(0.01 + 0.01 + 6.25))
        self.assertAlmostEqual(r["mean_range_m"], mean_range, places=9)
        self.assertAlmostEqual(r["rms_pct"], 100 * 0.03 / mean_range, places=9)

    def test_evaluate_refuses_a_file_that_is_not_a_track_bag_csv(self):
        path, _ = self.write()
        other = os.path.join(self.dir, "other.csv")
        with open(other, "w") as f:
            f.write("a,b\n1,2\n")
        with self.assertRaisesRegex(rf.FootageError, "not a track_bag CSV: no column 'stamp'"):
            rf.evaluate(path, other)


class NotTheRepositories(unittest.TestCase):
    def run_script(self, *args):
        return subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "real_pitch")] + list(args),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def test_missing_path(self):
        p = self.run_script("/nonexistent/stereo_pf_test_path")
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("'/nonexistent/stereo_pf_test_path' is not a directory", p.stderr)
        self.assertIn("bboyack/ecen631_bbcatcher or wynn4/ECEN_631", p.stderr)

    @unittest.skipUnless(shutil.which("git"), "git is not installed")
    def test_plain_directory_and_other_repository(self):
        with tempfile.TemporaryDirectory() as d:
            p = self.run_script(d, os.path.join(d, "out"))
            self.assertNotEqual(p.returncode, 0)
            self.assertIn("is not a git repository", p.stderr)
            env = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@t", GIT_COMMITTER_NAME="t",
                       GIT_COMMITTER_EMAIL="t@t")
            subprocess.run(["git", "init", "-q", d], check=True, env=env)
            with open(os.path.join(d, "README.md"), "w") as f:
                f.write("x\n")
            subprocess.run(["git", "-C", d, "add", "README.md"], check=True, env=env)
            subprocess.run(["git", "-C", d, "commit", "-q", "-m", "x"], check=True, env=env)
            p = self.run_script(d, os.path.join(d, "out"))
            self.assertNotEqual(p.returncode, 0)
            self.assertIn("is a git repository but not a copy of bboyack/ecen631_bbcatcher or wynn4/ECEN_631",
                          p.stderr)
            self.assertFalse(os.path.exists(os.path.join(d, "out")))   # nothing written


if __name__ == "__main__":
    unittest.main()
