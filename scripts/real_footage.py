# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Real stereo footage of pitched baseballs (BYU ECEn 631's baseball catcher) as stereo_pf bags.

The library behind scripts/real_pitch (see its --help and README.md, "Real footage"). It reads a local copy of
one of two public course repositories straight from its git objects (a bare copy or a clone; no work tree
needed), rectifies the stereo pairs, finds a reference trajectory of the ball and writes one bag per sequence
with camera1394stereo's topics and stereo_pf's ground truth topics.

The reference: the ball found in both rectified views by background subtraction (per-pixel median of the
sequence), threshold, the largest blob whose size and rows are consistent in both views, its centroid,
triangulated; then one ballistic fit (quadratic in time per axis, numpy least squares) over the flight, with
gross outliers dropped and the fit redone once. The reference at each frame is the fit; the RMS of its 3D
residual is reported as the reference's own uncertainty.

`evaluate(bag, csv)` compares a track_bag CSV with a bag's reference; the stress suite reuses it.

Nothing here embeds data or figures measured from the footage: the repositories carry no licence.
"""
import io
import json
import math
import os
import re
import subprocess
import tarfile

import numpy as np

try:
    import cv2
except ImportError as e:  # the scripts must fail with a clear message, not a traceback
    raise SystemExit("real_pitch: OpenCV for Python is missing (Debian: apt-get install python3-opencv; "
                     "scripts/deps.txt lists it): %s" % e)

INCH = 0.0254
FRAME_ID = "stereo_camera_optical_frame"   # as make_scene: the left rectified optical frame
EPOCH_NS = 1000 * 10**9                    # first stamp, as make_scene (deterministic, not the wall clock)
DEFAULT_FPS = 60.0
# What a blob pair may measure to count as the ball (a baseball is 7.3-7.5 cm across). Wide on purpose:
# segmentation cuts or blurs the silhouette; it only has to reject people and their arms.
BALL_DIAMETER_RANGE_M = (0.04, 0.15)
DEPTH_RANGE_M = (0.5, 40.0)
INLIER_PX = 6.0          # a detection further than this from a candidate trajectory (either view) is not on it
OUTLIER_MIN_PX = 3.0     # final outlier rule: further than max(3 px, 5 x median) from the fit
OUTLIER_MEDIANS = 5.0
MIN_SPEED_MPS = 2.0     # a trajectory slower than this (mid-sequence) is not a pitch
MAX_HOLE = 8            # frames: a flight has no longer run without a detection on it (else it is two)
MAX_CAPTURE_GAPS = 6     # at most this many skipped capture periods inferred per sequence
GAP_GAIN = 0.8           # a skipped period is accepted only if it cuts the trajectory cost by 20 % or more

TOPICS = {
    "left_image": "stereo_camera/left/image_raw",
    "right_image": "stereo_camera/right/image_raw",
    "left_info": "stereo_camera/left/camera_info",
    "right_info": "stereo_camera/right/camera_info",
    "truth": "ground_truth/target",
    "visible": "ground_truth/target_visible",
    "roi": "ground_truth/target_roi",
}


class FootageError(Exception):
    """Input that cannot be used (wrong path, missing files, unusable calibration); the message says why."""


# ---------------------------------------------------------------------------------------------------------
# Reading a repository without a work tree


class GitRepo:
    """A local git repository (bare, a .git directory, or a clone's top directory), read through git itself."""

    def __init__(self, path):
        self.path = path
        if not os.path.isdir(path):
            raise FootageError("'%s' is not a directory (expected a local copy of %s)" % (path, KNOWN_REPOS))
        candidates = [os.path.join(path, ".git"), path]
        for c in candidates:
            if os.path.exists(c) and self._is_git_dir(c):
                self.git_dir = c
                return
        raise FootageError("'%s' is not a git repository (bare, .git or a clone); expected a local copy of %s"
                           % (path, KNOWN_REPOS))

    @staticmethod
    def _is_git_dir(d):
        try:
            p = subprocess.run(["git", "--git-dir=" + d, "rev-parse", "--git-dir"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
        except FileNotFoundError:
            raise FootageError("git is not installed (needed to read the repository)")
        return p.returncode == 0

    def git(self, *args, binary=False):
        p = subprocess.run(["git", "--git-dir=" + self.git_dir] + list(args), stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE)
        if p.returncode != 0:
            raise FootageError("git %s failed in '%s': %s" % (" ".join(args), self.git_dir,
                                                              p.stderr.decode(errors="replace").strip()))
        return p.stdout if binary else p.stdout.decode()

    def exists(self, commit, path):
        return subprocess.run(["git", "--git-dir=" + self.git_dir, "cat-file", "-e", "%s:%s" % (commit, path)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0

    def files(self, commit, folder):
        """Paths of the files under `folder` at `commit`."""
        out = self.git("ls-tree", "-r", "--name-only", commit, "--", folder.rstrip("/") + "/")
        return [line for line in out.splitlines() if line]

    def tree_id(self, commit, folder):
        return self.git("rev-parse", "%s:%s" % (commit, folder.rstrip("/"))).strip()

    def read(self, commit, paths):
        """{path: bytes} for files at `commit` (one `git archive`, so hundreds of images cost one process)."""
        if not paths:
            return {}
        data = self.git("archive", "--format=tar", commit, "--", *paths, binary=True)
        out = {}
        with tarfile.open(fileobj=io.BytesIO(data)) as tar:
            for m in tar.getmembers():
                if m.isfile():
                    out[m.name] = tar.extractfile(m).read()
        missing = [p for p in paths if p not in out]
        if missing:
            raise FootageError("'%s' at %s lacks %s" % (self.path, commit, ", ".join(missing[:3])))
        return out

    def commit_adding(self, path):
        """The (oldest) commit that added `path`, or None when the history does not have it (shallow copy)."""
        out = self.git("log", "--all", "--diff-filter=A", "--format=%H", "--", path).split()
        return out[-1] if out else None


def decode_grey(data, what):
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise FootageError("cannot decode the image %s" % what)
    return image


def numbered(paths, pattern):
    """{number: path} for the paths whose file name matches `pattern` (one group: the frame number)."""
    out = {}
    for p in paths:
        m = re.fullmatch(pattern, os.path.basename(p))
        if m:
            out[int(m.group(1))] = p
    return out


# ---------------------------------------------------------------------------------------------------------
# The two repositories


class Sequence:
    """One stereo recording: pairs (capture number, left path, right path) read at `commit`."""

    def __init__(self, name, commit, pairs, note=""):
        self.name, self.commit, self.pairs, self.note = name, commit, pairs, note


class Calibration:
    """A raw stereo calibration: intrinsics, distortion, and the right camera's pose (R, T in metres)."""

    def __init__(self, K1, D1, K2, D2, R, T, size, source, figures=None):
        self.K1, self.D1, self.K2, self.D2 = [np.asarray(a, np.float64) for a in (K1, D1, K2, D2)]
        self.R = np.asarray(R, np.float64)
        self.T = np.asarray(T, np.float64).reshape(3, 1)
        self.size = tuple(size)
        self.source = source
        self.figures = figures or {}


class Bboyack:
    """bboyack/ecen631_bbcatcher: two sequences as PNGs in L/ and R/, calibration in .npz files (inches)."""

    NAME = "bboyack/ecen631_bbcatcher"
    SEQUENCES = ("Ball_Launch1", "catch_test1")
    CAL = "calibration_parameters"

    @classmethod
    def recognise(cls, repo):
        return (repo.exists("HEAD", "Ball_Launch1/L") and
                repo.exists("HEAD", cls.CAL + "/stereo_calibration_results.npz"))

    def __init__(self, repo):
        self.repo = repo
        self.commit = repo.git("rev-parse", "HEAD").strip()

    def sequences(self):
        out = []
        for name in self.SEQUENCES:
            left = numbered(self.repo.files(self.commit, name + "/L"), r"(\d+)\.png")
            right = numbered(self.repo.files(self.commit, name + "/R"), r"(\d+)\.png")
            common = sorted(set(left) & set(right))
            if not common:
                raise FootageError("%s: %s has no numbered L/R image pairs" % (self.NAME, name))
            out.append(Sequence(name, self.commit, [(k, left[k], right[k]) for k in common]))
        return out

    def calibration(self, cache_dir, log):
        files = self.repo.read(self.commit, ["%s/%s.npz" % (self.CAL, n) for n in
                                             ("left_cam_intr_param", "right_cam_intr_param",
                                              "stereo_calibration_results")])
        load = {k.split("/")[-1][:-4]: np.load(io.BytesIO(v)) for k, v in files.items()}
        try:
            left, right, stereo = (load["left_cam_intr_param"], load["right_cam_intr_param"],
                                   load["stereo_calibration_results"])
            K1, D1, K2, D2 = left["mtx"], left["dist"], right["mtx"], right["dist"]
            R, T = stereo["R"], stereo["T"]
        except KeyError as e:
            raise FootageError("%s: calibration npz lacks the key %s (has: %s)" % (
                self.NAME, e, {k: v.files for k, v in load.items()}))
        # The repository's own code rectifies at 640x480 and measures the board in inches.
        return Calibration(K1, D1, K2, D2, R, np.asarray(T) * INCH, (640, 480),
                           "%s/*.npz of %s (T in inches, converted to metres)" % (self.CAL, self.NAME))


class Wynn4:
    """wynn4/ECEN_631: Assignment_4's ball sequences; the stereo calibration is computed from Assignment_3's
    chessboard pairs (10x7 inner corners, 3.88-inch squares, as the repository's Assignment 3 code states)."""

    NAME = "wynn4/ECEN_631"
    NEW_BALL = "Assignment_4/newBall"
    OLD_BALL = "Assignment_4/ball"
    BOARD = "Assignment_3/stereo_images"
    BOARD_SIZE = (10, 7)
    SQUARE_M = 3.88 * INCH

    @classmethod
    def recognise(cls, repo):
        return repo.exists("HEAD", cls.NEW_BALL) and repo.exists("HEAD", cls.BOARD)

    def __init__(self, repo):
        self.repo = repo
        self.commit = repo.git("rev-parse", "HEAD").strip()

    def sequences(self):
        out = []
        files = self.repo.files(self.commit, self.NEW_BALL)
        left, right = numbered(files, r"Ball_testL(\d+)\.bmp"), numbered(files, r"Ball_testR(\d+)\.bmp")
        common = sorted(set(left) & set(right))
        out.append(Sequence("newBall", self.commit, [(k, left[k], right[k]) for k in common]))
        # The older sequence was deleted from the tree; read it at the commit that added it.
        added = self.repo.commit_adding(self.OLD_BALL + "/ballL00.bmp")
        if added is None:
            out.append(Sequence("ball", None, [], note="not in this copy's history (a shallow clone?): %s was "
                                                       "added and later deleted upstream" % self.OLD_BALL))
        else:
            files = self.repo.files(added, self.OLD_BALL)
            left, right = numbered(files, r"ballL(\d+)\.bmp"), numbered(files, r"ballR(\d+)\.bmp")
            common = sorted(set(left) & set(right))
            out.append(Sequence("ball", added, [(k, left[k], right[k]) for k in common],
                                note="read at %s, the commit that added it" % added[:7]))
        return out

    def calibration(self, cache_dir, log):
        tree = self.repo.tree_id(self.commit, self.BOARD)
        cache = os.path.join(cache_dir, "wynn4_calibration_%s.npz" % tree[:12]) if cache_dir else None
        if cache and os.path.exists(cache):
            z = np.load(cache, allow_pickle=False)
            figures = json.loads(str(z["figures"]))
            log("calibration: %s (cached in %s)" % (self.BOARD, cache))
            return Calibration(z["K1"], z["D1"], z["K2"], z["D2"], z["R"], z["T"], tuple(z["size"]),
                               self._source(), figures)
        files = self.repo.files(self.commit, self.BOARD)
        left, right = numbered(files, r"stereoL(\d+)\.bmp"), numbered(files, r"stereoR(\d+)\.bmp")
        common = sorted(set(left) & set(right))
        if len(common) < 10:
            raise FootageError("%s: %s has %d stereo chessboard pairs; at least 10 are needed"
                               % (self.NAME, self.BOARD, len(common)))
        log("calibration: finding the %dx%d chessboard in %d pairs of %s (a minute or two)"
            % (self.BOARD_SIZE + (len(common), self.BOARD)))
        data = self.repo.read(self.commit, [left[k] for k in common] + [right[k] for k in common])
        pairs = [(decode_grey(data[left[k]], left[k]), decode_grey(data[right[k]], right[k])) for k in common]
        cal = calibrate_stereo(pairs, self.BOARD_SIZE, self.SQUARE_M, self._source())
        if cache:
            os.makedirs(cache_dir, exist_ok=True)
            np.savez(cache, K1=cal.K1, D1=cal.D1, K2=cal.K2, D2=cal.D2, R=cal.R, T=cal.T, size=np.array(cal.size),
                     figures=json.dumps(cal.figures))
        return cal

    def _source(self):
        return "computed from %s of %s (%dx%d inner corners, 3.88-inch squares; k3 fixed at 0)" % (
            self.BOARD, self.NAME, self.BOARD_SIZE[0], self.BOARD_SIZE[1])


SOURCES = (Bboyack, Wynn4)
KNOWN_REPOS = " or ".join(s.NAME for s in SOURCES)


def identify(path):
    """The source object for the repository at `path`, or FootageError saying what was expected."""
    repo = GitRepo(path)
    for source in SOURCES:
        if source.recognise(repo):
            return source(repo)
    raise FootageError(
        "'%s' is a git repository but not a copy of %s: its HEAD has neither Ball_Launch1/L/ with "
        "calibration_parameters/stereo_calibration_results.npz (%s) nor Assignment_4/newBall/ with "
        "Assignment_3/stereo_images/ (%s)" % (path, KNOWN_REPOS, Bboyack.NAME, Wynn4.NAME))


# ---------------------------------------------------------------------------------------------------------
# Calibration and rectification


def calibrate_stereo(pairs, board_size, square_m, source):
    """Intrinsics per camera then the stereo pose, from grey image pairs showing the chessboard in both views."""
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 60, 1e-3)
    obj = np.zeros((board_size[0] * board_size[1], 3), np.float32)
    obj[:, :2] = np.mgrid[0:board_size[0], 0:board_size[1]].T.reshape(-1, 2) * square_m
    size = (pairs[0][0].shape[1], pairs[0][0].shape[0])
    found_l, found_r = [], []
    for left, right in pairs:
        if (left.shape[1], left.shape[0]) != size or left.shape != right.shape:
            raise FootageError("chessboard images differ in size (%s vs %s)" % (left.shape, right.shape))
        corners = []
        for image in (left, right):
            ok, c = cv2.findChessboardCorners(image, board_size,
                                              cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE)
            corners.append(cv2.cornerSubPix(image, c, (5, 5), (-1, -1), crit) if ok else None)
        if corners[0] is not None and corners[1] is not None:
            found_l.append(corners[0])
            found_r.append(corners[1])
    if len(found_l) < 10:
        raise FootageError("the chessboard was found in both views of only %d of %d pairs" % (len(found_l), len(pairs)))
    objs = [obj] * len(found_l)
    # k3 is fixed: with a long lens (about 22 degrees across) it is not observable and only absorbs noise.
    flags = cv2.CALIB_FIX_K3
    rms1, K1, D1, _, _ = cv2.calibrateCamera(objs, found_l, size, None, None, flags=flags)
    rms2, K2, D2, _, _ = cv2.calibrateCamera(objs, found_r, size, None, None, flags=flags)
    rms, K1, D1, K2, D2, R, T, _, _ = cv2.stereoCalibrate(objs, found_l, found_r, K1, D1, K2, D2, size,
                                                         flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    figures = {"pairs_used": len(found_l), "pairs": len(pairs), "rms_left_px": rms1, "rms_right_px": rms2,
               "rms_stereo_px": rms}
    return Calibration(K1, D1, K2, D2, R, T, size, source, figures)


def small_rotation(rx, ry, rz):
    return cv2.Rodrigues(np.array([rx, ry, rz], np.float64))[0]


class Rectification:
    """Rectifying maps and the rectified geometry (one fx, fy, cx, cy for both views; baseline in metres).

    `correction` = (pitch of the right view, roll of the right view, roll of both), radians: small rotations
    of the rectified cameras that remove a row mismatch the footage shows (see refine_rows)."""

    def __init__(self, cal, correction=(0.0, 0.0, 0.0)):
        self.cal = cal
        self.correction = tuple(float(c) for c in correction)
        R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(cal.K1, cal.D1, cal.K2, cal.D2, cal.size, cal.R, cal.T,
                                                    flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
        if abs(P2[1, 3]) > abs(P2[0, 3]):
            raise FootageError("the calibration's baseline is vertical (T = %s m); a side-by-side pair is expected"
                               % np.round(cal.T.ravel(), 3))
        pitch_r, roll_r, roll_both = self.correction
        self.R1 = small_rotation(0, 0, roll_both) @ R1
        self.R2 = small_rotation(pitch_r, 0, roll_r + roll_both) @ R2
        self.P1, self.P2 = P1, P2
        self.fx, self.fy, self.cx, self.cy = P1[0, 0], P1[1, 1], P1[0, 2], P1[1, 2]
        self.baseline = -P2[0, 3] / P2[0, 0]
        self.width, self.height = cal.size
        self.maps = [cv2.initUndistortRectifyMap(cal.K1, cal.D1, self.R1, P1, cal.size, cv2.CV_32FC1),
                     cv2.initUndistortRectifyMap(cal.K2, cal.D2, self.R2, P2, cal.size, cv2.CV_32FC1)]

    def rectify(self, image, view):
        return cv2.remap(image, self.maps[view][0], self.maps[view][1], cv2.INTER_LINEAR)

    def geometry(self):
        return Geometry(self.fx, self.fy, self.cx, self.cy, self.baseline, self.width, self.height)


class Geometry:
    """Rectified stereo geometry: triangulation and projection in the left rectified optical frame (metres)."""

    def __init__(self, fx, fy, cx, cy, baseline, width, height):
        self.fx, self.fy, self.cx, self.cy, self.baseline = fx, fy, cx, cy, baseline
        self.width, self.height = int(width), int(height)

    def triangulate(self, ul, vl, ur, vr):
        d = np.asarray(ul, float) - np.asarray(ur, float)
        z = self.fx * self.baseline / d
        v = 0.5 * (np.asarray(vl, float) + np.asarray(vr, float))
        return np.stack([(np.asarray(ul, float) - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z], axis=-1)

    def project(self, points):
        p = np.atleast_2d(points)
        ul = self.fx * p[:, 0] / p[:, 2] + self.cx
        v = self.fy * p[:, 1] / p[:, 2] + self.cy
        ur = self.fx * (p[:, 0] - self.baseline) / p[:, 2] + self.cx
        return ul, v, ur


def match_background_features(left, right, max_rows=12):
    """Static scene points seen in both rectified views: [(u_left, v_left, disparity, row mismatch)], the
    right position refined to a fraction of a pixel by normalised cross-correlation."""
    orb = cv2.ORB_create(3000)
    k1, d1 = orb.detectAndCompute(left, None)
    k2, d2 = orb.detectAndCompute(right, None)
    if d1 is None or d2 is None:
        return np.zeros((0, 4))
    out = []
    for m in cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(d1, d2):
        (u, v), (u2, v2) = k1[m.queryIdx].pt, k2[m.trainIdx].pt
        if abs(v - v2) > max_rows or u - u2 <= 0:
            continue
        u, v, u2, v2 = int(round(u)), int(round(v)), int(round(u2)), int(round(v2))
        h, w = left.shape
        if not (7 <= u < w - 7 and 7 <= v < h - 7 and 12 <= u2 < w - 12 and 12 <= v2 < h - 12):
            continue
        patch = left[v - 7:v + 8, u - 7:u + 8]
        if patch.std() < 8:
            continue
        score = cv2.matchTemplate(right[v2 - 12:v2 + 13, u2 - 12:u2 + 13], patch, cv2.TM_CCOEFF_NORMED)
        _, best, _, (x, y) = cv2.minMaxLoc(score)
        if best < 0.9 or not (0 < x < score.shape[1] - 1 and 0 < y < score.shape[0] - 1):
            continue

        def vertex(a, b, c):  # sub-pixel peak of a parabola through three samples
            den = a - 2 * b + c
            return 0.5 * (a - c) / den if den != 0 else 0.0

        sx = vertex(score[y, x - 1], score[y, x], score[y, x + 1])
        sy = vertex(score[y - 1, x], score[y, x], score[y + 1, x])
        ur, vr = u2 - 12 + x + 7 + sx, v2 - 12 + y + 7 + sy
        out.append((u, v, u - ur, v - vr))
    return np.array(out).reshape(-1, 4)


def row_mismatch(points, geometry, correction):
    """Row mismatch (v_left - v_right, px) of correspondences (u_left, v_left, disparity, mismatch) after the
    small extra rotations `correction` (see Rectification) are applied to the rectified cameras."""
    pitch_r, roll_r, roll_both = correction
    ul, vl, d, dv = points.T
    ur, vr = ul - d, vl - dv

    def move(u, v, rot):
        ray = np.stack([(u - geometry.cx) / geometry.fx, (v - geometry.cy) / geometry.fy, np.ones_like(u)])
        r = rot @ ray
        return geometry.fy * r[1] / r[2] + geometry.cy

    return move(ul, vl, small_rotation(0, 0, roll_both)) - move(ur, vr, small_rotation(pitch_r, 0, roll_r + roll_both))


def refine_rows(points, geometry):
    """The rotations (pitch and roll of the right view, roll of both) that best remove the row mismatch of the
    correspondences: a constant offset, one growing across the image, and one growing with disparity (a
    vertical component of the baseline). Robust (iteratively reweighted) Gauss-Newton."""
    p = np.zeros(3)
    w = np.ones(len(points))
    for _ in range(8):
        r0 = row_mismatch(points, geometry, p)
        J = np.empty((len(points), 3))
        for i in range(3):
            step = np.zeros(3)
            step[i] = 1e-6
            J[:, i] = (row_mismatch(points, geometry, p + step) - r0) / 1e-6
        dp, *_ = np.linalg.lstsq(J * w[:, None], -r0 * w, rcond=None)
        p = p + dp
        r = row_mismatch(points, geometry, p)
        scale = 1.4826 * np.median(np.abs(r)) + 0.05
        w = np.sqrt(np.minimum(1.0, 1.5 * scale / np.maximum(np.abs(r), 1e-9)))  # Huber weights
    return tuple(p)


# ---------------------------------------------------------------------------------------------------------
# The ball in each stereo pair


def background(images):
    """Per-pixel median of a sequence: the scene without anything that moves through it."""
    return np.median(np.stack(images), axis=0).astype(np.uint8)


def find_blobs(image, bg, min_area=8):
    """Connected regions that differ from the background: [(area, u, v, width, height)] (centroid u, v)."""
    diff = cv2.absdiff(cv2.GaussianBlur(image, (3, 3), 0), cv2.GaussianBlur(bg, (3, 3), 0))
    noise = 1.4826 * float(np.median(diff))
    mask = (diff > max(12.0, 6.0 * noise)).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))
    n, _, stats, centroids = cv2.connectedComponentsWithStats(mask)
    out = []
    for i in range(1, n):
        x, y, w, h, area = stats[i]
        if area < min_area or area < 0.45 * w * h or max(w, h) > 2.5 * min(w, h):
            continue  # too small, too ragged or too elongated for a (blurred) ball
        out.append((float(area), float(centroids[i][0]), float(centroids[i][1]), int(w), int(h)))
    return out


def pair_ball(left_blobs, right_blobs, geometry):
    """The largest left/right blob pair that can be the ball: rows consistent, positive disparity within the
    depth range, similar areas, and a metric diameter a ball can have. (uL, vL, uR, vR, radius_px) or None."""
    fb = geometry.fx * geometry.baseline
    best, best_area = None, 0.0
    for al, ul, vl, _, _ in left_blobs:
        rl = math.sqrt(al / math.pi)
        for ar, ur, vr, _, _ in right_blobs:
            d = ul - ur
            if not (fb / DEPTH_RANGE_M[1] <= d <= fb / DEPTH_RANGE_M[0]):
                continue
            if abs(vl - vr) > max(3.0, 0.5 * rl) or not (0.4 <= al / ar <= 2.5):
                continue
            radius = math.sqrt(0.5 * (al + ar) / math.pi)
            diameter = 2.0 * radius * geometry.baseline / d
            if not (BALL_DIAMETER_RANGE_M[0] <= diameter <= BALL_DIAMETER_RANGE_M[1]):
                continue
            if min(al, ar) > best_area:
                best, best_area = (ul, vl, ur, vr, radius), min(al, ar)
    return best


def detect(lefts, rights, geometry):
    """Per frame: the ball pair (uL, vL, uR, vR, radius_px) or None, against the sequences' medians."""
    bgl, bgr = background(lefts), background(rights)
    return [pair_ball(find_blobs(l, bgl), find_blobs(r, bgr), geometry) for l, r in zip(lefts, rights)]


# ---------------------------------------------------------------------------------------------------------
# The reference trajectory


def fit_ballistic(t, points):
    """Least-squares quadratic in time per axis: coefficients (3, 3), row i = coefficient of t^i."""
    A = np.stack([np.ones_like(t), t, t * t], axis=1)
    coef, *_ = np.linalg.lstsq(A, points, rcond=None)
    return coef


def evaluate_fit(coef, t):
    return np.stack([np.ones_like(t), t, t * t], axis=1) @ coef


def pixel_residual(geometry, fitted, obs):
    """Distance (px) between each detection and the fit's projection, the worse of the two views."""
    ul, v, ur = geometry.project(fitted)
    el = np.hypot(obs[:, 0] - ul, obs[:, 1] - v)
    er = np.hypot(obs[:, 2] - ur, obs[:, 3] - v)
    return np.maximum(el, er)


def _flight(mask, frames):
    """The longest run of `mask`'s detections with no hole of more than MAX_HOLE frames: a trajectory's
    extrapolation must not collect unrelated blobs long before or after the flight."""
    idx = np.nonzero(mask)[0]
    if len(idx) == 0:
        return mask
    runs, start = [], 0
    for j in range(1, len(idx) + 1):
        if j == len(idx) or frames[idx[j]] - frames[idx[j - 1]] > MAX_HOLE + 1:
            runs.append(idx[start:j])
            start = j
    best = max(runs, key=len)
    out = np.zeros_like(mask)
    out[best] = True
    return out


def _robust_fit(t, points, obs, frames, geometry, inliers, rounds=3):
    """Fit on `inliers`, take the flight of detections within INLIER_PX as the new inlier set, repeat."""
    for _ in range(rounds):
        if inliers.sum() < 4:
            return None, inliers, np.inf
        coef = fit_ballistic(t[inliers], points[inliers])
        e = pixel_residual(geometry, evaluate_fit(coef, t), obs)
        inliers = _flight(e <= INLIER_PX, frames)
    return coef, inliers, float(np.sum(np.minimum(e, INLIER_PX) ** 2))


def _ransac(t, points, obs, frames, geometry, iterations=300, seed=0):
    """Inliers (one flight) of the best ballistic trajectory through three detections (deterministic: seeded)."""
    rng = np.random.default_rng(seed)
    n = len(t)
    best, best_key = np.zeros(n, bool), (-1, 0.0)
    for _ in range(iterations):
        idx = rng.choice(n, 3, replace=False)
        if len(set(t[idx])) < 3:
            continue
        coef = fit_ballistic(t[idx], points[idx])
        fitted = evaluate_fit(coef, t)
        # A pitched ball moves: a still blob (someone's hand) repeated over frames fits a "trajectory" too.
        if np.any(fitted[:, 2] <= 0) or np.linalg.norm(coef[1] + coef[2] * (t[0] + t[-1])) < MIN_SPEED_MPS:
            continue
        e = pixel_residual(geometry, fitted, obs)
        inl = _flight(e <= INLIER_PX, frames)
        key = (int(inl.sum()), -float(np.sum(e[inl])))
        if key > best_key:
            best, best_key = inl, key
    return best


def reference_trajectory(numbers, detections, geometry, fps):
    """The ball's reference over a sequence.

    numbers: capture number of each frame; detections: per frame (uL, vL, uR, vR, radius_px) or None.
    Returns a dict: `times` (s, per frame, from 0, with inferred skipped captures), `captures` (the same in
    capture periods, integers), `coef`, `frames` (indices
    of the frames with the reference), `points` (fit at those frames), `kept`/`dropped` detections, `gaps`,
    residuals; or raises FootageError saying why there is no usable trajectory."""
    numbers = np.asarray(numbers, float)
    have = [i for i, d in enumerate(detections) if d is not None]
    if len(have) < 6:
        raise FootageError("the ball was found in both views in only %d frames (6 needed)" % len(have))
    obs = np.array([detections[i][:4] for i in have])
    radius_px = np.array([detections[i][4] for i in have])
    points = geometry.triangulate(obs[:, 0], obs[:, 1], obs[:, 2], obs[:, 3])
    frame_of = np.array(have)

    def captures(extra):
        # Capture periods since the first frame: the numbers, plus the skipped periods inferred so far (each
        # shifts every later frame).
        s = numbers - numbers[0]
        for i in extra:
            s[i:] += 1
        return s

    def times(extra):
        return captures(extra) / fps

    inliers = _ransac(times([])[frame_of], points, obs, frame_of, geometry)
    if inliers.sum() < 6:
        raise FootageError("no ballistic trajectory fits 6 or more detections within %.0f px" % INLIER_PX)
    # Skipped captures: a frame that came one capture period later than its number says shows up as a jump
    # along the path. Greedily add the skip that best explains the detections, while it helps clearly.
    gaps = []
    coef, inliers, cost = _robust_fit(times(gaps)[frame_of], points, obs, frame_of, geometry, inliers)
    while len(gaps) < MAX_CAPTURE_GAPS and coef is not None:
        best = None
        lo, hi = frame_of[inliers].min(), frame_of.max()
        for i in range(lo + 1, hi + 1):
            c2, in2, cost2 = _robust_fit(times(gaps + [i])[frame_of], points, obs, frame_of, geometry,
                                          inliers)
            if c2 is not None and in2.sum() >= inliers.sum() and (best is None or cost2 < best[2]):
                best = (i, c2, cost2, in2)
        if best is None or best[2] > GAP_GAIN * cost:
            break
        gaps.append(best[0])
        coef, cost, inliers = best[1], best[2], best[3]
    t_all = times(gaps)
    t = t_all[frame_of]
    # The flight: from the first to the last detection on the trajectory. Every detection in it is judged
    # against the trajectory; gross outliers are dropped and the fit is redone once.
    span = (frame_of >= frame_of[inliers].min()) & (frame_of <= frame_of[inliers].max())
    coef = fit_ballistic(t[inliers], points[inliers])
    e = pixel_residual(geometry, evaluate_fit(coef, t), obs)
    limit = max(OUTLIER_MIN_PX, OUTLIER_MEDIANS * float(np.median(e[inliers])))
    keep = span & (e <= limit)
    if keep.sum() < 6:
        raise FootageError("only %d detections agree with the ballistic fit" % keep.sum())
    coef = fit_ballistic(t[keep], points[keep])
    fitted = evaluate_fit(coef, t)
    res3 = np.linalg.norm(points - fitted, axis=1)
    e = pixel_residual(geometry, fitted, obs)
    first, last = frame_of[keep].min(), frame_of[keep].max()
    frames = np.arange(first, last + 1)
    ref = evaluate_fit(coef, t_all[frames])
    # The ball's metric radius, measured: apparent radius x depth / focal length over the kept detections.
    radius_m = float(np.median(radius_px[keep] * points[keep, 2] / geometry.fx))
    return {
        "times": t_all, "captures": captures(gaps).astype(int), "coef": coef, "frames": frames, "points": ref,
        "radius_m": radius_m,
        "kept": frame_of[keep], "dropped": frame_of[span & ~keep], "off_trajectory": frame_of[~span],
        "gaps": [int(numbers[i]) for i in gaps], "outlier_limit_px": limit,
        "residual_m": float(np.sqrt(np.mean(res3[keep] ** 2))),
        "residual_px": float(np.sqrt(np.mean(e[keep] ** 2))),
        "acceleration": (2.0 * coef[2]).tolist(), "velocity0": coef[1].tolist(),
        "detections": {int(f): (obs[k].tolist(), points[k].tolist()) for k, f in enumerate(frame_of)},
    }


def roi_of(geometry, point, radius_m):
    """Bounding box [x, y, w, h] of the ball's projection in the left image, clipped to it (None if outside)."""
    ul, v, _ = geometry.project(point)
    r = geometry.fx * radius_m / point[2]
    x0, y0 = max(0, int(math.floor(ul[0] - r))), max(0, int(math.floor(v[0] - r)))
    x1 = min(geometry.width, int(math.ceil(ul[0] + r)) + 1)
    y1 = min(geometry.height, int(math.ceil(v[0] + r)) + 1)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return [x0, y0, x1 - x0, y1 - y0]


# ---------------------------------------------------------------------------------------------------------
# Bags


def camera_info(geometry, right, header):
    from sensor_msgs.msg import CameraInfo
    g = geometry
    info = CameraInfo()
    info.header = header
    info.width, info.height = g.width, g.height
    info.distortion_model = "plumb_bob"
    info.D = [0.0] * 5
    info.K = [g.fx, 0.0, g.cx, 0.0, g.fy, g.cy, 0.0, 0.0, 1.0]
    info.R = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    info.P = [g.fx, 0.0, g.cx, -g.fx * g.baseline if right else 0.0, 0.0, g.fy, g.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return info


def stamps_ns(captures, fps):
    """Integer nanosecond stamps of frames `captures` capture periods after the first, as make_scene rounds
    them (once, so that they neither drift nor depend on float summation)."""
    return [EPOCH_NS + int(round(int(c) * 1e9 / fps)) for c in captures]


def write_bag(path, lefts, rights, geometry, stamps, reference=None):
    """A bag as make_scene writes one, from rectified mono8 images: camera1394stereo's four topics with one
    frame_id and identical stamps (bag time = stamp), and, per frame, ground_truth/target_visible; on the
    frames with a reference also ground_truth/target (left rectified optical frame, m) and target_roi.

    stamps: integer nanoseconds per frame (see stamps_ns).
    reference: {frame index: ([x, y, z], [x, y, w, h] or None)}."""
    import genpy
    import rosbag
    from geometry_msgs.msg import PointStamped
    from sensor_msgs.msg import Image, RegionOfInterest
    from std_msgs.msg import Bool, Header
    reference = reference or {}
    with rosbag.Bag(path, "w") as bag:
        for k, (left, right, stamp) in enumerate(zip(lefts, rights, stamps)):
            time = genpy.Time(int(stamp) // 10**9, int(stamp) % 10**9)
            header = Header(seq=k, stamp=time, frame_id=FRAME_ID)
            for image, topic in ((left, TOPICS["left_image"]), (right, TOPICS["right_image"])):
                msg = Image(header=header, height=image.shape[0], width=image.shape[1], encoding="mono8",
                            is_bigendian=0, step=image.shape[1], data=np.ascontiguousarray(image).tobytes())
                bag.write(topic, msg, time)
            bag.write(TOPICS["left_info"], camera_info(geometry, False, header), time)
            bag.write(TOPICS["right_info"], camera_info(geometry, True, header), time)
            entry = reference.get(k)
            if entry is not None:
                point, roi = entry
                msg = PointStamped(header=header)
                msg.point.x, msg.point.y, msg.point.z = (float(c) for c in point)
                bag.write(TOPICS["truth"], msg, time)
                if roi is not None:
                    bag.write(TOPICS["roi"], RegionOfInterest(x_offset=roi[0], y_offset=roi[1], width=roi[2],
                                                              height=roi[3], do_rectify=False), time)
            bag.write(TOPICS["visible"], Bool(data=entry is not None), time)


def read_truth(bag_path):
    """{stamp (s): (x, y, z)} of a bag's ground_truth/target."""
    import rosbag
    out = {}
    with rosbag.Bag(bag_path) as bag:
        for _, msg, _ in bag.read_messages(topics=[TOPICS["truth"], "/" + TOPICS["truth"]]):
            out[msg.header.stamp.to_sec()] = (msg.point.x, msg.point.y, msg.point.z)
    return out


# ---------------------------------------------------------------------------------------------------------
# Evaluation of a track_bag CSV against a bag's reference


def evaluate(bag_path, csv_path):
    """Compare track_bag's CSV (--output) with the bag's reference (ground_truth/target).

    Over the frames that have both a reference and a CSV row (track_bag writes rows from its target frame on):
    `frames` (such frames), `estimated` (with a 3D estimate), `missing` (without one), `rms_m` (3D RMS error
    over the estimated ones; None if none), `max_m`, `mean_range_m` (mean distance of the reference from the
    left camera over those frames), `rms_pct` (rms_m as % of mean_range_m), plus `rows` (CSV rows)."""
    import csv as csvlib
    for path in (bag_path, csv_path):
        if not os.path.isfile(path):
            raise FootageError("no file '%s'" % path)
    truth = read_truth(bag_path)
    if not truth:
        raise FootageError("'%s' has no %s messages" % (bag_path, TOPICS["truth"]))
    stamps = np.array(sorted(truth))
    rows = 0
    errors, ranges, missing = [], [], 0
    with open(csv_path, newline="") as f:
        reader = csvlib.DictReader(f)
        for field in ("stamp", "x", "y", "z"):
            if field not in (reader.fieldnames or []):
                raise FootageError("'%s' is not a track_bag CSV: no column '%s' (has %s)" % (
                    csv_path, field, reader.fieldnames))
        for row in reader:
            rows += 1
            stamp = float(row["stamp"])
            k = int(np.argmin(np.abs(stamps - stamp)))
            if abs(stamps[k] - stamp) > 1e-3:   # the CSV prints 9 significant digits: 10 us at 1000 s
                continue
            ref = np.array(truth[stamps[k]])
            ranges.append(float(np.linalg.norm(ref)))
            if row["x"] == "" or row["y"] == "" or row["z"] == "":
                missing += 1
                continue
            est = np.array([float(row["x"]), float(row["y"]), float(row["z"])])
            errors.append(float(np.linalg.norm(est - ref)))
    n = len(ranges)
    rms = float(np.sqrt(np.mean(np.square(errors)))) if errors else None
    mean_range = float(np.mean(ranges)) if ranges else None
    return {"rows": rows, "frames": n, "estimated": len(errors), "missing": missing, "rms_m": rms,
            "max_m": float(max(errors)) if errors else None, "mean_range_m": mean_range,
            "rms_pct": 100.0 * rms / mean_range if rms is not None and mean_range else None}
