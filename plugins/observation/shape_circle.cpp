// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Circle-contour observation model (thesis eq. 5.8-5.11); see include/stereo_pf/plugins/shape_circle.h.
#include "stereo_pf/plugins/shape_circle.h"
#include "stereo_pf/core/histogram.h"
#include "stereo_pf/core/silhouette.h"

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
constexpr double kPi = 3.14159265358979323846;
// Table resolution of the Gaussian: 1/32 px is far below the peaks' localisation error.
constexpr float kLutPerPixel = 32.0f;
// Lines whose factors are multiplied before taking one log: 16 factors of at most ~1e9 (numerators) stay
// far inside double range whatever the parameters; a power of two.
constexpr int kLinesPerLog = 16;
// Samples per vector of the line processing.
constexpr int kLanes = cv::v_uint8x16::nlanes;
// Lines per vector of the contour-point computation.
constexpr int kLines4 = cv::v_float32x4::nlanes;

}  // namespace

void ShapeCircle::onInitialize()
{
  applyTunables(readTunables());
}

ShapeCircle::Tunables ShapeCircle::readTunables() const
{
  const Parameters& p = params();
  Tunables t;
  t.lines = p.getInt("lines", 8, 3, 256, "radial measurement lines across the circle");
  t.line_half_length = p.getInt("line_half_length", 5, 1, 25, "px on each side of the circle along each line");
  t.sigma = p.getDouble("sigma", 1.5, 0.1, 50.0, "px; edge position noise along a measurement line");
  t.q0 = p.getDouble("q0", 0.1, 0.001, 0.999, "prior that no peak on a line is the contour (eq. 5.10)");
  t.edge_threshold = p.getDouble("edge_threshold", 16.0, 0.0, 255.0,
                                 "grey levels; smaller steps along a line are not edge peaks");
  t.radius = p.getDouble("radius", 0.0, 0.0, 2000.0,
                         "px; radius of 2D hypotheses (0: learned from the region of interest)");
  t.min_radius = p.getDouble("min_radius", 3.0, 0.5, 1000.0, "px; smaller apparent radii are clamped to it");
  t.perspective = p.getBool("perspective", true, "fit the off-axis ball's elliptical silhouette, not a circle");
  return t;
}

