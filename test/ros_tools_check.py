#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""The ROS command-line tools docs/ros_runtime.md uses work on a running tracker (ctest ros_tools).

On a fresh machine this fails when scripts/deps.txt misses a package a tool needs at run time (each of
python3-std-srvs, python3-nodelet and python3-tf2-msgs did: `rosservice call ~reset`, the manager's `list`
service and `rostopic echo /tf` could not load their message types), or when rosrun cannot find the package's
executables (it skips everything below <package>/build/).

Starts tracker.launch on a master of its own, feeds it frames of a make_scene bag (test/stereo_feed.py), then runs
each command and checks its exit status and output.

usage: source build/devel/setup.bash; test/ros_tools_check.py [--bag BAG]
"""
import argparse
import os
import subprocess
import sys
import threading
import time

import rospy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import stereo_feed  # noqa: E402

T = stereo_feed.TRACKER


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bag", default=os.path.join(HERE, "..", "build", "test_data", "pendulum_uncluttered_90.bag"))
    args = parser.parse_args()

    failures = []

    def check(cmd, expect="", timeout=20):
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
            out = p.stdout + p.stderr
            ok = p.returncode == 0 and expect in out
        except subprocess.TimeoutExpired as e:
            out, ok = "timed out after %d s: %s" % (timeout, e.output or ""), False
        print("%s  %s" % ("ok  " if ok else "FAIL", " ".join(cmd)), flush=True)
        if not ok:
            failures.append("%s: %s" % (" ".join(cmd), out.strip()[-400:]))

    # Without a master: rosrun must resolve the executables, rviz's media lookup must not fail.
    check(["rosrun", "stereo_pf", "track_bag", "--help"], "usage: track_bag")
    check(["rosrun", "stereo_pf", "make_scene", "--help"], "usage: make_scene")
    for exe in ("tracker_node", "scene_publisher", "ground_truth_matcher"):
        found = subprocess.run(["bash", "-c", "catkin_find --libexec stereo_pf %s" % exe], capture_output=True,
                               text=True).stdout.strip()
        ok = found and os.access(found.splitlines()[0], os.X_OK)
        print("%s  rosrun can find %s (%s)" % ("ok  " if ok else "FAIL", exe, found), flush=True)
        if not ok:
            failures.append("no executable %s in the package's libexec dir" % exe)
    check(["rospack", "plugins", "--attrib=ogre_media_path", "media_export"])

    frames = stereo_feed.load_frames(args.bag, limit=60)
    tracker = stereo_feed.Tracker()
    stop = threading.Event()
    try:
        tracker.wait_ready()
        rospy.init_node("ros_tools_check", anonymous=True, disable_signals=True)
        feed = stereo_feed.Feed(frames)
        feed.wait_connected()
        feed.teach()

        def play():
            k = 0
            while not stop.is_set():
                feed.publish_frame(k)
                k += 1
                time.sleep(1.0 / 30)
        player = threading.Thread(target=play, daemon=True)
        player.start()
        time.sleep(3.0)

        check(["rostopic", "echo", "-n", "1", T + "/target"], "point:")
        check(["rostopic", "echo", "-n", "1", "/tf"], "tracked_object")
        check(["rostopic", "echo", "-n", "1", "/diagnostics"], "stereo_pf")
        check(["rosservice", "call", T + "/reset"])
        check(["rosservice", "call", stereo_feed.MANAGER + "/list"], T)
        # The service answers; whether this box is acquired depends on what lies in it (a box with no match in the
        # right image is refused with the reason, and the previous target kept)
        check(["rosservice", "call", T + "/set_target", "roi: {x_offset: 300, y_offset: 200, width: 40, height: 40}"],
              "success:")
        check(["rosparam", "get", T + "/engine/seed"], "1")
        check(["rosrun", "dynamic_reconfigure", "dynparam", "get", T + "/engine"], "particles")
        check(["rosrun", "dynamic_reconfigure", "dynparam", "set", T + "/colour", "sigma", "0.2"])
        check(["rosnode", "list"], stereo_feed.MANAGER)
    except Exception as e:
        failures.append("%s: %s" % (type(e).__name__, e))
    finally:
        stop.set()
        tracker.stop()
        rospy.signal_shutdown("done")

    for f in failures:
        print("FAIL: " + f)
    print("ros tools: %d failed" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
