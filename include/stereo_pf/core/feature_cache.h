// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
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
  /// Keys must encode every setting the product depends on (e.g. "hsi_bins/8x8x4/s0.10"), except what changes
  /// while the tracker runs (a model's target: learned again, adapted, forgotten), which goes in `tag`: a product
  /// asked for with another tag than it was computed for is computed again, in the same buffer. A key per such
  /// change would keep a buffer per change for good (one full-size image per view each time a lost track's
  /// histogram went back to the one learned from the box).
  const cv::Mat& get(View view, const std::string& key, const Compute& compute, long tag = 0);

  /// Function that fills rows [y0, y1) of `out`. It allocates `out` at the image's size itself
  /// (`out.create()` keeps a buffer of that size, and the rows already in it) and must not write other rows.
  using RowCompute = std::function<void(const cv::Mat& image, cv::Mat& out, int y0, int y1)>;
  /// Like get(), for a product computed row by row, of which only rows [y0, y1) (clipped to the image)
  /// are needed: rows already computed this frame are kept and only the missing ones are computed. A
  /// model that reads only around its hypotheses asks for those rows; while tracking that is a band of
  /// the image, not all of it. Rows that were not asked for this frame hold stale data: read only the
  /// rows you asked for.
  const cv::Mat& getRows(View view, const std::string& key, int y0, int y1, const RowCompute& compute);

  /// Function that fills the pixels of `region` of `out` (allocating `out` at the image's size, like a RowCompute)
  /// and no others. `region` may be empty: then it only allocates.
  using RegionCompute = std::function<void(const cv::Mat& image, cv::Mat& out, const cv::Rect& region)>;
  /// Like getRows(), for a product computed pixel by pixel, of which only `region` (clipped to the image) is
  /// needed. What is valid this frame is one rectangle: a request outside it grows it to the bounding box of the
  /// two and computes only the strips that box adds (at most four calls). While tracking, the windows of a
  /// cloud cover a patch of the image, narrower than the band of rows it spans. Pixels that were not asked
  /// for this frame hold stale data. A key may be asked for both ways: getRows() computes whole rows, so the
  /// valid rectangle's rows are computed again whole when it is narrower than the image.
  const cv::Mat& getRegion(View view, const std::string& key, const cv::Rect& region, const RegionCompute& compute,
                           long tag = 0);
  /// 8-bit grey image of a view.
  const cv::Mat& gray(View view);
  /// Rows [y0, y1) (clipped) of the 8-bit grey image of a view (see getRows()).
  const cv::Mat& gray(View view, int y0, int y1);
  /// Sobel gradient magnitude |S| = sqrt(Sx^2 + Sy^2) of the grey image (CV_32F), thesis eq. 4.1.
  const cv::Mat& gradientMagnitude(View view);
  /// Sobel x and y derivatives of the grey image (CV_32F each).
  const cv::Mat& gradientX(View view);
  const cv::Mat& gradientY(View view);

  /// Photometric gain of a view this frame: what the colour products (HsiBinner::cachedBins()) multiply the
  /// pixel values by before binning them, so that a camera's gain or exposure changing since the target was
  /// learned, or a right camera brighter than the left, does not move a surface's colour into another
  /// intensity bin. Set by the engine right after reset() (1 until then); setting it makes every product of
  /// this frame stale.
  void setGain(View view, double gain);
  double gain(View view) const { return gain_[static_cast<int>(view)]; }
  /// Mean grey level (0..255) of a view's image over a 16 x 16 grid of pixels spread evenly over it, all channels
  /// alike (NaN for an empty image or one that is not 8-bit): the brightness the gains are measured from.
  double brightness(View view) const;

  /// How many products have been computed since construction (for tests: proves sharing).
  long computeCount() const { return compute_count_; }
  /// How many products (keys) the cache holds buffers for: bounded by the models and their settings, not by
  /// the frames or the targets seen (for tests).
  size_t products() const { return entries_.size(); }

private:
  /// getRegion(), and getRows() with `whole_rows`: `compute` fills whole rows only, so rows of the valid rectangle
  /// that it does not span are computed again whole, in one call.
  const cv::Mat& grow(View view, const std::string& key, const cv::Rect& region, const RegionCompute& compute,
                      bool whole_rows, long tag = 0);
  struct Entry
  {
    cv::Mat mat[2];
    long frame_id[2] = { -1, -1 };
    long tag[2] = { 0, 0 };  ///< what the product was computed for (get(), getRegion())
    cv::Rect valid[2];  ///< the pixels valid this frame (getRegion() and getRows() products)
  };
  StereoFrame frame_;
  long frame_id_ = 0;
  long compute_count_ = 0;
  double gain_[2] = { 1.0, 1.0 };
  std::map<std::string, Entry> entries_;
};

}  // namespace stereo_pf
