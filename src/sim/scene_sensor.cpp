// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Camera sensor model and image encodings of the synthetic scenes (see scene_sensor.h), and the part of
// SceneRenderer (scene.h) that applies them to each view: exposure (motion blur), then the sensor.
#include "stereo_pf/sim/scene_sensor.h"

#include "stereo_pf/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "scene_detail.h"

namespace stereo_pf
{
namespace
{
using scene_detail::mix64;

// The per-pixel noise stream must stay the one the renderer has always used, so shipped scenes keep their pixels.
// RNG state of the per-pixel noise of frame k in `view` (unchanged from the renderer's addNoise).
uint64_t pixelNoiseState(uint64_t seed, int k, View view)
{
  return mix64(seed ^ mix64(static_cast<uint64_t>(k) * 2 + static_cast<uint64_t>(view) + 1));
}

// RNG state of a per-frame gain: separate streams, so switching gains on does not change the pixel noise.
uint64_t gainState(uint64_t seed, int k, uint64_t stream)
{
  return mix64(mix64(seed ^ 0x6A09E667F3BCC909ULL) ^ mix64(static_cast<uint64_t>(k) * 4 + stream));
}

double jitter(uint64_t state, double sd)
{
  if (sd <= 0.0)
    return 1.0;
  cv::RNG rng(state);
  // Floored: a gain at or below zero would be a black frame, not a darker one.
  return std::max(0.1, 1.0 + sd * rng.gaussian(1.0));
}

const SceneEncoding kEncodings[] = { SceneEncoding::Bgr8, SceneEncoding::Rgb8, SceneEncoding::Mono8,
                                     SceneEncoding::Mono16, SceneEncoding::BayerGrbg8 };
}  // namespace

std::string encodingName(SceneEncoding encoding)
{
  switch (encoding)
  {
    case SceneEncoding::Bgr8:
      return "bgr8";
    case SceneEncoding::Rgb8:
      return "rgb8";
    case SceneEncoding::Mono8:
      return "mono8";
    case SceneEncoding::Mono16:
      return "mono16";
    case SceneEncoding::BayerGrbg8:
      return "bayer_grbg8";
  }
  return "bgr8";
}

std::vector<std::string> encodingNames()
{
  std::vector<std::string> names;
  for (SceneEncoding e : kEncodings)
    names.push_back(encodingName(e));
  return names;
}

bool encodingFromName(const std::string& name, SceneEncoding& encoding)
{
  for (SceneEncoding e : kEncodings)
    if (encodingName(e) == name)
    {
      encoding = e;
      return true;
    }
  return false;
}

std::string cameraInfoName(SceneCameraInfo mode)
{
  return mode == SceneCameraInfo::SizeOnly ? "size_only" : "full";
}

std::string SceneSensor::validate() const
{
  std::ostringstream out;
  auto range = [&out](double v, double lo, double hi, const char* field) {
    if (!(v >= lo && v <= hi))
      out << "sensor." << field << " must be in [" << lo << ", " << hi << "], got " << v << "\n";
  };
  range(exposure, 0.0, 1.0, "exposure");
  range(blur_samples, 0, 64, "blur_samples");
  range(vignetting, 0.0, 0.9, "vignetting");
  range(gain_jitter, 0.0, 0.5, "gain_jitter");
  range(right_gain, 0.5, 2.0, "right_gain");
  range(right_gain_jitter, 0.0, 0.5, "right_gain_jitter");
  range(jpeg_quality, 0, 100, "jpeg_quality");
  std::string s = out.str();
  if (!s.empty())
    s.pop_back();
  return s;
}

void encodeImage(const cv::Mat& bgr, SceneEncoding encoding, cv::Mat& out)
{
  if (bgr.type() != CV_8UC3)
    throw std::invalid_argument("encodeImage: expected a CV_8UC3 BGR image, got type " + std::to_string(bgr.type()));
  switch (encoding)
  {
    case SceneEncoding::Bgr8:
      bgr.copyTo(out);
      return;
    case SceneEncoding::Rgb8:
      cv::cvtColor(bgr, out, cv::COLOR_BGR2RGB);
      return;
    case SceneEncoding::Mono8:
      cv::cvtColor(bgr, out, cv::COLOR_BGR2GRAY);
      return;
    case SceneEncoding::Mono16:
    {
      cv::Mat grey;
      cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
      grey.convertTo(out, CV_16U, 257.0);  // 255 -> 65535: the full 16-bit range, and exact back to 8 bits
      return;
    }
    case SceneEncoding::BayerGrbg8:
    {
      // A colour filter array samples one channel per site: G R on even rows, B G on odd rows.
      out.create(bgr.size(), CV_8UC1);
      for (int row = 0; row < bgr.rows; ++row)
      {
        const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(row);
        uchar* o = out.ptr<uchar>(row);
        const int odd_col_channel = row % 2 == 0 ? 2 : 1;   // R on even rows, G on odd rows
        const int even_col_channel = row % 2 == 0 ? 1 : 0;  // G on even rows, B on odd rows
        for (int col = 0; col < bgr.cols; ++col)
          o[col] = in[col][col % 2 == 0 ? even_col_channel : odd_col_channel];
      }
      return;
    }
  }
}

SceneSensorModel::SceneSensorModel(const SceneSensor& sensor, double sigma, double shot, uint64_t seed, cv::Size size,
                                   double cx, double cy)
  : sensor_(sensor), sigma_(sigma), shot_(shot), seed_(seed), size_(size), cx_(cx), cy_(cy)
{
  corner2_ = 0.0;
  for (double u : { 0.0, size.width - 1.0 })
    for (double v : { 0.0, size.height - 1.0 })
      corner2_ = std::max(corner2_, (u - cx) * (u - cx) + (v - cy) * (v - cy));
  corner2_ = std::max(corner2_, 1e-12);
  if (sensor_.vignetting > 0.0)
  {
    cv::Mat factor(size, CV_32F);
    for (int row = 0; row < size.height; ++row)
    {
      float* f = factor.ptr<float>(row);
      for (int col = 0; col < size.width; ++col)
        f[col] = static_cast<float>(vignette(col, row));
    }
    cv::merge(std::vector<cv::Mat>{ factor, factor, factor }, vignette_);
  }
}

double SceneSensorModel::vignette(int col, int row) const
{
  // Quadratic radial fall-off: smooth, 1 at the principal point, 1 - vignetting at the farthest corner.
  const double r2 = ((col - cx_) * (col - cx_) + (row - cy_) * (row - cy_)) / corner2_;
  return 1.0 - sensor_.vignetting * r2;
}

double SceneSensorModel::gain(int k, View view) const
{
  double g = jitter(gainState(seed_, k, 0), sensor_.gain_jitter);
  if (view == View::Right)
    g *= sensor_.right_gain * jitter(gainState(seed_, k, 1), sensor_.right_gain_jitter);
  return g;
}

bool SceneSensorModel::plain(int k, View view) const
{
  return sensor_.vignetting == 0.0 && shot_ == 0.0 && gain(k, view) == 1.0;
}

void SceneSensorModel::apply(int k, View view, const cv::Mat& light, cv::Mat& out, bool with_noise)
{
  if (light.type() != CV_8UC3 && light.type() != CV_32FC3)
    throw std::invalid_argument("SceneSensorModel::apply: light must be CV_8UC3 or CV_32FC3");
  const bool noise = with_noise && (sigma_ > 0.0 || shot_ > 0.0);
  if (light.type() == CV_8UC3 && plain(k, view))
  {
    // The renderer's original path: whole grey levels of read noise added with saturation.
    if (&out != &light)
      light.copyTo(out);
    if (noise)
    {
      cv::RNG rng(pixelNoiseState(seed_, k, view));
      noise_.create(out.size(), CV_16SC3);
      rng.fill(noise_, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(sigma_));
      cv::add(out, noise_, out, cv::noArray(), CV_8U);
    }
  }
  else
  {
    light.convertTo(signal_, CV_32F);
    if (!vignette_.empty())
      cv::multiply(signal_, vignette_, signal_);
    const double g = gain(k, view);
    if (g != 1.0)
      signal_ *= g;
    if (noise)
    {
      // Photon noise is Poisson: its variance grows with the signal, sigma^2 = read^2 + shot * I.
      cv::max(signal_, 0.0, sd_);
      sd_.convertTo(sd_, CV_32F, shot_, sigma_ * sigma_);  // convertTo adds the offset to every channel
      cv::sqrt(sd_, sd_);
      cv::RNG rng(pixelNoiseState(seed_, k, view));
      noise_.create(signal_.size(), CV_32FC3);
      rng.fill(noise_, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(1));
      cv::multiply(noise_, sd_, noise_);
      signal_ += noise_;
    }
    signal_.convertTo(out, CV_8U);  // rounds to nearest and saturates at 0 and 255
  }
  if (sensor_.jpeg_quality > 0)
  {
    cv::imencode(".jpg", out, jpeg_, { cv::IMWRITE_JPEG_QUALITY, sensor_.jpeg_quality });
    cv::imdecode(jpeg_, cv::IMREAD_COLOR, &out);
  }
}

// --------------------------------------------------------------------------------------------------
// SceneRenderer: exposure (motion blur) and the sensor model applied to each view

void SceneRenderer::renderView(int k, View view, cv::Mat& bgr, bool with_noise)
{
  const double t = stamp(k);
  const int n = blurSamples(k);
  if (n <= 1)
  {
    drawScene(t, view, bgr);
    sensor_.apply(k, view, bgr, bgr, with_noise);
    return;
  }
  // Motion blur: the mean, in float, of renders at the centres of n equal slices of the exposure.
  const double exposure = scene_.sensor.exposure;
  exposure_sum_.create(scene_.camera.height, scene_.camera.width, CV_32FC3);
  exposure_sum_.setTo(cv::Scalar::all(0));
  for (int i = 0; i < n; ++i)
  {
    drawScene(t + exposure * ((i + 0.5) / n - 0.5), view, sub_frame_);
    cv::accumulate(sub_frame_, exposure_sum_);
  }
  exposure_sum_ *= 1.0 / n;
  sensor_.apply(k, view, exposure_sum_, bgr, with_noise);
}

int SceneRenderer::blurSamples(int k) const
{
  const SceneSensor& sensor = scene_.sensor;
  if (!(sensor.exposure > 0.0))
    return 1;
  if (sensor.blur_samples > 0)
    return sensor.blur_samples;
  // Longest image path of any moving thing over the exposure, in pixels, from 16 slices of it: each
  // object's projected centre, plus the change of its apparent radius and a spinning pattern's rim speed.
  constexpr int kSlices = 16;
  const SceneCamera& cam = scene_.camera;
  const double t = stamp(k), f = std::max(cam.fx, cam.fy);
  double longest = 0.0;
  auto path = [&](const Trajectory& tr, double radius, double spin) {
    for (int v = 0; v < 2; ++v)
    {
      const Eigen::Vector3d origin = cameraOrigin(static_cast<View>(v));
      double length = 0.0;
      Eigen::Vector3d prev;
      for (int i = 0; i <= kSlices; ++i)
      {
        const double ti = t + sensor.exposure * (static_cast<double>(i) / kSlices - 0.5);
        const Eigen::Vector3d c = tr.at(ti) - origin;
        if (c.z() <= 1e-3)
          return;  // behind the camera: not drawn
        const Eigen::Vector3d p(cam.fx * c.x() / c.z(), cam.fy * c.y() / c.z(), f * radius / c.z());
        if (i > 0)
          length += (p - prev).norm() + std::abs(spin) * sensor.exposure / kSlices * p.z();
        prev = p;
      }
      longest = std::max(longest, length);
    }
  };
  // An object's reach from its centre: what its outline and a turning surface move with.
  auto reach = [](const SceneSphere& s) {
    switch (s.shape)
    {
      case SceneSphere::Shape::Box:
        return 0.5 * s.size.norm();
      case SceneSphere::Shape::Cylinder:
        return std::hypot(s.radius, 0.5 * s.height);
      case SceneSphere::Shape::Square:
        return s.radius * std::sqrt(2.0);
      default:
        return s.radius;
    }
  };
  for (const SceneSphere& s : scene_.objects)
    if (s.trajectory.present(t))
      path(s.trajectory, reach(s), s.spin);
  for (const SceneOccluder& o : scene_.occluders)
    if (o.trajectory.present(t))
      path(o.trajectory, 0.5 * std::hypot(o.width, o.height), 0.0);
  return std::clamp(static_cast<int>(std::ceil(longest)), 1, 16);
}

}  // namespace stereo_pf
