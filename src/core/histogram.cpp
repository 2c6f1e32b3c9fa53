// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/histogram.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace stereo_pf
{
TargetHistogram::TargetHistogram(const std::vector<double>& counts)
{
  double sum = 0.0;
  for (const double c : counts)
  {
    if (!std::isfinite(c) || c < 0.0)
      throw std::invalid_argument("TargetHistogram: counts must be finite and non-negative, got " + std::to_string(c));
    sum += c;
  }
  if (sum <= 0.0)
    return;  // no mass: stays invalid
  p_.resize(counts.size());
  sqrt_p_.resize(counts.size());
  for (size_t b = 0; b < counts.size(); ++b)
  {
    p_[b] = counts[b] / sum;
    sqrt_p_[b] = std::sqrt(p_[b]);
  }
}

TargetHistogram TargetHistogram::fromBinImage(const cv::Mat& bin_image, const cv::Rect& roi, int bins)
{
  if (bins < 1)
    throw std::invalid_argument("TargetHistogram::fromBinImage: bins must be >= 1, got " + std::to_string(bins));
  const int type = bin_image.type();
  if (type != CV_8UC1 && type != CV_16UC1)
    throw std::invalid_argument("TargetHistogram::fromBinImage: expected a CV_8UC1 or CV_16UC1 bin image, got type " +
                                std::to_string(type));
  const cv::Rect r = roi & cv::Rect(0, 0, bin_image.cols, bin_image.rows);
  std::vector<double> counts(bins, 0.0);
  for (int y = r.y; y < r.y + r.height; ++y)
  {
    if (type == CV_8UC1)
    {
      const uint8_t* row = bin_image.ptr<uint8_t>(y);
      for (int x = r.x; x < r.x + r.width; ++x)
        if (row[x] < bins)
          counts[row[x]] += 1.0;
    }
    else
    {
      const uint16_t* row = bin_image.ptr<uint16_t>(y);
      for (int x = r.x; x < r.x + r.width; ++x)
        if (row[x] < bins)
          counts[row[x]] += 1.0;
    }
  }
  return TargetHistogram(counts);
}

double bhattacharyya(const std::vector<double>& p, const std::vector<double>& q)
{
  if (p.size() != q.size())
    throw std::invalid_argument("bhattacharyya: histograms have " + std::to_string(p.size()) + " and " +
                                std::to_string(q.size()) + " bins");
  double rho = 0.0;
  for (size_t u = 0; u < p.size(); ++u)
    rho += std::sqrt(std::max(p[u], 0.0) * std::max(q[u], 0.0));
  // Rounding can push identical histograms a hair above 1.
  return std::min(rho, 1.0);
}

void SparseHistogram::reset(int bins, int max_samples)
{
  if (bins < 1)
    throw std::invalid_argument("SparseHistogram::reset: bins must be >= 1, got " + std::to_string(bins));
  counts_.assign(static_cast<size_t>(bins) * kBanks, 0);
  stamp_.assign(bins, 0u);
  epoch_ = 1;
  touched_.assign(bins, 0);  // a bin is listed at most once per candidate
  const int m = std::max(max_samples, 1);
  sqrt_int_.resize(m + 1);
  for (int k = 0; k <= m; ++k)
    sqrt_int_[k] = std::sqrt(static_cast<double>(k));
  n_touched_ = 0;
  n_ = 0;
}

/// The counting state in locals: a counter store could alias the members (int / uint32_t), which would force a
/// reload and a store of each after every sample. count() then mark() per sample; store() writes it back.
struct SparseHistogram::Tally
{
  explicit Tally(SparseHistogram& h)
    : counts(h.counts_.data()), touched(h.touched_.data()), stamp(h.stamp_.data()), epoch(h.epoch_),
      n_touched(static_cast<size_t>(h.n_touched_))
  {
  }
  // Bins and banks as size_t: with int the compiler sign-extends every index it builds.
  void count(size_t b, size_t bank) { ++counts[b * kBanks + bank]; }
  void mark(size_t b)
  {
    if (stamp[b] != epoch)
    {
      stamp[b] = epoch;
      touched[n_touched++] = static_cast<int>(b);
    }
  }
  /// Four samples, one per bank: the counts first, then the marks (so no count waits for a mark's branch).
  void count4(size_t b0, size_t b1, size_t b2, size_t b3)
  {
    count(b0, 0);
    count(b1, 1);
    count(b2, 2);
    count(b3, 3);
    mark(b0);
    mark(b1);
    mark(b2);
    mark(b3);
  }
  void store(SparseHistogram& h, int samples) const
  {
    h.n_touched_ = static_cast<int>(n_touched);
    h.n_ += samples;
  }

  int* counts;
  int* touched;
  uint32_t* stamp;
  const uint32_t epoch;
  size_t n_touched;
};

void SparseHistogram::addGrid(const uint8_t* data, size_t step, const int* rows, int nr, const int* cols, int nc)
{
  Tally t(*this);
  static_assert(kBanks == 4, "the unrolled loop below assumes 4 banks");
  for (int j = 0; j < nr; ++j)
  {
    const uint8_t* row = data + static_cast<size_t>(rows[j]) * step;
    int k = 0;
    for (; k + 4 <= nc; k += 4)
    {
      const size_t b0 = row[cols[k]], b1 = row[cols[k + 1]], b2 = row[cols[k + 2]], b3 = row[cols[k + 3]];
      t.count4(b0, b1, b2, b3);
    }
    // The last 0-3 columns without a loop (their number is the same on every row), in order.
    const int rest = nc - k;
    if (rest > 0)
    {
      const size_t b = row[cols[k]];
      t.count(b, 0);
      t.mark(b);
    }
    if (rest > 1)
    {
      const size_t b = row[cols[k + 1]];
      t.count(b, 1);
      t.mark(b);
    }
    if (rest > 2)
    {
      const size_t b = row[cols[k + 2]];
      t.count(b, 2);
      t.mark(b);
    }
  }
  t.store(*this, nr * nc);
}

void SparseHistogram::addValues(const uint8_t* values, int n)
{
  Tally t(*this);
  static_assert(kBanks == 4, "the unrolled loop below assumes 4 banks");
  int k = 0;
  for (; k + 4 <= n; k += 4)
    t.count4(values[k], values[k + 1], values[k + 2], values[k + 3]);
  for (; k < n; ++k)
  {
    t.count(values[k], static_cast<size_t>(k & 3));
    t.mark(values[k]);
  }
  t.store(*this, std::max(n, 0));
}

double SparseHistogram::scoreAndClear(const TargetHistogram& target)
{
  const bool score = n_ > 0 && target.bins() == bins();
  // rho = sum_b sqrt(c_b / n) sqrt(q_b) = (1 / sqrt(n)) sum_b sqrt(c_b) sqrt(q_b): one division per candidate.
  const double* sqrt_q = score ? target.sqrtProbabilities().data() : nullptr;
  const double* sqrt_int = sqrt_int_.data();
  const int table_max = static_cast<int>(sqrt_int_.size()) - 1;
  double sum = 0.0;
  for (int k = 0; k < n_touched_; ++k)
  {
    const int b = touched_[k];
    int* c = &counts_[static_cast<size_t>(b) * kBanks];
    const int count = c[0] + c[1] + c[2] + c[3];
    c[0] = c[1] = c[2] = c[3] = 0;
    if (score)
      sum += (count <= table_max ? sqrt_int[count] : std::sqrt(static_cast<double>(count))) * sqrt_q[b];
  }
  const double rho = score ? std::min(sum / std::sqrt(static_cast<double>(n_)), 1.0) : 0.0;
  n_touched_ = 0;
  n_ = 0;
  // A new epoch unmarks every bin without visiting them; on wrap-around clear the stamps for real.
  if (++epoch_ == 0)
  {
    std::fill(stamp_.begin(), stamp_.end(), 0u);
    epoch_ = 1;
  }
  return rho;
}

bool learnTargetHistogram(const cv::Mat& bin_image, const cv::Rect& roi, double margin, int bins,
                          TargetHistogram& target, std::string& reason)
{
  cv::Rect inner;
  if (!targetRegion(bin_image.size(), roi, margin, inner, reason))
    return false;
  TargetHistogram t = TargetHistogram::fromBinImage(bin_image, inner, bins);
  if (!t.valid())
  {
    reason = "no pixel of " + describeRect(inner) + " could be binned";
    return false;
  }
  target = std::move(t);
  return true;
}

cv::FileNode targetNode(const cv::FileNode& node, const std::string& name, const std::string& what,
                        std::string& error)
{
  // Accept the map itself or its parent (the file root).
  cv::FileNode m = node;
  if (m.isMap() && m["histogram"].empty())
    m = node[name];
  if (m.empty() || !m.isMap())
  {
    error = name + ": no " + what + " named '" + name + "' in the file";
    return cv::FileNode();
  }
  return m;
}

std::string describeRect(const cv::Rect& r)
{
  return std::to_string(r.width) + "x" + std::to_string(r.height) + " at (" + std::to_string(r.x) + ", " +
         std::to_string(r.y) + ")";
}

bool targetRegion(const cv::Size& image_size, const cv::Rect& roi, double margin, cv::Rect& inner, std::string& reason)
{
  if (image_size.area() <= 0)
  {
    reason = "the frame has no image in this view";
    return false;
  }
  if (roi.width <= 0 || roi.height <= 0)
  {
    reason = "the region " + describeRect(roi) + " is empty";
    return false;
  }
  const cv::Rect bounds(0, 0, image_size.width, image_size.height);
  if ((roi & bounds).empty())
  {
    reason = "the region " + describeRect(roi) + " lies outside the " + std::to_string(image_size.width) + "x" +
             std::to_string(image_size.height) + " image";
    return false;
  }
  // Shrink relative to the object's box first, then clip: the margin is about the object's outline
  // (background corners of a ball's bounding box), not about the image border.
  const int mx = static_cast<int>(std::lround(roi.width * margin));
  const int my = static_cast<int>(std::lround(roi.height * margin));
  inner = cv::Rect(roi.x + mx, roi.y + my, roi.width - 2 * mx, roi.height - 2 * my) & bounds;
  if (inner.width < 3 || inner.height < 3)
  {
    reason = "the region " + describeRect(roi) + " leaves only " + describeRect(inner) +
             " inside the image after the target_margin of " + std::to_string(margin) +
             " per side (at least 3x3 pixels needed)";
    return false;
  }
  return true;
}

void WindowGrid::reset(int samples)
{
  if (samples < 1 || samples > kMaxSamples)
    throw std::invalid_argument("WindowGrid::reset: samples must lie in [1, " + std::to_string(kMaxSamples) +
                                "], got " + std::to_string(samples));
  samples_ = samples;
  // Padded to whole vectors with the last offset (its lanes are computed, never kept).
  const int padded = (samples + 3) / 4 * 4;
  offsets_.assign(padded, 0.0f);
  for (int k = 0; k < padded; ++k)
  {
    const int j = std::min(k, samples - 1);
    offsets_[k] = samples > 1 ? static_cast<float>(-1.0 + 2.0 * j / (samples - 1)) : 0.0f;
  }
  cols_.resize(padded);
  rows_.resize(padded);
}

namespace
{
/// The grid's coordinates along one axis, cvRound(c + half * offsets[k]) for every k < n, into out; the ones in
/// [0, size) are out[first, first + count). With half >= 0 they rise with k, so those in the image are one run:
/// where the coordinates below 0 and those below `size` end gives it without a test per sample.
void axisSpan(float c, float half, int size, int n, const float* offsets, int* out, int& first, int& count)
{
  if (half >= 0.0f && std::abs(c) + half < 1e9f)  // (beyond, a rounding overflows to INT_MIN and falls)
  {
    const cv::v_float32x4 v_c = cv::v_setall_f32(c), v_half = cv::v_setall_f32(half);
    const cv::v_int32x4 zero = cv::v_setzero_s32(), v_size = cv::v_setall_s32(size);
    uint64_t below = 0, inside_or_below = 0;
    for (int k = 0; k < n; k += 4)
    {
      const cv::v_int32x4 x = cv::v_round(v_c + v_half * cv::v_load(offsets + k));  // as cvRound: ties to even
      cv::v_store(out + k, x);
      below |= static_cast<uint64_t>(cv::v_signmask(x < zero)) << k;
      inside_or_below |= static_cast<uint64_t>(cv::v_signmask(x < v_size)) << k;
    }
    // Both masks are runs of ones from bit 0 (the coordinates rise): their lengths are the trailing ones
    // (one bit-scan instruction each; a population count is a library call without -mpopcnt).
    const uint64_t valid = (uint64_t{ 1 } << n) - 1u;
    first = __builtin_ctzll(~(below & valid));
    count = std::max(__builtin_ctzll(~(inside_or_below & valid)) - first, 0);
    return;
  }
  // A negative half-size (not used by the cues) or a huge one: kept in order, one by one.
  first = 0;
  count = 0;
  for (int k = 0; k < n; ++k)
  {
    const int x = cvRound(c + half * offsets[k]);
    if (x >= 0 && x < size)
      out[count++] = x;
  }
}
}  // namespace

bool WindowGrid::place(float u, float v, float half, int width, int height, int min_inside)
{
  nc_ = nr_ = 0;
  col0_ = row0_ = 0;
  // Written so that NaN positions fail too.
  if (!(u > -half - 1.0f && u < width + half + 1.0f && v > -half - 1.0f && v < height + half + 1.0f))
    return false;
  axisSpan(u, half, width, samples_, offsets_.data(), cols_.data(), col0_, nc_);
  axisSpan(v, half, height, samples_, offsets_.data(), rows_.data(), row0_, nr_);
  return nc_ * nr_ >= min_inside;
}

HistogramWindowTunables HistogramWindowTunables::fromParameters(const Parameters& p)
{
  HistogramWindowTunables t;
  t.sigma = p.getDouble("sigma", t.sigma, 0.001, 10.0,
                        "Bhattacharyya-distance sigma of the likelihood -(1 - rho) / (2 sigma^2)");
  t.window = p.getInt("window", t.window, 3, 101, "px, odd; sampling window of hypotheses without a radius");
  if (t.window % 2 == 0)
    throw ParameterError("parameter '" + (p.prefix().empty() ? std::string() : p.prefix() + "/") + "window' = " +
                         std::to_string(t.window) + " must be odd (allowed: odd integers in [3, 101])");
  t.window_scale = p.getDouble("window_scale", t.window_scale, 0.1, 3.0,
                               "window half-size as a fraction of the apparent radius");
  t.samples = p.getInt("samples", t.samples, 3, 31, "samples per window side (constant cost per hypothesis)");
  t.min_radius = p.getDouble("min_radius", t.min_radius, 0.5, 100.0, "px; smaller apparent radii are clamped to it");
  t.target_margin = p.getDouble("target_margin", t.target_margin, 0.0, 0.45,
                                "fraction of the learned box trimmed at each side");
  return t;
}

}  // namespace stereo_pf
