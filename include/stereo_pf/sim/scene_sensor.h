// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Camera sensor model of the synthetic scenes: what happens to the rendered light before and after it
// becomes an 8-bit image (vignetting, per-frame gains, read and shot noise, quantisation, JPEG), and the
// image encodings make_scene can publish. ROS-free; scene.h's SceneRenderer applies it to every view.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Image encodings make_scene can publish (the names are ROS's sensor_msgs/image_encodings).
enum class SceneEncoding
{
  Bgr8,       ///< "bgr8": the rendered image as is
  Rgb8,       ///< "rgb8": channels swapped
  Mono8,      ///< "mono8": luminance (OpenCV's BGR to grey weights)
  Mono16,     ///< "mono16": the 8-bit luminance times 257 (255 becomes 65535)
  BayerGrbg8  ///< "bayer_grbg8": one colour per pixel; row 0 G R G R ..., row 1 B G B G ...
};

/// What make_scene publishes on the camera_info topics.
enum class SceneCameraInfo
{
  Full,     ///< "full": the rectified calibration (plumb_bob, zero D, R = I, K, P with the baseline)
  SizeOnly  ///< "size_only": width and height only, as camera1394stereo publishes without a matching calibration
};

/// The scene YAML's `sensor` block: exposure (motion blur), optics and electronics of both cameras, and
/// what make_scene publishes. The defaults change nothing (bit-identical to a scene without the block).
struct SceneSensor
{
  double exposure = 0.0;        ///< exposure time, seconds; > 0 averages renders over [t - exposure/2, t + exposure/2]
  int blur_samples = 0;         ///< renders per exposure: 0 chooses (<= ~1 px of motion between them, at most 16)
  double vignetting = 0.0;      ///< fraction of brightness lost in the farthest image corner, [0, 0.9]
  double gain_jitter = 0.0;     ///< SD of a per-frame multiplicative gain shared by both cameras, [0, 0.5]
  double right_gain = 1.0;      ///< right camera gain relative to the left, [0.5, 2]
  double right_gain_jitter = 0.0;  ///< SD of a per-frame extra gain of the right camera alone, [0, 0.5]
  int jpeg_quality = 0;         ///< 0: off; 1..100: every image is JPEG-encoded and decoded at this quality
  SceneEncoding encoding = SceneEncoding::Bgr8;  ///< what make_scene publishes
  SceneCameraInfo camera_info = SceneCameraInfo::Full;  ///< what make_scene publishes as camera_info

  /// Empty when valid, otherwise every problem, one per line, naming the field ("sensor.vignetting ...").
  std::string validate() const;
};

/// ROS name of an encoding ("bgr8", "rgb8", "mono8", "mono16", "bayer_grbg8").
std::string encodingName(SceneEncoding encoding);
/// Every encoding name, in the order of SceneEncoding (for messages listing what is allowed).
std::vector<std::string> encodingNames();
/// Encoding from its ROS name; false when the name is not one of encodingNames().
bool encodingFromName(const std::string& name, SceneEncoding& encoding);
/// Name of a camera_info mode ("full", "size_only").
std::string cameraInfoName(SceneCameraInfo mode);

/// Convert a rendered CV_8UC3 BGR image into `encoding`: CV_8UC3 for bgr8 and rgb8, CV_8UC1 for mono8 and
/// bayer_grbg8, CV_16UC1 for mono16. `out` must not alias `bgr`. Throws std::invalid_argument for another
/// input type.
void encodeImage(const cv::Mat& bgr, SceneEncoding encoding, cv::Mat& out);

/// Everything after the light reaches a camera, in this order:
///   light (one render, or the float mean of the exposure's sub-frame renders)
///   -> vignetting (radial fall-off about the principal point)
///   -> gain (per-frame shared jitter; right view: right_gain and its own jitter)
///   -> noise (Gaussian, variance sigma^2 + shot * I, I the signal in grey levels after the gain)
///   -> quantisation to 8 bits (rounded, saturated)
///   -> JPEG encode/decode (when jpeg_quality > 0).
/// Everything random is seeded from (seed, frame, view), so frame k does not depend on the frames
/// rendered before. When neither vignetting, gain, shot noise nor blur is in play, the 8-bit render gets
/// exactly the noise the renderer has always added (whole grey levels), so such scenes keep their pixels.
/// Not thread-safe (scratch buffers).
class SceneSensorModel
{
public:
  /// `sigma`: read noise SD, grey levels; `shot`: grey levels of variance per grey level of signal;
  /// `seed`: the scene's noise seed; `size`, `cx`, `cy`: image size and principal point (vignetting centre).
  SceneSensorModel(const SceneSensor& sensor, double sigma, double shot, uint64_t seed, cv::Size size, double cx,
                   double cy);

  /// Apply the sensor to the light of frame k in `view`: `light` is CV_8UC3 (one render) or CV_32FC3 (mean
  /// of sub-frames, grey levels); `out` receives CV_8UC3 and may be `light` itself when that is CV_8UC3.
  /// `with_noise` false leaves out the per-pixel noise only (vignetting, gains and JPEG still apply).
  void apply(int k, View view, const cv::Mat& light, cv::Mat& out, bool with_noise);

  /// Total gain of `view` at frame k: shared jitter, times right_gain and the right jitter for the right
  /// view. Each jitter is 1 + SD * n (n standard normal, seeded per frame), floored at 0.1.
  double gain(int k, View view) const;
  /// Brightness factor of pixel (col, row), 1 at the principal point, 1 - vignetting at the farthest corner.
  double vignette(int col, int row) const;

private:
  /// True when the legacy 8-bit path reproduces this frame exactly (no vignetting, gain 1, no shot noise).
  bool plain(int k, View view) const;

  SceneSensor sensor_;
  double sigma_, shot_;
  uint64_t seed_;
  cv::Size size_;
  double cx_, cy_, corner2_;  ///< principal point, squared distance to the farthest corner
  cv::Mat vignette_;          ///< per-pixel factor, CV_32FC3 (empty without vignetting)
  cv::Mat signal_;            ///< float scratch, CV_32FC3
  cv::Mat noise_;             ///< noise scratch (CV_16SC3 on the 8-bit path, CV_32FC3 otherwise)
  cv::Mat sd_;                ///< per-pixel noise SD scratch, CV_32FC3
  std::vector<uchar> jpeg_;   ///< JPEG bytes scratch
};

}  // namespace stereo_pf
