// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Grey-level template observation model (weighted ZNCC with the boxed object, slowly adapted);
// see include/stereo_pf/plugins/template_match.h.
#include "stereo_pf/plugins/template_match.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <pluginlib/class_list_macros.hpp>

#include "stereo_pf/core/area_means.h"
#include "stereo_pf/core/histogram.h"

namespace stereo_pf
{
namespace
{
const char* const kType = "stereo_pf/TemplateMatch";
constexpr int kMapSamples = 7;  // samples per side of the template in targetMap()
}  // namespace

// TM_CCOEFF_NORMED from OpenCV's filters (see the header): cv::matchTemplate correlates through the DFT whatever
// the template's size, and for the 5-9 samples a side of the map's template it took three times as long (a
// 400 x 300 image, 7 x 7: 10 ms against 3.4; at 800 x 600 and a ball of 5 px radius the map took about 20 ms of
// every frame the recovery search ran).
void normalisedCorrelation(const cv::Mat& image, const cv::Mat& templ, cv::Mat& result)
{
  const cv::Size k = templ.size();
  const double n = k.area();
  const cv::Mat zero_mean = templ - cv::mean(templ)[0];
  const double t_norm = cv::norm(zero_mean);
  cv::Mat products, sums, squares;
  const cv::Point corner(0, 0);  // each output pixel is the window starting there, as matchTemplate's
  cv::filter2D(image, products, CV_32F, zero_mean, corner, 0.0, cv::BORDER_REPLICATE);
  cv::boxFilter(image, sums, CV_64F, k, corner, false, cv::BORDER_REPLICATE);
  cv::sqrBoxFilter(image, squares, CV_64F, k, corner, false, cv::BORDER_REPLICATE);
  result.create(image.rows - k.height + 1, image.cols - k.width + 1, CV_32F);
  for (int y = 0; y < result.rows; ++y)
  {
    const float* a = products.ptr<float>(y);
    const double* s = sums.ptr<double>(y);
    const double* q = squares.ptr<double>(y);
    float* r = result.ptr<float>(y);
    for (int x = 0; x < result.cols; ++x)
    {
      const double variation = q[x] - s[x] * s[x] / n;  // n times the window's variance
      r[x] = variation > 1e-6 * n && t_norm > 0.0 ? static_cast<float>(a[x] / (t_norm * std::sqrt(variation))) : 0.0f;
    }
  }
}

void TemplateMatch::onInitialize()
{
  size_ = params().getInt("size", size_, 5, 41, "template samples per side");
  tunables_ = readTunables();
  makeWeights();
}

TemplateMatch::Tunables TemplateMatch::readTunables() const
{
  const Parameters& p = params();
  Tunables t;
  t.ring_scale = p.getDouble("ring_scale", t.ring_scale, 1.0, 3.0,
                             "the sampled window: the box grown by this (the outline against the surround)");
  t.ring_weight = p.getDouble("ring_weight", t.ring_weight, 0.0, 1.0,
                              "weight of that ring (inside the box's ellipse: 1)");
  t.sigma = p.getDouble("sigma", t.sigma, 0.001, 10.0,
                        "log-likelihood (c - 1) / sigma, c: weighted ZNCC with the template");
  t.adapt_rate = p.getDouble("adapt_rate", t.adapt_rate, 0.0, 1.0,
                             "while tracked and seen, the template follows the object by this much per frame "
                             "(0: never)");
  t.adapt_min = p.getDouble("adapt_min", t.adapt_min, -1.0, 1.0,
                            "the template adapts only when the window near the estimate that matches it best "
                            "(adapt_align) correlates at least this well with it");
  t.adapt_align = p.getDouble("adapt_align", t.adapt_align, 0.0, 1.0,
                              "apparent radii around the estimate searched for the window that matches the template "
                              "best, which the template adapts to (0: the window at the estimate)");
  t.anchor = p.getDouble("anchor", t.anchor, 0.0, 1.0,
                         "share of the template in use that is the one learned from the box (the rest: the "
                         "adapted one)");
  return t;
}

void TemplateMatch::reconfigure()
{
  const Tunables t = readTunables();  // throws before anything changes
  ObservationModel::reconfigure();
  const bool reweigh = t.ring_scale != tunables_.ring_scale || t.ring_weight != tunables_.ring_weight;
  tunables_ = t;
  if (reweigh)
    makeWeights();  // a learned template keeps its samples; only their weighting changes
  useTemplate();
}

void TemplateMatch::makeWeights()
{
  weights_.assign(static_cast<size_t>(size_) * size_, 0.0f);
  weight_sum_ = 0.0;
  const double c = 0.5 * (size_ - 1);
  for (int y = 0; y < size_; ++y)
    for (int x = 0; x < size_; ++x)
    {
      // Distance from the centre in units of the box's half-size (the grid spans ring_scale of it).
      const double dx = (x - c) / c * tunables_.ring_scale, dy = (y - c) / c * tunables_.ring_scale;
      const double rho = std::sqrt(dx * dx + dy * dy);
      const float w = rho <= 1.0 ? 1.0f : rho <= tunables_.ring_scale ? static_cast<float>(tunables_.ring_weight) : 0.0f;
      weights_[static_cast<size_t>(y) * size_ + x] = w;
      weight_sum_ += w;
    }
  active_spans_.assign(size_, { 0, 0 });
  active_weights_.clear();
  for (int y = 0; y < size_; ++y)
  {
    const float* row = weights_.data() + static_cast<size_t>(y) * size_;
    int x0 = 0, x1 = size_;
    while (x0 < x1 && row[x0] == 0.0f)
      ++x0;
    while (x1 > x0 && row[x1 - 1] == 0.0f)
      --x1;
    active_spans_[y] = { x0, x1 };
    active_weights_.insert(active_weights_.end(), row + x0, row + x1);
  }
  active_scratch_.resize(active_weights_.size());
  activeWeighted();
}

void TemplateMatch::activeWeighted()
{
  active_weighted_.clear();
  if (weighted_.size() != weights_.size())
    return;
  for (int y = 0; y < size_; ++y)
  {
    const float* row = weighted_.data() + static_cast<size_t>(y) * size_;
    active_weighted_.insert(active_weighted_.end(), row + active_spans_[y].first, row + active_spans_[y].second);
  }
}

void TemplateMatch::halfSizes(double radius, double& hx, double& hy) const
{
  const double r = radius > 0.0 ? radius : box_radius_;
  hx = tunables_.ring_scale * r * aspect_x_;
  hy = tunables_.ring_scale * r * aspect_y_;
}

void TemplateMatch::sample(const cv::Mat& gray, double u, double v, double hx, double hy, std::vector<float>& out) const
{
  out.resize(static_cast<size_t>(size_) * size_);
  sampleSpans(gray, u, v, hx, hy, nullptr, out.data());
}

void TemplateMatch::sampleSpans(const cv::Mat& gray, double u, double v, double hx, double hy,
                                const std::pair<int, int>* spans, float* out) const
{
  const double c = 0.5 * (size_ - 1);
  const double sx = hx / c, sy = hy / c;
  int cols[41];
  for (int x = 0; x < size_; ++x)
    cols[x] = std::clamp(cvRound(u + (x - c) * sx), 0, gray.cols - 1);
  for (int y = 0; y < size_; ++y)
  {
    const int x0 = spans ? spans[y].first : 0, x1 = spans ? spans[y].second : size_;
    if (x0 >= x1)
      continue;
    const uint8_t* row = gray.ptr<uint8_t>(std::clamp(cvRound(v + (y - c) * sy), 0, gray.rows - 1));
    for (int x = x0; x < x1; ++x)
      *out++ = row[cols[x]];
  }
}

bool TemplateMatch::normalise(std::vector<float>& values) const
{
  double mean = 0.0;
  for (size_t i = 0; i < values.size(); ++i)
    mean += weights_[i] * values[i];
  mean /= weight_sum_;
  double norm = 0.0;
  for (size_t i = 0; i < values.size(); ++i)
  {
    values[i] = static_cast<float>(values[i] - mean);
    norm += weights_[i] * values[i] * values[i];
  }
  if (!(norm > 1e-6 * weight_sum_))  // below ~0.001 grey levels of spread: no structure to correlate
    return false;
  const double scale = 1.0 / std::sqrt(norm);
  for (float& x : values)
    x = static_cast<float>(x * scale);
  return true;
}

double TemplateMatch::score(const std::vector<float>& samples) const
{
  return correlate(samples.data(), weights_.data(), weighted_.data(), static_cast<Eigen::Index>(samples.size()));
}

double TemplateMatch::correlate(const float* samples, const float* weights, const float* weighted, Eigen::Index n) const
{
  // With the template zero-mean under the weights, sum w t (p - mean p) = sum w t p. Two passes in float
  // (vectorised by Eigen; the second about the mean, so no cancellation): this runs for every hypothesis.
  const Eigen::Map<const Eigen::ArrayXf> p(samples, n), w(weights, n), wt(weighted, n);
  const float mean = (w * p).sum() / static_cast<float>(weight_sum_);
  const double var = (w * (p - mean).square()).sum();
  if (!(var > 1e-6 * weight_sum_))
    return 0.0;
  return std::clamp(static_cast<double>((wt * p).sum()) / std::sqrt(var), -1.0, 1.0);
}

void TemplateMatch::useTemplate()
{
  if (learned_.empty())
    return;
  if (running_.size() != learned_.size())
    running_ = learned_;
  current_.resize(learned_.size());
  for (size_t i = 0; i < learned_.size(); ++i)
    current_[i] = static_cast<float>(tunables_.anchor * learned_[i] + (1.0 - tunables_.anchor) * running_[i]);
  if (!normalise(current_))
    current_ = learned_;
  weighted_.resize(current_.size());
  for (size_t i = 0; i < current_.size(); ++i)
    weighted_[i] = weights_[i] * current_[i];
  activeWeighted();
  ++template_version_;
}

void TemplateMatch::setTarget(const std::vector<float>& learned, double box_radius, double aspect_x, double aspect_y)
{
  box_radius_ = box_radius;
  aspect_x_ = aspect_x;
  aspect_y_ = aspect_y;
  learned_ = learned;
  running_ = learned;  // adaptation starts afresh from the box
  useTemplate();
}

std::pair<int, int> TemplateMatch::windowRows(const ImageHypotheses& hyp, int height) const
{
  // Only the rows the windows reach need the grey conversion (a band of the image while tracking). sample()
  // clamps to the image and the span is clipped alike, so the edge rows it then reads are in the span.
  return windowRowSpan(hyp, height, [&](int i) {
    double hx, hy;
    halfSizes(hyp.radius[i], hx, hy);
    return hy;
  });
}

const std::vector<float>& TemplateMatch::window(const cv::Mat& gray, double u, double v, double radius)
{
  double hx, hy;
  halfSizes(radius, hx, hy);
  sample(gray, u, v, hx, hy, scratch_);
  return scratch_;
}

bool TemplateMatch::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  cv::Rect inner;
  std::string reason;
  const cv::Mat& gray = cache.gray(view);
  if (!targetRegion(gray.size(), roi, 0.0, inner, reason))
  {
    error = name() + ": " + reason;
    return false;
  }
  const double radius = 0.25 * (roi.width + roi.height);
  const double ax = 0.5 * roi.width / radius, ay = 0.5 * roi.height / radius;
  std::vector<float> t;
  const double hx = tunables_.ring_scale * radius * ax, hy = tunables_.ring_scale * radius * ay;
  sample(gray, roi.x + 0.5 * roi.width - 0.5, roi.y + 0.5 * roi.height - 0.5, hx, hy, t);
  if (!normalise(t))
  {
    error = name() + ": the box " + describeRect(roi) + " and its surroundings are one flat grey level: nothing to " +
            "match (draw the box around the object, on its edge with the background)";
    return false;
  }
  setTarget(t, radius, ax, ay);
  return true;
}

