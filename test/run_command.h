// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// For the tests that drive the command-line tools: run a shell command and capture what it prints.
#pragma once

#include <cstdio>
#include <string>

namespace stereo_pf_test
{
/// Run `command` through the shell with stderr merged into stdout; returns the output, and sets `status` to
/// pclose()'s status (-1 when the command could not be started).
inline std::string run(const std::string& command, int& status)
{
  std::string out;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe)
  {
    status = -1;
    return out;
  }
  char buffer[4096];
  while (fgets(buffer, sizeof(buffer), pipe))
    out += buffer;
  status = pclose(pipe);
  return out;
}
}  // namespace stereo_pf_test
