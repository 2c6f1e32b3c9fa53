// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Stereo-consistency observation model, pluginlib class stereo_pf/StereoMatch. Declared here so tests can
// construct it directly; defined and exported in plugins/observation/stereo_match.cpp.
#pragma once

#include <string>
#include <vector>

#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// Stereo likelihood: do a 3D hypothesis's left and right images show the same thing?
///
/// The target cues (colour, texture, shape) compare each image with the learned target. Inside a uniformly
/// coloured ball they cannot tell hypotheses a pixel or two apart, and each view's error goes straight into
/// the disparity: at 1.1 m with f = 525 px and b = 9 cm one pixel of disparity is 2.6 cm of depth. This cue
/// compares the two images with each other instead, which measures the disparity directly (thesis 6.3: the
/// depth is the disparity's). The grey images of both views are sampled on the same grid of offsets around
/// the particle's left and right centres, over a disc of radius `window_scale` * apparent radius (> 1, so
/// the disc holds the ball's silhouette, where the images change fastest), and compared by the zero-mean
/// normalised cross-correlation
///   ZNCC = cov(L, R) / sqrt(max(var L, c^2) max(var R, c^2)),   c = `min_contrast` grey levels,
/// with log-likelihood -(1 - ZNCC) / (2 sigma^2) (the form of eq. 5.5) and similarity max(0, ZNCC).
/// ZNCC ignores the gain and offset between the cameras; the floor c keeps two featureless patches (sensor
/// noise only) near 0 instead of letting their noise correlate.
///
/// Outline contrast (`edges`, default true): near the cameras the two views see different things behind the
/// object, and an outline can be brighter than its surround in one view and darker in the other (a grey ball
/// before a dark curtain in the left image and a bright panel in the right one: catch_test1's last frames). Its
/// grey levels then correlate negatively at the true disparity, and the disparity went to wherever the
/// backgrounds happened to agree. So the same samples are also taken from each region's Sobel gradient
/// magnitude (a quarter of it, in 8 bits), which an outline shows whichever side is brighter, and a pair's ZNCC
/// is the better of the two. On the real pitches, seeds 1-30, median RMS (runs within 2 % of range):
/// catch_test1 2.9 -> 0.5 % (8 -> 20 of 30), newBall 0.44 -> 0.31 %, Ball_Launch1 0.59 -> 0.89 % (23 of 30
/// either way); on the drawn scenes (5 x 30, seeds 1 and 2) 173 of 300 runs succeed either way. Both
/// correlations are summed in one pass over the samples; the second costs about 3 % of a default step.
///
/// Near side (`surface_depth`, default 0.15 object radii): the texture the two views share lies on the object's
/// surface, in front of its centre (on a textured ball, 2/3 of a radius on average; at the near pole a whole
/// radius), so compared at the centre's disparity the views agree best a little short of the centre. The right
/// window is therefore centred on the right image of the point `surface_depth` radii in front of the centre on
/// the left ray: disparity d / (1 - surface_depth R / fx), R the apparent radius. The outline, which plain
/// objects are matched by, lies at the centre's depth, so the default is well below 2/3: 0.08 gave 1.32 % and
/// 0.25 1.19 % median RMS on the drawn scenes against 1.24 % at 0.15, but plain balls' depth 0.5 % long. With the
/// local search's disparities scored by this cue too (3262b8f), 0 -> 0.15: the drawn scenes (5 draws x 30,
/// tracker seeds 1 and 2) 172 -> 176 of 300 runs successful, median RMS 1.38 / 1.39 -> 1.17 / 1.32 % of range;
/// the real pitches, seeds 31-60, runs within 2 % of range 105 -> 110 of 120 (catch_test1 22 -> 27, the others
/// unchanged), seeds 1-10 35 -> 34 of 40 (Ball_Launch1 8 -> 7, catch_test1 7 -> 8, newBall 10 -> 9). Before
/// that change it had cost Ball_Launch1 7 of 60 runs and lost the turning box early on one seed in five.
/// zncc() compares the positions it is given.
///
/// Sampling: `rows` rows evenly spaced across the disc (at (k + 1) / (rows + 1) of its height), and on each
/// row the columns `column_step` whole pixels apart that lie inside the disc; column_step 0 derives the step from
/// the apparent size: rows * 2 * half-size / `samples`, rounded, at least 1 px, so each view has about `samples`
/// samples whatever the object's size. Whole-pixel steps give every sample of one view the centre's sub-pixel
/// phase, so the samples are interpolated linearly along the rows (the epipolar lines) with one pair of weights per
/// view, and the likelihood varies continuously with the disparity instead of in one-pixel steps. Rows are rounded:
/// a vertical shift moves both views alike. The grey levels are converted once per frame, only over the region the
/// hypotheses can read.
/// A fixed 3 px step (the default until column_step 0 replaced it) gives a 4 px ball 6 samples per view: its depth
/// jitters by 2-2.5 % of range from frame to frame on far, small targets. column_step 0 with 48 samples: the drawn
/// scenes (5 draws x 30, tracker seeds 1-3) 295 against 271 of 450 runs successful, median RMS 1.09-1.14 against
/// 1.11-1.21 % of range; the real pitches, seeds 1-60, 231 against 228 of 240 runs within 2 % of range,
/// catch_test1 tracked to its last reference frame in 40 against 36 of 60 (four rows: 299 drawn, but catch_test1
/// to the end in 9 of 60). Its first try as the default made the nodelet test's rejected ~set_target lose 4 of 10
/// frames after settling, in 3 of 5 runs: the engine's jumps then arrived from a drifted estimate (fixed there).
///
/// The cue says nothing about whether the matched thing is the target, so it is not part of the evidence
/// (comparesViews()). It scores sets observed in both images, i.e. the 3D state models; the
/// stereo-constraints model's 2D sets are observed in one image each and are not scored by it (their
/// pairing is the coupling's job). evaluate() on one view alone gives every hypothesis the same value.
/// There is no target to learn: learnTarget() only checks the region, and nothing is saved.
///
/// Cost per hypothesis pair: about `samples` per view with column_step 0 (fewer on objects under samples / (2 rows)
/// px across), else rows * 2 * window_scale * radius / column_step (~30 for a 17 px ball, step 3). Hypotheses
/// without a radius (2D), with valid == 0 in either view, or with fewer than half of their samples inside both
/// images get the log-likelihood of ZNCC = 0 and similarity 0.
/// Not thread-safe (scratch buffers are members).
///
/// Parameters (in the plugin's namespace): sigma (0.1, 0.001..10), window_scale (1.35, 0.2..3),
/// rows (2, 1..41), column_step (0: from samples; 1..20 px), samples (48, 4..10000), min_contrast (4 grey
/// levels, 0.1..100),
/// min_radius (2 px, 0.5..100), edges (true), surface_depth (0.15 radii, 0..1), only_while_tracking (true: the
/// engine skips the cue while searching or lost, where it would pull particles to any textured surface it can
/// triangulate); all are re-read by reconfigure().
class StereoMatch : public ObservationModel
{
public:
  StereoMatch() = default;

