// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The HSI colour-histogram observation model (thesis ch. 4.1, eq. 5.1-5.5), pluginlib class
// stereo_pf/ColourHSI. Declared here so tests can construct it directly; defined and exported in
// plugins/observation/colour_hsi.cpp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "stereo_pf/core/colour.h"
#include "stereo_pf/core/histogram.h"
#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// Colour likelihood: the HSI histogram of a window around each hypothesis is compared with the learned
/// target histogram by the Bhattacharyya coefficient rho (eq. 5.3), giving log-likelihood
/// -(1 - rho) / (2 sigma^2) (eq. 5.5 without its constant) and similarity rho.
///
/// The window depends on where the hypothesis comes from:
/// - 2D hypotheses (the stereo-constraints model: radius <= 0) use the thesis's fixed `window` x `window`
///   square (11 x 11 by default).
/// - 3D hypotheses (radius > 0: the apparent radius of the ball from its depth) use a square of
///   half-size `window_scale` * radius, i.e. with the default 0.7 the square sits inside the ball's disc,
///   so near and far balls are judged on their own pixels. Radii below `min_radius` are clamped to it
///   (a particle that far away cannot be observed better than a fixed minimum window).
/// Surround: a histogram inside the object only cannot tell a centred hypothesis from one shifted by a few
/// pixels, or (for 3D hypotheses) a far one whose small window still fits inside the ball, which biases
/// depth. So `surround_samples` points on a ring of radius `surround_scale` * radius around the hypothesis
/// (radius: the apparent one, or for 2D hypotheses half the smaller side of the learning ROI) are
/// compared with the target too, and their similarity rho_ring counts against the hypothesis:
/// log-likelihood -((1 - rho) + surround_weight * rho_ring) / (2 sigma^2). A ring on the background scores
/// low; a ring that cuts the object (wrong centre or too small a radius) scores high. The Bhattacharyya
/// coefficient grows like the square root of the overlap, so even a slight overlap is felt.
/// The ring keeps at least `surround_margin` pixels outside the radius: blur, demosaicing and compression
/// spread the object's edge over a few pixels, and a ring 25 % out on a small disc would pick up its colour
/// at the true size, so it pushed the depth nearer (a 2 cm ball at 1.2 m read 1.3 % short).
/// `surround_scale` 0 switches it off (the thesis's plain model).
///
/// In both cases the window is sampled on a fixed `samples` x `samples` grid, so the cost per hypothesis
/// is constant whatever the radius. Samples outside the image are skipped; a hypothesis with fewer than a
/// quarter of its samples inside (or valid == 0, or non-finite position) gets similarity 0 and the
/// log-likelihood of rho = 0.
///
/// Per-pixel work is shared: the HSI bin-index image of each view is computed once per frame through the
/// FeatureCache (key "hsi_bins/<binning>", shared with any other instance with the same binning); each
/// hypothesis then only reads bin indices. Not thread-safe (scratch buffers are members).
///
/// Parameters (in the plugin's namespace): hue_bins (8, 1..64), saturation_bins (8, 1..64),
/// intensity_bins (4, 1..64) with product <= 256, achromatic_saturation (0.1, 0..1),
/// achromatic_intensity (0.08, 0..1), sigma (0.15, 0.001..10), window (11, odd 3..101),
/// window_scale (0.7, 0.1..3), samples (11, 3..31), preview_samples (0 = none, else 3..31, at most samples),
/// min_radius (2 px, 0.5..100), target_margin (0.15, 0..0.45), surround_scale (1.25; 0 = off, else 1..4),
/// surround_margin (3 px, 0..100), surround_samples (32, 4..256), surround_weight (1.0, 0..10), adapt_rate (0.1;
/// 0 = off, 0..1), adapt_min (0.6, 0..1), anchor (0.3, 0..1), intensity_tolerance (0: off, 0..1). The binning is
/// structural (a learned target is tied to it) and is read at initialisation only; reconfigure() re-reads the others.
///
/// Shading (`intensity_tolerance` t > 0): a face turning away from the light keeps its hue and saturation and
/// darkens, and with 4 intensity slices a darker face shares no bin with the face learned. Candidates are then
/// compared with the target spread along intensity (HsiBinning::spreadAlongIntensity: each colour bin's mass also
/// in its darker and lighter neighbours, times t), rho(p, q') / rho(q, q'), at most 1: the target itself still
/// scores 1, a colour one slice darker or lighter about sqrt(t) instead of 0. Grey bins are not spread (a grey
/// object is told apart by intensity alone).
///
/// Adaptation (adapt(), on the frames the engine calls the object seen): when the histogram of the window at the
/// estimate scores at least adapt_min against the target in use, a running histogram moves towards it by
/// adapt_rate; the target in use is `anchor` parts the one learned from the box and the rest the running one, so
/// a box turning a face of another colour to the camera is followed, and its first face still scores when it
/// comes back. Target files hold the histogram learned from the box.
class ColourHSI : public ObservationModel
{
public:
  ColourHSI() = default;

