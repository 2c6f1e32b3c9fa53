// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Colour-outline observation model; see include/stereo_pf/plugins/colour_contour.h.
#include "stereo_pf/plugins/colour_contour.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>

#include "stereo_pf/core/silhouette.h"

namespace stereo_pf
{
namespace
{
// Pseudo-probability in P = (q + e) / (q + b + 2 e): a colour seen in neither histogram says nothing (0.5).
constexpr double kPrior = 1e-3;
// The background is learned outside the region grown by this fraction of its size on each side, so the
// object's blurred rim (and a shadow next to it) stays out.
constexpr double kBackgroundGrowth = 0.5;
// Resolution of the soft-step table: 1/32 px is far below what the outline can be located to.
constexpr float kStepsPerPixel = 32.0f;
// Lines per vector of the outline-point computation.
constexpr int kLines4 = cv::v_float32x4::nlanes;

std::string scoped(const Parameters& p, const std::string& key)
{
  return p.prefix().empty() ? key : p.prefix() + "/" + key;
}
}  // namespace

void ColourContour::onInitialize()
{
  const HsiBinning b = HsiBinning::fromParameters(params());
  const Tunables t = readTunables();  // validate everything before changing any state
  binner_ = std::make_unique<const HsiBinner>(b);  // the table: ~10 ms, once
  binning_ = b;
  target_ = background_ = TargetHistogram();  // a target learned with another binning would be meaningless
  lut_.assign(256, 128);
  applyTunables(t);
}

ColourContour::Tunables ColourContour::readTunables() const
{
  const Parameters& p = params();
  Tunables t;
  t.sigma = p.getDouble("sigma", 0.05, 0.001, 10.0,
                        "log-likelihood -m / (2 sigma^2), m: mean squared difference from the soft step");
  t.lines = p.getInt("lines", 16, 4, 256, "radial lines across the outline");
  t.preview_lines = p.getInt("preview_lines", t.preview_lines, 0, 256,
                             "lines of the cheap preview the engine screens particles by while tracking, at most "
                             "`lines` (0: no preview, the full outline screens)");
  if (t.preview_lines != 0 && t.preview_lines < 4)
    throw ParameterError("parameter '" + scoped(p, "preview_lines") + "' = " + std::to_string(t.preview_lines) +
                         " (allowed: 0 = no preview, or 4..256)");
  t.preview_lines = std::min(t.preview_lines, t.lines);
  t.line_half_length = p.getInt("line_half_length", 2, 1, 10, "px (pixel steps) on each side of the outline");
  t.softness = p.getDouble("softness", 0.7, 0.1, 10.0, "px; width of the expected step 1 / (1 + exp(d / softness))");
  t.target_margin = p.getDouble("target_margin", 0.15, 0.0, 0.45,
                                "fraction of the learned box trimmed at each side (target histogram)");
  t.radius = p.getDouble("radius", 0.0, 0.0, 2000.0,
                         "px; radius of 2D hypotheses (0: learned from the region of interest)");
  t.min_radius = p.getDouble("min_radius", 2.0, 0.5, 1000.0, "px; smaller apparent radii are clamped to it");
  t.perspective = p.getBool("perspective", true,
                            "3D hypotheses: the sphere's true (elliptical) outline off the optical axis");
  if (t.radius > 0.0 && t.radius < t.min_radius)
    throw ParameterError("parameter '" + scoped(p, "radius") + "' = " + std::to_string(t.radius) +
                         " is below '" + scoped(p, "min_radius") + "' = " + std::to_string(t.min_radius) +
                         " (allowed: 0 = learned, or >= min_radius)");
  t.intensity_tolerance = p.getDouble("intensity_tolerance", t.intensity_tolerance, 0.0, 1.0,
                                      "share of each colour's mass also given to one intensity slice darker and "
                                      "lighter in both histograms: a face of the target's colour in shade still "
                                      "counts as the target (0: off)");
  return t;
}

void ColourContour::applyTunables(const Tunables& t)
{
  tunables_ = t;
  const int half = t.line_half_length;
  // The soft step by signed distance, over every distance a sample can have: its position along the line
  // (at most sqrt(2) + 0.36 px per step) plus the base pixel's rounding offset (at most 0.71 px).
  const float max_distance = static_cast<float>(half) * 1.8f + 1.0f;
  const int entries = 2 * static_cast<int>(std::ceil(max_distance * kStepsPerPixel)) + 1;
  expected_.resize(entries);
  for (int i = 0; i < entries; ++i)
  {
    const double d = (i - entries / 2) / kStepsPerPixel;
    expected_[i] = static_cast<float>(1.0 / (1.0 + std::exp(d / t.softness)));
  }
  full_.build(t.lines, half, t.softness);
  preview_.build(std::max(t.preview_lines, 1), half, t.softness);
  const int padded = (std::max(t.lines, t.preview_lines) + kLines4 - 1) / kLines4 * kLines4;
  base_x_.resize(padded);
  base_y_.resize(padded);
  base_.resize(padded);
  origin_.resize(padded);
  // An unobservable hypothesis scores like background: no evidence either way.
  invalid_log_likelihood_ = -full_.background_mismatch / (2.0 * t.sigma * t.sigma);
  buildTable();  // intensity_tolerance may have changed
}

void ColourContour::Pattern::build(int line_count, int half, double softness)
{
  lines = line_count;
  samples_per_line = 2 * half + 1;
  const size_t samples = static_cast<size_t>(lines) * samples_per_line;
  const int padded = (lines + kLines4 - 1) / kLines4 * kLines4;
  line_c.assign(padded, 1.0f);
  line_s.assign(padded, 0.0f);
  dx.resize(samples);
  dy.resize(samples);
  along.resize(samples);
  along_scaled.resize(samples);
  reach = 0;
  for (int k = 0; k < lines; ++k)
  {
    const double angle = 2.0 * M_PI * k / lines;
    const double c = std::cos(angle), s = std::sin(angle);
    line_c[k] = static_cast<float>(c);
    line_s[k] = static_cast<float>(s);
    for (int j = 0; j < samples_per_line; ++j)
    {
      const size_t i = static_cast<size_t>(k) * samples_per_line + j;
      digitalLineStep(c, s, j - half, dx[i], dy[i]);
      along[i] = static_cast<float>(dx[i] * c + dy[i] * s);
      along_scaled[i] = along[i] * kStepsPerPixel;
      reach = std::max(reach, std::max(std::abs(dx[i]), std::abs(dy[i])));
    }
  }
  offsets_step = 0;  // rebuilt for the image's row step at the next evaluation
  // m on plain background (P = 0): the mean squared step over the pattern, for a base pixel on the outline.
  double sum = 0.0;
  for (const float d : along)
  {
    const double e = 1.0 / (1.0 + std::exp(d / softness));
    sum += e * e;
  }
  background_mismatch = static_cast<float>(sum / along.size());
}

void ColourContour::Pattern::buildOffsets(size_t step)
{
  offsets.resize(dx.size());
  for (size_t i = 0; i < dx.size(); ++i)
    offsets[i] = static_cast<std::ptrdiff_t>(dy[i]) * static_cast<std::ptrdiff_t>(step) + dx[i];
  offsets_step = step;
}

void ColourContour::reconfigure()
{
  const Tunables t = readTunables();  // throws before anything changes
  ObservationModel::reconfigure();
  applyTunables(t);
}

void ColourContour::setTarget(TargetHistogram target, TargetHistogram background)
{
  const int n = binning_.bins();
  target_ = std::move(target);
  // Nothing outside the region (it covers the image), or an old file: a uniform background.
  background_ = background.valid() ? std::move(background) : TargetHistogram(std::vector<double>(n, 1.0));
  buildTable();
}

void ColourContour::buildTable()
{
  lut_.assign(256, 128);
  ++target_version_;
  if (!target_.valid())
    return;
  // As learned when nothing is spread (tolerance 0, grey histograms), to the last bit.
  const std::vector<double> q = binning_.spreadAlongIntensity(target_.probabilities(), tunables_.intensity_tolerance);
  const std::vector<double> b =
      binning_.spreadAlongIntensity(background_.probabilities(), tunables_.intensity_tolerance);
  for (int i = 0; i < binning_.bins(); ++i)
    lut_[i] = cv::saturate_cast<uint8_t>(255.0 * (q[i] + kPrior) / (q[i] + b[i] + 2.0 * kPrior));
}

bool ColourContour::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  const cv::Mat& image = cache.image(view);
  const cv::Mat& bins = binner_->cachedBins(cache, view, 0, image.rows);
  TargetHistogram target;
  std::string reason;
  if (!learnTargetHistogram(bins, roi, tunables_.target_margin, binning_.bins(), target, reason))
  {
    error = name() + ": cannot learn the target: " + reason;
    return false;
  }
  // The background: every pixel outside the grown region (OpenCV's histogram of the bin image under a mask).
  const int gx = static_cast<int>(std::ceil(kBackgroundGrowth * roi.width));
  const int gy = static_cast<int>(std::ceil(kBackgroundGrowth * roi.height));
  cv::Mat mask(bins.size(), CV_8UC1, cv::Scalar(255));
  cv::rectangle(mask, cv::Rect(roi.x - gx, roi.y - gy, roi.width + 2 * gx, roi.height + 2 * gy), cv::Scalar(0),
                cv::FILLED);
  cv::Mat counts;
  const int channels[] = { 0 };
  const int hist_size[] = { binning_.bins() };
  const float range[] = { 0.0f, static_cast<float>(binning_.bins()) };
  const float* ranges[] = { range };
  cv::calcHist(&bins, 1, channels, mask, counts, 1, hist_size, ranges);
  std::vector<double> background(binning_.bins());
  for (int b = 0; b < binning_.bins(); ++b)
    background[b] = counts.at<float>(b);
  setTarget(std::move(target), TargetHistogram(background));
  const cv::Rect clipped = roi & cv::Rect(0, 0, image.cols, image.rows);
  learned_radius_ = 0.5f * static_cast<float>(std::min(clipped.width, clipped.height));
  return true;
}

