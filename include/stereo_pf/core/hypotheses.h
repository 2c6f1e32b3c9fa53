// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Image-space hypotheses: where a batch of particles says the object is in one image.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

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

/// The pixels of a `width` x `height` image that hold the coordinates [left, right] x [top, bottom] (rowSpan() in
/// each direction), as a rectangle; empty when the span is empty or misses the image.
inline cv::Rect spanRegion(float left, float right, float top, float bottom, int width, int height)
{
  const std::pair<int, int> rows = rowSpan(top, bottom, height);
  const std::pair<int, int> cols = rowSpan(left, right, width);
  if (rows.first >= rows.second || cols.first >= cols.second)
    return cv::Rect();
  return cv::Rect(cols.first, rows.first, cols.second - cols.first, rows.second - rows.first);
}

namespace detail
{
/// The bounds of the windows of `hyp`'s valid hypotheses (see windowRowSpan()), started from an empty span of a
/// `width` x `height` image (left = width, right = -1, top = height, bottom = -1) so that rowSpan() of them is
/// always within the image's limits.
template <class Reach>
void windowBounds(const ImageHypotheses& hyp, int width, int height, Reach reach, float& left, float& right,
                  float& top, float& bottom)
{
  left = static_cast<float>(width);
  top = static_cast<float>(height);
  right = bottom = -1.0f;
  for (int i = 0; i < hyp.size(); ++i)
  {
    if (!hyp.valid[i] || !std::isfinite(hyp.u[i]) || !std::isfinite(hyp.v[i]))
      continue;
    const float r = static_cast<float>(reach(i)) + 1.0f;
    if (!std::isfinite(r))
      continue;
    left = std::min(left, hyp.u[i] - r);
    right = std::max(right, hyp.u[i] + r);
    top = std::min(top, hyp.v[i] - r);
    bottom = std::max(bottom, hyp.v[i] + r);
  }
}
}  // namespace detail

/// rowSpan() of the windows of `hyp`'s valid hypotheses, each reaching `reach(i)` pixels above and below its row
/// (plus one: rounding to pixel centres); hypotheses with a position or reach that is not finite are left out, and
/// none left gives an empty span.
template <class Reach>
std::pair<int, int> windowRowSpan(const ImageHypotheses& hyp, int height, Reach reach)
{
  float left, right, top, bottom;
  detail::windowBounds(hyp, 0, height, reach, left, right, top, bottom);
  return rowSpan(top, bottom, height);
}

/// The pixels of a `width` x `height` image the windows of `hyp`'s valid hypotheses reach, each `reach(i)` pixels
/// around it (plus one) in both directions, as one rectangle (their bounding box, clipped to the image; empty when
/// none is left or none reaches the image). Models use it to ask FeatureCache::getRegion() for just that patch.
template <class Reach>
cv::Rect windowRegion(const ImageHypotheses& hyp, int width, int height, Reach reach)
{
  float left, right, top, bottom;
  detail::windowBounds(hyp, width, height, reach, left, right, top, bottom);
  return spanRegion(left, right, top, bottom, width, height);
}

}  // namespace stereo_pf
