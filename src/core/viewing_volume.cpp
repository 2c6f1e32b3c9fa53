// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/viewing_volume.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace stereo_pf
{
ViewingVolume::ViewingVolume(const StereoGeometry& g, double min_disparity, double max_depth)
  : width_(g.width()), height_(g.height())
{
  const double fb = g.fx() * g.baseline();
  max_disparity_ = static_cast<double>(g.width());
  // A configured maximum depth can only bring the far limit nearer, never beyond what disparity resolves.
  min_disparity_ = std::max(min_disparity, max_depth > 0.0 ? fb / max_depth : 0.0);
  min_disparity_ = std::min(min_disparity_, max_disparity_);
  near_depth_ = fb / max_disparity_;
  far_depth_ = fb / min_disparity_;
}

bool ViewingVolume::overlapsImage(double u, double v, double r) const
{
  if (!std::isfinite(u) || !std::isfinite(v))
    return false;
  const double m = std::isfinite(r) && r > 0.0 ? r : 0.0;
  // The image spans [-0.5, size - 0.5) in pixel-centre coordinates; the disc reaches m beyond its centre.
  return u > -0.5 - m && v > -0.5 - m && u < width_ - 0.5 + m && v < height_ - 0.5 + m;
}

std::string ViewingVolume::describe() const
{
  char buf[128];
  std::snprintf(buf, sizeof(buf), "near %.3g m, far %.3g m, disparity %.3g .. %.3g px", near_depth_, far_depth_,
                max_disparity_, min_disparity_);
  return buf;
}

}  // namespace stereo_pf