const cv::Mat& ColourContour::foregroundMap(FeatureCache& cache, View view, int y0, int y1)
{
  return foregroundMap(cache, view, cv::Rect(0, y0, cache.image(view).cols, std::max(0, y1 - y0)));
}

const cv::Mat& ColourContour::foregroundMap(FeatureCache& cache, View view, const cv::Rect& region)
{
  if (!binner_)
    throw std::logic_error("ColourContour: used before initialize()");
  const std::string key = "colour_contour/" + std::to_string(reinterpret_cast<uintptr_t>(this));
  return cache.getRegion(view, key, region, [this, &cache, view](const cv::Mat& image, cv::Mat& out, const cv::Rect& r) {
    out.create(image.size(), CV_8UC1);
    if (r.empty())
      return;
    cv::Mat part = out(r);
    const cv::Mat lut(1, 256, CV_8UC1, lut_.data());
    cv::LUT(binner_->cachedBins(cache, view, r)(r), lut, part);
  }, target_version_);
}

bool ColourContour::outline(const ImageHypotheses& hyp, int i, float focal, float cx, float cy, Outline& o) const
{
  if (!hyp.valid[i])
    return false;
  const float u = hyp.u[i], v = hyp.v[i];
  const bool has_radius = hyp.radius[i] > 0.0f;
  const float r = has_radius ? std::max(hyp.radius[i], static_cast<float>(tunables_.min_radius)) :
                               static_cast<float>(radius2D());
  // Also rejects NaN: a hypothesis this far off cannot have half of its samples inside any image.
  const float limit = 1e5f;
  if (!(r > 0.0f && r < limit && std::abs(u) < limit && std::abs(v) < limit))
    return false;
  o.cu = u;
  o.cv = v;
  o.ex = 1.0f;
  o.ey = 0.0f;
  o.a = o.b = r;
  if (has_radius && tunables_.perspective)
    sphereSilhouette(u, v, r, focal, cx, cy, o.ex, o.ey, o.a, o.b);
  return true;
}

