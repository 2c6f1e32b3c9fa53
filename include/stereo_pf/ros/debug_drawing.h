// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Debug images: the particles (coloured by weight) and the estimate drawn over one rectified image.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/engine.h"

namespace stereo_pf
{
/// Draws into a BGR copy of the frame's image; keeps its scratch buffers between frames.
class DebugDrawing
{
public:
  /// Draw `view` of `frame` with the engine's particles as weighed in the last step (before its resampling)
  /// and `result` into `out` (CV_8UC3, a copy: the frame's image is never written). Particles are projected
  /// with the state model and coloured by weight (blue low, red high); particles at the same pixel are merged,
  /// their weights summed. Marks and text are sized for the image's width (legible at its own size).
  void draw(const StereoFrame& frame, View view, const FilterEngine& engine, const FrameResult& result, cv::Mat& out);

private:
  ImageHypotheses hyp_;
  std::vector<int> order_;
  std::vector<float> merged_u_, merged_v_, merged_w_, merged_r_;
};

}  // namespace stereo_pf
