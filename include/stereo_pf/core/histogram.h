// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Normalised histograms over bin-index images and the Bhattacharyya similarity (thesis eq. 5.1-5.5).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
/// Histogram with precomputed square roots, for fast Bhattacharyya coefficients against sparse candidates.
class TargetHistogram
{
public:
  /// An empty (invalid) histogram.
  TargetHistogram() = default;
  /// From raw counts or weights (normalised here). An all-zero or empty input gives an empty (invalid)
  /// histogram; a negative or non-finite entry throws std::invalid_argument.
  explicit TargetHistogram(const std::vector<double>& counts);
  /// Histogram of a CV_8UC1 or CV_16UC1 bin-index image over `roi` (clipped to the image), `bins` bins;
  /// pixels whose index is >= bins are ignored. Empty (invalid) when no pixel counts.
  /// Throws std::invalid_argument for another image type or bins < 1.
  static TargetHistogram fromBinImage(const cv::Mat& bin_image, const cv::Rect& roi, int bins);

  /// True when the histogram holds mass.
  bool valid() const { return !p_.empty(); }
  /// Number of bins (0 when invalid).
  int bins() const { return static_cast<int>(p_.size()); }
  /// Normalised probabilities.
  const std::vector<double>& probabilities() const { return p_; }
  /// sqrt of each probability.
  const std::vector<double>& sqrtProbabilities() const { return sqrt_p_; }

private:
  std::vector<double> p_;
  std::vector<double> sqrt_p_;
};

/// The part of `roi` a target histogram is learned from: shrunk by `margin` (a fraction of its width and
/// height) on each side, so the background corners of an object's box stay out, then clipped to an image of
/// `image_size`. Returns false with `reason` (e.g. "the region 0x0 at (1, 2) is empty") when the image is
/// empty, the region is empty or outside the image, or less than 3x3 pixels remain.
bool targetRegion(const cv::Size& image_size, const cv::Rect& roi, double margin, cv::Rect& inner, std::string& reason);
/// "WxH at (x, y)", for messages about regions.
std::string describeRect(const cv::Rect& r);

/// A cue's target histogram: of `bin_image` (`bins` bins) over targetRegion(roi, margin). False with `reason`
/// (targetRegion's, or "no pixel of <inner> could be binned") when the region is unusable or holds no pixel of
/// a bin; `target` is then unchanged.
bool learnTargetHistogram(const cv::Mat& bin_image, const cv::Rect& roi, double margin, int bins,
                          TargetHistogram& target, std::string& reason);

/// The map of one cue's saved target in a target file: `node` itself when it is a map holding a "histogram"
/// (every histogram cue saves one), else its child `name`. `what` names the target in the error ("colour
/// target", ...); on failure `error` reads "<name>: no <what> named '<name>' in the file" and the result is
/// empty.
cv::FileNode targetNode(const cv::FileNode& node, const std::string& name, const std::string& what,
                        std::string& error);

/// Bhattacharyya coefficient rho = sum_u sqrt(p_u q_u) of two normalised histograms (eq. 5.3), clamped to
/// [0, 1]. Throws std::invalid_argument when the sizes differ.
double bhattacharyya(const std::vector<double>& p, const std::vector<double>& q);

/// Accumulates one candidate histogram from samples of a bin image and scores it against a target in
/// time proportional to the samples, not the bins (only touched bins are visited). Reusable without
/// allocation: reset() once, then add() or addGrid() and scoreAndClear() per candidate.
class SparseHistogram
{
public:
  /// Prepare for `bins` bins and typically at most `max_samples` samples per candidate (more are
  /// allowed, just slower to score). Throws std::invalid_argument when bins < 1.
  void reset(int bins, int max_samples);
  /// Add one sample in bin b (must be in [0, bins); not checked).
  void add(int b)
  {
    ++counts_[b * kBanks];
    if (stamp_[b] != epoch_)
    {
      stamp_[b] = epoch_;
      touched_[n_touched_++] = b;
    }
    ++n_;
  }
  /// Add the samples of a separable grid of a CV_8UC1 bin image: data[rows[j] * step + cols[k]] for every
  /// j < nr and k < nc (each must be < bins; coordinates are not checked). Same result as add() on each,
  /// several times faster: the bookkeeping stays in registers, and consecutive samples count into
  /// different banks (neighbouring pixels usually share a bin, and a single counter would make every
  /// increment wait for the previous one's store).
  void addGrid(const uint8_t* data, size_t step, const int* rows, int nr, const int* cols, int nc);
  /// Add the samples values[0..n) (each must be < bins; not checked): add() on each, kept in registers and
  /// spread over the banks as addGrid() does.
  void addValues(const uint8_t* values, int n);
  /// Bhattacharyya coefficient rho = sum_b sqrt(c_b / n) sqrt(q_b) of the accumulated candidate against
  /// `target` (which must have the same number of bins), then clears the candidate.
  /// Returns 0 when no sample was added or the target is invalid.
  double scoreAndClear(const TargetHistogram& target);
  /// Number of samples added since the last clear.
  int samples() const { return n_; }
  /// Number of bins given to reset().
  int bins() const { return static_cast<int>(stamp_.size()); }

private:
  static constexpr int kBanks = 4;
  struct Tally;  // addGrid() and addValues()' counting state, in locals

