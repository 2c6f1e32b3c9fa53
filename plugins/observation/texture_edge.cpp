// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Edge-texture observation model (thesis eq. 4.1, 5.6-5.7); see include/stereo_pf/plugins/texture_edge.h.
#include "stereo_pf/plugins/texture_edge.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>

#include <opencv2/core/hal/intrin.hpp>
#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
namespace
{
// A hypothesis needs at least this fraction of its samples inside the image to be judged at all
// (as in ColourHSI: a histogram of a few border pixels is too noisy to compare).
constexpr int kMinInsideDenominator = 4;  // 1/4

// Orientation sectors of the gradient, in integer arithmetic: |Sy| / |Sx| compared with tan 67.5 deg and
// tan 22.5 deg, in thousandths (products stay below 2^31 for |S| <= 1020).
constexpr int kTan67Milli = 2414;
constexpr int kTan22Milli = 414;
// Vector lanes of the edge-bin kernel.
constexpr int kLanes16 = cv::v_uint8x16::nlanes;
constexpr int kLanes8 = cv::v_int16x8::nlanes;

// Enough digits that different settings never share a cache key or pass as the same binning.
std::string number(double v)
{
  std::ostringstream s;
  s.precision(12);
  s << v;
  return s.str();
}
}  // namespace

// ------------------------------------------------------------------------------------------------
// EdgeBinning / EdgeBinner

void EdgeBinning::validate() const
{
  if (intensity_bins < 1 || intensity_bins > kMaxIntensityBins)
    throw std::invalid_argument("EdgeBinning: intensity_bins must be in [1, " + std::to_string(kMaxIntensityBins) +
                                "], got " + std::to_string(intensity_bins));
  if (!(tau >= 0.0) || !std::isfinite(tau))
    throw std::invalid_argument("EdgeBinning: tau must be finite and >= 0, got " + number(tau));
  if (!(max_magnitude > tau) || !std::isfinite(max_magnitude))
    throw std::invalid_argument("EdgeBinning: max_magnitude (" + number(max_magnitude) + ") must exceed tau (" +
                                number(tau) + ")");
}

std::string EdgeBinning::toString(Mode mode)
{
  return mode == Mode::Intensity ? "intensity" : "orientation";
}

std::string EdgeBinning::describe() const
{
  if (mode == Mode::Intensity)
    return toString(mode) + "/" + std::to_string(intensity_bins) + "/t" + number(tau) + "/m" + number(max_magnitude);
  return toString(mode) + "/t" + number(tau);
}

bool EdgeBinning::sameAs(const EdgeBinning& o) const
{
  if (mode != o.mode || tau != o.tau)
    return false;
  // The orientation bins do not depend on the intensity settings.
  return mode == Mode::Orientation || (intensity_bins == o.intensity_bins && max_magnitude == o.max_magnitude);
}

EdgeBinner::EdgeBinner(const EdgeBinning& binning) : binning_(binning)
{
  binning_.validate();
  const double step = (binning_.max_magnitude - binning_.tau) / binning_.intensity_bins;
  inv_step_ = static_cast<float>(1.0 / step);
  offset_ = static_cast<float>(1.0 - binning_.tau / step);
  tau2_ = static_cast<int>(std::min(std::ceil(binning_.tau * binning_.tau), 1e9));
}

int EdgeBinner::bin(int sx, int sy) const
{
  const int m2 = sx * sx + sy * sy;
  if (binning_.mode == EdgeBinning::Mode::Intensity)
  {
    // The same float operations, in the same order, as the vector code in binImage(). Truncation equals
    // floor wherever the clamp does not apply.
    const float t = std::sqrt(static_cast<float>(m2)) * inv_step_ + offset_;
    return std::clamp(static_cast<int>(t), 0, binning_.intensity_bins);
  }
  if (m2 < tau2_)
    return EdgeBinning::kNoEdge;
  const int ax = std::abs(sx), ay = std::abs(sy);
  // A gradient along y (|Sy| dominant) means intensity changes vertically: a horizontal edge line.
  if (1000 * ay > kTan67Milli * ax)
    return EdgeBinning::kHorizontal;
  if (1000 * ay < kTan22Milli * ax)
    return EdgeBinning::kVertical;
  return EdgeBinning::kDiagonal;
}