void TemplateMatch::evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                             Eigen::Ref<Eigen::VectorXd> similarity)
{
  const int n = hyp.size();
  if (current_.empty())
  {
    log_likelihood.setConstant(-2.0 / tunables_.sigma);
    similarity.setZero();
    return;
  }
  const std::pair<int, int> rows = windowRows(hyp, cache.image(hyp.view).rows);
  const cv::Mat& gray = cache.gray(hyp.view, rows.first, rows.second);
  for (int i = 0; i < n; ++i)
  {
    double c = -1.0;
    if (hyp.valid[i] && std::isfinite(hyp.u[i]) && std::isfinite(hyp.v[i]) && std::isfinite(hyp.radius[i]))
    {
      // Only the grid points that weigh anything (a third of the grid, its corners, does not).
      double hx, hy;
      halfSizes(hyp.radius[i], hx, hy);
      sampleSpans(gray, hyp.u[i], hyp.v[i], hx, hy, active_spans_.data(), active_scratch_.data());
      c = correlate(active_scratch_.data(), active_weights_.data(), active_weighted_.data(),
                    static_cast<Eigen::Index>(active_weights_.size()));
    }
    log_likelihood[i] = (c - 1.0) / tunables_.sigma;
    similarity[i] = std::max(0.0, c);
  }
}

