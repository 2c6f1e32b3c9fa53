#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
# Copyright (c) 2026, stereo_pf developers
"""Every source file of the repository says its licence in its first lines (the SPDX line, as LICENSE), so a file
copied out of it still carries it: C++ sources and headers, Python and shell scripts, CMake files, and the scripts
without an extension (scripts/*, .ci/run, anything starting with #!), in the package and in examples/.

The files are the ones git knows (tracked, and new ones it does not ignore, so a file is caught before its
commit); without git or outside a checkout, every file below the source directory but the build trees."""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

SPDX = "SPDX-License-Identifier: BSD-3-Clause"
HEAD_LINES = 3  # after a shebang: #!, the SPDX line, the copyright line
CODE_SUFFIXES = (".cpp", ".cc", ".c", ".h", ".hpp", ".py", ".sh", ".bash", ".cmake")
# Walking without git: what .gitignore keeps out (build trees, bags) and what is not ours.
SKIP_DIRS = ("build", "devel", "install", "data", "node_modules", "__pycache__")

SOURCE = None  # set from --source


def is_source(relpath, fullpath):
    """Whether a file is one that must carry the header: code by its suffix, CMakeLists.txt, and scripts without a
    suffix (everything in scripts/, elsewhere those starting with #!). Data and prose (.txt lists, YAML, XML,
    Markdown, images) are not."""
    name = os.path.basename(relpath)
    if name == "CMakeLists.txt" or name.endswith(CODE_SUFFIXES):
        return True
    if "." in name.lstrip("."):
        return False
    if relpath.split("/")[0] == "scripts":
        return True
    try:
        with open(fullpath, "rb") as f:
            return f.read(2) == b"#!"
    except OSError:
        return False


def git_files(source):
    """The files git knows below `source` (tracked, and untracked ones it does not ignore), or None without git or
    outside a checkout."""
    git = shutil.which("git")
    if not git:
        return None
    try:
        out = subprocess.run([git, "-C", source, "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, check=True).stdout
    except (subprocess.CalledProcessError, OSError):
        return None
    return sorted(set(p for p in out.decode("utf-8", "surrogateescape").split("\0") if p))


def walked_files(source):
    """Every file below `source` but hidden entries, build trees (and any directory holding a CMakeCache.txt) and
    bags."""
    files = []
    for root, dirs, names in os.walk(source):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") or root == source and d == ".ci")
        dirs[:] = [d for d in dirs if not (d in SKIP_DIRS or d.startswith("build_") or
                                           os.path.exists(os.path.join(root, d, "CMakeCache.txt")))]
        for n in sorted(names):
            files.append(os.path.relpath(os.path.join(root, n), source).replace(os.sep, "/"))
    return files


def missing_header(source, files):
    """The files of `files` (relative to `source`) that must carry the SPDX line and do not have it in their first
    HEAD_LINES lines, and how many were checked."""
    missing, checked = [], 0
    for rel in files:
        full = os.path.join(source, rel)
        if not os.path.isfile(full) or os.path.islink(full) or not is_source(rel, full):
            continue  # deleted in the working tree, a link, or not a source file
        checked += 1
        with open(full, encoding="utf-8", errors="replace") as f:
            head = [f.readline() for _ in range(HEAD_LINES)]
        if not any(SPDX in line for line in head):
            missing.append(rel)
    return missing, checked


class LicenceHeaders(unittest.TestCase):
    def test_every_source_file_carries_the_spdx_line(self):
        files = git_files(SOURCE)
        how = "git ls-files"
        if files is None:
            files, how = walked_files(SOURCE), "a walk of the source directory (no git checkout)"
        missing, checked = missing_header(SOURCE, files)
        print("%d source files checked (from %s)" % (checked, how))
        # A listing that found (almost) nothing would pass whatever the files say.
        self.assertGreater(checked, 50, "only %d source files found below %s by %s" % (checked, SOURCE, how))
        self.assertEqual(missing, [], "these files lack '%s' in their first %d lines (write it as the other "
                         "files do: a comment after the shebang if any, followed by 'Copyright (c) 2026, stereo_pf "
                         "developers'):\n  %s" % (SPDX, HEAD_LINES, "\n  ".join(missing)))

    def test_the_check_sees_a_missing_line_either_way(self):
        """The check itself, on a tree of its own: it flags exactly the file without the line, from git's listing and
        from the walk alike, and leaves data files alone."""
        tmp = tempfile.mkdtemp(prefix="licence_check_")
        try:
            files = {
                "src/good.cpp": "// %s\n// Copyright\nint x;\n" % SPDX,
                "src/bad.h": "#pragma once\n// %s\n// no: line 4 is too late\n\n// %s\n" % ("x", SPDX),
                "scripts/tool": "#!/bin/bash\n# %s\n# Copyright\n" % SPDX,
                "scripts/bare": "echo no header\n",
                "bin_tool": "#!/usr/bin/python3\nprint(1)\n",
                "scripts/deps.txt": "pkg\n",
                "build/x.cpp": "int y;\n",
            }
            for rel, text in files.items():
                os.makedirs(os.path.dirname(os.path.join(tmp, rel)), exist_ok=True)
                with open(os.path.join(tmp, rel), "w") as f:
                    f.write(text)
            expected = ["bin_tool", "scripts/bare", "src/bad.h"]
            self.assertEqual(sorted(missing_header(tmp, walked_files(tmp))[0]), expected)
            listed = sorted(r for r in files if not r.startswith("build/"))
            self.assertEqual(sorted(missing_header(tmp, listed)[0]), expected)
        finally:
            shutil.rmtree(tmp)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        help="the repository's top directory (default: this file's ../)")
    args, rest = parser.parse_known_args()
    SOURCE = os.path.abspath(args.source)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