void EdgeBinner::binImage(const cv::Mat& gray, cv::Mat& bins) const
{
  binImage(gray, bins, 0, gray.rows);
}

void EdgeBinner::binImage(const cv::Mat& gray, cv::Mat& bins, int y0, int y1) const
{
  if (gray.type() != CV_8UC1)
    throw std::invalid_argument("EdgeBinner::binImage: expected a CV_8UC1 grey image, got type " +
                                std::to_string(gray.type()));
  if (y0 < 0 || y1 > gray.rows || y0 > y1)
    throw std::invalid_argument("EdgeBinner::binImage: rows [" + std::to_string(y0) + ", " + std::to_string(y1) +
                                ") are not within the image's " + std::to_string(gray.rows));
  bins.create(gray.size(), CV_8UC1);
  const int w = gray.cols, h = gray.rows;
  if (w == 0 || h == 0 || y0 == y1)
    return;
  // Separable Sobel: per row, the vertical smoothing a + 2b + c (for Sx) and difference c - a (for Sy)
  // of the rows above and below, with one reflected column each side (BORDER_REFLECT_101), then
  // Sx = s[x + 1] - s[x - 1] and Sy = d[x - 1] + 2 d[x] + d[x + 1].
  std::vector<int16_t> smooth(w + 2 + kLanes8), diff(w + 2 + kLanes8);
  int16_t* s = smooth.data() + 1;
  int16_t* d = diff.data() + 1;
  const bool intensity = binning_.mode == EdgeBinning::Mode::Intensity;
  const cv::v_float32x4 v_inv = cv::v_setall_f32(inv_step_), v_off = cv::v_setall_f32(offset_);
  const cv::v_uint8x16 v_top = cv::v_setall_u8(static_cast<uint8_t>(intensity ? binning_.intensity_bins : 3));
  const cv::v_int32x4 v_tau2 = cv::v_setall_s32(tau2_), v_three = cv::v_setall_s32(3);
  const cv::v_int16x8 v_1000 = cv::v_setall_s16(1000), v_tan67 = cv::v_setall_s16(kTan67Milli);
  const cv::v_int16x8 v_tan22 = cv::v_setall_s16(kTan22Milli);
  // Intensity bins of 4 pixels from |S|^2: the float operations of bin(), lane by lane, truncated. The
  // clamp to [0, bins] is left to the saturating packs (negative -> 0; truncation and floor differ only
  // there) and one u8 minimum per 16 pixels: SSE2 has no 32-bit minimum, maximum or floor.
  auto intensityBins = [&](const cv::v_int32x4& m2) {
    return cv::v_trunc(cv::v_sqrt(cv::v_cvt_f32(m2)) * v_inv + v_off);
  };
  // Orientation bins of 4 pixels: with the masks h, v in {0, -1}, 3 + 2h + v is 1 (horizontal),
  // 2 (vertical) or 3 (diagonal); and-ed with the edge mask, 0 without an edge.
  auto orientationBins = [&](const cv::v_int32x4& m2, const cv::v_int32x4& ay1000, const cv::v_int32x4& ax67,
                             const cv::v_int32x4& ax22) {
    const cv::v_int32x4 hm = ay1000 > ax67;
    const cv::v_int32x4 vm = ay1000 < ax22;
    return (v_three + hm + hm + vm) & (m2 >= v_tau2);
  };

  for (int y = y0; y < y1; ++y)
  {
    const uint8_t* a = gray.ptr<uint8_t>(y > 0 ? y - 1 : std::min(1, h - 1));
    const uint8_t* b = gray.ptr<uint8_t>(y);
    const uint8_t* c = gray.ptr<uint8_t>(y < h - 1 ? y + 1 : std::max(h - 2, 0));
    int x = 0;
    for (; x + kLanes16 <= w; x += kLanes16)
    {
      cv::v_uint16x8 a0, a1, b0, b1, c0, c1;
      cv::v_expand(cv::v_load(a + x), a0, a1);
      cv::v_expand(cv::v_load(b + x), b0, b1);
      cv::v_expand(cv::v_load(c + x), c0, c1);
      cv::v_store(s + x, cv::v_reinterpret_as_s16(a0 + b0 + b0 + c0));
      cv::v_store(s + x + kLanes8, cv::v_reinterpret_as_s16(a1 + b1 + b1 + c1));
      cv::v_store(d + x, cv::v_reinterpret_as_s16(c0) - cv::v_reinterpret_as_s16(a0));
      cv::v_store(d + x + kLanes8, cv::v_reinterpret_as_s16(c1) - cv::v_reinterpret_as_s16(a1));
    }
    for (; x < w; ++x)
    {
      s[x] = static_cast<int16_t>(a[x] + 2 * b[x] + c[x]);
      d[x] = static_cast<int16_t>(c[x] - a[x]);
    }
    s[-1] = s[w > 1 ? 1 : 0];
    d[-1] = d[w > 1 ? 1 : 0];
    s[w] = s[w > 1 ? w - 2 : 0];
    d[w] = d[w > 1 ? w - 2 : 0];

    uint8_t* out = bins.ptr<uint8_t>(y);
    x = 0;
    for (; x + kLanes16 <= w; x += kLanes16)
    {
      cv::v_int16x8 packed[2];
      for (int half = 0; half < 2; ++half)
      {
        const int xx = x + half * kLanes8;
        const cv::v_int16x8 sx = cv::v_load(s + xx + 1) - cv::v_load(s + xx - 1);
        const cv::v_int16x8 dm = cv::v_load(d + xx);
        const cv::v_int16x8 sy = cv::v_load(d + xx - 1) + dm + dm + cv::v_load(d + xx + 1);
        // |S|^2 per pixel: interleave (Sx, Sy) and take pairwise dot products.
        cv::v_int16x8 z0, z1;
        cv::v_zip(sx, sy, z0, z1);
        const cv::v_int32x4 m2_0 = cv::v_dotprod(z0, z0), m2_1 = cv::v_dotprod(z1, z1);
        if (intensity)
        {
          packed[half] = cv::v_pack(intensityBins(m2_0), intensityBins(m2_1));
        }
        else
        {
          cv::v_int32x4 ay0, ay1, ax67_0, ax67_1, ax22_0, ax22_1;
          const cv::v_int16x8 ax = cv::v_reinterpret_as_s16(cv::v_abs(sx));
          const cv::v_int16x8 ay = cv::v_reinterpret_as_s16(cv::v_abs(sy));
          cv::v_mul_expand(ay, v_1000, ay0, ay1);
          cv::v_mul_expand(ax, v_tan67, ax67_0, ax67_1);
          cv::v_mul_expand(ax, v_tan22, ax22_0, ax22_1);
          packed[half] =
              cv::v_pack(orientationBins(m2_0, ay0, ax67_0, ax22_0), orientationBins(m2_1, ay1, ax67_1, ax22_1));
        }
      }
      cv::v_store(out + x, cv::v_min(cv::v_pack_u(packed[0], packed[1]), v_top));
    }
    for (; x < w; ++x)
      out[x] = static_cast<uint8_t>(bin(s[x + 1] - s[x - 1], d[x - 1] + 2 * d[x] + d[x + 1]));
  }
}

