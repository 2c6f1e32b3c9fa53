// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The depth of the local search's matches, filtered over frames (a proposal policy's helper; ROS-free): a
// constant-velocity Kalman filter on the depth each frame's match gives, its measurement noise what a fixed
// disparity error means at that depth (z^2 sigma_d / (fx b): nothing near the camera, much far away), its process
// noise a bound on the object's acceleration along the depth. A far object's per-frame disparity error is then
// averaged over frames, a near or approaching one follows its match; a match beyond three standard deviations
// of the prediction (a bounce, a new track) starts the filter again there.
#pragma once

#include <Eigen/Core>

namespace stereo_pf
{
class MatchDepthFilter
{
public:
  /// The filtered disparity and its standard deviation, px.
  struct Result
  {
    double disparity = 0.0;
    double sigma = 0.0;
  };

  /// `acceleration`: m/s^2, the process noise; `disparity_sigma`: px, one match's disparity error;
  /// `start_speed`: m/s, the spread of the depth velocity when the filter starts.
  MatchDepthFilter(double acceleration = 20.0, double disparity_sigma = 0.5, double start_speed = 20.0);
  void configure(double acceleration, double disparity_sigma, double start_speed);

  /// Forgets the track: the next match starts the filter.
  void reset() { known_ = false; }
  bool known() const { return known_; }

  /// One frame's match (disparity px > 0, at `stamp` s) seen by a camera of focal length times baseline `fb`
  /// (px m > 0); frames more than `max_gap` s after the last start the filter again. Returns the filtered
  /// disparity (the match's own, with disparity_sigma, when the filter starts or the input is not usable).
  Result update(double disparity, double fb, double stamp, double max_gap);

private:
  double acceleration_;
  double disparity_sigma_;
  double start_speed_;
  bool known_ = false;
  double stamp_ = 0.0;
  Eigen::Vector2d state_ = Eigen::Vector2d::Zero();  ///< depth m, depth velocity m/s
  Eigen::Matrix2d cov_ = Eigen::Matrix2d::Zero();
};

}  // namespace stereo_pf
