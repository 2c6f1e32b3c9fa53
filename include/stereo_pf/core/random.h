// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The one random number generator type of the engine (seeded explicitly, never from the clock).
#pragma once

#include <random>

namespace stereo_pf
{
/// Engine RNG. Identical seed + identical input gives identical output.
using Rng = std::mt19937_64;
}  // namespace stereo_pf