void ShapeCircle::applyTunables(const Tunables& t)
{
  tunables_ = t;
  const int half = t.line_half_length;
  samples_per_line_ = 2 * half + 5;
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
    const double major = std::max(std::abs(c), std::abs(s));
    line.spacing = static_cast<float>(1.0 / major);
    // U is the uniform density over the line's length: gain = (1 - q0) / (q0 U).
    const double length = (2 * half + 1) * line.spacing;
    line.gain = (1.0 - t.q0) / t.q0 * length;
    for (int j = 0; j < samples_per_line_; ++j)
    {
      int dx, dy;
      digitalLineStep(c, s, j - (half + 2), dx, dy);
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
  // Where central difference t (samples t and t + 2) lies along the line: at sample t + 1.
  difference_position_.assign(projection_.size(), 0.0f);
  for (int k = 0; k < t.lines; ++k)
    for (int j = 0; j + 1 < samples_per_line_; ++j)
    {
      const size_t idx = static_cast<size_t>(k) * samples_per_line_ + j;
      difference_position_[idx] = projection_[idx + 1];
    }
  // Line directions as arrays for the vector code, padded to whole vectors with a harmless direction.
  const size_t padded_lines = static_cast<size_t>((t.lines + kLines4 - 1) / kLines4) * kLines4;
  line_c_.assign(padded_lines, 1.0f);
  line_s_.assign(padded_lines, 0.0f);
  for (int k = 0; k < t.lines; ++k)
  {
    line_c_[k] = lines_[k].c;
    line_s_[k] = lines_[k].s;
  }
  start_x_.assign(padded_lines, 0);
  start_y_.assign(padded_lines, 0);
  start_e_.assign(padded_lines, 0.0f);
  offsets_stride_ = 0;  // rebuilt for the image stride at the next evaluate()

  // Distances up to the farthest sample plus a pixel (sub-pixel shifts and base rounding).
  const double max_distance = std::sqrt(2.0) * (half + 3) + 1.0;
  const int entries = static_cast<int>(std::ceil(max_distance * kLutPerPixel)) + 2;
  lut_scale_ = kLutPerPixel;
  gauss_lut_.resize(entries);
  similarity_lut_.resize(entries);
  const double norm = 1.0 / (std::sqrt(2.0 * kPi) * t.sigma);
  for (int i = 0; i < entries; ++i)
  {
    const double d = (i + 0.5) / kLutPerPixel;
    gauss_lut_[i] = static_cast<float>(norm * std::exp(-d * d / (2.0 * t.sigma * t.sigma)));
    similarity_lut_[i] = static_cast<float>(std::exp(-d * d / (2.0 * t.sigma * t.sigma)));
  }
  half_reciprocal_.resize(2 * 255 + 1);
  half_reciprocal_[0] = 0.0f;  // never used: a peak has 2b - a - c >= 1
  for (size_t x = 1; x < half_reciprocal_.size(); ++x)
    half_reciprocal_[x] = 0.5f / static_cast<float>(x);
  // Padded so that every vector load of the last chunk stays inside (the padding's values are masked out).
  const size_t padded = static_cast<size_t>((samples_per_line_ + kLanes - 1) / kLanes) * kLanes + kLanes + 4;
  intensity_.assign(padded, 0);
  derivative_.assign(padded, 0);
}

void ShapeCircle::buildOffsets(size_t stride)
{
  // Lines of fewer than kLanes samples are padded with offset 0 (the contour pixel, always readable), so
  // the single-vector path can read a full vector's worth; the padding's values are masked out.
  const int row = std::max(samples_per_line_, kLanes);
  offsets_.assign(static_cast<size_t>(tunables_.lines) * row, 0);
  for (int k = 0; k < tunables_.lines; ++k)
    for (int j = 0; j < samples_per_line_; ++j)
    {
      const size_t i = static_cast<size_t>(k) * samples_per_line_ + j;
      offsets_[static_cast<size_t>(k) * row + j] =
          static_cast<std::ptrdiff_t>(dy_[i]) * static_cast<std::ptrdiff_t>(stride) + dx_[i];
    }
  offsets_row_ = row;
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
    error = name() + ": cannot learn the radius: the region " + describeRect(roi) + " is empty or outside the " +
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

  const int width = cache.image(hyp.view).cols;
  const int height = cache.image(hyp.view).rows;

  const int k_lines = tunables_.lines;
  const int m = samples_per_line_;
  const int half = tunables_.line_half_length;
  const int min_inside = (k_lines + 1) / 2;  // at least half of the lines must be measurable
  // Integer threshold: derivatives are integers, so d >= threshold <=> d >= ceil(threshold).
  const int threshold = std::clamp(static_cast<int>(std::ceil(tunables_.edge_threshold)), 1, 255);
  const float min_radius = static_cast<float>(tunables_.min_radius);
  const float r2d = static_cast<float>(radius2D());
  const bool perspective = tunables_.perspective;
  const float focal = static_cast<float>(cache.geometry().fx());
  const float cx = static_cast<float>(cache.geometry().cx());
  const float cy = static_cast<float>(cache.geometry().cy());
  // Farther than any sample can reach (rounding included): a circle this large cannot be half inside.
  const float max_radius = 2.0f * static_cast<float>(std::max(width, height));
  const int reach = half + 4;  // bound on |sample offset| + base rounding, px
  const int lut_last = static_cast<int>(gauss_lut_.size()) - 1;
  const float lut_scale = lut_scale_;
  const float* gauss = gauss_lut_.data();
  const float* sim_lut = similarity_lut_.data();
  const float* half_reciprocal = half_reciprocal_.data();
  const float* line_c = line_c_.data();
  const float* line_s = line_s_.data();
  int* start_x = start_x_.data();
  int* start_y = start_y_.data();
  float* start_e = start_e_.data();
  uint8_t* intensity = intensity_.data();
  uint8_t* derivative = derivative_.data();
  const cv::v_uint8x16 v_threshold = cv::v_setall_u8(static_cast<uint8_t>(threshold));
  // Bits 1 .. m - 4: the differences that may be a peak (both neighbours exist).
  const uint64_t peak_range = ((uint64_t{ 1 } << (m - 3)) - 1) & ~uint64_t{ 1 };

  // The contours first: they say which rows of the grey image the lines can reach.
  contours_.resize(static_cast<size_t>(n));
  float top = static_cast<float>(height), bottom = -1.0f;
  for (int i = 0; i < n; ++i)
  {
    Contour& c = contours_[static_cast<size_t>(i)];
    c.usable = false;
    if (!hyp.valid[i])
      continue;
    const float u = hyp.u[i];
    const float v = hyp.v[i];
    const bool is_3d = hyp.radius[i] > 0.0f;
    c.r = is_3d ? std::max(hyp.radius[i], min_radius) : r2d;
    // Also rejects NaN radii and positions.
    if (!(c.r > 0.0f && c.r <= max_radius && std::abs(u) < 4.0f * width + max_radius &&
          std::abs(v) < 4.0f * height + max_radius))
      continue;
    // The contour: a circle of radius r around (u, v), or for a 3D hypothesis the ellipse its sphere
    // projects to. Along line k it lies at distance rho_k = a b / sqrt(b^2 cos^2 psi + a^2 sin^2 psi) from
    // the centre (psi: the line's angle to the radial direction).
    c.cu = u;
    c.cv = v;
    c.ex = 1.0f;
    c.ey = 0.0f;
    c.a = c.b = c.r;
    c.ellipse = is_3d && perspective && sphereSilhouette(u, v, c.r, focal, cx, cy, c.ex, c.ey, c.a, c.b);
    c.usable = true;
    const float extent = std::max(c.a, c.b) + static_cast<float>(reach);
    top = std::min(top, c.cv - extent);
    bottom = std::max(bottom, c.cv + extent);
  }
  // The grey image is the only per-image product needed (shared with every other model using it), and
  // only in the rows the lines reach.
  const std::pair<int, int> rows = rowSpan(top, bottom, height);
  const cv::Mat& gray = cache.gray(hyp.view, rows.first, rows.second);
  if (gray.type() != CV_8UC1)
    throw std::logic_error(name() + ": the cache's grey image is not CV_8UC1");
  const size_t stride = gray.step[0];
  if (stride != offsets_stride_)
    buildOffsets(stride);
  const uint8_t* data = gray.data;

  for (int i = 0; i < n; ++i)
  {
    const Contour& contour = contours_[static_cast<size_t>(i)];
    if (!contour.usable)
      continue;
    const float cu = contour.cu, cv = contour.cv, ex = contour.ex, ey = contour.ey, a = contour.a, b = contour.b;
    const float r = contour.r;
    const bool ellipse = contour.ellipse;
    // Fast path: the whole pattern is inside the image, no per-line bounds test.
    const float extent = std::max(a, b) + static_cast<float>(reach);
    const bool all_inside = cu - extent >= 0.0f && cu + extent <= width - 1 && cv - extent >= 0.0f &&
                            cv + extent <= height - 1;
    // Every line's contour point, rounded start pixel and rounding offset along the line, four lines per
    // vector instruction (per line this would be a square root and a division each).
    {
      const cv::v_float32x4 v_cu = cv::v_setall_f32(cu), v_cv = cv::v_setall_f32(cv);
      const cv::v_float32x4 v_ex = cv::v_setall_f32(ex), v_ey = cv::v_setall_f32(ey);
      const cv::v_float32x4 v_ab = cv::v_setall_f32(a * b), v_a2 = cv::v_setall_f32(a * a);
      const cv::v_float32x4 v_b2 = cv::v_setall_f32(b * b), v_r = cv::v_setall_f32(r);
      for (int k = 0; k < k_lines; k += kLines4)
      {
        const cv::v_float32x4 c = cv::v_load(line_c + k), sn = cv::v_load(line_s + k);
        cv::v_float32x4 rho = v_r;
        if (ellipse)
        {
          const cv::v_float32x4 cos_psi = c * v_ex + sn * v_ey, sin_psi = sn * v_ex - c * v_ey;
          rho = v_ab / cv::v_sqrt(v_b2 * cos_psi * cos_psi + v_a2 * sin_psi * sin_psi);
        }
        const cv::v_float32x4 bxf = v_cu + rho * c, byf = v_cv + rho * sn;
        const cv::v_int32x4 bxi = cv::v_round(bxf), byi = cv::v_round(byf);
        cv::v_store(start_x + k, bxi);
        cv::v_store(start_y + k, byi);
        cv::v_store(start_e + k, (cv::v_cvt_f32(bxi) - bxf) * c + (cv::v_cvt_f32(byi) - byf) * sn);
      }
    }

    double numerator = 1.0, denominator = 1.0, log_sum = 0.0;
    float similarity_sum = 0.0f;
    int inside = 0;
    for (int k = 0; k < k_lines; ++k)
    {
      if (k > 0 && (k & (kLinesPerLog - 1)) == 0)
      {
        log_sum += std::log(numerator / denominator);
        numerator = denominator = 1.0;
      }
      const Line& line = lines_[k];
      const int bx = start_x[k];
      const int by = start_y[k];
      if (!all_inside && (bx + line.dx_min < 0 || bx + line.dx_max >= width || by + line.dy_min < 0 ||
                          by + line.dy_max >= height))
        continue;  // a line leaving the image tells nothing: factor 1
      ++inside;
      const uint8_t* base = data + static_cast<std::ptrdiff_t>(by) * static_cast<std::ptrdiff_t>(stride) + bx;
      const std::ptrdiff_t* off = &offsets_[static_cast<size_t>(k) * offsets_row_];
      // The 1-D edge detector: central differences along the line, D[t] = |I[t + 2] - I[t]|, located at
      // sample t + 1 (between the pixels it compares). Peaks are local maxima at least `threshold` high
      // within L of the contour point (t = 1 .. m - 4: both neighbours exist). Both steps run 16 samples per
      // vector instruction into a bit mask of peaks (done one by one they cost most of the time); the few
      // peaks are then visited bit by bit.
      uint64_t peaks = 0;
      if (m <= kLanes)
      {
        // One vector holds the whole line. It is assembled in registers: writing the bytes to memory and
        // reading them back as a vector would stall on store forwarding.
        uint64_t lo = 0, hi = 0;
        for (int j = 0; j < 8; ++j)
          lo |= static_cast<uint64_t>(base[off[j]]) << (8 * j);
        for (int j = 8; j < kLanes; ++j)
          hi |= static_cast<uint64_t>(base[off[j]]) << (8 * (j - 8));
        const cv::v_uint8x16 in = cv::v_reinterpret_as_u8(cv::v_uint64x2(lo, hi));
        const cv::v_uint8x16 d = cv::v_absdiff(cv::v_rotate_right<2>(in), in);  // lane t: D[t]
        const cv::v_uint8x16 is_peak =
            (d >= v_threshold) & (d > cv::v_rotate_left<1>(d)) & (d >= cv::v_rotate_right<1>(d));
        peaks = static_cast<uint64_t>(static_cast<unsigned>(cv::v_signmask(is_peak)));
        cv::v_store(derivative, d);  // for the peaks' sub-pixel positions (read back byte by byte)
      }
      else
      {
        for (int j = 0; j < m; ++j)
          intensity[j] = base[off[j]];
        for (int c = 0; c < m; c += kLanes)
          cv::v_store(derivative + c, cv::v_absdiff(cv::v_load(intensity + c + 2), cv::v_load(intensity + c)));
        for (int c = 0; c < m; c += kLanes)
        {
          const cv::v_uint8x16 b = cv::v_load(derivative + c + 1);
          const cv::v_uint8x16 is_peak = (b >= v_threshold) & (b > cv::v_load(derivative + c)) &
                                         (b >= cv::v_load(derivative + c + 2));
          peaks |= static_cast<uint64_t>(static_cast<unsigned>(cv::v_signmask(is_peak))) << (c + 1);
        }
      }
      peaks &= peak_range;
      if (peaks == 0)
        continue;  // the clutter term alone: factor 1
      // Where the rounded start lies along the line relative to the true contour point.
      const float e = start_e[k];
      const float* position = &difference_position_[static_cast<size_t>(k) * m];
      int sum_w = 0;
      float sum_wg = 0.0f, sum_ws = 0.0f;
      for (; peaks != 0; peaks &= peaks - 1)
      {
        const int j = __builtin_ctzll(peaks);
        const int a = derivative[j - 1], b = derivative[j], c = derivative[j + 1];
        // Vertex of the parabola through the three differences: delta = (c - a) / (2 (2b - a - c)). At a
        // peak (b > a, b >= c) the denominator is in [1, 510] and |delta| <= 1/2: a table replaces the
        // division.
        const float delta = static_cast<float>(c - a) * half_reciprocal[2 * b - a - c];
        // Sub-pixel position along the line, interpolated towards the neighbour on the side of the shift.
        const float where =
            position[j] + delta * (delta > 0.0f ? position[j + 1] - position[j] : position[j] - position[j - 1]);
        const float d = std::abs(e + where);
        const int idx = std::min(static_cast<int>(d * lut_scale), lut_last);
        sum_w += b;
        sum_wg += static_cast<float>(b) * gauss[idx];
        sum_ws += static_cast<float>(b) * sim_lut[idx];
      }
      // p_k / (q0 U) = 1 + gain sum_i w_i N(d_i) with w_i = b_i / sum_w: kept as a fraction, numerator and
      // denominator multiplied up separately (no division per line; both stay far inside double range).
      numerator *= static_cast<double>(sum_w) + line.gain * static_cast<double>(sum_wg);
      denominator *= static_cast<double>(sum_w);
      similarity_sum += sum_ws / static_cast<float>(sum_w);
    }
    if (inside < min_inside)
      continue;
    log_likelihood[i] = log_sum + std::log(numerator / denominator);
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
