#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""scripts/stress: its metric definitions on hand-made runs, its scene draw (deterministic, within its limits), and
a smoke run (two short drawn scenes and a fake real-footage manifest over a synthetic bag) whose outputs must exist
and be well formed. Registered with ctest as test_stress; arguments: --devel DIR (catkin devel space with
make_scene and track_bag) --out DIR (scratch directory)."""
import argparse
import csv
import importlib.machinery
import io
import json
import math
import os
import shutil
import subprocess
import sys
import unittest

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
stress = importlib.machinery.SourceFileLoader("stress", os.path.join(ROOT, "scripts", "stress")).load_module()
from bag_runs import read_csv  # noqa: E402

OPTIONS = argparse.Namespace(devel=os.path.join(ROOT, "build", "devel"), out="/tmp/test_stress")
HEADER = "frame,stamp,x,y,z,sxx,syy,szz,u_left,v_left,u_right,v_right,ess,state,ms,gt_x,gt_y,gt_z,err"


def run_csv(truth, estimates):
    """A track_bag CSV (as read_csv returns it) with the given truth and estimates (None: no estimate)."""
    lines = [HEADER]
    for k, (g, e) in enumerate(zip(truth, estimates)):
        xyz = ",".join("%.6f" % v for v in e) if e is not None else ",,"
        err = "%.6f" % math.dist(g, e) if e is not None else "inf"
        lines.append("%d,%d,%s,,,,,,,,,tracking,1.5,%s,%s" % (k, 1000 + k, xyz, ",".join("%.6f" % v for v in g), err))
    return read_csv(io.StringIO("\n".join(lines) + "\n"))


class Metrics(unittest.TestCase):
    """The definitions in scripts/stress's docstring, on runs whose answers are known."""

    def setUp(self):
        self.truth = [(0.0, 0.0, 2.0)] * 60  # range 2 m: 5 % is 10 cm, 2 % is 4 cm

    def test_converges_at_the_first_of_ten_visible_frames_within_five_percent(self):
        est = [(0.0, 0.0, 2.3)] * 7 + [(0.0, 0.0, 2.05)] * 53  # 15 cm off (7.5 %), then 5 cm (2.5 %)
        g = stress.score(run_csv(self.truth, est), [True] * 60, [])
        self.assertEqual(g["converged_frame"], 7)
        self.assertEqual(g["frames_to_converge"], 7)
        self.assertAlmostEqual(g["rms_cm"], 5.0, places=3)
        self.assertAlmostEqual(g["rms_pct"], 2.5, places=3)
        self.assertFalse(g["success"])  # 2.5 % > 2 %

    def test_success_needs_both_fast_convergence_and_small_rms(self):
        good = [(0.0, 0.03, 2.0)] * 60  # 3 cm = 1.5 %
        self.assertTrue(stress.score(run_csv(self.truth, good), [True] * 60, [])["success"])
        late = [(0.0, 0.0, 3.0)] * 31 + [(0.0, 0.03, 2.0)] * 29
        g = stress.score(run_csv(self.truth, late), [True] * 60, [])
        self.assertEqual(g["frames_to_converge"], 31)
        self.assertFalse(g["success"])

    def test_a_break_in_the_ten_frames_restarts_the_count_but_hidden_frames_do_not(self):
        est = [(0.0, 0.0, 2.02)] * 60
        est[5] = (0.0, 0.0, 2.5)  # one bad frame
        visible = [True] * 60
        g = stress.score(run_csv(self.truth, est), visible, [])
        self.assertEqual(g["converged_frame"], 6)
        # hidden frames are skipped: bad estimates while hidden neither break nor count
        est = [(0.0, 0.0, 2.02)] * 60
        for k in range(3, 8):
            est[k] = (1.0, 0.0, 2.0)
            visible[k] = False
        visible[5] = True
        est[5] = (0.0, 0.0, 2.02)
        g = stress.score(run_csv(self.truth, est), visible, [])
        self.assertEqual(g["converged_frame"], 0)

    def test_never_converged_has_no_rms_and_fails(self):
        est = [None] * 60
        g = stress.score(run_csv(self.truth, est), [True] * 60, [])
        self.assertIsNone(g["converged_frame"])
        self.assertIsNone(g["rms_pct"])
        self.assertFalse(g["success"])

    def test_a_tracker_that_cannot_start_is_a_run_that_never_converges(self):
        truth = {"visible": [True] * 20, "target": [[0.0, 0.0, 2.0]] * 20, "others": [[]] * 20}
        d = stress.without_estimates(truth, 5)
        self.assertEqual(list(d["frame"]), list(range(5, 20)))
        g = stress.score(d, truth["visible"], truth["others"])
        self.assertIsNone(g["converged_frame"])
        self.assertIsNone(g["ms_per_frame"])
        self.assertFalse(g["success"])
        self.assertAlmostEqual(g["mean_range_m"], 2.0)

    def test_missing_estimates_after_convergence_and_reacquisition(self):
        est = [(0.0, 0.0, 2.01)] * 60
        visible = [True] * 60
        for k in range(20, 30):
            visible[k] = False  # hidden span 20..29
        for k in range(30, 34):
            est[k] = None  # back at 30, re-acquired at 34
        for k in range(45, 50):
            visible[k] = False  # second span; never re-acquired after it
        for k in range(50, 60):
            est[k] = (0.5, 0.0, 2.0)
        g = stress.score(run_csv(self.truth, est), visible, [])
        self.assertEqual(g["reacquire"], [4, None])
        visible_after = 60 - 15
        self.assertAlmostEqual(g["no_estimate_pct"], 100.0 * 4 / visible_after, places=6)

    def test_truth_inside_the_95_percent_ellipsoid_of_the_full_covariance_while_tracking(self):
        head = "frame,stamp,x,y,z,sxx,syy,szz,u_left,v_left,u_right,v_right,ess,state,ms,sxy,sxz,syz,gt_x,gt_y,gt_z,err"
        rows = [  # (estimate, sxx syy szz, sxy sxz syz, state); the truth is (0, 0, 2)
            ((0.0, 0.0, 2.1), (0.01, 0.01, 0.01), (0.0, 0.0, 0.0), "tracking"),      # 1 sigma in z: inside
            ((0.0, 0.0, 2.4), (0.01, 0.01, 0.01), (0.0, 0.0, 0.0), "tracking"),      # 4 sigma: outside
            # x and z strongly correlated: inside by the diagonal alone (chi-square 2), far outside the ellipsoid
            ((0.1, 0.0, 1.9), (0.01, 0.01, 0.01), (0.0, 0.0099, 0.0), "tracking"),
            ((0.0, 0.0, 2.0), (0.01, 0.01, 0.01), (0.0, 0.0, 0.0), "lost"),          # not tracking: not judged
        ]
        lines = [head]
        for k, (e, v, c, state) in enumerate(rows):
            lines.append("%d,%d,%s,%s,,,,,1,%s,1.5,%s,0,0,2,0.1" % (k, 1000 + k, ",".join(map(str, e)),
                                                                   ",".join(map(str, v)), state, ",".join(map(str, c))))
        d = read_csv(io.StringIO("\n".join(lines) + "\n"))
        g = stress.score(d, [True] * len(rows), [])
        self.assertEqual(g["tracked_frames"], 3)
        self.assertEqual(g["covered_frames"], 1)

    def test_wrong_object_lock_needs_five_frames_near_the_other_object(self):
        other = (0.4, 0.0, 2.0)
        est = [(0.0, 0.0, 2.0)] * 10 + [(0.41, 0.0, 2.0)] * 4 + [(0.0, 0.0, 2.0)] * 10 + [(0.41, 0.0, 2.0)] * 6 + \
            [(0.0, 0.0, 2.0)] * 30
        g = stress.score(run_csv(self.truth, est), [True] * 60, [[other]] * 60)
        self.assertEqual(g["wrong_locks"], 1)  # the 4-frame visit is too short
        self.assertEqual(g["wrong_lock_frames"], 6)

    def test_real_footage_scores_the_frames_with_a_reference(self):
        truth = [(0.0, 0.0, 2.0)] * 20
        # homing in (10 frames, 1 m off: left out), then 10 cm off, the last two frames without estimate
        d = run_csv(truth, [(1.0, 0.0, 2.0)] * 10 + [(0.0, 0.0, 2.1)] * 8 + [None] * 2)
        d["gt_x"][::2] = np.nan  # reference points in odd frames only
        g = stress.score_real(d, 2.0)
        self.assertEqual(g["reference_frames"], 5)
        self.assertAlmostEqual(g["rms_cm"], 10.0, places=3)
        self.assertAlmostEqual(g["rms_pct"], 5.0, places=3)
        self.assertAlmostEqual(g["no_estimate_pct"], 10.0)
        # of the 10 frames with a reference point, the last one (frame 19) has no estimate
        self.assertEqual(g["referenced_frames"], 10)
        self.assertEqual(g["reference_missing"], 1)

    def test_the_summary_counts_the_runs_that_went_without_an_estimate_in_view(self):
        # four runs that converged: three went without an estimate in at most a tenth of their visible frames, the
        # fourth in half of them; the summary gives the median, the mean and that one run
        runs = []
        for share in (0.0, 0.0, 10.0, 50.0):
            r = argparse.Namespace(figures={"no_estimate_pct": share})
            runs.append(r)
        self.assertEqual(stress.no_estimate_text(runs), "5.0 / 15.0; 1 over 20 %")
        self.assertEqual(stress.no_estimate_text([]), "-")


