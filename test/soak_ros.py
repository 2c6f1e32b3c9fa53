#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Soak test of the tracker nodelet: good frames at 30 Hz with bad input mixed in, for a fixed duration.

Starts tracker.launch (nodelet manager + TrackerNodelet, config/tracker.yaml) on a master of its own and plays
one swing (60 frames, 2 s: it loops seamlessly) of a make_scene pendulum bag into it, each frame with a fresh
stamp. Every 10 s cycle: 5 s of good frames, 2 s in which every other frame is bad, 1 s of bad frames only, 2 s
of good frames. The bad frames go through every case of test/stereo_feed.py's bad_variants() (wrong
encodings, truncated data, size mismatches, camera_info without size or with NaN/inf, unsynchronised,
repeated and backward stamps, black images).

Checks (exit status 1 and a FAIL line for each that does not hold):
  - the manager process is alive at the end and answered the last good frames (no crash, no hang);
  - after every bad-only burst tracking resumes: within 30 good frames, 10 consecutive estimates within 5 cm
    of the ground truth of their frame;
  - the bad frames are counted: bad image, size mismatch, bad camera_info and out of order drops and unpaired sets
    all rise;
  - the manager's resident memory grows less than --rss-limit MB from the end of the first cycle (by then every
    kind of bad input has been seen once) to the end.
Prints ~target rate and latency (publish -> ~target received here) for the first and the last cycle, and the
manager's RSS over time. Timings are the machine's: printed, not checked.

usage: source build/devel/setup.bash
       test/soak_ros.py [--bag BAG] [--duration 60] [--rss-limit 10]   (--duration 600: the 10-minute soak)
