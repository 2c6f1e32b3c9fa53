// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/map_proposals.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

namespace stereo_pf
{
void MapProposals::draw(FeatureCache& cache, const std::vector<std::shared_ptr<ObservationModel>>& models,
                        const std::vector<double>& trust, const StereoGeometry& g, int count, const Bounds& bounds,
                        Rng& rng, std::vector<std::pair<Pixel, Pixel>>& pairs)
{
  if (count <= 0)
    return;
  // Where every model with a map agrees (their product: the colour of a grey object is everywhere, its
  // template is not), on 4x4-pixel cells: a CDF over 20k cells instead of 300k pixels, and averaging
  // suppresses isolated pixels that happen to share the target's colour. Each map is brought to the cells
  // first (a model may give it at a lower resolution than the image's).
  constexpr int kCell = ObservationModel::kTargetMapCell;
  const cv::Size cells(std::max(1, g.width() / kCell), std::max(1, g.height() / kCell));
  auto toCells = [&cells](const cv::Mat& map, cv::Mat& out) {
    const bool shrink = map.cols >= cells.width && map.rows >= cells.height;
    cv::resize(map, out, cells, 0, 0, shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  };
  cv::Mat one_left, one_right;
  bool have = false;
  for (size_t k = 0; k < models.size(); ++k)
  {
    ObservationModel& m = *models[k];
    // A cue the learning frame showed to match the background as well as the object (trust 0) has no say.
    if (m.enabled() && trust[k] > 0.0 && m.targetMap(cache, View::Left, one_left) &&
        m.targetMap(cache, View::Right, one_right) && !one_left.empty() && !one_right.empty())
    {
      if (!have)
      {
        toCells(one_left, small_left_);
        toCells(one_right, small_right_);
      }
      else
      {
        toCells(one_left, cell_scratch_);
        cv::multiply(small_left_, cell_scratch_, small_left_, 1.0 / 255.0);
        toCells(one_right, cell_scratch_);
        cv::multiply(small_right_, cell_scratch_, small_right_, 1.0 / 255.0);
      }
      have = true;
    }
  }
  if (!have)
    return;
  const int cols = small_left_.cols, rows = small_left_.rows;
  // The partner lies on the same row, at a positive disparity up to that of the nearest depth; while tracking
  // (`near`), within a factor `reach` of the estimate's: the maps see the target at about its present size,
  // which a far smaller or larger disparity would contradict (a tiny far hypothesis matches anything).
  double min_disparity = 1.0, max_disparity = g.disparity(bounds.min_depth);
  if (bounds.near && bounds.near->valid)
  {
    const double d = bounds.near->left.u - bounds.near->right.u;
    min_disparity = std::max(min_disparity, d / bounds.reach);
    max_disparity = std::min(max_disparity, d * bounds.reach);
  }
  // Searching for a lost object: the cells whose pixels' rays can pass within the reach (the left image's bounding
  // box of the sphere's image), and the disparities of its depths.
  cv::Rect allowed(0, 0, cols, rows);
  if (bounds.last_seen && std::isfinite(bounds.reach_radius) && bounds.reach_radius >= 0.0)
  {
    const Eigen::Vector3d& c = *bounds.last_seen;
    const double r = bounds.reach_radius;
    const double z_near = std::max(bounds.min_depth, c.z() - r), z_far = c.z() + r;
    if (!(z_far > z_near))
      return;
    max_disparity = std::min(max_disparity, g.disparity(z_near));
    min_disparity = std::max(min_disparity, g.disparity(z_far));
    // Over a box of depths, x / z is extreme at a corner: the nearest or farthest depth with the extreme x (or y).
    const auto extent = [&](double centre, double f, double principal, double& lo, double& hi) {
      lo = HUGE_VAL;
      hi = -HUGE_VAL;
      for (const double z : { z_near, z_far })
        for (const double side : { -r, r })
        {
          const double px = f * (centre + side) / z + principal;
          lo = std::min(lo, px);
          hi = std::max(hi, px);
        }
    };
    double u0, u1, v0, v1;
    extent(c.x(), g.fx(), g.cx(), u0, u1);
    extent(c.y(), g.fy(), g.cy(), v0, v1);
    const auto cell = [](double px) {
      return static_cast<int>(std::clamp(std::floor((px + 0.5) / kCell), -1.0, 1e6));
    };
    allowed &= cv::Rect(cv::Point(cell(u0), cell(v0)), cv::Point(cell(u1) + 1, cell(v1) + 1));
  }
  cdf_.resize(static_cast<size_t>(cols) * rows);
  double total = 0.0;
  for (int y = 0; y < rows; ++y)
  {
    const uint8_t* row = small_left_.ptr<uint8_t>(y);
    for (int x = 0; x < cols; ++x)
    {
      // Squared: favour strong matches.
      const double w = allowed.contains(cv::Point(x, y)) ? static_cast<double>(row[x]) * row[x] : 0.0;
      total += w;
      cdf_[static_cast<size_t>(y) * cols + x] = total;
    }
  }
  if (total <= 0.0)
    return;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  row_cdf_.resize(cols);
  for (int k = 0; k < count; ++k)
  {
    const size_t cell = std::upper_bound(cdf_.begin(), cdf_.end(), unit(rng) * total) -
                        cdf_.begin();
    const int cx = static_cast<int>(std::min(cell, cdf_.size() - 1) % cols);
    const int cy = static_cast<int>(std::min(cell, cdf_.size() - 1) / cols);
    const Pixel left{ (cx + unit(rng)) * kCell - 0.5, (cy + unit(rng)) * kCell - 0.5 };
    const int first = std::max(0, static_cast<int>(std::floor((left.u - max_disparity) / kCell)));
    const int last = std::min(cols - 1, static_cast<int>(std::floor((left.u - min_disparity) / kCell)));
    if (last < first)
      continue;
    const uint8_t* row = small_right_.ptr<uint8_t>(cy);
    double row_total = 0.0;
    for (int x = first; x <= last; ++x)
    {
      row_total += static_cast<double>(row[x]) * row[x];
      row_cdf_[x - first] = row_total;
    }
    if (row_total <= 0.0)
      continue;
    const int n = last - first + 1;
    const int rx = first + static_cast<int>(std::min<long>(
                               std::upper_bound(row_cdf_.begin(), row_cdf_.begin() + n, unit(rng) * row_total) -
                                   row_cdf_.begin(),
                               n - 1));
    const Pixel right{ (rx + unit(rng)) * kCell - 0.5, left.v };
    if (left.u - right.u > 0.0)
      pairs.emplace_back(left, right);
  }
}

}  // namespace stereo_pf
