// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Filling the ROS-free Parameters tree from YAML (config files, command-line overrides).
#pragma once

#include <string>

#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
/// Merge a YAML file into `params` (maps become namespaces, sequences of maps become "<key>/<index>/...",
/// sequences of scalars become "[a, b, c]"). Throws ParameterError naming the file on a parse error.
void loadYamlFile(const std::string& path, Parameters& params);
/// Same for YAML text.
void loadYamlString(const std::string& text, Parameters& params);
/// Apply one "ns/key=value" override (value parsed as YAML, so lists and maps work).
void applyOverride(const std::string& assignment, Parameters& params);

}  // namespace stereo_pf
