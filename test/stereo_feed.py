# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Drive the tracker from Python: a make_scene bag's frames re-stamped and published live, bad variants of a
frame, the tracker launched on a master of its own, its diagnostics and its memory.

Shared by test/soak_ros.py (the soak test) and test/bad_input_table.py (the bad-input table of
docs/ros_runtime.md). Needs build/devel/setup.bash sourced (the package, its plugins and its messages).
"""
import copy
import math
import os
import signal
import socket
import subprocess
import tempfile
import threading
import time

import rosbag
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import CameraInfo, Image, RegionOfInterest
from stereo_pf.msg import TrackStatus

TRACKER = "/stereo_pf_tracker"
MANAGER = "/stereo_pf_manager"
CAMERA = "/stereo_camera"


class Frame:
    """One stereo frame of a bag: the four camera messages and the ground truth."""

    def __init__(self):
        self.left = self.right = self.left_info = self.right_info = None
        self.truth = None   # (x, y, z) in the left optical frame
        self.roi = None     # sensor_msgs/RegionOfInterest

    def complete(self):
        return None not in (self.left, self.right, self.left_info, self.right_info)


def load_frames(bag_path, limit=None):
    """The bag's frames in order (camera1394stereo topics and make_scene's ground truth), grouped by stamp."""
    by_stamp = {}
    topics = {CAMERA + "/left/image_raw": "left", CAMERA + "/right/image_raw": "right",
              CAMERA + "/left/camera_info": "left_info", CAMERA + "/right/camera_info": "right_info"}
    with rosbag.Bag(bag_path) as bag:
        for topic, msg, _ in bag.read_messages():
            topic = "/" + topic.lstrip("/")
            stamp = msg.header.stamp.to_nsec() if hasattr(msg, "header") else None
            if topic in topics:
                setattr(by_stamp.setdefault(stamp, Frame()), topics[topic], msg)
            elif topic == "/ground_truth/target":
                by_stamp.setdefault(stamp, Frame()).truth = (msg.point.x, msg.point.y, msg.point.z)
            elif topic == "/ground_truth/target_roi":
                roi_msg = msg
                # the ROI has no header: it belongs to the latest frame read
                if by_stamp:
                    by_stamp[max(by_stamp)].roi = roi_msg
    frames = [by_stamp[k] for k in sorted(by_stamp) if by_stamp[k].complete()]
    if not frames:
        raise RuntimeError("no complete stereo frame in " + bag_path)
    return frames[:limit] if limit else frames


def free_port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


class Tracker:
    """tracker.launch (manager + TrackerNodelet, config/tracker.yaml) on a master of its own."""

    def __init__(self, extra_params=None, log_path=None):
        self.port = free_port()
        os.environ["ROS_MASTER_URI"] = "http://localhost:%d" % self.port
        self._config = tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False)
        pkg = subprocess.check_output(["rospack", "find", "stereo_pf"], text=True).strip()
        with open(os.path.join(pkg, "config", "tracker.yaml")) as f:
            self._config.write(f.read())
        for key, value in (extra_params or {}).items():
            self._config.write("\n%s: %s\n" % (key, value))
        self._config.close()
        if log_path:
            os.makedirs(os.path.dirname(os.path.abspath(log_path)), exist_ok=True)
        self._log = open(log_path, "w") if log_path else subprocess.DEVNULL
        self.launch = subprocess.Popen(
            ["roslaunch", "-p", str(self.port), "stereo_pf", "tracker.launch", "config:=" + self._config.name,
             "target_roi_topic:=/feed/target_roi"],
            stdout=self._log, stderr=subprocess.STDOUT, preexec_fn=os.setsid)
        self.manager_pid = None

    def wait_ready(self, timeout=40.0):
        """Wait until the manager runs and the tracker subscribes to the cameras; returns the manager's pid."""
        import rosgraph
        import xmlrpc.client
        master = rosgraph.Master("/feed", master_uri=os.environ["ROS_MASTER_URI"])
        deadline = time.time() + timeout
        while True:
            try:
                uri = master.lookupNode(MANAGER)
                code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/feed")
                _, subs, _ = master.getSystemState()
                if code == 1 and any(t == CAMERA + "/right/camera_info" for t, _ in subs):
                    self.manager_pid = int(pid)
                    return self.manager_pid
            except Exception:
                pass
            if self.launch.poll() is not None:
                raise RuntimeError("tracker.launch exited with %s" % self.launch.returncode)
            if time.time() > deadline:
                raise RuntimeError("the tracker did not start within %.0f s" % timeout)
            time.sleep(0.3)

    def alive(self):
        return self.manager_pid is not None and os.path.exists("/proc/%d" % self.manager_pid) and \
            self.launch.poll() is None

    def stop(self):
        if self.launch.poll() is None:
            os.killpg(self.launch.pid, signal.SIGINT)
            try:
                self.launch.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(self.launch.pid, signal.SIGKILL)
                self.launch.wait()
        os.unlink(self._config.name)