class Draw(unittest.TestCase):
    """The scene draw: deterministic from the seed, and within the limits the docstring states."""

    def test_same_seed_same_scenes_and_scene_i_does_not_depend_on_n(self):
        a = [stress.scene_text(*stress.draw_scene(1, i, 150), 1, 150) for i in range(5)]
        b = [stress.scene_text(*stress.draw_scene(1, i, 150), 1, 150) for i in range(5)]
        self.assertEqual(a, b)
        c = [stress.scene_text(*stress.draw_scene(2, i, 150), 1, 150) for i in range(5)]
        self.assertNotEqual(a, c)

    def test_drawn_scenes_are_within_the_limits(self):
        kinds = set()
        for i in range(300):
            scene, brief = stress.draw_scene(3, i, 120)
            cam = scene["camera"]
            w, h, fx = cam["width"], cam["height"], cam["fx"]
            self.assertLessEqual(scene["frames"], 120)
            self.assertTrue(0.4 <= brief["range_drawn_m"] <= 15.0)
            self.assertTrue(0.01 <= brief["radius_m"] <= 0.15 and 0.05 <= cam["baseline"] <= 0.6)
            r_px = fx * brief["radius_m"] / brief["range_drawn_m"]
            d_px = fx * cam["baseline"] / brief["range_drawn_m"]
            self.assertTrue(4 <= r_px <= h / 6.0, (i, r_px))
            self.assertTrue(8 <= d_px <= w / 4.0, (i, d_px))
            self.assertLessEqual(abs(cam["row_offset"]), 0.5)
            self.assertLess(scene["sensor"]["exposure"], 0.8 / scene["fps"] + 1e-12)
            kinds.add(brief["motion"])
            c = stress.Camera(w, h, fx, cam["cx"], cam["cy"], cam["baseline"])
            tr = scene["objects"][0]["trajectory"]
            if tr["type"] == "pendulum":  # the first position of each kind of trajectory
                a = math.radians(tr["amplitude_deg"]) * math.cos(math.radians(tr["phase_deg"]))
                phi = math.radians(tr["plane_angle_deg"])
                q, n = tr["pivot"], tr["length"]
                p = [q[0] + n * math.sin(a) * math.cos(phi), q[1] + n * math.cos(a),
                     q[2] + n * math.sin(a) * math.sin(phi)]
            else:
                p = {"ballistic": tr.get("start"), "bounce": tr.get("start"), "random_walk": tr.get("centre"),
                     "waypoints": (tr.get("points") or [None])[0]}[tr["type"]]
            for shift in (0.0, cam["baseline"]):
                u, v = c.project([p[0] - shift, p[1], p[2]])
                self.assertTrue(0 <= u < w and 0 <= v < h, (i, tr["type"], u, v))
        self.assertEqual(kinds, set(stress.MOTIONS))


