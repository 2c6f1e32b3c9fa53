// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/stereo_frame.h"

#include <sstream>

namespace stereo_pf
{
std::string StereoFrame::validate() const
{
  std::ostringstream err;
  const std::string g = geometry.validate();
  if (!g.empty())
    return "invalid calibration: " + g;
  if (left.empty() || right.empty())
    return "empty image";
  if (left.size() != right.size())
  {
    err << "left and right image sizes differ (" << left.cols << "x" << left.rows << " vs " << right.cols << "x"
        << right.rows << ")";
    return err.str();
  }
  if (left.type() != right.type())
    return "left and right images have different pixel types";
  if (left.type() != CV_8UC3 && left.type() != CV_8UC1)
    return "images must be 8-bit BGR or mono (converted before they reach the engine)";
  if (left.cols != geometry.width() || left.rows != geometry.height())
  {
    err << "image size " << left.cols << "x" << left.rows << " does not match the calibration's "
        << geometry.width() << "x" << geometry.height();
    return err.str();
  }
  return "";
}

}  // namespace stereo_pf