namespace
{
// Sum of squared differences over the samples of every line when all of them are inside the image: no
// per-sample test, and with the samples per line known at compile time the inner loop unrolls into
// independent work (the lines' base pixels and table origins are computed beforehand).
template <int M>
float insideSum(const uint8_t* fg, const std::ptrdiff_t* base, const float* origin, const std::ptrdiff_t* offsets,
                const float* along, const float* expected, int last, int lines)
{
  constexpr float kScale = 1.0f / 255.0f;
  float sum = 0.0f;
  for (int k = 0; k < lines; ++k)
  {
    const uint8_t* p = fg + base[k];
    const float o = origin[k];
    const std::ptrdiff_t* off = offsets + k * M;
    const float* al = along + k * M;
    float line_sum = 0.0f;
#pragma GCC unroll 8  // -O2 keeps the loop over a line's M samples otherwise (a fifth of the cost)
    for (int j = 0; j < M; ++j)
    {
      const int t = std::min(std::max(static_cast<int>(al[j] + o), 0), last);
      const float diff = static_cast<float>(p[off[j]]) * kScale - expected[t];
      line_sum += diff * diff;
    }
    sum += line_sum;
  }
  return sum;
}
}  // namespace

float ColourContour::score(Pattern& pattern, const uint8_t* fg, size_t step, int width, int height, const Outline& o)
{
  if (step != pattern.offsets_step)
    pattern.buildOffsets(step);
  const int lines = pattern.lines;
  const int m = pattern.samples_per_line;
  const float ab = o.a * o.b, a2 = o.a * o.a, b2 = o.b * o.b;
  const bool circle = o.a == o.b;
  const std::ptrdiff_t stride = static_cast<std::ptrdiff_t>(step);
  const float centre = static_cast<float>(expected_.size() / 2);
  // Every line's base pixel (the outline point rounded) and the table position of the outline point relative
  // to it: a sample's distance is its pattern offset plus where the base pixel lies along the line. + 0.5 so
  // that truncation rounds (the table covers every distance a sample can have; the clamp is a safety net).
  // The line arrays are padded to whole vectors (padding: direction (1, 0), never read afterwards).
  int* base_x = base_x_.data();
  int* base_y = base_y_.data();
  std::ptrdiff_t* base = base_.data();
  float* origin = origin_.data();
  {
    // Four lines per vector instruction: per line this is a square root, a division and two roundings, as
    // much work as its samples.
    const cv::v_float32x4 v_cu = cv::v_setall_f32(o.cu), v_cv = cv::v_setall_f32(o.cv);
    const cv::v_float32x4 v_ex = cv::v_setall_f32(o.ex), v_ey = cv::v_setall_f32(o.ey);
    const cv::v_float32x4 v_ab = cv::v_setall_f32(ab), v_a2 = cv::v_setall_f32(a2), v_b2 = cv::v_setall_f32(b2);
    const cv::v_float32x4 v_a = cv::v_setall_f32(o.a);
    const cv::v_float32x4 v_steps = cv::v_setall_f32(kStepsPerPixel), v_centre = cv::v_setall_f32(centre + 0.5f);
    for (int k = 0; k < lines; k += kLines4)
    {
      const cv::v_float32x4 c = cv::v_load(pattern.line_c.data() + k), sn = cv::v_load(pattern.line_s.data() + k);
      cv::v_float32x4 rho = v_a;
      if (!circle)
      {
        // Distance from the centre to the ellipse along the line (psi: its angle to the radial axis).
        const cv::v_float32x4 cos_psi = c * v_ex + sn * v_ey, sin_psi = sn * v_ex - c * v_ey;
        rho = v_ab / cv::v_sqrt(v_b2 * cos_psi * cos_psi + v_a2 * sin_psi * sin_psi);
      }
      const cv::v_float32x4 bx = v_cu + rho * c, by = v_cv + rho * sn;
      const cv::v_int32x4 xi = cv::v_round(bx), yi = cv::v_round(by);
      cv::v_store(base_x + k, xi);
      cv::v_store(base_y + k, yi);
      const cv::v_float32x4 e = (cv::v_cvt_f32(xi) - bx) * c + (cv::v_cvt_f32(yi) - by) * sn;
      cv::v_store(origin + k, e * v_steps + v_centre);
    }
  }
  for (int k = 0; k < lines; ++k)
    base[k] = static_cast<std::ptrdiff_t>(base_y[k]) * stride + base_x[k];
  const int last = static_cast<int>(expected_.size()) - 1;
  const float extent = std::max(o.a, o.b) + static_cast<float>(pattern.reach) + 1.0f;
  if (o.cu - extent >= 0.0f && o.cu + extent <= static_cast<float>(width - 1) && o.cv - extent >= 0.0f &&
      o.cv + extent <= static_cast<float>(height - 1))
  {
    // Every sample inside (the usual case).
    const std::ptrdiff_t* off = pattern.offsets.data();
    const float* al = pattern.along_scaled.data();
    const float* ex = expected_.data();
    float sum;
    switch (m)
    {
      case 3:
        sum = insideSum<3>(fg, base, origin, off, al, ex, last, lines);
        break;
      case 5:
        sum = insideSum<5>(fg, base, origin, off, al, ex, last, lines);
        break;
      case 7:
        sum = insideSum<7>(fg, base, origin, off, al, ex, last, lines);
        break;
      default:
        sum = 0.0f;
        for (int k = 0; k < lines; ++k)
          for (int i = k * m; i < (k + 1) * m; ++i)
          {
            const int t = std::min(std::max(static_cast<int>(al[i] + origin[k]), 0), last);
            const float diff = static_cast<float>(fg[base[k] + off[i]]) * (1.0f / 255.0f) - ex[t];
            sum += diff * diff;
          }
    }
    return sum / static_cast<float>(lines * m);
  }
  // Near the border: test every sample.
  constexpr float kScale = 1.0f / 255.0f;
  float sum = 0.0f;
  int inside = 0;
  for (int k = 0; k < lines; ++k)
    for (int j = 0; j < m; ++j)
    {
      const size_t i = static_cast<size_t>(k) * m + j;
      const int x = base_x[k] + pattern.dx[i], y = base_y[k] + pattern.dy[i];
      if (x < 0 || x >= width || y < 0 || y >= height)
        continue;
      const int t = std::min(std::max(static_cast<int>(pattern.along_scaled[i] + origin[k]), 0), last);
      const float diff = static_cast<float>(fg[base[k] + pattern.offsets[i]]) * kScale - expected_[t];
      sum += diff * diff;
      ++inside;
    }
  if (2 * inside < lines * m)
    return std::numeric_limits<float>::quiet_NaN();
  return sum / static_cast<float>(inside);
}

