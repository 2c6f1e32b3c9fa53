// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/stereo_geometry.h"

#include <cmath>
#include <sstream>

namespace stereo_pf
{
StereoGeometry::StereoGeometry(double fx, double fy, double cx, double cy, double baseline, int width, int height)
  : fx_(fx), fy_(fy), cx_(cx), cy_(cy), baseline_(baseline), width_(width), height_(height)
{
}

std::string StereoGeometry::validate() const
{
  std::ostringstream err;
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(fx_) || !finite(fy_) || fx_ <= 0.0 || fy_ <= 0.0)
    err << "focal length must be positive and finite (fx=" << fx_ << ", fy=" << fy_ << "); ";
  if (!finite(cx_) || !finite(cy_))
    err << "principal point is not finite (cx=" << cx_ << ", cy=" << cy_ << "); ";
  if (!finite(baseline_) || baseline_ <= 0.0)
    err << "baseline must be positive and finite (got " << baseline_
        << " m; for ROS camera_info it is -P[3]/P[0] of the right camera); ";
  if (width_ <= 0 || height_ <= 0)
    err << "image size must be positive (got " << width_ << "x" << height_ << "); ";
  std::string s = err.str();
  if (!s.empty())
    s.resize(s.size() - 2);
  return s;
}

Pixel StereoGeometry::projectLeft(const Eigen::Vector3d& p) const
{
  return { fx_ * p.x() / p.z() + cx_, fy_ * p.y() / p.z() + cy_ };
}

Pixel StereoGeometry::projectRight(const Eigen::Vector3d& p) const
{
  // The right camera sits at (+baseline, 0, 0) with the same orientation (rectified pair).
  return { fx_ * (p.x() - baseline_) / p.z() + cx_, fy_ * p.y() / p.z() + cy_ };
}

bool StereoGeometry::triangulate(const Pixel& left, double u_right, Eigen::Vector3d& p) const
{
  const double d = left.u - u_right;
  if (!(d > 0.0))
    return false;
  p = backProject(left, depth(d));
  return true;
}

Eigen::Vector3d StereoGeometry::backProject(const Pixel& left, double z) const
{
  return { (left.u - cx_) * z / fx_, (left.v - cy_) * z / fy_, z };
}

bool StereoGeometry::inImage(const Pixel& px, double margin) const
{
  // Pixel centres are at integer coordinates, so the image spans [-0.5, size - 0.5).
  return px.u >= -0.5 + margin && px.v >= -0.5 + margin && px.u < width_ - 0.5 - margin &&
         px.v < height_ - 0.5 - margin;
}

bool StereoGeometry::visible(const Eigen::Vector3d& p, double margin) const
{
  return inFront(p) && inImage(projectLeft(p), margin) && inImage(projectRight(p), margin);
}

}  // namespace stereo_pf
