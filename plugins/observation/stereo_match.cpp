// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Stereo-consistency observation model (ZNCC of a hypothesis's left and right grey patches);
// see include/stereo_pf/plugins/stereo_match.h.
#include "stereo_pf/plugins/stereo_match.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>

#include "stereo_pf/core/histogram.h"

namespace stereo_pf
{
void StereoMatch::onInitialize()
{
  tunables_ = readTunables();
  invalid_log_likelihood_ = -1.0 / (2.0 * tunables_.sigma * tunables_.sigma);
}

StereoMatch::Tunables StereoMatch::readTunables() const
{
  const Parameters& p = params();
  Tunables t;
  t.sigma = p.getDouble("sigma", t.sigma, 0.001, 10.0, "log-likelihood -(1 - ZNCC) / (2 sigma^2)");
  t.window_scale = p.getDouble("window_scale", t.window_scale, 0.2, 3.0,
                               "compared disc, in apparent radii (> 1: includes the silhouette)");
  t.surface_depth = p.getDouble("surface_depth", t.surface_depth, 0.0, 1.0,
                                "object radii; the right window is centred on the image of the point this far in "
                                "front of the centre on the left ray: what the views match is the object's near side");
  t.rows = p.getInt("rows", t.rows, 1, 41, "sample rows across the disc");
  t.column_step = p.getInt("column_step", t.column_step, 0, 20,
                           "px between samples along a row (whole pixels: one sub-pixel phase); 0: from samples");
  t.samples = p.getInt("samples", t.samples, 4, 10000,
                       "samples per view the column step aims at when column_step is 0");
  t.min_contrast = p.getDouble("min_contrast", t.min_contrast, 0.1, 100.0,
                               "grey levels; floor of each patch's standard deviation");
  t.min_radius = p.getDouble("min_radius", t.min_radius, 0.5, 100.0, "px; smaller apparent radii are clamped to it");
  t.edges = p.getBool("edges", t.edges,
                       "also correlate the views' Sobel gradient magnitudes and take the better of the two: an "
                       "outline whose contrast the two views' backgrounds invert still matches");
  t.only_while_tracking = p.getBool("only_while_tracking", t.only_while_tracking,
                                    "skipped while searching or lost, where it would reward any textured surface it "
                                    "can triangulate");
  return t;
}

void StereoMatch::reconfigure()
{
  const Tunables t = readTunables();  // throws before anything changes
  ObservationModel::reconfigure();
  tunables_ = t;
  invalid_log_likelihood_ = -1.0 / (2.0 * t.sigma * t.sigma);
}

bool StereoMatch::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  cv::Rect inner;
  std::string reason;
  if (!targetRegion(cache.image(view).size(), roi, 0.0, inner, reason))
  {
    error = name() + ": " + reason;
    return false;
  }
  return true;
}

void StereoMatch::evaluate(FeatureCache&, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                           Eigen::Ref<Eigen::VectorXd> similarity)
{
  if (log_likelihood.size() != hyp.size() || similarity.size() != hyp.size())
    throw std::invalid_argument(name() + ": evaluate: outputs must have " + std::to_string(hyp.size()) + " entries");
  log_likelihood.setConstant(invalid_log_likelihood_);
  similarity.setZero();
}

double StereoMatch::zncc(FeatureCache& cache, float u_left, float u_right, float v, float radius)
{
  const cv::Mat& left = cache.gray(View::Left);
  const cv::Mat& right = cache.gray(View::Right);
  const cv::Point origin(0, 0);
  if (!tunables_.edges)
    return match(left, origin, right, origin, u_left, u_right, v, radius);
  edgeImage(left, edges_[0]);
  edgeImage(right, edges_[1]);
  return match(left, origin, right, origin, u_left, u_right, v, radius, &edges_[0], &edges_[1]);
}

