// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// stereo_pf/Position3D: the thesis's 3D filter, state {x, y, z}.
#pragma once

#include "stereo_pf/plugins/point_model_3d.h"

namespace stereo_pf
{
/// Parameters (namespace ~/<name>): noise (m per frame, 0.04: a 30 fps pendulum moves up to ~2.5 cm per frame), z_min (0.3 m), z_max (3.0 m),
/// init_depth (volume | depth | disparity), object_radius (0.035 m).
class Position3D : public PointModel3D
{
public:
  int dimension(int) const override { return 3; }
  /// x += N(0, noise) on each axis.
  void predict(int set, double dt, ParticleSet& particles, Rng& rng) const override;

protected:
  void onInitialize() override;
};

}  // namespace stereo_pf