def rss_mb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def percentile(values, q):
    if not values:
        return float("nan")
    s = sorted(values)
    return s[min(len(s) - 1, int(q * (len(s) - 1) + 0.5))]


class Feed:
    """Publishes frames on the camera topics with fresh stamps and records what the tracker answers."""

    def __init__(self, frames):
        self.frames = frames
        self.lock = threading.Lock()
        self.truth_by_stamp = {}    # stamp (ns) -> ground truth of the frame published with it
        self.sent_at = {}           # stamp (ns) -> wall time of publishing
        self.estimates = {}         # stamp (ns) -> (x, y, z)
        self.latency_ms = {}        # stamp (ns) -> ~target arrival - publish, ms
        self.arrivals = []          # wall time of every ~target received
        self.status = {}            # stamp (ns) -> (state_name, support) of the last ~status with that stamp
        self.diag = {}
        self.diag_level = None
        self.diag_message = ""
        self.log = []               # (wall time, level, text) of the tracker's warnings and errors
        self.pubs = {
            "left": rospy.Publisher(CAMERA + "/left/image_raw", Image, queue_size=4, tcp_nodelay=True),
            "right": rospy.Publisher(CAMERA + "/right/image_raw", Image, queue_size=4, tcp_nodelay=True),
            "left_info": rospy.Publisher(CAMERA + "/left/camera_info", CameraInfo, queue_size=4, tcp_nodelay=True),
            "right_info": rospy.Publisher(CAMERA + "/right/camera_info", CameraInfo, queue_size=4, tcp_nodelay=True),
        }
        self.roi_pub = rospy.Publisher("/feed/target_roi", RegionOfInterest, queue_size=1, latch=True)
        self.subs = [
            rospy.Subscriber(TRACKER + "/target", PointStamped, self._on_target, queue_size=200, tcp_nodelay=True),
            rospy.Subscriber(TRACKER + "/status", TrackStatus, self._on_status, queue_size=200, tcp_nodelay=True),
            rospy.Subscriber("/diagnostics", DiagnosticArray, self._on_diag, queue_size=20),
            rospy.Subscriber("/rosout_agg", Log, self._on_log, queue_size=200),
        ]
        self.last_stamp = rospy.Time(0)   # the last fresh stamp handed out
        self.last_sent = rospy.Time(0)    # the stamp the last set's left image went out with

    # --- incoming --------------------------------------------------------------------------------------
    def _on_target(self, msg):
        now = time.time()
        key = msg.header.stamp.to_nsec()
        with self.lock:
            self.estimates[key] = (msg.point.x, msg.point.y, msg.point.z)
            self.arrivals.append(now)
            if key in self.sent_at:
                self.latency_ms[key] = (now - self.sent_at[key]) * 1e3

    def _on_status(self, msg):
        with self.lock:
            self.status[msg.header.stamp.to_nsec()] = (msg.state_name, msg.support)

    def _on_diag(self, msg):
        for s in msg.status:
            if s.name.endswith(": tracker"):
                with self.lock:
                    self.diag = {kv.key: kv.value for kv in s.values}
                    self.diag_level = s.level
                    self.diag_message = s.message

    def _on_log(self, msg):
        if msg.level >= Log.WARN and msg.name in (MANAGER, TRACKER):
            with self.lock:
                self.log.append((time.time(), msg.level, msg.msg))

    # --- outgoing --------------------------------------------------------------------------------------
    def wait_connected(self, timeout=20.0):
        deadline = time.time() + timeout
        while time.time() < deadline:
            if all(p.get_num_connections() > 0 for p in self.pubs.values()):
                return
            time.sleep(0.1)
        raise RuntimeError("the tracker did not subscribe to the camera topics")

    def teach(self):
        """Publish the first frame's ROI (the tracker learns the target from the next frame)."""
        roi = next(f.roi for f in self.frames if f.roi is not None)
        self.roi_pub.publish(roi)

    def next_stamp(self):
        stamp = rospy.Time.now()
        if stamp <= self.last_stamp:
            stamp = self.last_stamp + rospy.Duration(0, 1000)
        self.last_stamp = stamp
        return stamp

    def publish(self, msgs, truth=None, offsets=None):
        """Publish a set {left, right, left_info, right_info} with one fresh stamp; `offsets` (seconds) shift
        single messages' stamps, or "repeat" gives every message the stamp the previous set's left image went out
        with (after a set stamped back, that stamp: a repeat on the wire, not the fresh stamp it was shifted from)."""
        if offsets == "repeat":
            stamp, offsets = self.last_sent, None
        else:
            stamp = self.next_stamp()
        out = {}
        for key, msg in msgs.items():
            m = copy.copy(msg)               # shallow: the pixel data are shared, only the header changes
            m.header = copy.copy(msg.header)
            m.header.stamp = stamp + rospy.Duration.from_sec((offsets or {}).get(key, 0.0))
            out[key] = m
        with self.lock:
            self.sent_at[stamp.to_nsec()] = time.time()
            if truth is not None:
                self.truth_by_stamp[stamp.to_nsec()] = truth
        for key in ("left_info", "right_info", "left", "right"):
            self.pubs[key].publish(out[key])
        self.last_sent = out["left"].header.stamp
        return stamp

    def publish_frame(self, k):
        f = self.frames[k % len(self.frames)]
        return self.publish({"left": f.left, "right": f.right, "left_info": f.left_info, "right_info": f.right_info},
                            truth=f.truth)

    # --- results ---------------------------------------------------------------------------------------
    def error(self, stamp):
        """|estimate - truth| in metres for the frame published with `stamp`, None without an estimate."""
        key = stamp.to_nsec()
        with self.lock:
            e, t = self.estimates.get(key), self.truth_by_stamp.get(key)
        if e is None or t is None:
            return None
        return math.dist(e, t)

    def targets_between(self, t0, t1):
        """Number of ~target messages received between wall times t0 and t1."""
        with self.lock:
            return sum(1 for t in self.arrivals if t0 <= t < t1)

    def answered(self, stamp):
        with self.lock:
            return stamp.to_nsec() in self.estimates

    def status_of(self, stamp):
        """(state_name, support) of the last ~status stamped `stamp`, None when none came."""
        with self.lock:
            return self.status.get(stamp.to_nsec())

    def diagnostics(self):
        with self.lock:
            return dict(self.diag), self.diag_level, self.diag_message

    def log_since(self, t0):
        with self.lock:
            return [(lvl, text) for t, lvl, text in self.log if t >= t0]