// ------------------------------------------------------------------------------------------------
// TextureEdge

void TextureEdge::onInitialize()
{
  const Parameters& p = params();
  EdgeBinning b;
  const std::string mode = p.getString("mode", "intensity", { "intensity", "orientation" },
                                       "intensity: edge-intensity bins; orientation: horizontal/vertical/diagonal "
                                       "edge counts");
  b.mode = mode == "intensity" ? EdgeBinning::Mode::Intensity : EdgeBinning::Mode::Orientation;
  b.intensity_bins = p.getInt("bins", 8, 1, EdgeBinning::kMaxIntensityBins, "edge-intensity bins");
  b.tau = p.getDouble("tau", 24.0, 0.0, 4000.0, "gradient magnitude below this is not an edge");
  b.max_magnitude = p.getDouble("max_magnitude", 400.0, 1e-3, 5000.0, "upper end of the edge-intensity bins (> tau)");
  if (!(b.max_magnitude > b.tau))
  {
    const std::string ns = p.prefix().empty() ? "" : p.prefix() + "/";
    throw ParameterError("parameter '" + ns + "max_magnitude' = " + number(b.max_magnitude) + " must exceed '" + ns +
                         "tau' = " + number(b.tau) + " (the edge-intensity bins span [tau, max_magnitude])");
  }
  const Tunables t = readTunables();  // validate everything before changing any state

  binner_ = std::make_unique<const EdgeBinner>(b);
  binning_ = b;
  cache_key_ = "edge_bins/" + b.describe();
  target_ = TargetHistogram();  // a target learned with another binning would be meaningless
  applyTunables(t);
}

