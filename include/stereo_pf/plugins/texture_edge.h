// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The edge-texture observation model (thesis ch. 4.2, eq. 4.1, 5.6-5.7), pluginlib class
// stereo_pf/TextureEdge. Declared here so tests can construct it directly; defined and exported in
// plugins/observation/texture_edge.cpp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "stereo_pf/core/histogram.h"
#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// How edge pixels are put into histogram bins (thesis 4.2). Bin 0 always holds the pixels that are not
/// edges (|S| = sqrt(Sx^2 + Sy^2) < tau, eq. 4.1), so a flat region has a valid histogram (all in bin 0)
/// and the edge density is part of the texture. Structural: a learned target is tied to these settings.
struct EdgeBinning
{
  /// What the edge bins count.
  enum class Mode
  {
    Intensity,   ///< edge intensity: `intensity_bins` equal slices of |S| in [tau, max_magnitude]
    Orientation  ///< the thesis's 3-bin variant: horizontal, vertical and diagonal edges
  };
  /// Orientation-mode bin indices.
  enum OrientationBin
  {
    kNoEdge = 0,      ///< |S| < tau (both modes)
    kHorizontal = 1,  ///< edge line within 22.5 deg of horizontal (|Sy| dominates)
    kVertical = 2,    ///< edge line within 22.5 deg of vertical (|Sx| dominates)
    kDiagonal = 3     ///< any other edge
  };

  /// Largest number of edge-intensity bins.
  static constexpr int kMaxIntensityBins = 64;

  Mode mode = Mode::Intensity;  ///< what the edge bins count
  int intensity_bins = 8;       ///< Intensity mode: number of edge-intensity bins (1..kMaxIntensityBins)
  double tau = 24.0;            ///< edge threshold on |S| in Sobel units (a step of s grey levels gives 4 s)
  double max_magnitude = 400.0; ///< Intensity mode: |S| at and above which an edge falls in the top bin

  /// Total number of bins: 1 + intensity_bins (Intensity) or 1 + 3 (Orientation).
  int bins() const { return 1 + (mode == Mode::Intensity ? intensity_bins : 3); }
  /// Throws std::invalid_argument when a setting is out of range (bins, tau < 0, max_magnitude <= tau).
  void validate() const;
  /// Compact text naming every setting, e.g. "intensity/8/t24/m400" (cache keys, messages, saved targets).
  std::string describe() const;
  /// True when both binnings put every gradient in the same bin.
  bool sameAs(const EdgeBinning& other) const;
  /// "intensity" or "orientation".
  static std::string toString(Mode mode);
};

/// Puts pixels into EdgeBinning bins from the 3x3 Sobel derivatives (Sx, Sy) of an 8-bit grey image.
class EdgeBinner
{
public:
  /// Validates `binning` (std::invalid_argument when invalid).
  explicit EdgeBinner(const EdgeBinning& binning = EdgeBinning());
  /// The settings in force.
  const EdgeBinning& binning() const { return binning_; }
  /// Bin of one pixel with Sobel derivatives (sx, sy) (integers, as the 3x3 Sobel of 8-bit images gives).
  /// Intensity mode: floor((|S| - tau) / step) + 1 clamped to [0, bins], |S| = sqrt(sx^2 + sy^2) in float
  /// (eq. 4.1); orientation mode: the gradient's sector, with the edge line horizontal when
  /// |sy| > 2.414 |sx|, vertical when |sy| < 0.414 |sx| (tan 67.5 and tan 22.5 degrees), diagonal otherwise.
  int bin(int sx, int sy) const;
  /// Fill `bins` (CV_8UC1, same size; reused when it fits) with the bin of every pixel of the CV_8UC1
  /// image `gray`, derivatives as cv::Sobel (3x3, BORDER_REFLECT_101) gives them. Exactly bin() on every
  /// pixel, in one pass of 16-lane vector code (SSE2 baseline): ~0.23 ms at 640x480 where two float Sobel
  /// images, their magnitude and a conversion took ~0.33 ms. Throws std::invalid_argument for another type.
  void binImage(const cv::Mat& gray, cv::Mat& bins) const;
  /// The same for rows [y0, y1) of `bins` only (0 <= y0 <= y1 <= rows): it reads grey rows y0 - 1 to y1, and
  /// leaves the other rows of `bins` as they were.
  void binImage(const cv::Mat& gray, cv::Mat& bins, int y0, int y1) const;

private:
  EdgeBinning binning_;
  float inv_step_ = 1.0f;    // 1 / width of one edge-intensity bin (Sobel units)
  float offset_ = 0.0f;      // 1 - tau / step: bin = floor(|S| inv_step + offset)
  int tau2_ = 0;             // smallest integer |S|^2 that is an edge: ceil(tau^2)
};

