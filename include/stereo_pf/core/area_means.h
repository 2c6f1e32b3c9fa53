// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Means of square blocks of 8-bit rows, rounded as OpenCV's area resize rounds them.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace stereo_pf
{
/// Sums `cell` rows of `width` 8-bit values column by column, then gives each `cell`-wide block's mean, rounded
/// to the nearest integer (ties to even) from its sum times 1 / cell^2 in float: what cv::resize with INTER_AREA
/// gives for a whole factor of 3 or more (for 2 OpenCV rounds ties up). `cell`: 1 to 16 (the sums are 16 bits).
class CellRows
{
public:
  /// Start a row of cells `cell` pixels across over the first `width` columns (a multiple of `cell`).
  void start(int width, int cell);
  /// Add one row of the cells' `width` values.
  void add(const uint8_t* row);
  /// The width / cell means of the rows added since start() (which must have been `cell` rows).
  void means(uint8_t* out) const;

private:
  std::vector<uint16_t> down_;  // per column, the sum down the rows added
  int rows_ = 0;  // rows added since start()
  int cell_ = 1;
  float inv_area_ = 1.0f;
};

/// `out` (CV_8UC1, grey.cols / cell x grey.rows / cell): the mean of each `cell` x `cell` block of the CV_8UC1
/// image `grey`, value for value what cv::resize(INTER_AREA) gives on its first (cols / cell) * cell columns and
/// rows, in one pass (OpenCV's area resize by a whole factor other than 2 takes about 5 instructions a pixel, this
/// under 3). Throws std::invalid_argument for another type or a cell outside 1 to 16.
void areaMeans(const cv::Mat& grey, int cell, cv::Mat& out);
}  // namespace stereo_pf