TextureEdge::Tunables TextureEdge::readTunables() const
{
  return HistogramWindowTunables::fromParameters(params());
}

void TextureEdge::applyTunables(const Tunables& t)
{
  tunables_ = t;
  invalid_log_likelihood_ = bhattacharyyaLogLikelihood(0.0, t.sigma);
  // A fixed grid in [-1, 1]^2, scaled by the window half-size per hypothesis: constant cost per hypothesis.
  window_.reset(t.samples);
  candidate_.reset(binning_.bins(), t.samples * t.samples);
}

void TextureEdge::reconfigure()
{
  const Tunables t = readTunables();  // throws before anything changes
  ObservationModel::reconfigure();
  applyTunables(t);
}

const cv::Mat& TextureEdge::binImage(FeatureCache& cache, View view)
{
  return binImage(cache, view, 0, cache.image(view).rows);
}

const cv::Mat& TextureEdge::binImage(FeatureCache& cache, View view, int y0, int y1)
{
  if (!binner_)
    throw std::logic_error("TextureEdge: used before initialize()");
  // From the cache's grey image (shared with ShapeCircle and anyone else), in one pass; a row's bins need
  // the grey rows above and below it.
  return cache.getRows(view, cache_key_, y0, y1, [&](const cv::Mat& image, cv::Mat& out, int a, int b) {
    const cv::Mat& gray = cache.gray(view, a - 1, b + 1);
    out.create(image.size(), CV_8UC1);
    binner_->binImage(gray, out, a, b);
  });
}

bool TextureEdge::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  std::string reason;
  if (!learnTargetHistogram(binImage(cache, view), roi, tunables_.target_margin, binning_.bins(), target_, reason))
  {
    error = name() + ": cannot learn the target: " + reason;
    return false;
  }
  return true;
}