void TemplateMatch::forgetAdaptation()
{
  running_ = learned_;
  useTemplate();
}

void TemplateMatch::adapt(FeatureCache& cache, const ImageHypotheses& estimate)
{
  if (current_.empty() || tunables_.adapt_rate <= 0.0 || estimate.size() < 1 || !estimate.valid[0])
    return;
  if (!std::isfinite(estimate.u[0]) || !std::isfinite(estimate.v[0]) || !std::isfinite(estimate.radius[0]))
    return;
  // The window adapted to is the one that matches the template best within adapt_align radii of the estimate, on
  // whole pixels: adapted at the estimate itself, a template follows the estimate's error (the window off the
  // object's centre is learned, so the next estimate lies farther off, and so on). A grey textured ball turning
  // while thrown (stress draw 4, stress_004) drifted 12 px (half its apparent radius) off its centre that way; aligned,
  // 1 px. Real pitches at seeds 1-40: runs with an estimate on every reference frame 149 against 135 of 160, within 2 %
  // of range 160 against 156; stress draws 1-6 at seeds 1-3: 388 against 395 of 540, draws 1 and 6 at seeds 4-6: 128 of
  // 180 either way (docs/results.md). On a large image of the object (a reach over 15 px), a grid of at most 17 x 17
  // windows first, then every pixel around its best.
  const double r = estimate.radius[0];
  const int reach = static_cast<int>(std::floor(tunables_.adapt_align * std::max(r, 0.0)));
  const int step = std::max(1, reach / 8);  // coarse grid step, px
  ImageHypotheses span = estimate;  // the rows of the highest and the lowest window searched
  span.resize(2);
  span.u[1] = span.u[0];
  span.radius[1] = span.radius[0];
  span.valid[1] = span.valid[0];
  span.v[0] -= static_cast<float>(reach);
  span.v[1] = estimate.v[0] + static_cast<float>(reach);
  const std::pair<int, int> rows = windowRows(span, cache.image(estimate.view).rows);
  const cv::Mat& gray = cache.gray(estimate.view, rows.first, rows.second);
  double best = -std::numeric_limits<double>::infinity();
  int best_dx = 0, best_dy = 0;
  auto search = [&](int from_x, int from_y, int half, int by) {
    for (int dy = from_y - half; dy <= from_y + half; dy += by)
      for (int dx = from_x - half; dx <= from_x + half; dx += by)
      {
        if (dx * dx + dy * dy > reach * reach)
          continue;
        const double c = score(window(gray, estimate.u[0] + dx, estimate.v[0] + dy, r));
        if (c > best || (c == best && dx * dx + dy * dy < best_dx * best_dx + best_dy * best_dy))
        {
          best = c;
          best_dx = dx;
          best_dy = dy;
        }
      }
  };
  search(0, 0, reach, step);  // every pixel when step is 1 ...
  if (step > 1)
    search(best_dx, best_dy, step - 1, 1);  // ... else every pixel around the best of the coarse grid
  // Confidently the object where it is adapted to, not at the estimate: the estimate is one particle, off the object's
  // centre by a few pixels, and there a box turning one face away from the camera correlated 0.51 with its template
  // one frame after the box; held to that, the template never adapted and the track was lost as the face turned
  // (the turning-box test at engine seeds 1-21: lost by frame 60 at 6 seeds; gated here, kept to frame 100 or later at
  // every one).
  if (best < tunables_.adapt_min)
    return;  // not confidently the object anywhere near the estimate: the template stays
  window(gray, estimate.u[0] + best_dx, estimate.v[0] + best_dy, r);
  if (!normalise(scratch_))
    return;
  const double a = tunables_.adapt_rate;
  for (size_t i = 0; i < running_.size(); ++i)
    running_[i] = static_cast<float>((1.0 - a) * running_[i] + a * scratch_[i]);
  if (!normalise(running_))
    running_ = learned_;
  useTemplate();
}

