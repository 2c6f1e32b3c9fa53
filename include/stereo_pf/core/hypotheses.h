// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Image-space hypotheses: where a batch of particles says the object is in one image.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// One batch of hypotheses in one view, one entry per particle (structure of arrays).
struct ImageHypotheses
{
  View view = View::Left;        ///< image the hypotheses live in
  std::vector<float> u;          ///< column of the middle of the object's image (pixels; for a sphere off the axis
                                 ///< a little beyond its centre's projection)
  std::vector<float> v;          ///< row of the middle of the object's image (pixels)
  std::vector<float> radius;     ///< apparent object radius (pixels)
  std::vector<unsigned char> valid;  ///< 0 when the particle cannot be observed (behind camera, outside image)

  /// Number of hypotheses.
  int size() const { return static_cast<int>(u.size()); }
  /// Resize every array to n entries.
  void resize(int n)
  {
    u.resize(n);
    v.resize(n);
    radius.resize(n);
    valid.resize(n);
  }
};

/// Pixel rows [first, second) of an image of `height` rows that hold the row coordinates [top, bottom],
/// clipped to the image; empty (first >= second) when bottom < top or the span misses the image. Models use
/// it to ask FeatureCache::getRows() for just the rows their hypotheses' windows reach.
inline std::pair<int, int> rowSpan(float top, float bottom, int height)
{
  const int first = static_cast<int>(std::floor(std::max(top, 0.0f)));
  const int last = static_cast<int>(std::ceil(std::min(bottom, static_cast<float>(height - 1)))) + 1;
  return { first, last };
}

/// rowSpan() of the windows of `hyp`'s valid hypotheses, each reaching `reach(i)` pixels above and below its row
/// (plus one: rounding to pixel centres); hypotheses with a row or reach that is not finite are left out, and
/// none left gives an empty span.
template <class Reach>
std::pair<int, int> windowRowSpan(const ImageHypotheses& hyp, int height, Reach reach)
{
  float top = static_cast<float>(height), bottom = -1.0f;
  for (int i = 0; i < hyp.size(); ++i)
  {
    if (!hyp.valid[i] || !std::isfinite(hyp.v[i]))
      continue;
    const float r = static_cast<float>(reach(i)) + 1.0f;
    if (!std::isfinite(r))
      continue;
    top = std::min(top, hyp.v[i] - r);
    bottom = std::max(bottom, hyp.v[i] + r);
  }
  return rowSpan(top, bottom, height);
}

}  // namespace stereo_pf
