// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/match_depth_filter.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace stereo_pf
{
MatchDepthFilter::MatchDepthFilter(double acceleration, double disparity_sigma, double start_speed)
{
  configure(acceleration, disparity_sigma, start_speed);
}

void MatchDepthFilter::configure(double acceleration, double disparity_sigma, double start_speed)
{
  acceleration_ = std::max(0.0, acceleration);
  disparity_sigma_ = std::max(0.0, disparity_sigma);
  start_speed_ = std::max(0.0, start_speed);
}

MatchDepthFilter::Result MatchDepthFilter::update(double disparity, double fb, double stamp, double max_gap)
{
  Result own{ disparity, disparity_sigma_ };
  if (!(disparity > 0.0) || !(fb > 0.0) || !std::isfinite(disparity) || !std::isfinite(fb) || !std::isfinite(stamp))
  {
    known_ = false;
    return own;
  }
  const double z = fb / disparity;
  const double z_sigma = z * z * disparity_sigma_ / fb;  // dz = z^2 dd / (fx b)
  const double r = z_sigma * z_sigma;
  const double dt = stamp - stamp_;
  bool start = !known_ || !(dt > 0.0) || dt > max_gap;
  if (!start)
  {
    Eigen::Matrix2d f;
    f << 1.0, dt, 0.0, 1.0;
    Eigen::Matrix2d q;  // white acceleration over dt
    q << 0.25 * dt * dt * dt * dt, 0.5 * dt * dt * dt, 0.5 * dt * dt * dt, dt * dt;
    const Eigen::Vector2d x = f * state_;
    const Eigen::Matrix2d p = f * cov_ * f.transpose() + acceleration_ * acceleration_ * q;
    const double s = p(0, 0) + r;
    const double innovation = z - x[0];
    start = !(s > 0.0) || innovation * innovation > 9.0 * s;
    if (!start)
    {
      const Eigen::Vector2d k = p.col(0) / s;
      state_ = x + k * innovation;
      cov_ = p - k * p.row(0);
    }
  }
  if (start)
  {
    state_ << z, 0.0;
    cov_ << r, 0.0, 0.0, start_speed_ * start_speed_;
  }
  known_ = true;
  stamp_ = stamp;
  if (!(state_[0] > 0.0))
  {
    known_ = false;
    return own;
  }
  const double d = fb / state_[0];
  return Result{ d, std::sqrt(std::max(0.0, cov_(0, 0))) * d * d / fb };
}

}  // namespace stereo_pf