  /// Nothing to learn: true when `roi` lies in the image (so a bad region is still reported).
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  /// Always true: the cue needs no target.
  bool hasTarget() const override { return true; }
  /// False: nothing is saved, and target files need no entry for it.
  bool learnsTarget() const override { return false; }
  /// One view alone cannot be matched: every hypothesis gets the log-likelihood of ZNCC = 0, similarity 0.
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// True: scored through evaluatePair().
  bool comparesViews() const override { return true; }
  /// `only_while_tracking` (default true): it sharpens depth once colour, texture or shape found the object.
  bool onlyWhileTracking() const override { return tunables_.only_while_tracking; }
  /// ZNCC of each particle's left and right patches (see the class comment).
  void evaluatePair(FeatureCache& cache, const ImageHypotheses& left, const ImageHypotheses& right,
                    Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// Nothing to save.
  void saveTarget(cv::FileStorage& /*fs*/) const override {}
  /// Nothing to load: always true.
  bool loadTarget(const cv::FileNode& /*node*/, std::string& /*error*/) override { return true; }
  /// Re-read every parameter; on a bad value throws ParameterError and keeps the previous settings.
  void reconfigure() override;

  /// ZNCC of one hypothesis pair (the better of grey and edges, with `edges`), NaN when it cannot be judged (for
  /// tests and diagnostics).
  double zncc(FeatureCache& cache, float u_left, float u_right, float v, float radius);

protected:
  void onInitialize() override;
  /// True: a refining cue (parameter `refine`), applied after the target cues on the set they resampled.
  /// Applied together with them, it let a textured object of the target's colour win the particles over
  /// (scenes/colour_distractor.yaml); after them it only sharpens the disparity where they put the target.
  bool refinesByDefault() const override { return true; }

private:
  struct Tunables
  {
    double sigma = 0.1;
    double window_scale = 1.35;
    int rows = 2;
    int column_step = 0;
    int samples = 48;
    double min_contrast = 4.0;
    double min_radius = 2.0;
    double surface_depth = 0.15;
    bool edges = true;
    bool only_while_tracking = true;
  };
  Tunables readTunables() const;
  /// Half-size of the compared disc for an apparent radius.
  double halfSize(float radius) const;
  /// ZNCC of one pair on grey regions whose pixel (0, 0) is image pixel `*_origin` (NaN when it cannot be
  /// judged). With `*_edges` (the regions' edgeImage()s), the better of that and the edges' ZNCC.
  double match(const cv::Mat& left, cv::Point left_origin, const cv::Mat& right, cv::Point right_origin, float u_left,
               float u_right, float v, float radius, const cv::Mat* left_edges = nullptr,
               const cv::Mat* right_edges = nullptr) const;
  /// Grey version of the part of `hyp.view` the valid pairs' discs can read (whole image at worst).
  void greyRegion(FeatureCache& cache, const ImageHypotheses& hyp, const ImageHypotheses& partner, cv::Mat& grey,
                  cv::Point& origin);

  /// The Sobel gradient magnitude of `grey`, a quarter of it in 8 bits (`edges`).
  void edgeImage(const cv::Mat& grey, cv::Mat& edges);

  Tunables tunables_;
  double invalid_log_likelihood_ = 0.0;  // log-likelihood of ZNCC = 0
  ImageHypotheses near_side_;             // scratch: the right hypotheses moved to the near side (surface_depth)
  cv::Mat grey_[2];                       // scratch: the grey regions of the left and right image
  cv::Mat edges_[2];                      // scratch: their gradient magnitudes (`edges`)
  cv::Mat sobel_x_, sobel_y_, magnitude_;  // scratch of edgeImage()
};

}  // namespace stereo_pf
