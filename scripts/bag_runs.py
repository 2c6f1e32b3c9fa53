# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""What scripts/experiments.py and scripts/stress share: running the tools two at a time, each pinned to its own
core, reading track_bag's summary line and CSV, and reading ground truth from a bag with rosbag."""
import heapq
import itertools
import os
import subprocess
import threading

import numpy as np


class PinnedPool:
    """Runs commands `jobs` at a time, each worker pinned to its own core with taskset.

    submit() queues a command with a callback that receives (returncode, combined output) when it ends; callbacks
    run one at a time (so they may update shared state without locks) and may submit more commands, which lets a
    render be followed by the runs on its bag. Lower `priority` runs first; ties run in submission order."""

    def __init__(self, jobs):
        self.jobs = max(1, min(jobs, os.cpu_count() or 1))
        self._queue = []
        self._order = itertools.count()
        self._running = 0
        self._cond = threading.Condition()
        self._callback_lock = threading.Lock()
        self.failures = []  # exceptions raised by callbacks (re-raised by run())

    def submit(self, cmd, done=None, priority=0, env=None):
        with self._cond:
            heapq.heappush(self._queue, (priority, next(self._order), cmd, done, env))
            self._cond.notify()

    def run(self):
        """Blocks until every submitted command (and those its callbacks submitted) has ended."""
        threads = [threading.Thread(target=self._worker, args=(core,)) for core in range(self.jobs)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        if self.failures:
            raise self.failures[0]

    def _worker(self, core):
        while True:
            with self._cond:
                while not self._queue and self._running > 0:
                    self._cond.wait()
                if not self._queue:  # nothing queued and nothing running that could queue more
                    self._cond.notify_all()
                    return
                _, _, cmd, done, env = heapq.heappop(self._queue)
                self._running += 1
            p = subprocess.run(["taskset", "-c", str(core)] + cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, env=env)
            try:
                if done is not None:
                    with self._callback_lock:
                        done(p.returncode, p.stdout)
            except Exception as e:  # noqa: BLE001 - reported by run(), after the other workers finish
                self.failures.append(e)
            finally:
                with self._cond:
                    self._running -= 1
                    self._cond.notify_all()


def parse_summary(text):
    """track_bag's last 'summary:' line as a dict (lists for comma-separated values); {} without one."""
    line = [l for l in text.splitlines() if l.startswith("summary:")]
    if not line:
        return {}
    kv = {}
    for item in line[-1].split()[1:]:
        if "=" in item:
            k, v = item.split("=", 1)
            kv[k] = [float(x) for x in v.split(",")] if "," in v else float(v)
    return kv


def read_csv(path):
    """track_bag's CSV as a structured numpy array (empty fields are NaN)."""
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")


def read_truth(bag_path, with_target=False):
    """Per frame of a make_scene bag: whether the target is visible (ground_truth/target_visible, in order) and the
    other objects' centres (ground_truth/others, by header.seq; [] where there are none). with_target: also the
    target's centre ("target", ground_truth/target) and box in the left image ("roi": x, y, width, height)."""
    import rosbag  # Debian's python3-rosbag; only needed here
    visible, others, target, roi = {}, {}, {}, {}
    topics = ["ground_truth/target_visible", "ground_truth/others"]
    if with_target:
        topics += ["ground_truth/target", "ground_truth/target_roi"]
    with rosbag.Bag(bag_path) as bag:
        for topic, msg, _ in bag.read_messages(topics=topics):
            if topic == "ground_truth/target_visible":
                visible[len(visible)] = bool(msg.data)
            elif topic == "ground_truth/others":
                others[msg.header.seq] = [[p.position.x, p.position.y, p.position.z] for p in msg.poses]
            elif topic == "ground_truth/target":
                target[msg.header.seq] = [msg.point.x, msg.point.y, msg.point.z]
            else:  # RegionOfInterest has no header: in order, one per frame
                roi[len(roi)] = [msg.x_offset, msg.y_offset, msg.width, msg.height]
    n = len(visible)
    truth = {"visible": [visible[k] for k in sorted(visible)], "others": [others.get(k, []) for k in range(n)]}
    if with_target:
        truth["target"] = [target.get(k) for k in range(n)]
        truth["roi"] = [roi.get(k) for k in range(n)]
    return truth
