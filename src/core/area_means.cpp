// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/area_means.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace stereo_pf
{
void CellRows::start(int width, int cell)
{
  cell_ = cell;
  inv_area_ = 1.0f / static_cast<float>(cell * cell);
  down_.resize(static_cast<size_t>(std::max(width, 0)));
  rows_ = 0;
}

namespace
{
/// down[x] = row[x] (the first row of a cell row: no pass to zero the sums first) or down[x] += row[x].
template <bool First>
void sumDown(const uint8_t* row, int width, uint16_t* down)
{
  int x = 0;
#if CV_SIMD128
  for (; x + 16 <= width; x += 16)
  {
    cv::v_uint16x8 lo, hi;
    cv::v_expand(cv::v_load(row + x), lo, hi);
    cv::v_store(down + x, First ? lo : cv::v_load(down + x) + lo);  // at most 16 x 255: no saturation
    cv::v_store(down + x + 8, First ? hi : cv::v_load(down + x + 8) + hi);
  }
#endif
  for (; x < width; ++x)
    down[x] = static_cast<uint16_t>(First ? row[x] : down[x] + row[x]);
}
}  // namespace

void CellRows::add(const uint8_t* row)
{
  const int width = static_cast<int>(down_.size());
  if (rows_++ == 0)
    sumDown<true>(row, width, down_.data());
  else
    sumDown<false>(row, width, down_.data());
}

void CellRows::means(uint8_t* out) const
{
  const int cols = static_cast<int>(down_.size()) / cell_;
  const uint16_t* down = down_.data();
  int cx = 0;
#if CV_SIMD128
  if (cell_ == 4)  // the recovery search's cells: 8 cells from 32 columns, rounded as below
  {
    const cv::v_float32x4 v_inv_area = cv::v_setall_f32(inv_area_);
    auto mean = [&](const cv::v_uint32x4& sum)
    { return cv::v_round(cv::v_cvt_f32(cv::v_reinterpret_as_s32(sum)) * v_inv_area); };
    for (; cx + 8 <= cols; cx += 8)
    {
      cv::v_uint16x8 a, b, c, d;
      cv::v_load_deinterleave(down + cx * 4, a, b, c, d);
      cv::v_uint32x4 lo, hi;
      cv::v_expand(a + b + c + d, lo, hi);
      cv::v_pack_u_store(out + cx, cv::v_pack(mean(lo), mean(hi)));
    }
  }
#endif
  for (; cx < cols; ++cx)
  {
    uint32_t sum = 0;
    for (int k = cx * cell_; k < (cx + 1) * cell_; ++k)
      sum += down[k];
    out[cx] = cv::saturate_cast<uint8_t>(static_cast<float>(sum) * inv_area_);  // cvRound: ties to even
  }
}

void areaMeans(const cv::Mat& grey, int cell, cv::Mat& out)
{
  if (grey.type() != CV_8UC1)
    throw std::invalid_argument("areaMeans: expected a CV_8UC1 image, got type " + std::to_string(grey.type()));
  if (cell < 1 || cell > 16)
    throw std::invalid_argument("areaMeans: a cell is 1 to 16 pixels across, got " + std::to_string(cell));
  const int cols = grey.cols / cell, rows = grey.rows / cell;
  out.create(rows, cols, CV_8UC1);
  CellRows sums;
  for (int cy = 0; cy < rows; ++cy)
  {
    sums.start(cols * cell, cell);
    for (int y = cy * cell; y < (cy + 1) * cell; ++y)
      sums.add(grey.ptr<uint8_t>(y));
    sums.means(out.ptr<uint8_t>(cy));
  }
}
}  // namespace stereo_pf