"""
import argparse
import os
import sys
import time

import rospy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import stereo_feed  # noqa: E402

CYCLE = 300            # frames per cycle (10 s at 30 Hz)
GOOD_UNTIL = 150       # frames [0, 150): good
MIXED_UNTIL = 210      # [150, 210): every other frame bad
BAD_UNTIL = 240        # [210, 240): bad only; then good again
RESUME_WITHIN = 30     # good frames after the bad-only burst
RESUME_RUN = 10        # consecutive estimates within RESUME_CM
RESUME_CM = 5.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bag", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build",
                                                      "test_data", "pendulum_uncluttered_90.bag"),
                        help="make_scene bag of pendulum_uncluttered, at least 60 frames (default: the rostests')")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds after warm-up (whole cycles of 10 s)")
    parser.add_argument("--rate", type=float, default=30.0, help="frames per second")
    parser.add_argument("--rss-limit", type=float, default=10.0, help="MB of RSS growth allowed after cycle 1")
    parser.add_argument("--log", default="", help="write the launch's output here")
    args = parser.parse_args()

    frames = stereo_feed.load_frames(args.bag, limit=60)
    if len(frames) < 60:
        print("FAIL: the bag has %d frames, the soak needs 60 (one swing)" % len(frames))
        return 1
    bad_cases = [c for f in frames[:1] for c in stereo_feed.bad_variants(f)]
    cycles = max(1, int(round(args.duration / (CYCLE / args.rate))))

    tracker = stereo_feed.Tracker(extra_params={"diagnostic_period": 0.5}, log_path=args.log or None)
    failures = []
    try:
        pid = tracker.wait_ready()
        rospy.init_node("soak", anonymous=True, disable_signals=True)
        feed = stereo_feed.Feed(frames)
        feed.wait_connected()
        feed.teach()
        period = 1.0 / args.rate
        next_tick = time.time()
        k = 0

        def tick():
            nonlocal next_tick
            next_tick += period
            delay = next_tick - time.time()
            if delay > 0:
                time.sleep(delay)
            else:
                next_tick = time.time()  # late: do not try to catch up with a burst

        # Warm-up: 5 s of good frames; the target is learned from the first one.
        for _ in range(int(5 * args.rate)):
            feed.publish_frame(k)
            k += 1
            tick()
        time.sleep(0.3)

        t0 = time.time()
        rss = [(0.0, stereo_feed.rss_mb(pid))]
        windows = []        # per cycle: (targets received, good frames sent, latencies)
        bad_index = 0
        good_stamps = []
        for cycle in range(cycles):
            cycle_stamps, resume_stamps = [], []
            cycle_start = time.time()
            for i in range(CYCLE):
                bad = (GOOD_UNTIL <= i < MIXED_UNTIL and i % 2 == 1) or MIXED_UNTIL <= i < BAD_UNTIL
                if bad:
                    _, _, msgs, offsets = bad_cases[bad_index % len(bad_cases)]
                    bad_index += 1
                    feed.publish(msgs, offsets=offsets)
                else:
                    stamp = feed.publish_frame(k)
                    k += 1
                    cycle_stamps.append(stamp)
                    if i >= BAD_UNTIL:
                        resume_stamps.append(stamp)
                if i % int(5 * args.rate) == 0 and i > 0:
                    rss.append((time.time() - t0, stereo_feed.rss_mb(pid)))
                tick()
            rss.append((time.time() - t0, stereo_feed.rss_mb(pid)))
            time.sleep(0.2)  # the last answers

            answered = [s for s in cycle_stamps if feed.answered(s)]
            with feed.lock:
                latencies = [feed.latency_ms[s.to_nsec()] for s in answered if s.to_nsec() in feed.latency_ms]
            windows.append((len(answered), len(cycle_stamps), latencies,
                            feed.targets_between(cycle_start, time.time()) / (time.time() - cycle_start)))
            good_stamps = cycle_stamps

            # Tracking resumes after the bad-only burst.
            run, resumed_at = 0, None
            for j, s in enumerate(resume_stamps[:RESUME_WITHIN]):
                e = feed.error(s)
                run = run + 1 if e is not None and e * 100 < RESUME_CM else 0
                if run >= RESUME_RUN:
                    resumed_at = j + 1 - RESUME_RUN
                    break
            errors = [feed.error(s) for s in resume_stamps]
            errors_cm = [100 * e for e in errors if e is not None]
            print("cycle %2d: t=%5.0f s  ~target for %d of %d good frames, latency median %.1f ms p95 %.1f ms, "
                  "RSS %.1f MB, after the burst: %s, error median %.2f cm" % (
                      cycle + 1, time.time() - t0, len(answered), len(cycle_stamps),
                      stereo_feed.percentile(latencies, 0.5), stereo_feed.percentile(latencies, 0.95), rss[-1][1],
                      "tracking from good frame %d" % (resumed_at + 1) if resumed_at is not None else "NOT RESUMED",
                      stereo_feed.percentile(errors_cm, 0.5)), flush=True)
            if resumed_at is None:
                # What the tracker said about each of those frames: the reason is in the states.
                print("  after the burst, per good frame (state/support error cm): " + "; ".join(
                    "%s/%s %s" % ((feed.status_of(s) or ("-", "-")) + ("%.1f" % (100 * e) if e is not None else "-",))
                    for s, e in zip(resume_stamps[:RESUME_WITHIN], errors[:RESUME_WITHIN])), flush=True)
                failures.append("cycle %d: no %d consecutive estimates within %.0f cm in the first %d good frames "
                                "after the bad-only burst" % (cycle + 1, RESUME_RUN, RESUME_CM, RESUME_WITHIN))
            if not tracker.alive():
                failures.append("cycle %d: the tracker's manager is gone (crash)" % (cycle + 1))
                break

        time.sleep(1.2)  # one more diagnostics period
        diag, level, message = feed.diagnostics()
        if not tracker.alive():
            if not any("crash" in f for f in failures):
                failures.append("the tracker's manager is gone (crash)")
        elif good_stamps and not any(feed.answered(s) for s in good_stamps[-10:]):
            failures.append("no ~target for the last 10 good frames (hung?)")
        for key in ("dropped: bad image", "dropped: size mismatch", "dropped: bad camera_info", "dropped: out of order",
                    "unpaired stereo sets"):
            if int(diag.get(key, "0")) <= 0:
                failures.append("diagnostics '%s' is %s after %d bad frames" % (key, diag.get(key, "missing"),
                                                                                 bad_index))
        reference = next((m for t, m in rss if t >= (CYCLE / args.rate) - 1.0), rss[-1][1])
        growth = max(m for _, m in rss) - reference
        if growth >= args.rss_limit:
            failures.append("RSS grew %.1f MB after the first cycle (limit %.1f MB)" % (growth, args.rss_limit))

        first, last = windows[0], windows[-1]
        span = CYCLE / args.rate
        print("\n== soak: %d cycles, %.0f s, %d bad frames of %d kinds ==" % (len(windows), time.time() - t0, bad_index,
                                                                             len(bad_cases)))
        for name, (n, sent, lat, rate) in (("first cycle", first), ("last cycle", last)):
            print("%-11s: ~target %.1f Hz (frames sent: %.0f/s, %.0f/s of them good), %d of %d good frames answered; "
                  "latency publish -> ~target received: median %.1f ms, p95 %.1f ms, max %.1f ms" % (
                      name, rate, args.rate, sent / span, n, sent, stereo_feed.percentile(lat, 0.5),
                      stereo_feed.percentile(lat, 0.95), stereo_feed.percentile(lat, 1.0)))
        print("manager RSS (s: MB): " + ", ".join("%.0f: %.1f" % (t, m) for t, m in rss))
        print("RSS growth after the first cycle: %+.1f MB (limit %.1f)" % (growth, args.rss_limit))
        print("diagnostics: %s; dropped %s (bad image %s, size mismatch %s, bad camera_info %s, out of sync %s, "
              "out of order %s), unpaired %s, processing median %s ms, latency median %s ms; last drop: %s" % (
                  message, diag.get("dropped frames"), diag.get("dropped: bad image"),
                  diag.get("dropped: size mismatch"), diag.get("dropped: bad camera_info"),
                  diag.get("dropped: out of sync"), diag.get("dropped: out of order"), diag.get("unpaired stereo sets"),
                  diag.get("processing time median (ms)"), diag.get("latency from arrival median (ms)"),
                  diag.get("last drop")))
    except Exception as e:  # a failure to start is a failure, with the reason
        failures.append("%s: %s" % (type(e).__name__, e))
    finally:
        tracker.stop()
        rospy.signal_shutdown("done")

    for f in failures:
        print("FAIL: " + f)
    print("soak: %s" % ("passed" if not failures else "FAILED (%d)" % len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
