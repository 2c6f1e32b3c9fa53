#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""The extension path a user takes: examples/my_cues, a catkin package of its own with one ObservationModel, built
as an overlay and loaded by track_bag through pluginlib.

(a) against the devel space: the overlay is configured and built with stereo_pf's devel setup.bash sourced; with the
    overlay's setup.bash sourced, track_bag tracks the default scene with the example's config (ColourHSI, the
    example cue, ColourContour) and with the example cue alone, and the target file it saves holds the cue's entry
    and loads back. Without the overlay the same config fails with the unknown-type error and its hint.
(b) against an install prefix: stereo_pf's build tree installed (`make install`'s install step), staged with DESTDIR
    in a fresh directory. Only public headers are there, each compiles on its own with what stereo_pf exports, and
    the example is built against that prefix alone (no devel space in the environment), installed into a prefix of
    its own, and loaded by the installed track_bag.

Registered with ctest as test_cue_overlay; arguments: --source DIR (stereo_pf's source) --build DIR (its build tree)
--devel DIR (its devel space) --out DIR (scratch directory, emptied first)."""
import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import time

SCENE = "pendulum_uncluttered"  # the bundled default (scripts/demo)
FRAMES = 60
CUE_TYPE = "my_cues/MeanColour"


class Failure(Exception):
    pass


def clean_env(out):
    """The environment of a fresh shell: no ROS workspace sourced (Debian's ROS needs none), nothing of ours on
    any path; rospack's cache in a directory of its own."""
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp"), "LANG": "C.UTF-8",
           "ROS_HOME": os.path.join(out, "ros_home")}
    return env


def sh(script, env, what, log):
    """Run a bash script; on failure raise with its output. Returns stdout + stderr."""
    started = time.time()
    p = subprocess.run(["bash", "-c", "set -eo pipefail\n" + script], env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, universal_newlines=True)
    log.write("### %s (%.1f s, exit %d)\n%s\n%s\n" % (what, time.time() - started, p.returncode, script, p.stdout))
    log.flush()
    if p.returncode != 0:
        raise Failure("%s failed (exit %d):\n%s\n--- output (last 60 lines) ---\n%s" %
                      (what, p.returncode, script, "\n".join(p.stdout.splitlines()[-60:])))
    return p.stdout


def summary(output, what):
    """The key=value pairs of track_bag's summary line."""
    m = re.search(r"^summary: (.*)$", output, re.M)
    if not m:
        raise Failure("%s: no summary line in track_bag's output:\n%s" % (what, output))
    return dict(item.split("=", 1) for item in m.group(1).split())


def check_tracked(output, what, max_rms_cm, max_converged=10):
    """track_bag's summary says it converged (error below 5 cm for 10 frames) by frame `max_converged` and kept the
    RMS error after that within `max_rms_cm`."""
    s = summary(output, what)
    converged = int(s["converged_at"])
    rms = float(s.get("rms_cm", "inf"))
    if converged < 0 or converged > max_converged or not rms <= max_rms_cm:
        raise Failure("%s: tracking did not run as expected (converged_at=%d, want 0..%d; rms_cm=%.2f, want <= %.1f):"
                      "\n%s" % (what, converged, max_converged, rms, max_rms_cm, output))
    return s


def check_target_file(path, what):
    """The target file track_bag --save-target wrote holds the example cue's entry, written by its saveTarget()."""
    with open(path) as f:
        text = f.read()
    m = re.search(r"^mean_colour:\s*\n((?:[ \t]+.*\n)+)", text, re.M)
    if not m or CUE_TYPE not in m.group(1) or "mean_bgr" not in m.group(1):
        raise Failure("%s: the target file %s has no 'mean_colour' entry of type %s with its mean_bgr:\n%s" %
                      (what, path, CUE_TYPE, text))


def build_overlay(src, build, env_setup, env, log, what, cmake_args, install=False):
    """Configure and build (and install) examples/my_cues in `build` with `env_setup` sourced; -Werror so that
    warnings from stereo_pf's public headers in a user's build are errors here."""
    return sh("%s\ncmake -S %s -B %s -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_CXX_FLAGS=-Werror %s\n"
              "make -C %s -j2 %s" % (env_setup, src, build, cmake_args, build, "install" if install else ""),
              env, what, log)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", required=True)
    ap.add_argument("--build", required=True)
    ap.add_argument("--devel", required=True)
    ap.add_argument("--out", required=True)
    o = ap.parse_args()
    source, build, devel, out = (os.path.abspath(p) for p in (o.source, o.build, o.devel, o.out))
    example = os.path.join(source, "examples", "my_cues")
    example_config = os.path.join(example, "config", "mean_colour.yaml")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(os.path.join(out, "ros_home"))
    env = clean_env(out)
    log_path = os.path.join(out, "log.txt")
    log = open(log_path, "w")
    started = time.time()
    print("test_cue_overlay: commands and their output in %s" % log_path)

    # Only our own package's build may see the example: the main build must not have built or registered it.
    if glob.glob(os.path.join(devel, "lib", "libmy_cues*")) or os.path.exists(os.path.join(devel, "share", "my_cues")):
        raise Failure("the main build built or registered examples/my_cues: it must stay a package of its own")

    devel_setup = "source %s/setup.bash" % devel
    bag = os.path.join(out, "%s_%d.bag" % (SCENE, FRAMES))
    sh("%s\n%s/lib/stereo_pf/make_scene %s/scenes/%s.yaml %s --frames %d --quiet" %
       (devel_setup, devel, source, SCENE, bag, FRAMES), env, "make_scene", log)
    cue_alone = os.path.join(out, "mean_colour_alone.yaml")
    with open(cue_alone, "w") as f:
        f.write("observation_models:\n  - {name: mean_colour, type: %s}\n" % CUE_TYPE)

    # --- (a) overlay on the devel space -------------------------------------------------------------------------
    overlay = os.path.join(out, "devel_overlay")
    build_overlay(example, os.path.join(overlay, "build"), devel_setup, env, log, "(a) building my_cues on the devel space",
                  "-DCATKIN_DEVEL_PREFIX=%s/devel" % overlay)
    overlay_setup = "source %s/devel/setup.bash" % overlay
    track_bag = "%s/lib/stereo_pf/track_bag" % devel
    found = sh("%s\nrospack find my_cues\nrospack find stereo_pf" % overlay_setup, env, "(a) rospack", log).split()
    if found[0] != example:
        raise Failure("(a) rospack finds my_cues at %s, expected the example's source %s" % (found[0], example))
    target = os.path.join(out, "devel_target.yml")
    run = sh("%s\n%s %s --config %s --seed 1 --quiet --save-target %s --output %s/devel.csv" %
             (overlay_setup, track_bag, bag, example_config, target, out), env, "(a) track_bag with my_cues", log)
    s = check_tracked(run, "(a) the example config", 2.0)
    check_target_file(target, "(a)")
    run = sh("%s\n%s %s --config %s --seed 1 --quiet --target-model %s" %
             (overlay_setup, track_bag, bag, example_config, target), env, "(a) track_bag --target-model", log)
    check_tracked(run, "(a) the example config from the saved target (loadTarget)", 2.0)
    alone = sh("%s\n%s %s --config %s --seed 1 --quiet" % (overlay_setup, track_bag, bag, cue_alone), env,
               "(a) track_bag with MeanColour alone", log)
    # Alone the mean colour pins the ball's place but hardly its depth (a window inside the ball fits at several):
    # slower and looser, but it tracks. At weight 0 (no likelihood) the same run never converges.
    s_alone = check_tracked(alone, "(a) MeanColour as the only cue", 6.0, 30)
    blind = summary(sh("%s\n%s %s --config %s --seed 1 --quiet --set mean_colour/weight=0" %
                       (overlay_setup, track_bag, bag, cue_alone), env, "(a) MeanColour alone at weight 0", log),
                    "(a) weight 0")
    if int(blind["converged_at"]) >= 0:
        raise Failure("(a) with MeanColour alone at weight 0 the run converged (at %s): the check above would not "
                      "show that the cue's likelihood tracks" % blind["converged_at"])
    # Without the overlay the type is unknown, and the error says where to look.
    p = subprocess.run(["bash", "-c", "%s\n%s %s --config %s --quiet" % (devel_setup, track_bag, bag, example_config)],
                       env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    log.write("### (a) without the overlay (exit %d)\n%s\n" % (p.returncode, p.stdout))
    if p.returncode == 0 or "unknown type '%s'" % CUE_TYPE not in p.stdout or "<export>" not in p.stdout \
            or "ROS_PACKAGE_PATH" not in p.stdout:
        raise Failure("(a) without the overlay, track_bag should fail with the unknown-type error and its hint "
                      "(<export>, ROS_PACKAGE_PATH); exit %d, output:\n%s" % (p.returncode, p.stdout))
    print("(a) devel overlay: built, loaded; %d frames of %s, seed 1: with ColourHSI + ColourContour rms_cm=%s, "
          "alone converged_at=%s rms_cm=%s (never at weight 0); unknown without the overlay, with the hint" %
          (FRAMES, SCENE, s["rms_cm"], s_alone["converged_at"], s_alone["rms_cm"]))

    # --- (b) overlay on an install prefix --------------------------------------------------------------------------
    # The install step of `make install` (cmake --install: without make's rebuild of `all`, so the test installs
    # what the other tests ran), staged under DESTDIR: the build tree's install prefix (CMAKE_INSTALL_PREFIX,
    # /usr/local by default) is not ours to write to, and cmake --install --prefix would not do: catkin installs
    # its setup files to the prefix configured, whatever the prefix given at install time. Everything lands in
    # <stage><prefix>; catkin's setup.bash and the package's CMake config find their files relative to themselves.
    configured = re.search(r"^CMAKE_INSTALL_PREFIX:PATH=(.*)$", open(os.path.join(build, "CMakeCache.txt")).read(), re.M)
    if not configured or not os.path.isabs(configured.group(1)):
        raise Failure("(b) no absolute CMAKE_INSTALL_PREFIX in %s/CMakeCache.txt" % build)
    stage = os.path.join(out, "stage")
    prefix = os.path.normpath(stage + "/" + configured.group(1))
    sh("DESTDIR=%s cmake --install %s" % (stage, build), env, "(b) installing stereo_pf (staged)", log)
    outside = [f for f in glob.glob(stage + "/**", recursive=True) if os.path.isfile(f) and not f.startswith(prefix + "/")]
    if outside:
        raise Failure("(b) make install wrote outside the install prefix %s: %s" % (configured.group(1), outside[:5]))
    inc = os.path.join(prefix, "include", "stereo_pf")
    for h in ("observation_model.h", "state_model.h", "core/engine.h", "core/feature_cache.h",
              "plugins/colour_hsi.h", "plugins/stereo_coupling.h", "TrackStatus.h"):
        if not os.path.isfile(os.path.join(inc, h)):
            raise Failure("(b) the public header %s is not installed under %s" % (h, inc))
    for h in ("ros/stereo_input.h", "sim/scene.h", "sim/scene_sensor.h", "eval/evaluation.h", "eval/baseline_tracker.h"):
        if os.path.exists(os.path.join(inc, h)):
            raise Failure("(b) the private header %s is installed under %s" % (h, inc))
    install_setup = "source %s/setup.bash" % prefix
    ex_prefix = os.path.join(out, "my_cues_prefix")
    ex_build = os.path.join(out, "install_overlay")
    build_overlay(example, ex_build, install_setup, env, log, "(b) building and installing my_cues on the install prefix",
                  "-DCATKIN_DEVEL_PREFIX=%s/devel -DCMAKE_INSTALL_PREFIX=%s" % (ex_build, ex_prefix), install=True)
    # It must have compiled against the installed headers and linked the installed libraries, not the build tree's.
    flags = open(os.path.join(ex_build, "CMakeFiles", "my_cues.dir", "flags.make")).read()
    link = open(os.path.join(ex_build, "CMakeFiles", "my_cues.dir", "link.txt")).read()
    includes = [a or b for a, b in re.findall(r"-I(\S+)|-isystem (\S+)", flags)]
    if os.path.join(prefix, "include") not in includes or os.path.join(source, "include") in includes or \
            any(i.startswith(devel) for i in includes):
        raise Failure("(b) my_cues did not compile against the installed headers only: %s" % includes)
    if os.path.join(prefix, "lib", "libstereo_pf_core.so") not in link or \
            os.path.join(prefix, "lib", "libstereo_pf_plugins.so") not in link or devel in link:
        raise Failure("(b) my_cues did not link the installed stereo_pf_core and stereo_pf_plugins:\n%s" % link)
    ex_setup = "source %s/setup.bash" % ex_prefix
    found = sh("%s\nrospack find my_cues\nrospack find stereo_pf\nldd %s/lib/libmy_cues.so" % (ex_setup, ex_prefix),
               env, "(b) rospack, ldd", log)
    lines = found.splitlines()
    if lines[0] != os.path.join(ex_prefix, "share", "my_cues") or lines[1] != os.path.join(prefix, "share", "stereo_pf"):
        raise Failure("(b) rospack finds my_cues at %s and stereo_pf at %s, expected the two prefixes" % tuple(lines[:2]))
    core = [l for l in lines if "libstereo_pf_core.so" in l]
    if not core or os.path.join(prefix, "lib") not in core[0]:
        raise Failure("(b) libmy_cues.so does not load stereo_pf_core from the install prefix:\n%s" % found)
    target = os.path.join(out, "install_target.yml")
    run = sh("%s\n%s/lib/stereo_pf/track_bag %s --config %s/share/my_cues/config/mean_colour.yaml --seed 1 --quiet "
             "--save-target %s --output %s/install.csv" % (ex_setup, prefix, bag, ex_prefix, target, out),
             env, "(b) installed track_bag with the installed my_cues", log)
    s_b = check_tracked(run, "(b) the example config", 2.0)
    check_target_file(target, "(b)")
    # Same plugins, same bag, same seed: the same figures as from the devel space.
    if s_b["rms_cm"] != s["rms_cm"] or s_b["converged_at"] != s["converged_at"]:
        raise Failure("(b) the installed run gives rms_cm=%s converged_at=%s, the devel one rms_cm=%s converged_at=%s" %
                      (s_b["rms_cm"], s_b["converged_at"], s["rms_cm"], s["converged_at"]))
    # Every installed header of ours compiles on its own with only what find_package(catkin COMPONENTS stereo_pf)
    # exports: none includes a header that is not installed, none needs an include directory that is not exported.
    # (The message headers genmsg generates are its to keep so.)
    headers = sorted(h for h in (os.path.relpath(p, os.path.join(prefix, "include"))
                                 for p in glob.glob(os.path.join(inc, "**", "*.h"), recursive=True))
                     if os.path.isfile(os.path.join(source, "include", h)))
    check = os.path.join(out, "header_check")
    os.makedirs(os.path.join(check, "tu"))
    for h in headers:
        with open(os.path.join(check, "tu", h.replace("/", "__") + ".cpp"), "w") as f:
            f.write("#include <%s>\n" % h)
    with open(os.path.join(check, "CMakeLists.txt"), "w") as f:
        f.write("cmake_minimum_required(VERSION 3.16)\nproject(stereo_pf_header_check CXX)\n"
                "set(CMAKE_CXX_STANDARD 17)\nfind_package(catkin REQUIRED COMPONENTS stereo_pf)\n"
                "file(GLOB units ${CMAKE_SOURCE_DIR}/tu/*.cpp)\nadd_library(header_check OBJECT ${units})\n"
                "target_include_directories(header_check PRIVATE ${catkin_INCLUDE_DIRS})\n"
                "target_compile_options(header_check PRIVATE -Wall -Wextra -Werror)\n")
    sh("%s\ncmake -S %s -B %s/build -DCMAKE_BUILD_TYPE=Debug -DPYTHON_EXECUTABLE=/usr/bin/python3\n"
       "make -C %s/build -j2 -k" % (install_setup, check, check, check), env,
       "(b) every installed header on its own (%d)" % len(headers), log)
    print("(b) install prefix: %d headers, all public and each compiling on its own; my_cues built against the "
          "prefix and loaded by the installed track_bag, rms_cm=%s as from the devel space" % (len(headers), s_b["rms_cm"]))
    print("test_cue_overlay: passed in %.0f s" % (time.time() - started))


if __name__ == "__main__":
    try:
        main()
    except Failure as e:
        print("test_cue_overlay: FAILED: %s" % e)
        sys.exit(1)