void ColourContour::evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                             Eigen::Ref<Eigen::VectorXd> similarity)
{
  judge(cache, hyp, full_, log_likelihood, similarity, "evaluate");
}

bool ColourContour::preview(FeatureCache& cache, const ImageHypotheses& hyp,
                            Eigen::Ref<Eigen::VectorXd> log_likelihood)
{
  if (tunables_.preview_lines <= 0)
    return false;
  preview_similarity_.resize(hyp.size());
  judge(cache, hyp, preview_, log_likelihood, preview_similarity_, "preview");
  return true;
}

void ColourContour::judge(FeatureCache& cache, const ImageHypotheses& hyp, Pattern& pattern,
                          Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity,
                          const char* what)
{
  const int n = hyp.size();
  if (log_likelihood.size() != n || similarity.size() != n || static_cast<int>(hyp.v.size()) != n ||
      static_cast<int>(hyp.radius.size()) != n || static_cast<int>(hyp.valid.size()) != n)
    throw std::invalid_argument(name() + ": " + what + ": hypothesis arrays and outputs must all have " +
                                std::to_string(n) + " entries");
  log_likelihood.setConstant(invalid_log_likelihood_);
  similarity.setZero();
  if (!target_.valid() || n == 0)
    return;
  const int width = cache.image(hyp.view).cols;
  const int height = cache.image(hyp.view).rows;
  const float focal = static_cast<float>(cache.geometry().fx());
  const float cx = static_cast<float>(cache.geometry().cx());
  const float cy = static_cast<float>(cache.geometry().cy());

  // The outlines first: they say which pixels of the P map are read.
  outlines_.resize(static_cast<size_t>(n));
  float left = static_cast<float>(width), right = -1.0f, top = static_cast<float>(height), bottom = -1.0f;
  for (int i = 0; i < n; ++i)
  {
    Outline& o = outlines_[static_cast<size_t>(i)];
    if (!outline(hyp, i, focal, cx, cy, o))
    {
      o.a = 0.0f;
      continue;
    }
    const float extent = std::max(o.a, o.b) + static_cast<float>(pattern.reach) + 1.0f;
    left = std::min(left, o.cu - extent);
    right = std::max(right, o.cu + extent);
    top = std::min(top, o.cv - extent);
    bottom = std::max(bottom, o.cv + extent);
  }
  const cv::Mat& fg = foregroundMap(cache, hyp.view, spanRegion(left, right, top, bottom, width, height));

  const double inv_two_sigma2 = 1.0 / (2.0 * tunables_.sigma * tunables_.sigma);
  const double inv_background = 1.0 / pattern.background_mismatch;
  for (int i = 0; i < n; ++i)
  {
    const Outline& o = outlines_[static_cast<size_t>(i)];
    if (!(o.a > 0.0f))
      continue;
    const float mis = score(pattern, fg.data, fg.step[0], width, height, o);
    if (std::isnan(mis))
      continue;
    log_likelihood[i] = -mis * inv_two_sigma2;
    similarity[i] = std::max(0.0, 1.0 - mis * inv_background);
  }
}

