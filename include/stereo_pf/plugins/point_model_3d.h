// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Shared base of the 3D state models (Position3D, Velocity3D): the first three state coordinates are
// the object centre {x, y, z} in the left optical frame, projected into both images.
#pragma once

#include "stereo_pf/state_model.h"

namespace stereo_pf
{
class PointModel3D : public StateModel
{
public:
  /// One set, observed in both images.
  std::vector<View> views(int set) const override;
  /// Uniform over the part of the viewing frustum seen by both cameras, between z_min and z_max
  /// (`init_depth`: uniform in disparity, the default: as many particles per pixel of disparity at every range;
  /// in volume; or in depth).
  void samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin, int end,
                   Rng& rng) const override;
  /// Triangulate the pair; false outside [z_min, z_max].
  bool seedFromStereo(const StereoGeometry& geometry, int set, ParticleSet& particles, int row, const Pixel& left,
                      const Pixel& right) const override;
  /// Centre and apparent radius of the sphere in hyp.view; valid when in front of the camera and
  /// inside the image.
  void project(const StereoGeometry& geometry, int set, const ParticleSet& particles,
               ImageHypotheses& hyp) const override;
  /// Estimator over {x, y, z}, weighted covariance, projections; velocity when the state has one.
  StateEstimate estimate(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets, Estimator estimator,
                         double density_radius) const override;
  /// The particles' {x, y, z} and weights.
  void cloud(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets, Eigen::MatrixX3d& points,
             Eigen::VectorXd& weights) const override;

protected:
  /// Read the shared parameters: noise, z_min, z_max, init_depth, object_radius.
  void readCommonParameters();
  /// The prior's depth range: z_min / z_max, or where they are 0 the camera's own (the depth at which the
  /// disparity equals the image width, and the depth at which it falls to one pixel).
  void depthRange(const StereoGeometry& geometry, double& z_min, double& z_max) const;
  /// The sphere's radius, m: `object_radius` when set, else the one learned with the target, else 3.5 cm.
  double radius() const;
  static constexpr double kDefaultRadius = 0.035;
  /// Random-walk noise on x, y, z per frame (thesis eq. 5.12-5.14, the same alpha on every axis), m.
  double noise_ = 0.04;
  double z_min_ = 0.0;          ///< nearest depth of the prior, m (0: from the camera)
  double z_max_ = 0.0;          ///< farthest depth of the prior, m (0: from the camera)
  std::string init_depth_ = "disparity";
  double object_radius_ = 0.0;  ///< radius of the tracked sphere, m (0: learned with the target)
  /// Relative depth band around the cloud's mean depth in which every particle gets that depth's apparent
  /// radius (so a size error cannot bias depth; 0: each particle its own f R / z, the thesis).
  double size_band_ = 0.3;
};

}  // namespace stereo_pf