void TextureEdge::evaluate(FeatureCache& cache, const ImageHypotheses& hyp,
                           Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity)
{
  const int n = hyp.size();
  if (log_likelihood.size() != n || similarity.size() != n || static_cast<int>(hyp.v.size()) != n ||
      static_cast<int>(hyp.radius.size()) != n || static_cast<int>(hyp.valid.size()) != n)
    throw std::invalid_argument(name() + ": evaluate: hypothesis arrays and outputs must all have " +
                                std::to_string(n) + " entries");
  log_likelihood.setConstant(invalid_log_likelihood_);
  similarity.setZero();
  if (!target_.valid() || n == 0)
    return;

  const cv::Mat& image = cache.image(hyp.view);
  const int width = image.cols;
  const int height = image.rows;
  const int s = tunables_.samples;
  const int min_inside = (s * s + kMinInsideDenominator - 1) / kMinInsideDenominator;
  const float fixed_half = 0.5f * static_cast<float>(tunables_.window - 1);
  const float scale = static_cast<float>(tunables_.window_scale);
  const float min_radius = static_cast<float>(tunables_.min_radius);
  // Beyond this the window cannot have a quarter of its samples inside anyway; it also keeps cvRound in range.
  const float max_half = 4.0f * static_cast<float>(std::max(width, height));
  const double inv_two_sigma2 = 1.0 / (2.0 * tunables_.sigma * tunables_.sigma);
  // radius <= 0 (or NaN): a 2D hypothesis with the fixed window; otherwise scale with the object.
  auto halfSize = [&](int i) {
    const float r = hyp.radius[i];
    return std::min(r > 0.0f ? scale * std::max(r, min_radius) : fixed_half, max_half);
  };

  // Only the rows the windows reach need edge bins (a band of the image while tracking).
  const std::pair<int, int> rows = windowRowSpan(hyp, height, halfSize);
  // Once per view per frame (in the rows not binned yet), shared by every hypothesis.
  const cv::Mat& bins = binImage(cache, hyp.view, rows.first, rows.second);
  const size_t step = bins.step[0];
  const uint8_t* data = bins.data;

  for (int i = 0; i < n; ++i)
  {
    if (!hyp.valid[i])
      continue;
    const float u = hyp.u[i];
    const float v = hyp.v[i];
    const float half = halfSize(i);
    if (!window_.place(u, v, half, width, height, min_inside))
      continue;

    candidate_.addGrid(data, step, window_.rows(), window_.numRows(), window_.cols(), window_.numCols());
    const double rho = candidate_.scoreAndClear(target_);
    log_likelihood[i] = -(1.0 - rho) * inv_two_sigma2;
    similarity[i] = rho;
  }
}

void TextureEdge::saveTarget(cv::FileStorage& fs) const
{
  if (!target_.valid())
    return;
  fs << name() << "{";
  fs << "type" << "stereo_pf/TextureEdge";
  fs << "mode" << EdgeBinning::toString(binning_.mode);
  fs << "bins" << binning_.intensity_bins << "tau" << binning_.tau << "max_magnitude" << binning_.max_magnitude;
  fs << "histogram" << target_.probabilities();
  fs << "}";
}

bool TextureEdge::loadTarget(const cv::FileNode& node, std::string& error)
{
  const cv::FileNode m = targetNode(node, name(), "texture target", error);
  if (m.empty())
    return false;
  if (!m["mode"].isString())
  {
    error = name() + ": texture target lacks its 'mode' (intensity or orientation)";
    return false;
  }
  for (const char* key : { "bins", "tau", "max_magnitude" })
    if (!m[key].isInt() && !m[key].isReal())
    {
      error = name() + ": texture target lacks the number '" + key + "'";
      return false;
    }
  EdgeBinning stored;
  const std::string mode = m["mode"].string();
  if (mode != "intensity" && mode != "orientation")
  {
    error = name() + ": texture target has mode '" + mode + "' (allowed: intensity, orientation)";
    return false;
  }
  stored.mode = mode == "intensity" ? EdgeBinning::Mode::Intensity : EdgeBinning::Mode::Orientation;
  stored.intensity_bins = static_cast<int>(m["bins"]);
  stored.tau = static_cast<double>(m["tau"]);
  stored.max_magnitude = static_cast<double>(m["max_magnitude"]);
  if (!stored.sameAs(binning_))
  {
    error = name() + ": the texture target was learned with edge binning " + stored.describe() +
            " (mode/bins/tau/max_magnitude) but this model is configured with " + binning_.describe() +
            "; relearn the target or set the same binning";
    return false;
  }
  if (!m["histogram"].isSeq())
  {
    error = name() + ": texture target lacks its 'histogram' list";
    return false;
  }
  std::vector<double> hist;
  m["histogram"] >> hist;
  if (static_cast<int>(hist.size()) != binning_.bins())
  {
    error = name() + ": texture target histogram has " + std::to_string(hist.size()) + " entries, expected " +
            std::to_string(binning_.bins());
    return false;
  }
  try
  {
    TargetHistogram t(hist);
    if (!t.valid())
    {
      error = name() + ": texture target histogram is all zero";
      return false;
    }
    target_ = std::move(t);
  }
  catch (const std::invalid_argument& e)
  {
    error = name() + ": texture target histogram is invalid: " + e.what();
    return false;
  }
  return true;
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::TextureEdge, stereo_pf::ObservationModel)
