// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// stereo_pf/Position3D: {x, y, z} with a Gaussian random walk (thesis 5.1, eq. 5.12-5.14).
#include "stereo_pf/plugins/position_3d.h"

#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
void Position3D::onInitialize()
{
  readCommonParameters();
}

void Position3D::predict(int, double, ParticleSet& particles, Rng& rng) const
{
  // The thesis's random walk: the same alpha on every axis, independent of the frame interval.
  std::normal_distribution<double> noise(0.0, noise_);
  for (int k = 0; k < 3; ++k)
  {
    double* c = particles.states.col(k).data();
    for (int i = 0; i < particles.size(); ++i)
      c[i] += noise(rng);
  }
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::Position3D, stereo_pf::StateModel)