double ColourContour::mismatch(FeatureCache& cache, View view, float u, float v, float radius)
{
  if (!target_.valid())
    return std::numeric_limits<double>::quiet_NaN();
  ImageHypotheses hyp;
  hyp.view = view;
  hyp.resize(1);
  hyp.u[0] = u;
  hyp.v[0] = v;
  hyp.radius[0] = radius;
  hyp.valid[0] = 1;
  Outline o;
  const StereoGeometry& g = cache.geometry();
  if (!outline(hyp, 0, static_cast<float>(g.fx()), static_cast<float>(g.cx()), static_cast<float>(g.cy()), o))
    return std::numeric_limits<double>::quiet_NaN();
  const cv::Mat& image = cache.image(view);
  const float extent = std::max(o.a, o.b) + static_cast<float>(full_.reach) + 1.0f;
  const cv::Mat& fg = foregroundMap(
      cache, view, spanRegion(o.cu - extent, o.cu + extent, o.cv - extent, o.cv + extent, image.cols, image.rows));
  return score(full_, fg.data, fg.step[0], image.cols, image.rows, o);
}

void ColourContour::saveTarget(cv::FileStorage& fs) const
{
  if (!target_.valid())
    return;
  fs << name() << "{";
  fs << "type" << "stereo_pf/ColourContour";
  binning_.write(fs);
  fs << "histogram" << target_.probabilities();
  fs << "background" << background_.probabilities();
  fs << "learned_radius" << static_cast<double>(learned_radius_);
  fs << "}";
}