/// Texture likelihood: the edge histogram (EdgeBinning) of a window around each hypothesis is compared with
/// the learned target histogram by the Bhattacharyya coefficient rho, giving log-likelihood
/// -(1 - rho) / (2 sigma^2) and similarity rho, exactly as ColourHSI does for colour (eq. 5.6-5.7).
///
/// Windows as in ColourHSI: 2D hypotheses (radius <= 0, stereo-constraints sets) use the fixed
/// `window` x `window` square; 3D hypotheses a square of half-size `window_scale` * max(radius,
/// `min_radius`); both sampled on a `samples` x `samples` grid (constant cost per hypothesis). Samples
/// outside the image are skipped; fewer than a quarter inside (or valid == 0, or a non-finite position)
/// gives similarity 0 and the log-likelihood of rho = 0.
///
/// Per-pixel work is shared: the edge-bin image of each view (Sobel magnitude, eq. 4.1, binned) is
/// computed once per frame from the FeatureCache's grey image (shared with ShapeCircle) and kept in the
/// cache (key "edge_bins/<binning>"); each hypothesis only reads bin indices. Not thread-safe (scratch buffers are members).
///
/// Parameters (in the plugin's namespace): mode ("intensity" or "orientation"), bins (8, 1..64: edge-
/// intensity bins), tau (24, 0..4000: edge threshold on |S|), max_magnitude (400, > tau, ..5000),
/// sigma (0.15, 0.001..10), window (11, odd 3..101), window_scale (0.7, 0.1..3), samples (11, 3..31),
/// min_radius (2 px, 0.5..100), target_margin (0.15, 0..0.45). mode, bins, tau and max_magnitude are the
/// binning (a learned target is tied to it) and are read at initialisation only; reconfigure() re-reads
/// the others.
class TextureEdge : public ObservationModel
{
public:
  TextureEdge() = default;

  /// Learn the target histogram from `roi` of `view`, shrunk by `target_margin` on each side (so that a
  /// ball's box gives the texture inside the ball, the same square a 3D hypothesis samples). False with
  /// `error` set when the region is empty, outside the image or too small.
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  /// True once a target has been learned or loaded.
  bool hasTarget() const override { return target_.valid(); }
  /// Log-likelihood and similarity of every hypothesis (see the class comment). Without a target every
  /// hypothesis is treated as invalid.
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// Write a map named name() holding the binning and the target histogram (nothing without a target).
  void saveTarget(cv::FileStorage& fs) const override;
  /// Read a target written by saveTarget. `node` is either that map itself or a map containing it under
  /// name(). False with `error` set when absent, malformed or learned with a different binning.
  bool loadTarget(const cv::FileNode& node, std::string& error) override;
  /// Re-read the common parameters and the tunables (everything but the binning); on a bad value throws
  /// ParameterError and keeps the previous settings.
  void reconfigure() override;

  /// The learned target histogram (invalid before learning).
  const TargetHistogram& target() const { return target_; }
  /// The binning in force (the defaults before initialize()).
  const EdgeBinning& binning() const { return binning_; }
  /// The per-view edge-bin image of the cache's current frame (CV_8UC1), computed on first use.
  const cv::Mat& binImage(FeatureCache& cache, View view);
  /// The same image, of which only rows [y0, y1) are guaranteed (FeatureCache::getRows()).
  const cv::Mat& binImage(FeatureCache& cache, View view, int y0, int y1);

protected:
  /// Read and validate every parameter, build the bin table and the scratch buffers.
  void onInitialize() override;

private:
  /// The tunables (everything that does not change the meaning of a bin).
  using Tunables = HistogramWindowTunables;
  Tunables readTunables() const;
  void applyTunables(const Tunables& t);

  EdgeBinning binning_;
  std::unique_ptr<const EdgeBinner> binner_;
  std::string cache_key_;  // FeatureCache key of the bin image, encodes the binning
  Tunables tunables_;
  TargetHistogram target_;
  double invalid_log_likelihood_ = 0.0;  // log-likelihood of rho = 0
  // scratch, sized in applyTunables: no allocation per hypothesis
  WindowGrid window_;         // the sample grid, placed per hypothesis
  SparseHistogram candidate_;
};

}  // namespace stereo_pf
