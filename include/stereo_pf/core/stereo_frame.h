// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// One synchronised, rectified stereo pair as the engine sees it.
#pragma once

#include <opencv2/core.hpp>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Rectified left/right images of one instant. Images are CV_8UC3 (BGR) or CV_8UC1 (mono), same size
/// as geometry.width() x geometry.height(). The Mats share data with their source (no copy).
struct StereoFrame
{
  cv::Mat left;              ///< rectified left image
  cv::Mat right;             ///< rectified right image
  double stamp = 0.0;        ///< acquisition time, seconds
  StereoGeometry geometry;   ///< calibration of the rectified pair

  /// The image of one view.
  const cv::Mat& image(View view) const { return view == View::Left ? left : right; }
  /// Empty string when the frame is usable, otherwise why not (size mismatch, type, calibration).
  std::string validate() const;
};

}  // namespace stereo_pf