class Smoke(unittest.TestCase):
    """scripts/stress end to end on two short scenes and a fake manifest over a synthetic bag."""

    @classmethod
    def setUpClass(cls):
        cls.out = OPTIONS.out
        shutil.rmtree(cls.out, ignore_errors=True)
        os.makedirs(cls.out)
        bin_dir = os.path.join(OPTIONS.devel, "lib", "stereo_pf")
        cls.env = stress.ros_env(OPTIONS.devel)
        bag = os.path.join(cls.out, "fake_real.bag")
        subprocess.run([os.path.join(bin_dir, "make_scene"), os.path.join(ROOT, "scenes", "pendulum_uncluttered.yaml"),
                        bag, "--frames", "30", "--quiet"], check=True, env=cls.env)
        cls.manifest = os.path.join(cls.out, "manifest.json")
        entry = {"name": "fake_pendulum", "bag": "fake_real.bag", "repo": "(synthetic)", "frames": 30, "fps": 30,
                 "first_frame": 5, "roi": [0, 0, 1, 1], "reference_frames": 25, "residual_m": 0.01,
                 "mean_range_m": 1.1, "baseline_m": 0.09, "fx": 525}
        with open(cls.manifest, "w") as f:
            json.dump([entry], f)
        cls.docs = os.path.join(cls.out, "docs")
        cls.result = subprocess.run(
            [os.path.join(ROOT, "scripts", "stress"), "--n", "2", "--frames", "30", "--no-build", "--devel",
             OPTIONS.devel, "--out", os.path.join(cls.out, "suite"), "--docs", cls.docs, "--real", cls.manifest,
             "--set", "engine/recovery_period=2"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def test_runs_and_writes_a_csv_row_per_run(self):
        self.assertEqual(self.result.returncode, 0, self.result.stdout)
        with open(os.path.join(self.docs, "stress.csv")) as f:
            rows = list(csv.DictReader(f))
            f.seek(0)
            header = f.readline().strip().split(",")
        self.assertEqual(header, stress.CSV_COLUMNS)
        synthetic = [r for r in rows if r["kind"] == "synthetic"]
        real = [r for r in rows if r["kind"] == "real"]
        self.assertEqual(sorted((r["scene"], r["tracker"], r["seed"]) for r in synthetic),
                         sorted((s, t, x) for s in ("stress_000", "stress_001")
                                for t, x in (("ours", "1"), ("ours", "2"), ("ours", "3"), ("csrt", ""))))
        self.assertEqual(sorted((r["tracker"], r["seed"]) for r in real),
                         sorted([("csrt", "")] + [("ours", str(s)) for s in stress.REAL_SEEDS]))
        for r in rows:
            self.assertEqual(r["error"], "", r)
            if r["ms_per_frame"]:
                self.assertGreater(float(r["ms_per_frame"]), 0.0)
            else:  # a tracker that could not start (e.g. CSRT without a right-image match) has no time and no result
                self.assertEqual((r["converged_frame"], r["rms_cm"]), ("", ""))
            if r["kind"] == "synthetic":
                self.assertIn(r["success"], ("0", "1"))
                self.assertTrue(0 < int(r["visible_frames"]) <= 30)
                self.assertGreater(float(r["mean_range_m"]), 0.3)
                if r["converged_frame"]:
                    self.assertTrue(float(r["rms_pct"]) >= 0 and 0 <= float(r["no_estimate_pct"]) <= 100)
            else:
                self.assertEqual((r["frames"], r["success"]), ("30", ""))  # success is for drawn scenes only
        # the fake footage is an easy synthetic pendulum from frame 5: our filter finds it
        ours_real = [r for r in real if r["tracker"] == "ours"]
        self.assertTrue(all(r["rms_cm"] and float(r["rms_cm"]) < 10 for r in ours_real), ours_real)

    def test_writes_the_report_tables(self):
        self.assertEqual(self.result.returncode, 0, self.result.stdout)
        with open(os.path.join(self.docs, "stress.md")) as f:
            md = f.read()
        for heading in ("## Overall", "## Per scene", "## Failures", "## Real footage", "## How the scenes are drawn",
                        "## Metrics"):
            self.assertIn(heading, md)
        self.assertRegex(md, r"\| ours \(3 seeds\) \| 6 \| \d+ \(")
        self.assertRegex(md, r"\| CSRT \| 2 \| \d+ \(")
        self.assertRegex(md, r"\n\| stress_000 \| \d+x\d+ ")
        self.assertRegex(md, r"\n\| stress_001 \| \d+x\d+ ")
        self.assertRegex(md, r"\n\| fake_pendulum \| 30 \| 5 \| 1\.10 \| 1\.0 \| [0-9.]+ \|")
        self.assertIn("scripts/stress --n 2 --frames 30", md)
        # a variant's settings are given to every run of ours and said on the page
        self.assertIn("changed by `--set engine/recovery_period=2`", md)
        for name in ("stress_000.yaml", "stress_001.yaml"):
            self.assertTrue(os.path.exists(os.path.join(self.out, "suite", "scenes", name)))
        self.assertEqual(os.listdir(os.path.join(self.out, "suite", "bags")), [])  # deleted once scored

    def test_the_report_says_whether_the_checkout_had_local_changes(self):
        # Its docs are outside the checkout here: the report must still see the checkout's own changes.
        self.assertEqual(self.result.returncode, 0, self.result.stdout)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "."], cwd=ROOT,
                               stdout=subprocess.PIPE, text=True, check=True).stdout.strip()
        with open(os.path.join(self.docs, "stress.md")) as f:
            md = f.read()
        self.assertEqual(", with local changes" in md, bool(dirty), dirty)

    def test_bad_manifest_is_refused_with_the_field_named(self):
        bad = os.path.join(self.out, "bad.json")
        with open(bad, "w") as f:
            json.dump([{"name": "x", "bag": "fake_real.bag"}], f)
        p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--no-build", "--real", bad,
                            "--out", os.path.join(self.out, "bad"), "--docs", os.path.join(self.out, "bad")],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("entry 0: field 'repo' missing", p.stdout)

    def test_a_malformed_setting_is_refused(self):
        p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--no-build", "--set",
                            "recovery_period", "--out", os.path.join(self.out, "bad"), "--docs",
                            os.path.join(self.out, "bad")],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--set takes KEY=VALUE", p.stdout)

    def test_other_tracker_seeds_are_run_and_said(self):
        out = os.path.join(self.out, "seeds")
        p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--frames", "12", "--no-build",
                            "--devel", OPTIONS.devel, "--tracker-seeds", "4,7", "--out", out, "--docs", out],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.assertEqual(p.returncode, 0, p.stdout)
        with open(os.path.join(out, "stress.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(sorted((r["tracker"], r["seed"]) for r in rows), [("csrt", ""), ("ours", "4"), ("ours", "7")])
        with open(os.path.join(out, "stress.md")) as f:
            md = f.read()
        self.assertIn("and seeds 4, 7;", md)
        self.assertRegex(md, r"\| ours \(2 seeds\) \| 2 \| \d+ \(")

    def test_without_csrt_only_ours_runs_and_the_report_says_so(self):
        out = os.path.join(self.out, "no_csrt")
        p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--frames", "12", "--no-build",
                            "--devel", OPTIONS.devel, "--no-csrt", "--tracker-seeds", "2", "--out", out, "--docs", out],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.assertEqual(p.returncode, 0, p.stdout)
        with open(os.path.join(out, "stress.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([(r["tracker"], r["seed"]) for r in rows], [("ours", "2")])
        self.assertFalse([n for n in os.listdir(os.path.join(out, "runs")) if "csrt" in n])
        with open(os.path.join(out, "stress.md")) as f:
            md = f.read()
        self.assertIn("CSRT was not run (`--no-csrt`)", md)
        self.assertIn("| not run |", md)

    def test_kept_bags_are_tracked_again_while_their_scene_is_the_same(self):
        out = os.path.join(self.out, "kept")

        def run(*extra):
            p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--frames", "12", "--no-build",
                                "--devel", OPTIONS.devel, "--keep-bags", "--out", out, "--docs", out] + list(extra),
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            self.assertEqual(p.returncode, 0, p.stdout)
            with open(os.path.join(out, "stress.csv")) as f:
                rows = {(r["tracker"], r["seed"]): r for r in csv.DictReader(f)}
            return p.stdout, rows

        bag = os.path.join(out, "bags", "stress_000.bag")
        first, rows = run()
        self.assertIn("stress_000 rendered", first)
        self.assertTrue(os.path.exists(bag) and os.path.exists(bag + ".scene.yaml"))
        rendered_at = os.stat(bag).st_mtime_ns
        with open(os.path.join(out, "stress.md")) as f:
            self.assertNotIn("kept from an earlier run", f.read())
        again, rows_again = run()
        self.assertIn("stress_000 kept from an earlier run", again)
        self.assertNotIn("stress_000 rendered", again)
        self.assertEqual(os.stat(bag).st_mtime_ns, rendered_at)
        with open(os.path.join(out, "stress.md")) as f:
            self.assertIn("The bags of 1 of the 1 scenes were kept from an earlier run", f.read())
        # The same bag, the same figures (the trackers are deterministic; time per frame aside).
        self.assertEqual(sorted(rows), sorted(rows_again))
        for key, row in rows.items():
            for column in ("converged_frame", "rms_pct", "tracked_frames", "covered_frames", "success"):
                self.assertEqual(row[column], rows_again[key][column], (key, column))
        # Another draw is another scene: rendered afresh, and the copy beside the bag follows it.
        other, _ = run("--seed", "2")
        self.assertIn("stress_000 rendered", other)
        with open(bag + ".scene.yaml") as a, open(os.path.join(out, "scenes", "stress_000.yaml")) as b:
            self.assertTrue(a.read().startswith(b.read()))
        # Another renderer (as after a change to make_scene or its libraries): rendered afresh too.
        with open(bag + ".scene.yaml") as f:
            kept = f.read()
        with open(bag + ".scene.yaml", "w") as f:
            f.write(kept.replace(" sha256 ", " sha256 0"))
        self.assertIn("stress_000 rendered", run("--seed", "2")[0])

    def test_malformed_tracker_seeds_are_refused(self):
        for bad in ("4,x", "", "3,3", "-1", "0,2"):  # 0 would be taken for the CSRT run
            p = subprocess.run([os.path.join(ROOT, "scripts", "stress"), "--n", "1", "--no-build", "--tracker-seeds",
                                bad, "--out", os.path.join(self.out, "bad"), "--docs", os.path.join(self.out, "bad")],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            self.assertNotEqual(p.returncode, 0, bad)
            self.assertIn("--tracker-seeds takes distinct seeds", p.stdout, bad)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--devel", default=OPTIONS.devel)
    ap.add_argument("--out", default=OPTIONS.out)
    OPTIONS, rest = ap.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