bool TemplateMatch::targetMap(FeatureCache& cache, View view, cv::Mat& map)
{
  if (current_.empty())
    return false;
  const cv::Mat& gray = cache.gray(view);  // cached first: the computation below must not re-enter the cache
  // Per model (two templates in one tracker have maps of their own), computed again when the template changes.
  const std::string key = "template_match_map/" + std::to_string(reinterpret_cast<uintptr_t>(this));
  map = cache.get(view, key, [this, &gray](const cv::Mat&, cv::Mat& out) {
    double hx, hy;
    halfSizes(0.0, hx, hy);
    // The template spans 2 hx x 2 hy pixels; shrink the image so that it spans kMapSamples samples (a map for
    // proposals on 4-px cells needs no finer match, and the correlation's cost goes as the fourth power of
    // this), or less when the image would be wider than 200 px, but never below 5 samples; by a whole
    // factor, which OpenCV's area resize does several times faster than a fractional one.
    const double samples = std::min(size_, kMapSamples);
    const double scale =
        std::clamp(std::min(samples / (2.0 * hx), 200.0 / gray.cols), 5.0 / (2.0 * std::min(hx, hy)), 1.0);
    const int factor = std::max(1, static_cast<int>(std::floor(1.0 / scale + 1e-9)));
    cv::Mat small, result;
    // The columns and rows a whole number of cells cover: resized by a fractional factor (640 / 213), OpenCV
    // weighs every sample's pixels separately, nearly three times as slowly as by the whole factor.
    const cv::Size cells(gray.cols / factor, gray.rows / factor);
    const cv::Mat whole = gray(cv::Rect(0, 0, cells.width * factor, cells.height * factor));
    if (factor == 2 || factor > 16)
      cv::resize(whole, small, cells, 0, 0, cv::INTER_AREA);
    else
      areaMeans(whole, factor, small);  // the same values, in about half the instructions
    cv::Mat templ(size_, size_, CV_32F, const_cast<float*>(current_.data()));
    cv::Mat t;
    const int tw = std::max(3, static_cast<int>(std::lround(2.0 * hx / factor)));
    const int th = std::max(3, static_cast<int>(std::lround(2.0 * hy / factor)));
    if (tw >= small.cols || th >= small.rows)
    {
      out = cv::Mat(small.size(), CV_8UC1, cv::Scalar(128));
      return;
    }
    cv::resize(templ, t, cv::Size(tw, th), 0, 0, cv::INTER_AREA);
    small.convertTo(small, CV_32F);
    normalisedCorrelation(small, t, result);
    // At the shrunk image's resolution (the engine resizes maps to its proposal grid).
    cv::Mat full(small.size(), CV_32F, cv::Scalar(0));
    result.copyTo(full(cv::Rect(tw / 2, th / 2, result.cols, result.rows)));
    full.convertTo(out, CV_8U, 255.0);  // saturates: negative correlations become 0
  }, template_version_);
  return true;
}