  std::vector<int> counts_;       // kBanks counters per bin, [kBanks * b + bank]; all zero between candidates
  // stamp_[b] == epoch_: bin b is listed in touched_ for this candidate. Only written on a first touch, so
  // (unlike testing a counter for zero) it adds no store-to-load dependency between samples.
  std::vector<uint32_t> stamp_;
  std::vector<int> touched_;      // bins with a non-zero count, first n_touched_ entries
  std::vector<double> sqrt_int_;  // sqrt(k) for k = 0..max_samples
  uint32_t epoch_ = 1;
  int n_touched_ = 0;
  int n_ = 0;
};

/// A fixed `samples` x `samples` grid over a square window around a hypothesis, clipped to the image. The
/// grid is separable, so only its in-image columns and rows are kept (no per-sample test), and the cost per
/// hypothesis is the same whatever the window size. Used with SparseHistogram::addGrid.
class WindowGrid
{
public:
  /// Prepare a grid of `samples` points per axis spread evenly over [-1, 1].
  void reset(int samples);
  /// Place the grid on a window of half-size `half` centred at (u, v) in an image of width x height.
  /// False when the window is off the image (NaN positions included) or fewer than `min_inside` samples land
  /// inside it.
  bool place(float u, float v, float half, int width, int height, int min_inside);
  const int* cols() const { return cols_.data() + col0_; }  ///< in-image sample columns of the last place()
  const int* rows() const { return rows_.data() + row0_; }  ///< in-image sample rows of the last place()
  /// Grid points per axis (reset()'s `samples`).
  int samples() const { return samples_; }
  int numCols() const { return nc_; }
  int numRows() const { return nr_; }
  static constexpr int kMaxSamples = 32;  ///< reset() throws std::invalid_argument beyond it (or below 1)

private:
  std::vector<float> offsets_;  // padded to whole vectors
  std::vector<int> cols_, rows_;
  int samples_ = 0;
  int nc_ = 0, nr_ = 0;
  int col0_ = 0, row0_ = 0;  // the last place()'s in-image samples start here in cols_ and rows_
};

/// The settings every histogram cue (ColourHSI, TextureEdge) reads the same way: the likelihood's sigma, where
/// each hypothesis's window lies and how it is sampled, and the learning box's margin. All reconfigurable.
struct HistogramWindowTunables
{
  double sigma = 0.15;          ///< `sigma`: of the Bhattacharyya log-likelihood
  int window = 11;              ///< `window`: px, odd; side of the fixed window of 2D hypotheses
  double window_scale = 0.7;    ///< `window_scale`: half-size of 3D hypotheses' windows, in apparent radii
  int samples = 11;             ///< `samples`: sample grid points per window side
  double min_radius = 2.0;      ///< `min_radius`: px; smaller apparent radii are clamped to it
  double target_margin = 0.15;  ///< `target_margin`: fraction of the learned box trimmed at each side

  /// Read (and declare, with their descriptions) from `params`: throws ParameterError naming the parameter when
  /// one is out of range or `window` is even.
  static HistogramWindowTunables fromParameters(const Parameters& params);
};

/// Bhattacharyya log-likelihood of thesis eq. 5.5 without its constant: -(1 - rho) / (2 sigma^2).
inline double bhattacharyyaLogLikelihood(double rho, double sigma)
{
  return -(1.0 - rho) / (2.0 * sigma * sigma);
}

}  // namespace stereo_pf