  /// Learn the target histogram from `roi` of `view`, shrunk by `target_margin` on each side to keep the
  /// background out. False with `error` set when the region is empty, outside the image or too small.
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  /// True once a target has been learned or loaded.
  bool hasTarget() const override { return target_.valid(); }
  /// Log-likelihood and similarity of every hypothesis (see the class comment). Without a target every
  /// hypothesis is treated as invalid.
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// The log-likelihood of a coarser window (preview_samples per side) and ring, for screening; false when
  /// preview_samples is 0.
  bool preview(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood) override;
  /// Back-projection of the target histogram, q[bin] / max q, averaged over each kTargetMapCell-pixel cell (CV_8UC1,
  /// image size / kTargetMapCell), once per frame per view.
  bool targetMap(FeatureCache& cache, View view, cv::Mat& map) override;
  /// Write a map named name() holding the binning and the target histogram (nothing without a target).
  void saveTarget(cv::FileStorage& fs) const override;
  /// Read a target written by saveTarget. `node` is either that map itself or a map containing it under
  /// name(). False with `error` set when absent, malformed or learned with a different binning.
  bool loadTarget(const cv::FileNode& node, std::string& error) override;
  /// Re-read the common parameters and the tunables (everything but the binning); on a bad value throws
  /// ParameterError and keeps the previous settings.
  void reconfigure() override;
  /// Follow the object's colours at the estimate (see the class comment).
  void adapt(FeatureCache& cache, const ImageHypotheses& estimate) override;
  /// Back to the target learned from the box (the track was lost).
  void forgetAdaptation() override;

  /// Target probability q_b of bin `b` (0 without a target or for an out-of-range bin): the
  /// back-projection of the target, e.g. for detection-driven proposals.
  double targetProbability(int bin) const;
  /// The learned target histogram (invalid before learning).
  const TargetHistogram& target() const { return target_; }
  /// The binning in force (the defaults before initialize()).
  const HsiBinning& binning() const { return binning_; }
  /// The per-view bin-index image of the cache's current frame (CV_8UC1), computed on first use.
  const cv::Mat& binImage(FeatureCache& cache, View view);
  /// The same image, of which only rows [y0, y1) are guaranteed (FeatureCache::getRows()).
  const cv::Mat& binImage(FeatureCache& cache, View view, int y0, int y1);
  /// The same image, of which only the pixels of `region` are guaranteed (FeatureCache::getRegion()).
  const cv::Mat& binImage(FeatureCache& cache, View view, const cv::Rect& region);

protected:
  /// Read and validate every parameter, build the colour table and the scratch buffers.
  void onInitialize() override;

private:
  /// The tunables (everything that does not change the meaning of a bin).
  struct Tunables : HistogramWindowTunables
  {
    double surround_scale = 1.25;
    double surround_margin = 3.0;
    int surround_samples = 32;
    double surround_weight = 1.0;
    double adapt_rate = 0.1;
    double adapt_min = 0.6;
    double anchor = 0.3;
    double intensity_tolerance = 0.0;
    int preview_samples = 0;
  };
  /// A new target learned or loaded: adaptation starts afresh from it.
  void setLearned(TargetHistogram learned);
  /// The target as candidates are compared with it (scoring_, scoring_scale_), from target_ and the tunables.
  void refreshScoring();
  /// rho against scoring_ made relative to the target's own (times scoring_scale_), at most 1.
  double relative(double rho) const;
  /// rho of a candidate or ring histogram (cleared) against the target, intensity_tolerance applied (relative()).
  double score(SparseHistogram& histogram) const;
  /// Where a hypothesis is sampled: the window's grid and the ring's points on the unit circle.
  struct Sampling
  {
    void reset(int samples, int ring_samples);
    WindowGrid window;
    std::vector<float> ring_cos, ring_sin;
  };
  /// evaluate() with the samples of `sampling` (`what` names the caller in errors).
  void judge(FeatureCache& cache, const ImageHypotheses& hyp, Sampling& sampling,
             Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity, const char* what);
  Tunables readTunables() const;
  void applyTunables(const Tunables& t);

  HsiBinning binning_;
  std::unique_ptr<const HsiBinner> binner_;  // LUT, built once in onInitialize (not at construction: ~10 ms)
  std::string cache_key_;     // FeatureCache key of the bin image, encodes the binning
  Tunables tunables_;
  TargetHistogram target_;     // in use: anchor parts learned_, the rest running_
  TargetHistogram learned_;    // from the box (or the target file)
  std::vector<double> running_;  // the adapted histogram
  // target_ spread along intensity (intensity_tolerance), and 1 / its rho against target_: rho(p, scoring_) times
  // this is 1 for a candidate equal to the target (scoring_ is target_ and the factor 1 at tolerance 0)
  TargetHistogram scoring_;
  double scoring_scale_ = 1.0;
  double invalid_log_likelihood_ = 0.0;  // log-likelihood of rho = 0
  // scratch, sized in applyTunables: no allocation per hypothesis
  Sampling full_;     // evaluate()'s: `samples` per side, `surround_samples` on the ring
  Sampling preview_;  // preview()'s: `preview_samples` per side, as many on the ring as on the grid's border
  Eigen::VectorXd preview_similarity_;  // preview()'s similarities (not returned)
  SparseHistogram candidate_;
  SparseHistogram ring_;          // the surround ring's histogram
  std::vector<uint8_t> ring_values_;        // scratch: one hypothesis's ring bins
  std::vector<uint8_t> grid_values_;        // scratch: one hypothesis's window bins (evaluate()'s sparse path)
  float learned_radius_ = 0.0f;   // half the smaller side of the learning ROI: the 2D hypotheses' ring
  long target_version_ = 0;       // bumped when the target changes: the back-projection's cache tag
};

}  // namespace stereo_pf
