// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The appearance-template observation model, pluginlib class stereo_pf/TemplateMatch. Declared here so tests can
// construct it directly; defined and exported in plugins/observation/template_match.cpp.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// The normalised correlation coefficient of `templ` at every place of `image` (both CV_32FC1, the template no
/// larger than the image) where it fits whole: what cv::matchTemplate gives with TM_CCOEFF_NORMED (to 1e-4),
/// `result` (image size - template size + 1, CV_32F) at each window's top-left corner. Windows without contrast, and
/// a template without, give 0. Computed with OpenCV's filters, faster for small templates (targetMap()).
void normalisedCorrelation(const cv::Mat& image, const cv::Mat& templ, cv::Mat& result);

/// Grey-level template likelihood: does the hypothesis's window look like the object the user boxed?
///
/// Why: a colour histogram tells a saturated object from its surroundings, but on mono8/mono16 images, and for
/// white or grey objects, it scores most of the background nearly as high as the target (on the stress suite's
/// grey scenes: 1.0 at the target, 0.9 beside it), so the track cannot be told from the background. The
/// object's grey-level structure, its texture and its outline against the surroundings, can.
///
/// Model. The template is `size` x `size` grey values sampled (nearest pixel) over the box grown by `ring_scale`
/// about its centre, weighted 1 inside the box's inscribed ellipse, `ring_weight` in the ring out to the grown
/// ellipse and 0 in the corners; stored zero-mean with unit weighted norm. A hypothesis (u, v, r) samples the same
/// grid over its window (half-size ring_scale r times the box's aspect; 2D hypotheses, r <= 0, use the box's
/// half-size) and scores the weighted zero-mean normalised cross-correlation c in [-1, 1] (one pass of three sums,
/// so a gain and offset between the cameras or frames does not matter):
///   log-likelihood = (c - 1) / sigma,   similarity = max(0, c).
/// A window without contrast has c = 0. Invalid or non-finite hypotheses score c = -1.
///
/// Adaptation (adapt(), called by the engine after frames in which the tracked object was seen): of the windows
/// within `adapt_align` apparent radii of the estimate (whole pixels), the one that correlates best with the current
/// template is taken, and when it correlates by at least `adapt_min` a running template moves by `adapt_rate` towards
/// it: the object, not the estimate's error, is learned, and the object is recognised near the estimate, not only at
/// it. The template used is `anchor` parts the one learned from the box and the rest the running one, so it follows
/// a turning object but cannot drift away from what was boxed. Not thread-safe.
///
/// Parameters (in the plugin's namespace): size (13, 5..41; structural), ring_scale (1.25, 1..3), ring_weight
/// (0.3, 0..1), sigma (0.3, 0.001..10: tempered, the samples are nearest pixels, so a sharper term pins the
/// centres to whole pixels; on the pendulum 0.1 gave 1.5 cm, 0.3 0.7 cm), adapt_rate (0.1, 0..1; 0: no adaptation), adapt_min (0.6, -1..1),
/// adapt_align (0.3, 0..1; 0: the window at the estimate), anchor (0.3, 0..1).
class TemplateMatch : public ObservationModel
{
public:
  TemplateMatch() = default;
  /// Sample the template over `roi` (grown by ring_scale) of `view`'s grey image. False with `error` when the
  /// region is empty or outside the image, or holds no contrast.
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  bool hasTarget() const override { return !learned_.empty(); }
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  void adapt(FeatureCache& cache, const ImageHypotheses& estimate) override;
  /// Back to the target learned from the box (the track was lost).
  void forgetAdaptation() override;
  /// The template's correlation with the whole image at the learned box size (the engine's proposals while
  /// searching or lost): the image shrunk to at most 200 px wide (less shrunk for a small box: the template keeps
  /// at least 5 samples a side), the normalised correlation coefficient (cv::matchTemplate's TM_CCOEFF_NORMED,
  /// computed with OpenCV's filters), negative values 0, at the shrunk image's resolution.
  bool targetMap(FeatureCache& cache, View view, cv::Mat& map) override;
  /// Write a map named name() with the size, aspect, the box's half-size and the learned template.
  void saveTarget(cv::FileStorage& fs) const override;
  bool loadTarget(const cv::FileNode& node, std::string& error) override;
  void reconfigure() override;

protected:
  void onInitialize() override;

private:
  struct Tunables
  {
    double ring_scale = 1.25;
    double ring_weight = 0.3;
    double sigma = 0.3;
    double adapt_rate = 0.1;
    double adapt_min = 0.6;
    double adapt_align = 0.3;
    double anchor = 0.3;
  };
  Tunables readTunables() const;
  /// The sampling weights of the grid (ellipse, ring, corners).
  void makeWeights();
  /// active_weighted_ from weighted_ (empty until a template is in use).
  void activeWeighted();
  /// Sample the grid at (u, v) with half-sizes (hx, hy) from `gray` into `out` (size*size values).
  void sample(const cv::Mat& gray, double u, double v, double hx, double hy, std::vector<float>& out) const;
  /// Zero-mean, unit weighted norm; false when the values have no contrast.
  bool normalise(std::vector<float>& values) const;
  /// Sample the grid's rows at (u, v) into `out`, row y over the columns spans[y] (every column when `spans` is
  /// null), in row order.
  void sampleSpans(const cv::Mat& gray, double u, double v, double hx, double hy, const std::pair<int, int>* spans,
                   float* out) const;
  /// Weighted ZNCC of the whole grid's raw samples (sample()) with the template in use.
  double score(const std::vector<float>& samples) const;
  /// Weighted ZNCC of `n` raw samples with their weights and the weighted template in use (score(), or the grid's
  /// points of non-zero weight: active_*).
  double correlate(const float* samples, const float* weights, const float* weighted, Eigen::Index n) const;
  /// Window half-sizes for an apparent radius (<= 0: the box's).
  void halfSizes(double radius, double& hx, double& hy) const;
  void useTemplate();
  /// Take `learned` (normalised) as the target learned from a box of `box_radius` px and that aspect; the
  /// adaptation restarts from it.
  void setTarget(const std::vector<float>& learned, double box_radius, double aspect_x, double aspect_y);
  /// Rows [first, second) of an image `height` rows high that the windows of `hyp`'s valid hypotheses read.
  std::pair<int, int> windowRows(const ImageHypotheses& hyp, int height) const;
  /// The raw samples of the window at (u, v) with apparent `radius` (<= 0: the box's), in scratch_.
  const std::vector<float>& window(const cv::Mat& gray, double u, double v, double radius);

  Tunables tunables_;
  int size_ = 13;
  std::vector<float> weights_;
  double weight_sum_ = 0.0;
  /// Per grid row, the columns [first, second) of non-zero weight (the ellipse and its ring are convex, so one
  /// run per row): a third of the grid, its corners, weighs nothing and is neither sampled nor scored.
  std::vector<std::pair<int, int>> active_spans_;
  std::vector<float> active_weights_;   ///< weights_ of those points, in row order
  std::vector<float> active_weighted_;  ///< weighted_ of those points
  std::vector<float> learned_, running_, current_;  ///< normalised templates (current_ = anchor mix)
  std::vector<float> weighted_;  ///< weights_ times current_, for score()
  long template_version_ = 0;    ///< bumped when current_ changes: the target map's cache tag
  double box_radius_ = 0.0;  ///< half the box's mean side, px (2D hypotheses)
  double aspect_x_ = 1.0, aspect_y_ = 1.0;  ///< the box's half-width and half-height over box_radius_
  std::vector<float> scratch_;
  std::vector<float> active_scratch_;  ///< evaluate()'s samples (sampleSpans() over active_spans_)
};

}  // namespace stereo_pf