def bad_variants(frame):
    """The bad inputs fed to the tracker: name -> (what was fed, dict of the four messages, per-message stamps
    offsets in seconds or None). Each is built from a good frame so only the named fault differs."""
    def msgs():
        return {"left": frame.left, "right": frame.right, "left_info": frame.left_info,
                "right_info": frame.right_info}

    def image(base, **fields):
        m = copy.copy(base)
        for k, v in fields.items():
            setattr(m, k, v)
        return m

    def info(base, **fields):
        m = copy.deepcopy(base)
        for k, v in fields.items():
            if k in ("K", "P", "D", "R") and isinstance(v, dict):
                values = list(getattr(m, k))
                for index, value in v.items():
                    values[index] = value
                setattr(m, k, values)
            else:
                setattr(m, k, v)
        return m

    L, R, LI, RI = frame.left, frame.right, frame.left_info, frame.right_info
    nan, inf = float("nan"), float("inf")
    small = image(R, width=R.width // 2, height=R.height // 2, step=R.step // 2,
                  data=bytes(R.data[:(R.step // 2) * (R.height // 2)]))
    cases = []

    def case(name, fed, **changes):
        m = msgs()
        offsets = changes.pop("offsets", None)
        m.update(changes)
        cases.append((name, fed, m, offsets))

    case("unsupported encoding", "left image labelled `32FC1` (same bytes)", left=image(L, encoding="32FC1"))
    case("unknown encoding", "left image labelled `yuv999`", left=image(L, encoding="yuv999"))
    case("mixed encodings", "left image mono16 (a valid one), right image bgr8",
         left=image(L, encoding="mono16", step=L.width * 2, data=bytes(L.data[:L.width * 2 * L.height])))
    case("row step too short", "left image with step = width (bgr8 needs 3 x width)", left=image(L, step=L.width))
    case("truncated data", "right image with half of its data", right=image(R, data=bytes(R.data[:len(R.data) // 2])))
    case("empty image", "left image 0x0, no data", left=image(L, width=0, height=0, step=0, data=b""))
    case("left/right size mismatch", "right image at half size (320x240), camera_info unchanged", right=small)
    case("image/camera_info size mismatch", "both camera_info say 1280x960, images are 640x480",
         left_info=info(LI, width=1280, height=960), right_info=info(RI, width=1280, height=960))
    case("camera_info without size", "left camera_info width = height = 0", left_info=info(LI, width=0, height=0))
    case("camera_info size only", "both camera_info with only width and height (K, D, R, P zero), as an "
         "uncalibrated camera1394stereo publishes",
         left_info=info(LI, K={i: 0.0 for i in range(9)}, R={i: 0.0 for i in range(9)}, P={i: 0.0 for i in range(12)},
                        D=[], distortion_model=""),
         right_info=info(RI, K={i: 0.0 for i in range(9)}, R={i: 0.0 for i in range(9)}, P={i: 0.0 for i in range(12)},
                         D=[], distortion_model=""))
    case("NaN in K", "left camera_info K[0] (fx) = NaN", left_info=info(LI, K={0: nan}))
    case("infinity in P", "right camera_info P[3] (-fx * baseline) = inf", right_info=info(RI, P={3: inf}))
    case("NaN in D", "left camera_info D[0] = NaN", left_info=info(LI, D={0: nan}))
    case("zero focal length", "left camera_info K[0] = P[0] = 0", left_info=info(LI, K={0: 0.0}, P={0: 0.0}))
    case("zero baseline", "right camera_info P[3] = 0 (right camera on the left one)", right_info=info(RI, P={3: 0.0}))
    case("negative disparity rig", "right camera_info P[3] = +fx * baseline (cameras swapped)",
         right_info=info(RI, P={3: -RI.P[3]}))
    case("different focal lengths", "right camera_info fx = 2 x left fx in K and P",
         right_info=info(RI, K={0: 2 * RI.K[0]}, P={0: 2 * RI.P[0]}))
    case("unsynchronised stamps", "right image and camera_info stamped 10 ms after the left ones",
         offsets={"right": 0.010, "right_info": 0.010})
    case("camera_info stamp differs", "left camera_info stamped 1 ms after its image", offsets={"left_info": 0.001})
    case("stamp going back", "a good frame stamped 1 s before the previous one",
         offsets={k: -1.0 for k in ("left", "right", "left_info", "right_info")})
    case("stamp repeated", "a good frame with the previous frame's stamp", offsets="repeat")
    case("all-black images", "both images black (valid messages, nothing to see)",
         left=image(L, data=bytes(len(L.data))), right=image(R, data=bytes(len(R.data))))
    return cases
