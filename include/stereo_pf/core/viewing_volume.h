// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// What the stereo pair can observe: the depths at which a point is measurable by both cameras, and the image
// area a hypothesis must overlap. Derived from the calibration (focal length, baseline, image size), so the
// engine's bounds follow the camera, not one scene.
#pragma once

#include <string>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// The viewing volume of a rectified stereo pair, in disparity (pixels) and in depth (metres).
///
/// Far limit: the depth at which the disparity falls to `min_disparity` pixels (fx b / min_disparity; beyond it
/// depth is not measurable, one pixel of disparity being more than the depth itself), or `max_depth` when
/// that is nearer. Near limit: the depth at which the disparity reaches the image width (fx b / width): nearer,
/// a point cannot lie in both images. A hypothesis overlaps an image when its disc (centre, apparent radius)
/// reaches into it.
class ViewingVolume
{
public:
  ViewingVolume() = default;
  /// @param geometry a valid calibration; @param min_disparity px (> 0); @param max_depth m (0: no extra limit).
  ViewingVolume(const StereoGeometry& geometry, double min_disparity, double max_depth = 0.0);

  /// Smallest accepted disparity, px (the far limit).
  double minDisparity() const { return min_disparity_; }
  /// Largest accepted disparity, px (the near limit: the image width).
  double maxDisparity() const { return max_disparity_; }
  /// Nearest depth both cameras see, m.
  double nearDepth() const { return near_depth_; }
  /// Farthest depth at which depth is measurable (or max_depth), m.
  double farDepth() const { return far_depth_; }
  /// Image size, px.
  double imageWidth() const { return width_; }
  double imageHeight() const { return height_; }

  /// True when a left/right disparity (px) is within [minDisparity, maxDisparity] (false for NaN).
  bool containsDisparity(double disparity) const
  {
    return disparity >= min_disparity_ && disparity <= max_disparity_;
  }
  /// True when a depth (m) is within [nearDepth, farDepth] (false for NaN).
  bool containsDepth(double z) const { return z >= near_depth_ && z <= far_depth_; }
  /// True when the disc at (u, v) with radius r (px; r <= 0 or NaN: a point) overlaps the image, and u, v are
  /// finite.
  bool overlapsImage(double u, double v, double r) const;

  /// "near 0.0738 m, far 94.5 m, disparity 640 .. 0.5 px", for messages.
  std::string describe() const;

private:
  double min_disparity_ = 0.0, max_disparity_ = 0.0, near_depth_ = 0.0, far_depth_ = 0.0;
  double width_ = 0.0, height_ = 0.0;
};

}  // namespace stereo_pf