bool ColourContour::loadTarget(const cv::FileNode& node, std::string& error)
{
  const cv::FileNode m = targetNode(node, name(), "colour-outline target", error);
  if (m.empty())
    return false;
  std::string reason;
  if (!binning_.matches(m, reason))
  {
    error = name() + ": " + reason;
    return false;
  }
  std::vector<double> histogram, background;
  if (m["histogram"].isSeq())
    m["histogram"] >> histogram;
  if (m["background"].isSeq())
    m["background"] >> background;
  const size_t bins = static_cast<size_t>(binning_.bins());
  if (histogram.size() != bins || background.size() != bins)
  {
    error = name() + ": the target needs 'histogram' and 'background' lists of " + std::to_string(bins) +
            " entries (found " + std::to_string(histogram.size()) + " and " + std::to_string(background.size()) + ")";
    return false;
  }
  if (!m["learned_radius"].isReal() && !m["learned_radius"].isInt())
  {
    error = name() + ": the target lacks the number 'learned_radius'";
    return false;
  }
  try
  {
    TargetHistogram target(histogram), back(background);
    if (!target.valid())
    {
      error = name() + ": the target histogram is all zero";
      return false;
    }
    setTarget(std::move(target), std::move(back));
  }
  catch (const std::invalid_argument& e)
  {
    error = name() + ": the target's histograms are invalid: " + e.what();
    return false;
  }
  learned_radius_ = static_cast<float>(static_cast<double>(m["learned_radius"]));
  return true;
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::ColourContour, stereo_pf::ObservationModel)