void StereoMatch::edgeImage(const cv::Mat& grey, cv::Mat& edges)
{
  // 3x3 Sobel: a full 0-255 step gives at most 4 * 255 along one axis, so a quarter keeps the levels in 8 bits
  // (a diagonal step's sqrt(2) more saturates: an outline is still an outline).
  cv::Sobel(grey, sobel_x_, CV_32F, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(grey, sobel_y_, CV_32F, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::magnitude(sobel_x_, sobel_y_, magnitude_);
  magnitude_.convertTo(edges, CV_8U, 0.25);
}

namespace
{
int floorDiv(int a, int b)  // b > 0
{
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

struct MatchSums
{
  int n = 0;
  float sa = 0.0f, sb = 0.0f, saa = 0.0f, sbb = 0.0f, sab = 0.0f;
};
}  // namespace

double StereoMatch::halfSize(float radius) const
{
  return tunables_.window_scale * std::max(static_cast<double>(radius), tunables_.min_radius);
}

double StereoMatch::match(const cv::Mat& left, cv::Point left_origin, const cv::Mat& right, cv::Point right_origin,
                          float u_left, float u_right, float v, float radius, const cv::Mat* left_edges,
                          const cv::Mat* right_edges) const
{
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  if (!(radius > 0.0f) || !std::isfinite(u_left) || !std::isfinite(u_right) || !std::isfinite(v))
    return kNaN;
  // Work in the regions' own coordinates; outside a region is outside the image for this hypothesis.
  u_left -= static_cast<float>(left_origin.x);
  u_right -= static_cast<float>(right_origin.x);
  const float v_left = v - static_cast<float>(left_origin.y);
  const int row_shift = left_origin.y - right_origin.y;  // right row = left row + row_shift
  const double half = halfSize(radius);
  const int max_extent = std::max({ left.cols, left.rows, right.cols, right.rows });
  if (half > 4.0 * max_extent)
    return kNaN;
  // Samples on `rows` rows across the disc, `column_step` whole pixels apart along each row: every sample of
  // a view shares the centre's sub-pixel phase, hence one pair of interpolation weights per view. Dense
  // along the rows because only horizontal shifts change the disparity; a few rows suffice.
  const int rows = tunables_.rows;
  const int step = tunables_.column_step > 0 ?
                       tunables_.column_step :
                       std::max(1, static_cast<int>(std::lround(rows * 2.0 * half / tunables_.samples)));
  const double row_spacing = 2.0 * half / (rows + 1);
  const double half2 = half * half;
  const double xl_f = std::floor(u_left), xr_f = std::floor(u_right);
  // Far outside: nothing to sample (and the int conversions below stay in range).
  const double far = half + 2.0 * max_extent;
  if (std::abs(xl_f) > far || std::abs(xr_f) > far || std::abs(v_left) > far)
    return kNaN;
  const int xl0 = static_cast<int>(xl_f), xr0 = static_cast<int>(xr_f);
  const float fl = u_left - static_cast<float>(xl_f), fr = u_right - static_cast<float>(xr_f);
  // Offsets whose columns x and x + 1 lie in both regions.
  const int in_lo = std::max(-floorDiv(xl0, step), -floorDiv(xr0, step));
  const int in_hi = std::min(floorDiv(left.cols - 2 - xl0, step), floorDiv(right.cols - 2 - xr0, step));

  int nominal = 0;
  MatchSums m, e;  // grey levels, and gradient magnitudes (`edges`) at the same samples
  const bool edges = left_edges && right_edges;
  // Relative to mid-grey: keeps the float sums of squares well conditioned.
  const auto add = [fl, fr](MatchSums& sums, const uint8_t* lrow, const uint8_t* rrow, int xl, int xr) {
    const float l0 = lrow[xl], r0 = rrow[xr];
    const float a = l0 + fl * (static_cast<float>(lrow[xl + 1]) - l0) - 128.0f;
    const float b = r0 + fr * (static_cast<float>(rrow[xr + 1]) - r0) - 128.0f;
    sums.sa += a;
    sums.sb += b;
    sums.saa += a * a;
    sums.sbb += b * b;
    sums.sab += a * b;
  };
  for (int k = 0; k < rows; ++k)
  {
    const double dy = (k - 0.5 * (rows - 1)) * row_spacing;
    const int kx_max = static_cast<int>(std::sqrt(std::max(0.0, half2 - dy * dy)) / step);
    nominal += 2 * kx_max + 1;
    const int yl = static_cast<int>(std::lround(v_left + dy)), yr = yl + row_shift;
    const int lo = std::max(-kx_max, in_lo), hi = std::min(kx_max, in_hi);
    if (yl < 0 || yl >= left.rows || yr < 0 || yr >= right.rows || lo > hi)
      continue;
    const uint8_t* lrow = left.ptr<uint8_t>(yl);
    const uint8_t* rrow = right.ptr<uint8_t>(yr);
    if (edges)
    {
      // One pass over both pairs of images: the samples' places and interpolation weights are shared.
      const uint8_t* lerow = left_edges->ptr<uint8_t>(yl);
      const uint8_t* rerow = right_edges->ptr<uint8_t>(yr);
      for (int kx = lo; kx <= hi; ++kx)
      {
        add(m, lrow, rrow, xl0 + kx * step, xr0 + kx * step);
        add(e, lerow, rerow, xl0 + kx * step, xr0 + kx * step);
      }
    }
    else
      for (int kx = lo; kx <= hi; ++kx)
        add(m, lrow, rrow, xl0 + kx * step, xr0 + kx * step);
    m.n += hi - lo + 1;
  }
  if (m.n < 3 || 2 * m.n < nominal)
    return kNaN;
  const double inv_n = 1.0 / m.n;
  const double floor2 = tunables_.min_contrast * tunables_.min_contrast;
  const auto zncc = [inv_n, floor2](const MatchSums& sums) {
    const double ma = sums.sa * inv_n, mb = sums.sb * inv_n;
    const double var_a = std::max(sums.saa * inv_n - ma * ma, floor2);
    const double var_b = std::max(sums.sbb * inv_n - mb * mb, floor2);
    const double cov = sums.sab * inv_n - ma * mb;
    return std::max(-1.0, std::min(1.0, cov / std::sqrt(var_a * var_b)));
  };
  // The better of the two: an outline matches in its edges whichever side of it is brighter in each view.
  return edges ? std::max(zncc(m), zncc(e)) : zncc(m);
}

void StereoMatch::greyRegion(FeatureCache& cache, const ImageHypotheses& hyp, const ImageHypotheses& partner,
                             cv::Mat& grey, cv::Point& origin)
{
  const cv::Mat& image = cache.image(hyp.view);
  // Bounding box of every window that will be read (plus the interpolation's extra column).
  double x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL;
  for (int i = 0; i < hyp.size(); ++i)
  {
    if (!hyp.valid[i] || !partner.valid[i] || !(hyp.radius[i] > 0.0f) || !std::isfinite(hyp.u[i]) ||
        !std::isfinite(hyp.v[i]))
      continue;
    const double half = halfSize(hyp.radius[i]);
    if (half > 4.0 * std::max(image.cols, image.rows))
      continue;  // match() judges these unobservable
    x0 = std::min(x0, hyp.u[i] - half);
    x1 = std::max(x1, hyp.u[i] + half);
    y0 = std::min(y0, hyp.v[i] - half);
    y1 = std::max(y1, hyp.v[i] + half);
  }
  const cv::Rect whole(0, 0, image.cols, image.rows);
  cv::Rect box;
  if (x0 <= x1)
  {
    const auto clip = [](double x, int lo, int hi) { return static_cast<int>(std::max<double>(lo, std::min<double>(hi, x))); };
    const int bx0 = clip(std::floor(x0) - 1, 0, image.cols), bx1 = clip(std::floor(x1) + 3, 0, image.cols);
    const int by0 = clip(std::floor(y0) - 1, 0, image.rows), by1 = clip(std::ceil(y1) + 2, 0, image.rows);
    box = cv::Rect(bx0, by0, bx1 - bx0, by1 - by0) & whole;
  }
  if (box.empty())
    box = cv::Rect(0, 0, std::min(2, image.cols), std::min(2, image.rows));
  origin = box.tl();
  // Only the region is converted: while tracking a few thousand pixels instead of two whole images.
  if (image.channels() == 1)
    grey = image(box);
  else if (image.channels() == 3)
    cv::cvtColor(image(box), grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image(box), grey, cv::COLOR_BGRA2GRAY);
  else
    throw std::invalid_argument(name() + ": images must be 8-bit grey, BGR or BGRA");
}

void StereoMatch::evaluatePair(FeatureCache& cache, const ImageHypotheses& left, const ImageHypotheses& right,
                               Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity)
{
  const int n = left.size();
  if (right.size() != n || log_likelihood.size() != n || similarity.size() != n ||
      static_cast<int>(left.v.size()) != n || static_cast<int>(left.radius.size()) != n ||
      static_cast<int>(left.valid.size()) != n || static_cast<int>(right.valid.size()) != n ||
      static_cast<int>(right.v.size()) != n || static_cast<int>(right.radius.size()) != n)
    throw std::invalid_argument(name() + ": evaluatePair: hypothesis arrays and outputs must all have " +
                                std::to_string(n) + " entries");
  if (left.view != View::Left || right.view != View::Right)
    throw std::invalid_argument(name() + ": evaluatePair: expects the left view's hypotheses first");
  log_likelihood.setConstant(invalid_log_likelihood_);
  similarity.setZero();
  if (n == 0)
    return;
  // The matched surface lies in front of the centre by about surface_depth radii: at depth z - k r instead of z,
  // so its disparity is d z / (z - k r) = d / (1 - k R / fx), R the apparent radius (r / z = R / fx).
  const ImageHypotheses* compared = &right;
  const double k_over_fx = tunables_.surface_depth / cache.geometry().fx();
  if (k_over_fx > 0.0)
  {
    near_side_ = right;
    for (int i = 0; i < n; ++i)
    {
      const double shrink = 1.0 - k_over_fx * left.radius[i];
      if (left.valid[i] && right.valid[i] && shrink > 0.5)
        near_side_.u[i] = static_cast<float>(left.u[i] - (left.u[i] - right.u[i]) / shrink);
    }
    compared = &near_side_;
  }
  cv::Point origin_left, origin_right;
  greyRegion(cache, left, *compared, grey_[0], origin_left);
  greyRegion(cache, *compared, left, grey_[1], origin_right);
  const bool edges = tunables_.edges;
  if (edges)
  {
    edgeImage(grey_[0], edges_[0]);
    edgeImage(grey_[1], edges_[1]);
  }
  const double inv_two_sigma2 = 1.0 / (2.0 * tunables_.sigma * tunables_.sigma);
  for (int i = 0; i < n; ++i)
  {
    if (!left.valid[i] || !right.valid[i])
      continue;
    // Rectified: both views share the row; the radius is the left one (equal for a point model).
    const double z = match(grey_[0], origin_left, grey_[1], origin_right, left.u[i], compared->u[i], left.v[i],
                           left.radius[i], edges ? &edges_[0] : nullptr, edges ? &edges_[1] : nullptr);
    if (std::isnan(z))
      continue;
    log_likelihood[i] = -(1.0 - z) * inv_two_sigma2;
    similarity[i] = std::max(0.0, z);
  }
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::StereoMatch, stereo_pf::ObservationModel)
