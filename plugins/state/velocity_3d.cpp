// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// stereo_pf/Velocity3D: constant velocity with Gaussian acceleration noise; dt from the frame stamps.
#include "stereo_pf/plugins/velocity_3d.h"

#include <algorithm>
#include <cmath>

#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
void Velocity3D::onInitialize()
{
  readCommonParameters();
  // Velocity carries the motion, so the position jitter is much smaller than Position3D's walk: by default
  // (noise 0) jitter_radii of the object's radius per frame, so that it follows the object's scale.
  noise_ = params().getDouble("noise", 0.0, 0.0, 10.0,
                              "m per frame of extra position jitter (0: jitter_radii of the object's radius)");
  jitter_radii_ = params().getDouble("jitter_radii", 0.25, 0.0, 10.0,
                                     "position jitter per frame in object radii, when noise is 0");
  acceleration_noise_ = params().getDouble("acceleration_noise", 20.0, 0.0, 1000.0,
                                           "m/s^2; std of the acceleration noise");
  smooth_fraction_ = params().getDouble("smooth_fraction", 0.8, 0.0, 1.0,
                                       "share of the particles predicted with the smooth motion's noise each frame");
  smooth_acceleration_noise_ = params().getDouble("smooth_acceleration_noise", 2.0, 0.0, 1000.0,
                                                  "m/s^2; acceleration noise of the smooth motion");
  smooth_jitter_ = params().getDouble("smooth_jitter", 0.5, 0.0, 10.0,
                                      "position jitter of the smooth motion, as a fraction of the jitter");
  initial_speed_ = params().getDouble("initial_speed", 0.3, 0.0, 100.0, "m/s; spread of the prior's velocities");
  max_speed_ = params().getDouble("max_speed", 40.0, 0.01, 1000.0,
                                  "m/s; each velocity component is clamped to +-max_speed (keeps a diverging "
                                  "particle finite)");
}

void Velocity3D::samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin, int end,
                             Rng& rng) const
{
  PointModel3D::samplePrior(geometry, set, particles, begin, end, rng);
  std::normal_distribution<double> speed(0.0, initial_speed_);
  for (int k = 3; k < 6; ++k)
    for (int i = begin; i < end; ++i)
      particles.states(i, k) = speed(rng);
}

void Velocity3D::setArrival(const StateEstimate& from, double dt, int, ParticleSet& particles, int row) const
{
  if (!from.valid || !(dt > 0.0))
    return;
  for (int k = 0; k < 3; ++k)
    particles.states(row, 3 + k) = std::clamp((particles.states(row, k) - from.position[k]) / dt, -max_speed_, max_speed_);
}

void Velocity3D::predict(int, double dt, ParticleSet& particles, Rng& rng) const
{
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> pick(0.0, 1.0);
  const double jitter = noise_ > 0.0 ? noise_ : jitter_radii_ * radius();
  const double wide[2] = { acceleration_noise_ * dt, jitter };
  const double smooth[2] = { smooth_acceleration_noise_ * dt, smooth_jitter_ * jitter };
  for (int i = 0; i < particles.size(); ++i)
  {
    const double* sd = pick(rng) < smooth_fraction_ ? smooth : wide;
    for (int k = 0; k < 3; ++k)
    {
      double& v = particles.states(i, k + 3);
      v = std::clamp(v + sd[0] * unit(rng), -max_speed_, max_speed_);
      particles.states(i, k) += v * dt + sd[1] * unit(rng);
    }
  }
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::Velocity3D, stereo_pf::StateModel)
