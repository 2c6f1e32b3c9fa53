// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// stereo_pf/Velocity3D: state {x, y, z, vx, vy, vz} with constant velocity (thesis 5.1's richer option).
#pragma once

#include "stereo_pf/plugins/point_model_3d.h"

namespace stereo_pf
{
/// Parameters (namespace ~/<name>): as Position3D (noise is an extra position jitter per frame, m; default 0:
/// jitter_radii, 0.25, of the object's radius) plus acceleration_noise (m/s^2, 12: a pendulum accelerates at up to
/// ~5 m/s^2 and the filter must also absorb the likelihood's jitter), initial_speed (m/s standard deviation of
/// the prior velocity, 0.3), max_speed (m/s, 40: velocities are clamped to keep a diverging particle finite).
/// Jumps the dynamics cannot follow (a throw's first frames, a bounce) come from the engine's recovery
/// proposals, which give their particles the jump's velocity (setArrival).
class Velocity3D : public PointModel3D
{
public:
  int dimension(int) const override { return 6; }
  /// Draws positions like Position3D and velocities from N(0, initial_speed).
  void samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin, int end,
                   Rng& rng) const override;
  /// v += N(0, acceleration_noise * dt); x += v * dt + N(0, noise).
  void predict(int set, double dt, ParticleSet& particles, Rng& rng) const override;
  /// v = (x - from) / dt, clamped to max_speed.
  void setArrival(const StateEstimate& from, double dt, int set, ParticleSet& particles, int row) const override;

protected:
  void onInitialize() override;

private:
  double acceleration_noise_ = 12.0;
  double initial_speed_ = 0.3;
  double max_speed_ = 40.0;
  double jitter_radii_ = 0.25;  ///< position jitter per frame in object radii when noise is 0
};

}  // namespace stereo_pf
