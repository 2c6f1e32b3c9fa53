// Per-frame cache of per-image work shared by every particle and every observation model.
#pragma once

#include <functional>
#include <map>
#include <string>

#include <opencv2/core.hpp>

#include "stereo_pf/core/stereo_frame.h"

namespace stereo_pf
{
/// Computes, lazily and at most once per image per frame, what observation models ask for.
/// Buffers are kept across frames (same key, same size: no reallocation). Not thread-safe: one
/// cache per engine, used from the engine's thread.
class FeatureCache
{
public:
  /// Function that fills `out` from one image of the frame.
  using Compute = std::function<void(const cv::Mat& image, cv::Mat& out)>;

  /// Start a new frame: every cached product becomes stale (buffers are kept for reuse).
  void reset(const StereoFrame& frame);
  /// The frame currently cached.
  const StereoFrame& frame() const { return frame_; }
  /// Geometry of the current frame.
  const StereoGeometry& geometry() const { return frame_.geometry; }
  /// The raw (rectified) image of a view.
  const cv::Mat& image(View view) const { return frame_.image(view); }

  /// The product named `key` for `view`, computed with `compute` on first use this frame.
  /// Keys must encode every setting the product depends on (e.g. "hsi_bins/8x8x4/s0.10").
  const cv::Mat& get(View view, const std::string& key, const Compute& compute);

  /// 8-bit grey image of a view.
  const cv::Mat& gray(View view);
  /// Sobel gradient magnitude |S| = sqrt(Sx^2 + Sy^2) of the grey image (CV_32F), thesis eq. 4.1.
  const cv::Mat& gradientMagnitude(View view);
  /// Sobel x and y derivatives of the grey image (CV_32F each).
  const cv::Mat& gradientX(View view);
  const cv::Mat& gradientY(View view);

  /// How many products have been computed since construction (for tests: proves sharing).
  long computeCount() const { return compute_count_; }

private:
  struct Entry
  {
    cv::Mat mat[2];
    long frame_id[2] = { -1, -1 };
  };
  StereoFrame frame_;
  long frame_id_ = 0;
  long compute_count_ = 0;
  std::map<std::string, Entry> entries_;
};

}  // namespace stereo_pf
