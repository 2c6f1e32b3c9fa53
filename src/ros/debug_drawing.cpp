// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/debug_drawing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "stereo_pf/ros/tracker_outputs.h"

namespace stereo_pf
{
namespace
{
constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
constexpr double kScale = 1 << kShift;

cv::Point fixedPoint(double u, double v)
{
  return cv::Point(static_cast<int>(std::lround(u * kScale)), static_cast<int>(std::lround(v * kScale)));
}

// weightColour() as an OpenCV BGR colour.
cv::Scalar heat(double t)
{
  const std::array<float, 3> rgb = weightColour(t);
  return cv::Scalar(rgb[2] * 255.0, rgb[1] * 255.0, rgb[0] * 255.0);
}

cv::Scalar stateColour(TrackState s)
{
  switch (s)
  {
    case TrackState::Tracking:
      return cv::Scalar(40, 220, 40);
    case TrackState::Lost:
      return cv::Scalar(40, 40, 230);
    default:
      return cv::Scalar(0, 160, 255);
  }
}
}  // namespace

void DebugDrawing::draw(const StereoFrame& frame, View view, const FilterEngine& engine, const FrameResult& result,
                        cv::Mat& out)
{
  const cv::Mat& image = frame.image(view);
  if (image.channels() == 1)
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  else
    image.copyTo(out);

  // Collect this view's particles from every set observed in it, merging resampled copies.
  merged_u_.clear();
  merged_v_.clear();
  merged_w_.clear();
  merged_r_.clear();
  const StateModel& model = engine.stateModel();
  // The set as weighed, before the step's resampling (which leaves every weight 1/N on copies of a few).
  const std::vector<ParticleSet>& sets = engine.weightedSets();
  std::map<std::pair<float, float>, size_t> index;
  for (int s = 0; s < static_cast<int>(sets.size()); ++s)
  {
    const std::vector<View> views = model.views(s);
    if (std::find(views.begin(), views.end(), view) == views.end())
      continue;
    hyp_.view = view;
    model.project(frame.geometry, s, sets[s], hyp_);
    for (int i = 0; i < hyp_.size(); ++i)
    {
      if (!hyp_.valid[i])
        continue;
      const float w = i < sets[s].weights.size() ? static_cast<float>(sets[s].weights[i]) : 0.0f;
      const auto [it, fresh] = index.emplace(std::make_pair(hyp_.u[i], hyp_.v[i]), merged_u_.size());
      if (fresh)
      {
        merged_u_.push_back(hyp_.u[i]);
        merged_v_.push_back(hyp_.v[i]);
        merged_r_.push_back(hyp_.radius[i]);
        merged_w_.push_back(w);
      }
      else
        merged_w_[it->second] += w;
    }
  }

  // Marks, lines and text grow with the image (sizes below are for 640 px wide), so a debug image of any
  // resolution reads the same when shown at its own size.
  const double scale = std::max(out.cols / 640.0, 0.5);
  const int line = std::max(static_cast<int>(std::lround(2.0 * scale)), 1);

  // Light particles first so the heavy ones stay visible on top.
  order_.resize(merged_w_.size());
  std::iota(order_.begin(), order_.end(), 0);
  std::sort(order_.begin(), order_.end(), [this](int a, int b) { return merged_w_[a] < merged_w_[b]; });
  const float max_w = merged_w_.empty() ? 1.0f : std::max(*std::max_element(merged_w_.begin(), merged_w_.end()), 1e-12f);
  double radius_sum = 0.0, weight_sum = 0.0;
  for (int i : order_)
  {
    cv::circle(out, fixedPoint(merged_u_[i], merged_v_[i]), static_cast<int>(1.5 * scale * kScale),
               heat(merged_w_[i] / max_w), cv::FILLED, cv::LINE_AA, kShift);
    if (std::isfinite(merged_r_[i]))
    {
      radius_sum += merged_w_[i] * merged_r_[i];
      weight_sum += merged_w_[i];
    }
  }

  const cv::Scalar colour = stateColour(result.state);
  if (result.estimate.valid)
  {
    const Pixel p = view == View::Left ? result.estimate.left : result.estimate.right;
    const double r = weight_sum > 0.0 ? radius_sum / weight_sum : 10.0;
    if (std::isfinite(p.u) && std::isfinite(p.v) && std::isfinite(r))
    {
      cv::circle(out, fixedPoint(p.u, p.v), static_cast<int>(std::lround(r * kScale)), colour, line, cv::LINE_AA, kShift);
      cv::drawMarker(out, cv::Point(static_cast<int>(std::lround(p.u)), static_cast<int>(std::lround(p.v))), colour,
                     cv::MARKER_CROSS, static_cast<int>(std::lround(12 * scale)), std::max(line / 2, 1), cv::LINE_AA);
    }
  }
  char text[160];
  std::snprintf(text, sizeof(text), "%s %s  ESS %.0f  evidence %.2f", view == View::Left ? "L" : "R",
                toString(result.state).c_str(), result.ess, result.evidence);
  // About 15 px capitals at 640 px: legible when the image is shown at its own size.
  const double font = 0.7 * scale;
  const int thickness = std::max(static_cast<int>(std::lround(1.5 * scale)), 1);
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, font, thickness, &baseline);
  const cv::Point origin(static_cast<int>(std::lround(10 * scale)), static_cast<int>(std::lround(10 * scale)) + size.height);
  cv::putText(out, text, origin, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), thickness + 3, cv::LINE_AA);
  cv::putText(out, text, origin, cv::FONT_HERSHEY_SIMPLEX, font, colour, thickness, cv::LINE_AA);
}

}  // namespace stereo_pf
