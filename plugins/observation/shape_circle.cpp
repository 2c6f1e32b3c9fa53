// Circle-contour observation model (thesis eq. 5.8-5.11); see include/stereo_pf/plugins/shape_circle.h.
#include "stereo_pf/plugins/shape_circle.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
// Table resolution of the Gaussian: 1/32 px is far below the peaks' localisation error.
constexpr float kLutPerPixel = 32.0f;

std::string rectText(const cv::Rect& r)
{
  std::ostringstream s;
  s << r.width << "x" << r.height << " at (" << r.x << ", " << r.y << ")";
  return s.str();
}
}  // namespace

void ShapeCircle::onInitialize()
{
  applyTunables(readTunables());
}

ShapeCircle::Tunables ShapeCircle::readTunables() const
{
  const Parameters& p = params();
  Tunables t;
  t.lines = p.getInt("lines", 16, 3, 256);
  t.line_half_length = p.getInt("line_half_length", 5, 1, 50);
  t.sigma = p.getDouble("sigma", 1.5, 0.1, 50.0);
  t.q0 = p.getDouble("q0", 0.1, 0.001, 0.999);
  t.edge_threshold = p.getDouble("edge_threshold", 40.0, 0.0, 5000.0);
  t.radius = p.getDouble("radius", 0.0, 0.0, 2000.0);
  t.min_radius = p.getDouble("min_radius", 3.0, 0.5, 1000.0);
  return t;
}

void ShapeCircle::applyTunables(const Tunables& t)
{
  tunables_ = t;
  const int half = t.line_half_length;
  samples_per_line_ = 2 * half + 3;
  lines_.assign(t.lines, Line());
  dx_.resize(static_cast<size_t>(t.lines) * samples_per_line_);
  dy_.resize(dx_.size());
  projection_.resize(dx_.size());
  for (int k = 0; k < t.lines; ++k)
  {
    Line& line = lines_[k];
    const double theta = 2.0 * kPi * k / t.lines;
    const double c = std::cos(theta), s = std::sin(theta);
    line.c = static_cast<float>(c);
    line.s = static_cast<float>(s);
    // Step one pixel along the dominant axis per sample (a digital line): every sample is a distinct
    // pixel, and the pattern is the same for every hypothesis, so it is tabulated once here.
    const bool along_x = std::abs(c) >= std::abs(s);
    const double major = along_x ? std::abs(c) : std::abs(s);
    line.spacing = static_cast<float>(1.0 / major);
    // U is the uniform density over the line's length: gain = (1 - q0) / (q0 U).
    const double length = samples_per_line_ * line.spacing;
    line.gain = (1.0 - t.q0) / t.q0 * length;
    for (int j = 0; j < samples_per_line_; ++j)
    {
      const int step = j - (half + 1);
      int dx, dy;
      if (along_x)
      {
        dx = c > 0 ? step : -step;
        dy = static_cast<int>(std::lround(step * s / major));
      }
      else
      {
        dy = s > 0 ? step : -step;
        dx = static_cast<int>(std::lround(step * c / major));
      }
      const size_t idx = static_cast<size_t>(k) * samples_per_line_ + j;
      dx_[idx] = dx;
      dy_[idx] = dy;
      projection_[idx] = static_cast<float>(dx * c + dy * s);  // exact position along the line, px
      line.dx_min = std::min(line.dx_min, dx);
      line.dx_max = std::max(line.dx_max, dx);
      line.dy_min = std::min(line.dy_min, dy);
      line.dy_max = std::max(line.dy_max, dy);
    }
  }
  offsets_stride_ = 0;  // rebuilt for the image stride at the next evaluate()

  // Distances up to the farthest sample plus a pixel (sub-pixel shifts and base rounding).
  const double max_distance = std::sqrt(2.0) * (half + 2) + 1.0;
  const int entries = static_cast<int>(std::ceil(max_distance * kLutPerPixel)) + 2;
  lut_scale_ = kLutPerPixel;
  gauss_lut_.resize(entries);
  similarity_lut_.resize(entries);
  const double norm = 1.0 / (std::sqrt(2.0 * kPi) * t.sigma);
  for (int i = 0; i < entries; ++i)
  {
    const double d = (i + 0.5) / kLutPerPixel;
    gauss_lut_[i] = static_cast<float>(norm * std::exp(-d * d / (2.0 * t.sigma * t.sigma)));
    similarity_lut_[i] = static_cast<float>(std::exp(-d * d / (8.0 * t.sigma * t.sigma)));
  }
  profile_.resize(samples_per_line_);
}

