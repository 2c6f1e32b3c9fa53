// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Rectified stereo pinhole geometry (thesis 6.3, eq. 6.1-6.3).
#pragma once

#include <Eigen/Core>
#include <string>

#include "stereo_pf/core/silhouette.h"

namespace stereo_pf
{
/// Which image of the stereo pair.
enum class View : int
{
  Left = 0,
  Right = 1
};

/// Pixel position of a point in one image (OpenCV pixel-centre convention).
struct Pixel
{
  double u = 0.0;  ///< column
  double v = 0.0;  ///< row
};

/// A rectified stereo pair: identical intrinsics, right camera displaced by +baseline along x.
/// Coordinates are the left rectified optical frame: x right, y down, z forward, metres.
class StereoGeometry
{
public:
  StereoGeometry() = default;
  /// @param fx,fy focal lengths in pixels; @param cx,cy principal point; @param baseline metres (> 0);
  /// @param width,height image size in pixels.
  StereoGeometry(double fx, double fy, double cx, double cy, double baseline, int width, int height);

  /// Empty string when the calibration is usable, otherwise what is wrong with it
  /// (zero or NaN focal length, non-positive baseline, empty image size, ...).
  std::string validate() const;
  /// True when validate() is empty.
  bool valid() const { return validate().empty(); }

  /// Project a 3D point into the left image.
  Pixel projectLeft(const Eigen::Vector3d& p) const;
  /// Project a 3D point into the right image.
  Pixel projectRight(const Eigen::Vector3d& p) const;
  /// Project into the given view.
  Pixel project(const Eigen::Vector3d& p, View view) const { return view == View::Left ? projectLeft(p) : projectRight(p); }
  /// The middle of the image of a sphere of `radius` (m) centred at p in the given view: off the optical axis a
  /// little beyond p's projection (sphereImageScale() in core/silhouette.h). The 3D state models' hypotheses.
  Pixel projectSphere(const Eigen::Vector3d& p, double radius, View view) const
  {
    const double x = view == View::Right ? p.x() - baseline_ : p.x();
    const double k = sphereImageScale(p.z(), radius * radius) / p.z();
    return { fx_ * x * k + cx_, fy_ * p.y() * k + cy_ };
  }
  /// Disparity u_left - u_right (pixels) of a point at depth z.
  double disparity(double z) const { return fx_ * baseline_ / z; }
  /// Depth of a point with disparity d (pixels).
  double depth(double disparity) const { return fx_ * baseline_ / disparity; }
  /// Apparent radius in pixels of a sphere of radius `radius` (m) whose centre is at depth z.
  double apparentRadius(double radius, double z) const { return fx_ * radius / z; }
  /// Triangulate from a left pixel and the right column (rows equal after rectification).
  /// Returns false (and leaves p untouched) when the disparity is not positive.
  bool triangulate(const Pixel& left, double u_right, Eigen::Vector3d& p) const;
  /// Back-project a left pixel at depth z.
  Eigen::Vector3d backProject(const Pixel& left, double z) const;
  /// True when the point is in front of both cameras (z > min_depth).
  bool inFront(const Eigen::Vector3d& p, double min_depth = 1e-3) const { return p.z() > min_depth; }
  /// True when the pixel lies inside the image (with an optional margin in pixels).
  bool inImage(const Pixel& px, double margin = 0.0) const;
  /// True when the point is in front and projects inside both images.
  bool visible(const Eigen::Vector3d& p, double margin = 0.0) const;

  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double baseline() const { return baseline_; }
  int width() const { return width_; }
  int height() const { return height_; }

private:
  double fx_ = 0.0, fy_ = 0.0, cx_ = 0.0, cy_ = 0.0, baseline_ = 0.0;
  int width_ = 0, height_ = 0;
};

}  // namespace stereo_pf