void TemplateMatch::saveTarget(cv::FileStorage& fs) const
{
  if (learned_.empty())
    return;
  fs << name() << "{";
  fs << "type" << kType << "size" << size_ << "box_radius" << box_radius_ << "aspect_x" << aspect_x_ << "aspect_y"
     << aspect_y_;
  fs << "template" << std::vector<float>(learned_);
  fs << "}";
}

bool TemplateMatch::loadTarget(const cv::FileNode& node, std::string& error)
{
  const cv::FileNode m = node.isMap() && !node["template"].empty() ? node : node[name()];
  if (m.empty() || !m.isMap() || !m["template"].isSeq())
  {
    error = name() + ": no template target named '" + name() + "' in the file";
    return false;
  }
  int size = 0;
  m["size"] >> size;
  std::vector<float> t;
  m["template"] >> t;
  double radius = 0.0, ax = 0.0, ay = 0.0;
  m["box_radius"] >> radius;
  m["aspect_x"] >> ax;
  m["aspect_y"] >> ay;
  if (size != size_ || static_cast<int>(t.size()) != size_ * size_)
  {
    error = name() + ": the template was learned with size " + std::to_string(size) + " (" + std::to_string(t.size()) +
            " values); this model uses size " + std::to_string(size_);
    return false;
  }
  if (!(radius > 0.0) || !(ax > 0.0) || !(ay > 0.0) || !std::all_of(t.begin(), t.end(), [](float x) { return std::isfinite(x); }))
  {
    error = name() + ": the template's box_radius, aspect or values are not valid";
    return false;
  }
  setTarget(t, radius, ax, ay);
  return true;
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::TemplateMatch, stereo_pf::ObservationModel)