void ShapeCircle::buildOffsets(size_t stride)
{
  offsets_.resize(dx_.size());
  for (size_t i = 0; i < dx_.size(); ++i)
    offsets_[i] = static_cast<std::ptrdiff_t>(dy_[i]) * static_cast<std::ptrdiff_t>(stride) + dx_[i];
  offsets_stride_ = stride;
}

void ShapeCircle::reconfigure()
{
  const Tunables t = readTunables();  // throws before anything changes
  ObservationModel::reconfigure();
  applyTunables(t);
}

bool ShapeCircle::learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error)
{
  const cv::Mat& image = cache.image(view);
  if (image.empty())
  {
    error = name() + ": cannot learn the radius: the frame has no image in this view";
    return false;
  }
  const cv::Rect inside = roi & cv::Rect(0, 0, image.cols, image.rows);
  if (roi.width <= 0 || roi.height <= 0 || inside.empty())
  {
    error = name() + ": cannot learn the radius: the region " + rectText(roi) + " is empty or outside the " +
            std::to_string(image.cols) + "x" + std::to_string(image.rows) + " image";
    return false;
  }
  learned_radius_ = 0.5 * std::min(inside.width, inside.height);
  return true;
}

void ShapeCircle::evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                           Eigen::Ref<Eigen::VectorXd> similarity)
{
  const int n = hyp.size();
  if (log_likelihood.size() != n || similarity.size() != n || static_cast<int>(hyp.v.size()) != n ||
      static_cast<int>(hyp.radius.size()) != n || static_cast<int>(hyp.valid.size()) != n)
    throw std::invalid_argument(name() + ": evaluate: hypothesis arrays and outputs must all have " +
                                std::to_string(n) + " entries");
  log_likelihood.setZero();
  similarity.setZero();
  if (n == 0 || samples_per_line_ == 0)
    return;

  // The cache's Sobel derivatives: computed once per image per frame, shared with TextureEdge.
  const cv::Mat& sx = cache.gradientX(hyp.view);
  const cv::Mat& sy = cache.gradientY(hyp.view);
  if (sx.step != sy.step || sx.size() != sy.size())
    throw std::logic_error(name() + ": Sobel images of different layout");
  const size_t stride = sx.step1();
  if (stride != offsets_stride_)
    buildOffsets(stride);
  const float* gx = sx.ptr<float>();
  const float* gy = sy.ptr<float>();
  const int width = sx.cols;
  const int height = sx.rows;

  const int k_lines = tunables_.lines;
  const int m = samples_per_line_;
  const int half = tunables_.line_half_length;
  const int min_inside = (k_lines + 1) / 2;  // at least half of the lines must be measurable
  const float threshold = static_cast<float>(tunables_.edge_threshold);
  const float min_radius = static_cast<float>(tunables_.min_radius);
  const float r2d = static_cast<float>(radius2D());
  // Farther than any sample can reach (rounding included): a circle this large cannot be half inside.
  const float max_radius = 2.0f * static_cast<float>(std::max(width, height));
  const int reach = half + 3;  // bound on |sample offset| + base rounding, px
  const int lut_last = static_cast<int>(gauss_lut_.size()) - 1;
  const float lut_scale = lut_scale_;
  const float* gauss = gauss_lut_.data();
  const float* sim_lut = similarity_lut_.data();
  float* profile = profile_.data();

  for (int i = 0; i < n; ++i)
  {
    if (!hyp.valid[i])
      continue;
    const float u = hyp.u[i];
    const float v = hyp.v[i];
    float r = hyp.radius[i] > 0.0f ? std::max(hyp.radius[i], min_radius) : r2d;
    // Also rejects NaN radii and positions.
    if (!(r > 0.0f && r <= max_radius && std::abs(u) < 4.0f * width + max_radius &&
          std::abs(v) < 4.0f * height + max_radius))
      continue;
    // Fast path: the whole pattern is inside the image, no per-line bounds test.
    const float extent = r + static_cast<float>(reach);
    const bool all_inside = u - extent >= 0.0f && u + extent <= width - 1 && v - extent >= 0.0f &&
                            v + extent <= height - 1;

    double product = 1.0;
    float similarity_sum = 0.0f;
    int inside = 0;
    for (int k = 0; k < k_lines; ++k)
    {
      const Line& line = lines_[k];
      const float bxf = u + r * line.c;
      const float byf = v + r * line.s;
      const int bx = cvRound(bxf);
      const int by = cvRound(byf);
      if (!all_inside && (bx + line.dx_min < 0 || bx + line.dx_max >= width || by + line.dy_min < 0 ||
                          by + line.dy_max >= height))
        continue;  // a line leaving the image tells nothing: factor 1
      ++inside;
      // Where the rounded start lies along the line relative to the true contour point.
      const float e = (static_cast<float>(bx) - bxf) * line.c + (static_cast<float>(by) - byf) * line.s;
      const std::ptrdiff_t base = static_cast<std::ptrdiff_t>(by) * static_cast<std::ptrdiff_t>(stride) + bx;
      const std::ptrdiff_t* off = &offsets_[static_cast<size_t>(k) * m];
      const float* proj = &projection_[static_cast<size_t>(k) * m];
      for (int j = 0; j < m; ++j)
      {
        const std::ptrdiff_t p = base + off[j];
        profile[j] = std::abs(gx[p] * line.c + gy[p] * line.s);
      }
      // Peaks: local maxima above the threshold, excluding the guard samples at both ends (a maximum
      // there may be a slope continuing outside the line).
      float sum_w = 0.0f, sum_wg = 0.0f, best = 0.0f;
      for (int j = 1; j <= 2 * half + 1; ++j)
      {
        const float b = profile[j];
        if (b < threshold || b <= profile[j - 1] || b < profile[j + 1])
          continue;
        const float a = profile[j - 1], c = profile[j + 1];
        // Vertex of the parabola through the three samples (den < 0 at a strict maximum).
        const float den = a - 2.0f * b + c;
        const float delta = den < 0.0f ? std::clamp(0.5f * (a - c) / den, -0.5f, 0.5f) : 0.0f;
        // Sub-pixel position along the line, interpolated between the samples on the side of the shift.
        const float where = proj[j] + delta * (delta > 0.0f ? proj[j + 1] - proj[j] : proj[j] - proj[j - 1]);
        const float d = std::abs(e + where);
        const int idx = std::min(static_cast<int>(d * lut_scale), lut_last);
        sum_w += b;
        sum_wg += b * gauss[idx];
        best = std::max(best, sim_lut[idx]);
      }
      if (sum_w > 0.0f)
        product *= 1.0 + line.gain * static_cast<double>(sum_wg / sum_w);
      similarity_sum += best;
    }
    if (inside < min_inside)
      continue;
    log_likelihood[i] = std::log(product);
    similarity[i] = similarity_sum / inside;
  }
}

void ShapeCircle::saveTarget(cv::FileStorage& fs) const
{
  if (!(learned_radius_ > 0.0))
    return;
  fs << name() << "{";
  fs << "type" << "stereo_pf/ShapeCircle";
  fs << "radius" << learned_radius_;
  fs << "}";
}

bool ShapeCircle::loadTarget(const cv::FileNode& node, std::string& error)
{
  cv::FileNode m = node;
  if (m.isMap() && m["radius"].empty())
    m = node[name()];
  if (m.empty() || !m.isMap())
  {
    if (tunables_.radius > 0.0)
      return true;  // nothing stored and nothing needed: the radius is configured
    error = name() + ": no shape target named '" + name() + "' in the file (and the 'radius' parameter is 0)";
    return false;
  }
  const cv::FileNode r = m["radius"];
  if (!r.isInt() && !r.isReal())
  {
    error = name() + ": shape target lacks the number 'radius'";
    return false;
  }
  const double radius = r.real();
  if (!(radius > 0.0) || !std::isfinite(radius))
  {
    error = name() + ": shape target radius must be > 0, got " + std::to_string(radius);
    return false;
  }
  learned_radius_ = radius;
  return true;
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::ShapeCircle, stereo_pf::ObservationModel)
