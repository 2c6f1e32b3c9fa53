#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Measure the ROS tracker at 30 Hz: latency to ~target, CPU of the nodelet manager, memory over time.

Starts `roslaunch stereo_pf demo.launch rviz:=false` on its own master port (scene_publisher renders the
640x480 pendulum scene at 30 Hz, stamping each frame when it publishes it; the tracker runs with the
default config: Position3D, 1000 particles, colour), then samples for --duration seconds:

  - end-to-end latency: arrival of ~target in this probe minus its header stamp (= the moment
    scene_publisher published the images), so it includes image transport to the manager, the
    synchroniser, tracking and the transport of ~target back here (an upper bound of the tracker's own);
  - the tracker's own latency, from image arrival in its callback to ~target published (its diagnostics
    key "latency from arrival median (ms)", over the last 300 frames);
  - CPU of the manager process from /proc/<pid>/stat (utime + stime), in % of one core;
  - resident memory (VmRSS) of the manager every 10 s; growth is judged from minute 1 to the end.

usage: source build/devel/setup.bash; test/measure_runtime.py [--duration 300] [--port 11511] [--with-viz]
  --with-viz also subscribes to ~particles, ~markers and both debug images (the load rviz adds).
"""
import argparse
import os
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client

import rosgraph
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import Image, PointCloud2
from visualization_msgs.msg import MarkerArray

from stereo_feed import percentile, rss_mb  # beside this script

TRACKER = "/stereo_pf_tracker"
MANAGER = "/stereo_pf_manager"


def node_pid(master, name):
    uri = master.lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/runtime_probe")
    if code != 1:
        raise RuntimeError("cannot get the pid of " + name)
    return int(pid)


def cpu_seconds(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks  # utime + stime


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=300.0, help="seconds of measurement (after warm-up)")
    parser.add_argument("--port", type=int, default=11511, help="ROS master port for this run")
    parser.add_argument("--with-viz", action="store_true", help="also subscribe to particles, markers, debug images")
    parser.add_argument("--warmup", type=float, default=10.0)
    args = parser.parse_args()

    env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % args.port)
    os.environ["ROS_MASTER_URI"] = env["ROS_MASTER_URI"]
    launch = subprocess.Popen(["roslaunch", "-p", str(args.port), "stereo_pf", "demo.launch", "rviz:=false"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=os.setsid)
    try:
        master = rosgraph.Master("/runtime_probe", master_uri=env["ROS_MASTER_URI"])
        deadline = time.time() + 30
        while True:
            try:
                manager_pid = node_pid(master, MANAGER)
                node_pid(master, TRACKER)
                break
            except Exception:
                if time.time() > deadline:
                    raise RuntimeError("the demo did not start (is build/devel/setup.bash sourced?)")
                time.sleep(0.5)

        rospy.init_node("runtime_probe", disable_signals=True)
        lock = threading.Lock()
        latencies = []
        diag = {}

        def on_target(msg):
            lat = (rospy.Time.now() - msg.header.stamp).to_sec() * 1e3
            with lock:
                latencies.append(lat)

        def on_diag(msg):
            for s in msg.status:
                if s.name.endswith(": tracker"):
                    with lock:
                        diag.clear()
                        diag.update({kv.key: kv.value for kv in s.values})

        subs = [rospy.Subscriber(TRACKER + "/target", PointStamped, on_target, queue_size=100, tcp_nodelay=True),
                rospy.Subscriber("/diagnostics", DiagnosticArray, on_diag, queue_size=10)]
        if args.with_viz:
            subs += [rospy.Subscriber(TRACKER + "/particles", PointCloud2, lambda m: None, queue_size=2),
                     rospy.Subscriber(TRACKER + "/markers", MarkerArray, lambda m: None, queue_size=2),
                     rospy.Subscriber(TRACKER + "/left/debug_image", Image, lambda m: None, queue_size=2),
                     rospy.Subscriber(TRACKER + "/right/debug_image", Image, lambda m: None, queue_size=2)]

        time.sleep(args.warmup)
        with lock:
            latencies.clear()
        t0, c0 = time.time(), cpu_seconds(manager_pid)
        rss = [(0.0, rss_mb(manager_pid))]
        internal = []
        while time.time() - t0 < args.duration:
            time.sleep(min(10.0, args.duration - (time.time() - t0)))
            rss.append((time.time() - t0, rss_mb(manager_pid)))
            with lock:
                if "latency from arrival median (ms)" in diag:
                    internal.append(float(diag["latency from arrival median (ms)"]))
            print("  t=%5.0f s  RSS %.1f MB  frames with ~target %d" % (rss[-1][0], rss[-1][1], len(latencies)),
                  flush=True)
        t1, c1 = time.time(), cpu_seconds(manager_pid)
        with lock:
            lat = list(latencies)
            d = dict(diag)

        cpu = 100.0 * (c1 - c0) / (t1 - t0)
        after_1min = [m for t, m in rss if t >= 60.0] or [rss[-1][1]]
        print("\n== stereo_pf runtime at 30 Hz (%s), %.0f s ==" % ("with viz subscribers" if args.with_viz else
                                                                  "headless", t1 - t0))
        print("~target rate: %.1f Hz (%d estimates)" % (len(lat) / (t1 - t0), len(lat)))
        print("end-to-end latency (publish of images -> ~target received by this probe), ms: median %.2f, "
              "p95 %.2f, max %.2f" % (percentile(lat, 0.5), percentile(lat, 0.95), percentile(lat, 1.0)))
        print("tracker latency (image arrival in the nodelet -> ~target published), median of the last 300 "
              "frames, ms: %s (diagnostics samples: median %.2f, max %.2f)" % (
                  d.get("latency from arrival median (ms)", "?"), percentile(internal, 0.5), percentile(internal, 1.0)))
        print("tracker processing per frame (diagnostics), ms: median %s, max %s" % (
            d.get("processing time median (ms)", "?"), d.get("processing time max (ms)", "?")))
        print("manager CPU: %.1f %% of one core" % cpu)
        print("manager RSS: start %.1f MB, at 1 min %.1f MB, end %.1f MB, max after 1 min %.1f MB "
              "(growth after 1 min: %+.1f MB)" % (rss[0][1], after_1min[0], rss[-1][1], max(after_1min),
                                                   rss[-1][1] - after_1min[0]))
        print("dropped frames: %s, track state: %s" % (d.get("dropped frames", "?"), d.get("track state", "?")))
        return 0
    finally:
        os.killpg(launch.pid, signal.SIGINT)
        try:
            launch.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(launch.pid, signal.SIGKILL)
        rospy.signal_shutdown("done")


if __name__ == "__main__":
    sys.exit(main())
