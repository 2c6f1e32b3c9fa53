// Edge-texture observation model (thesis eq. 4.1, 5.6-5.7); see include/stereo_pf/plugins/texture_edge.h.
#include "stereo_pf/plugins/texture_edge.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>

#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
namespace
{
// A hypothesis needs at least this fraction of its samples inside the image to be judged at all
// (as in ColourHSI: a histogram of a few border pixels is too noisy to compare).
constexpr int kMinInsideDenominator = 4;  // 1/4

// Orientation sectors of the gradient: within 22.5 deg of an axis, or diagonal.
const float kTan22 = static_cast<float>(std::tan(22.5 * 3.14159265358979323846 / 180.0));
const float kTan67 = static_cast<float>(std::tan(67.5 * 3.14159265358979323846 / 180.0));

std::string rectText(const cv::Rect& r)
{
  std::ostringstream s;
  s << r.width << "x" << r.height << " at (" << r.x << ", " << r.y << ")";
  return s.str();
}

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
  step_ = static_cast<float>((binning_.max_magnitude - binning_.tau) / binning_.intensity_bins);
}

int EdgeBinner::bin(float sx, float sy) const
{
  const float magnitude = std::sqrt(sx * sx + sy * sy);
  const float tau = static_cast<float>(binning_.tau);
  if (binning_.mode == EdgeBinning::Mode::Intensity)
  {
    // The same float expression binImage() hands to convertTo: floor((|S| - tau) / step) + 1, saturated.
    const int b = cvRound(magnitude * (1.0f / step_) + (0.5f - tau / step_));
    return std::clamp(b, 0, binning_.intensity_bins);
  }
  if (!(magnitude >= tau))
    return EdgeBinning::kNoEdge;
  const float ax = std::fabs(sx), ay = std::fabs(sy);
  // A gradient along y (|Sy| dominant) means intensity changes vertically: a horizontal edge line.
  if (ay > kTan67 * ax)
    return EdgeBinning::kHorizontal;
  if (ay < kTan22 * ax)
    return EdgeBinning::kVertical;
  return EdgeBinning::kDiagonal;
}

void EdgeBinner::binImage(const cv::Mat& sx, const cv::Mat& sy, const cv::Mat& magnitude, cv::Mat& bins) const
{
  if (sx.type() != CV_32FC1 || sy.type() != CV_32FC1 || magnitude.type() != CV_32FC1)
    throw std::invalid_argument("EdgeBinner::binImage: expected CV_32FC1 derivative and magnitude images");
  if (sx.size() != sy.size() || sx.size() != magnitude.size())
    throw std::invalid_argument("EdgeBinner::binImage: derivative and magnitude images differ in size");
  const float tau = static_cast<float>(binning_.tau);
  if (binning_.mode == EdgeBinning::Mode::Intensity)
  {
    // Two vectorised passes instead of a per-pixel loop (~0.05 ms at 640x480): scale-shift-round-saturate
    // gives floor((|S| - tau) / step) + 1 (0 below tau), then cap at the top bin.
    magnitude.convertTo(bins, CV_8U, 1.0f / step_, 0.5f - tau / step_);
    cv::min(bins, cv::Scalar::all(binning_.intensity_bins), bins);
    return;
  }
  bins.create(sx.size(), CV_8UC1);
  for (int y = 0; y < sx.rows; ++y)
  {
    const float* gx = sx.ptr<float>(y);
    const float* gy = sy.ptr<float>(y);
    const float* m = magnitude.ptr<float>(y);
    uint8_t* out = bins.ptr<uint8_t>(y);
    for (int x = 0; x < sx.cols; ++x)
    {
      // Branch-free (the sectors are data-dependent and mispredict on real images): with h and v
      // exclusive, 3 - 2h - v is 1 (horizontal), 2 (vertical) or 3 (diagonal).
      const float ax = std::fabs(gx[x]), ay = std::fabs(gy[x]);
      const int edge = m[x] >= tau;
      const int h = ay > kTan67 * ax;
      const int v = ay < kTan22 * ax;
      out[x] = static_cast<uint8_t>(edge * (3 - 2 * h - v));
    }
  }
}

// ------------------------------------------------------------------------------------------------
// TextureEdge

void TextureEdge::onInitialize()
{
  const Parameters& p = params();
  EdgeBinning b;
  b.mode = p.getString("mode", "intensity", { "intensity", "orientation" }) == "intensity" ?
               EdgeBinning::Mode::Intensity :
               EdgeBinning::Mode::Orientation;
  b.intensity_bins = p.getInt("bins", 8, 1, EdgeBinning::kMaxIntensityBins);
  b.tau = p.getDouble("tau", 24.0, 0.0, 4000.0);
  b.max_magnitude = p.getDouble("max_magnitude", 400.0, 1e-3, 5000.0);
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
  const Parameters& p = params();
  Tunables t;
  t.sigma = p.getDouble("sigma", 0.15, 0.001, 10.0);
  t.window = p.getInt("window", 11, 3, 101);
  if (t.window % 2 == 0)
    throw ParameterError("parameter '" + (p.prefix().empty() ? std::string() : p.prefix() + "/") + "window' = " +
                         std::to_string(t.window) + " must be odd (allowed: odd integers in [3, 101])");
  t.window_scale = p.getDouble("window_scale", 0.7, 0.1, 3.0);
  t.samples = p.getInt("samples", 11, 3, 31);
  t.min_radius = p.getDouble("min_radius", 2.0, 0.5, 100.0);
  t.target_margin = p.getDouble("target_margin", 0.15, 0.0, 0.45);
  return t;
}

