#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Feed the tracker nodelet every kind of bad input, one at a time, and print what it did as a markdown table.

Starts tracker.launch (manager + TrackerNodelet, config/tracker.yaml) on a master of its own, teaches it the
target on a make_scene pendulum bag and keeps it tracking with good frames at 30 Hz. For each case of
test/stereo_feed.py's bad_variants(): 30 good frames, the bad stereo set, 30 good frames. A row says what was
fed, the outcome (which diagnostics counter rose: dropped and why, an unpaired set, or accepted and tracked,
with the state and support ~status gave that frame; whether tracking went on, from the error of the last good
frames against the ground truth) and the message the tracker logged (its warnings and errors while the case
ran; else the diagnostics' "last drop").

usage: source build/devel/setup.bash
       test/bad_input_table.py [--bag BAG] [--write docs/ros_runtime.md]
  --write replaces the table between the markers "<!-- bad-input table -->" and "<!-- end of bad-input table -->"
  in that file; without it the table goes to standard output.
"""
import argparse
import datetime
import os
import re
import subprocess
import sys
import time

import rospy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import stereo_feed  # noqa: E402

BEGIN, END = "<!-- bad-input table -->", "<!-- end of bad-input table -->"
COUNTERS = ("dropped: bad image", "dropped: size mismatch", "dropped: bad camera_info", "dropped: out of sync",
            "dropped: out of order", "dropped: processing error", "dropped: no target", "unpaired stereo sets")


def cell(text):
    return text.replace("|", "\\|").replace("\n", " ")


def counters(feed):
    diag, _, _ = feed.diagnostics()
    values = {k: int(diag.get(k, 0)) for k in COUNTERS}
    values["frames tracked"] = int(diag.get("frames tracked", 0))
    values["frames received"] = int(diag.get("frames received", 0))
    return values, diag


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bag", default=os.path.join(HERE, "..", "build", "test_data", "pendulum_uncluttered_90.bag"))
    parser.add_argument("--write", default="", help="markdown file whose table to replace")
    parser.add_argument("--rate", type=float, default=30.0)
    args = parser.parse_args()

    frames = stereo_feed.load_frames(args.bag, limit=60)  # one swing: loops seamlessly
    cases = stereo_feed.bad_variants(frames[0])
    tracker = stereo_feed.Tracker(extra_params={"diagnostic_period": 0.1})
    rows = []
    try:
        tracker.wait_ready()
        rospy.init_node("bad_input_table", anonymous=True, disable_signals=True)
        feed = stereo_feed.Feed(frames)
        feed.wait_connected()
        feed.teach()
        k = 0

        def good(n):
            nonlocal k
            stamps = []
            for _ in range(n):
                stamps.append(feed.publish_frame(k))
                k += 1
                time.sleep(1.0 / args.rate)
            return stamps

        good(60)
        for name, fed, msgs, offsets in cases:
            good(30)
            time.sleep(0.3)
            before, _ = counters(feed)
            t_case = time.time()
            stamp = feed.publish(msgs, offsets=offsets)
            time.sleep(1.0 / args.rate)
            after_stamps = good(30)
            time.sleep(0.4)
            after, diag = counters(feed)
            rose = [key for key in COUNTERS if after[key] > before[key]]
            tracked_extra = (after["frames tracked"] - before["frames tracked"]) - \
                sum(1 for s in after_stamps if feed.answered(s))
            errors = [feed.error(s) for s in after_stamps[-10:]]
            errors_cm = [100 * e for e in errors if e is not None]
            alive = tracker.alive()

            if not alive:
                outcome = "**the tracker crashed**"
            elif rose:
                outcome = "; ".join(r if r.startswith("unpaired") else r.replace("dropped: ", "dropped (") + ")"
                                    for r in rose)
                if "unpaired stereo sets" in rose:
                    outcome = outcome.replace("unpaired stereo sets", "never paired: counted as an unpaired set")
            elif offsets != "repeat" and feed.answered(stamp) or tracked_extra > 0:
                outcome = "accepted and tracked"
                # What the tracker said about that frame: one frame without evidence is not yet lost
                # (engine/lost_frames), and the support shows it.
                shift = offsets.get("left", 0.0) if isinstance(offsets, dict) else 0.0
                status = feed.status_of(stamp + rospy.Duration.from_sec(shift))
                if status is not None:
                    outcome += " (`~status`: %s, support: %s)" % status
            else:
                outcome = "no effect seen (neither dropped nor tracked)"
            if alive:
                if len(errors_cm) == 10 and max(errors_cm) < 5.0:
                    outcome += "; tracking went on (error %.1f cm)" % stereo_feed.percentile(errors_cm, 0.5)
                else:
                    outcome += "; next 30 good frames: %d estimates, state %s" % (
                        len([e for e in errors if e is not None]), diag.get("track state", "?"))

            logged = []
            for level, text in feed.log_since(t_case):
                if text not in logged and "no target" not in text:
                    logged.append(text)
            if logged:
                message = " / ".join("`%s`" % t for t in logged)
            elif rose and not rose == ["unpaired stereo sets"]:
                message = "(no new log line: warnings are throttled per reason) diagnostics: `%s`" % diag.get(
                    "last drop", "")
            else:
                message = "none"
            rows.append((name, fed, outcome, message))
            print("%-32s %s" % (name, outcome), file=sys.stderr, flush=True)
    finally:
        tracker.stop()
        rospy.signal_shutdown("done")

    commit = subprocess.run(["git", "-C", HERE, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    lines = [BEGIN,
             "Generated by `test/bad_input_table.py` on %s (commit %s): each bad stereo set sent between 30 good "
             "frames at 30 Hz into `tracker.launch` with `config/tracker.yaml`." % (
                 datetime.date.today().isoformat(), commit or "?"),
             "",
             "| case | what was fed | outcome | message |",
             "|---|---|---|---|"]
    lines += ["| %s |" % " | ".join(cell(c) for c in row) for row in rows]
    lines.append(END)
    table = "\n".join(lines)
    if args.write:
        with open(args.write) as f:
            text = f.read()
        if BEGIN not in text or END not in text:
            print("%s has no '%s' ... '%s' markers" % (args.write, BEGIN, END), file=sys.stderr)
            return 1
        text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda m: table, text, flags=re.S)
        with open(args.write, "w") as f:
            f.write(text)
        print("wrote the table (%d cases) into %s" % (len(rows), args.write), file=sys.stderr)
    else:
        print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