void TextureEdge::applyTunables(const Tunables& t)
{
  tunables_ = t;
  invalid_log_likelihood_ = bhattacharyyaLogLikelihood(0.0, t.sigma);
  // A fixed grid in [-1, 1]^2, scaled by the window half-size per hypothesis: constant cost per hypothesis.
  grid_.resize(t.samples);
  for (int k = 0; k < t.samples; ++k)
    grid_[k] = static_cast<float>(-1.0 + 2.0 * k / (t.samples - 1));
  cols_.resize(t.samples);
  rows_.resize(t.samples);
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
  if (!binner_)
    throw std::logic_error("TextureEdge: used before initialize()");
  // The derivatives and magnitude are the cache's own products, shared with ShapeCircle (and anyone else).
  const cv::Mat& sx = cache.gradientX(view);
  const cv::Mat& sy = cache.gradientY(view);
  const cv::Mat& magnitude = cache.gradientMagnitude(view);
  return cache.get(view, cache_key_,
                   [&](const cv::Mat&, cv::Mat& out) { binner_->binImage(sx, sy, magnitude, out); });
}

bool TextureEdge::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  const cv::Mat& image = cache.image(view);
  if (image.empty())
  {
    error = name() + ": cannot learn the target: the frame has no image in this view";
    return false;
  }
  if (roi.width <= 0 || roi.height <= 0)
  {
    error = name() + ": cannot learn the target: the region " + rectText(roi) + " is empty";
    return false;
  }
  const cv::Rect bounds(0, 0, image.cols, image.rows);
  if ((roi & bounds).empty())
  {
    error = name() + ": cannot learn the target: the region " + rectText(roi) + " lies outside the " +
            std::to_string(image.cols) + "x" + std::to_string(image.rows) + " image";
    return false;
  }
  // Shrink relative to the object's box, then clip (as ColourHSI): with the default margin the box of a
  // ball becomes the square of half-size 0.7 r that a 3D hypothesis samples, inside the ball's rim.
  const int mx = static_cast<int>(std::lround(roi.width * tunables_.target_margin));
  const int my = static_cast<int>(std::lround(roi.height * tunables_.target_margin));
  const cv::Rect inner = cv::Rect(roi.x + mx, roi.y + my, roi.width - 2 * mx, roi.height - 2 * my) & bounds;
  if (inner.width < 3 || inner.height < 3)
  {
    error = name() + ": cannot learn the target: the region " + rectText(roi) + " leaves only " +
            rectText(inner) + " inside the image after the target_margin of " +
            std::to_string(tunables_.target_margin) + " per side (at least 3x3 pixels needed)";
    return false;
  }
  TargetHistogram t = TargetHistogram::fromBinImage(binImage(cache, view), inner, binning_.bins());
  if (!t.valid())
  {
    error = name() + ": cannot learn the target: no pixel of " + rectText(inner) + " could be binned";
    return false;
  }
  target_ = std::move(t);
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

  const cv::Mat& bins = binImage(cache, hyp.view);  // once per view per frame, shared by every hypothesis
  const int width = bins.cols;
  const int height = bins.rows;
  const size_t step = bins.step[0];
  const uint8_t* data = bins.data;

  const int s = tunables_.samples;
  const int min_inside = (s * s + kMinInsideDenominator - 1) / kMinInsideDenominator;
  const float fixed_half = 0.5f * static_cast<float>(tunables_.window - 1);
  const float scale = static_cast<float>(tunables_.window_scale);
  const float min_radius = static_cast<float>(tunables_.min_radius);
  // Beyond this the window cannot have a quarter of its samples inside anyway; it also keeps cvRound in range.
  const float max_half = 4.0f * static_cast<float>(std::max(width, height));
  const double inv_two_sigma2 = 1.0 / (2.0 * tunables_.sigma * tunables_.sigma);
  const float* grid = grid_.data();
  int* cols = cols_.data();
  int* rows = rows_.data();

  for (int i = 0; i < n; ++i)
  {
    if (!hyp.valid[i])
      continue;
    const float u = hyp.u[i];
    const float v = hyp.v[i];
    const float r = hyp.radius[i];
    // radius <= 0 (or NaN): a 2D hypothesis with the fixed window; otherwise scale with the object.
    float half = r > 0.0f ? scale * std::max(r, min_radius) : fixed_half;
    half = std::min(half, max_half);
    // Written so that NaN positions fail too.
    if (!(u > -half - 1.0f && u < width + half + 1.0f && v > -half - 1.0f && v < height + half + 1.0f))
      continue;

    // The grid is separable, so inside-ness is too: clip the columns and rows once, no per-sample test.
    int nc = 0;
    int nr = 0;
    for (int k = 0; k < s; ++k)
    {
      const int x = cvRound(u + half * grid[k]);
      if (x >= 0 && x < width)
        cols[nc++] = x;
      const int y = cvRound(v + half * grid[k]);
      if (y >= 0 && y < height)
        rows[nr++] = y;
    }
    if (nc * nr < min_inside)
      continue;

    candidate_.addGrid(data, step, rows, nr, cols, nc);
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
  // Accept the map itself or its parent (the file root).
  cv::FileNode m = node;
  if (m.isMap() && m["histogram"].empty())
    m = node[name()];
  if (m.empty() || !m.isMap())
  {
    error = name() + ": no texture target named '" + name() + "' in the file";
    return false;
  }
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
