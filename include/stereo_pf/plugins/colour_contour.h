// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The colour-outline observation model, pluginlib class stereo_pf/ColourContour. Declared here so tests can
// construct it directly; defined and exported in plugins/observation/colour_contour.cpp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "stereo_pf/core/colour.h"
#include "stereo_pf/core/histogram.h"
#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// Colour-outline likelihood: does the edge between the target's colours and the background's lie on the
/// outline the hypothesis predicts, to a fraction of a pixel?
///
/// Why: a colour histogram (ColourHSI) is blind to where exactly its window sits as long as the window stays
/// inside the object, so on a plain ball it leaves each view's centre free by a few pixels, and the
/// disparity with it: at 1.1 m (f = 525 px, b = 9 cm) one pixel of disparity is 2.6 cm of depth. The outline
/// of the object's colour pins the centre in each image, hence the disparity, hence the depth.
///
/// Model. From the target histogram q (learned like ColourHSI's, from the region of interest shrunk by
/// `target_margin`) and a background histogram b (the rest of the learning image, outside the region grown by
/// half its size on each side), every pixel gets the probability of being the target rather than the
/// background, P = (q + e) / (q + b + 2 e) with e = 1e-3 (a colour seen in neither is 0.5): one table read per
/// pixel of the cached HSI bin image, done once per frame per view and only in the rows the outlines reach.
/// On each of `lines` radial lines the pixels of a digital line (one pixel per step along its dominant axis,
/// `line_half_length` steps each side of the outline point) are compared with a soft step:
///   expected(d) = 1 / (1 + exp(d / softness)),  d = the pixel's signed distance outside the outline, px
/// (d is exact to 1/32 px, so the score moves continuously as the outline moves by a fraction of a pixel).
/// With m the mean of (P - expected)^2 over the samples inside the image:
///   log-likelihood = -m / (2 sigma^2),   similarity = max(0, 1 - m / m_background),
/// where m_background is m for a hypothesis on plain background (P = 0 everywhere). Hypotheses that are
/// invalid, non-finite, or have fewer than half of their samples inside the image score like background.
///
/// The outline: 3D hypotheses (radius > 0: the apparent radius f R / z of the 3D state models) use the
/// ellipse a sphere really projects to off the optical axis (`perspective`; as ShapeCircle, from the frame's
/// fx and principal point; a circle would bias depth by a few cm towards the image edges); 2D hypotheses
/// (radius <= 0) use a circle of `radius`, or of the learned radius (half the smaller side of the region)
/// when that is 0. Radii below `min_radius` are clamped to it.
///
/// It is a refining cue (parameter `refine`, default true): sharper, by construction, than a 1000-particle
/// cloud spread by the dynamics can sample, so the engine applies it after the other cues, between a resample
/// and a kernel jitter (FilterEngine, "progressive correction"), and only while tracking. Not thread-safe
/// (scratch buffers are members).
///
/// Parameters (in the plugin's namespace): hue_bins, saturation_bins, intensity_bins, achromatic_saturation,
/// achromatic_intensity (as ColourHSI; structural, read at initialisation only), sigma (0.05, 0.001..10),
/// lines (16, 4..256), preview_lines (8; 0 = none, else 4..256, at most lines),
/// line_half_length (2 px, 1..10), softness (0.7 px, 0.1..10), target_margin
/// (0.15, 0..0.45), radius (0 = learned; px, 0..2000), min_radius (2 px, 0.5..1000), perspective (true),
/// intensity_tolerance (0: off, 0..1: P from both histograms spread along intensity, as ColourHSI's: a face of the
/// target's colour in shade is still the target's, not a colour seen in neither histogram);
/// reconfigure() re-reads all but the binning.
class ColourContour : public ObservationModel
{
public:
  ColourContour() = default;

  /// Learn the target histogram from `roi` shrunk by `target_margin`, the background histogram from the rest
  /// of the image (outside `roi` grown by half its size on each side; uniform when nothing is left) and the
  /// 2D radius. False with `error` set when the region is empty, outside the image or too small.
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  /// True once a target has been learned or loaded.
  bool hasTarget() const override { return target_.valid(); }
  /// Log-likelihood and similarity of every hypothesis (see the class comment).
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// The log-likelihood of the outline on preview_lines lines, for screening; false when preview_lines is 0.
  bool preview(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood) override;
  /// Write a map named name() with the binning, both histograms and the learned radius.
  void saveTarget(cv::FileStorage& fs) const override;
  /// Read what saveTarget wrote (`node`: that map, or a map holding it under name()). False with `error` set
  /// when absent, malformed or learned with a different binning.
  bool loadTarget(const cv::FileNode& node, std::string& error) override;
  /// Re-read the common parameters and everything but the binning; on a bad value throws ParameterError and
  /// keeps the previous settings.
  void reconfigure() override;

  /// Rows [y0, y1) of the per-pixel target probability P of `view` (CV_8UC1, 255 P), through the cache.
  /// Without a target every pixel is 128.
  const cv::Mat& foregroundMap(FeatureCache& cache, View view, int y0, int y1);
  /// The same map, of which only the pixels of `region` are guaranteed (FeatureCache::getRegion()).
  const cv::Mat& foregroundMap(FeatureCache& cache, View view, const cv::Rect& region);
  /// Mean squared difference m between P and the soft step for one hypothesis at (u, v) with `radius` (as in
  /// ImageHypotheses), NaN when it cannot be measured (for tests and diagnostics).
  double mismatch(FeatureCache& cache, View view, float u, float v, float radius);
  /// The learned target and background histograms (invalid before learning).
  const TargetHistogram& target() const { return target_; }
  const TargetHistogram& background() const { return background_; }
  /// The radius 2D hypotheses use, px (0 before learning when the parameter `radius` is 0).
  double radius2D() const { return tunables_.radius > 0.0 ? tunables_.radius : learned_radius_; }

protected:
  /// Read and validate every parameter, build the colour table and the line patterns.
  void onInitialize() override;
  /// True: applied after the other cues (see the class comment).
  bool refinesByDefault() const override { return true; }

private:
  struct Tunables
  {
    double sigma = 0.05;
    int lines = 16;
    int line_half_length = 2;
    double softness = 0.7;
    double target_margin = 0.15;
    double radius = 0.0;
    double min_radius = 2.0;
    bool perspective = true;
    double intensity_tolerance = 0.0;
    int preview_lines = 8;
  };
  /// The lines across the outline a hypothesis is sampled on, the same for every hypothesis.
  struct Pattern
  {
    /// `line_count` lines evenly spread around, `half` pixel steps on each side of the outline.
    void build(int line_count, int half, double softness);
    /// Pixel offsets of the samples for an image of `step` bytes per row.
    void buildOffsets(size_t step);
    int lines = 0;
    int samples_per_line = 0;            // 2 line_half_length + 1
    std::vector<float> line_c, line_s;   // cos, sin of each line's angle (padded to whole vectors)
    std::vector<int> dx, dy;             // [k * samples_per_line + j]: pixel offset of sample j of line k
    std::vector<float> along;            // the same offset projected on the line's direction, px
    std::vector<float> along_scaled;     // ... in soft-step table entries
    std::vector<std::ptrdiff_t> offsets;  // dy * step + dx
    size_t offsets_step = 0;              // step offsets was built for (0: not yet)
    int reach = 0;                        // largest |dx|, |dy| of any sample, px
    float background_mismatch = 0.0f;     // m on plain background (P = 0)
  };
  /// One hypothesis's outline: centre, radial unit vector and semi-axes (a circle: a = b, e = (1, 0)).
  struct Outline
  {
    float cu = 0.0f, cv = 0.0f, ex = 1.0f, ey = 0.0f, a = 0.0f, b = 0.0f;
  };
  Tunables readTunables() const;
  void applyTunables(const Tunables& t);
  /// Set the histograms (a target change) and rebuild the table from bin to P.
  void setTarget(TargetHistogram target, TargetHistogram background);
  /// The table from bin to P, from the histograms and intensity_tolerance.
  void buildTable();
  /// The outline of a hypothesis; false when it has none (invalid, non-finite, no usable radius).
  bool outline(const ImageHypotheses& hyp, int i, float focal, float cx, float cy, Outline& o) const;
  /// m for one outline on rows of the P map that cover it, sampled on `pattern` (NaN with fewer than half of the
  /// samples inside).
  float score(Pattern& pattern, const uint8_t* fg, size_t step, int width, int height, const Outline& o);
  /// evaluate() on the lines of `pattern` (`what` names the caller in errors).
  void judge(FeatureCache& cache, const ImageHypotheses& hyp, Pattern& pattern,
             Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity, const char* what);

  HsiBinning binning_;
  std::unique_ptr<const HsiBinner> binner_;
  Tunables tunables_;
  TargetHistogram target_, background_;
  std::vector<uint8_t> lut_;      // bin -> 255 P, 256 entries
  float learned_radius_ = 0.0f;
  long target_version_ = 0;       // the P map's cache tag (bumped when the target changes)
  double invalid_log_likelihood_ = 0.0;
  // The line patterns (built in applyTunables).
  Pattern full_;     // evaluate()'s: `lines` lines
  Pattern preview_;  // preview()'s: `preview_lines` lines
  Eigen::VectorXd preview_similarity_;  // preview()'s similarities (not returned)
  std::vector<float> expected_;          // soft step by quantised distance (kStepsPerPixel per px)
  std::vector<Outline> outlines_;        // scratch: one per hypothesis of a batch
  std::vector<int> base_x_, base_y_;     // scratch: each line's base pixel (its outline point, rounded)
  std::vector<std::ptrdiff_t> base_;     // ... as an offset into the P map
  std::vector<float> origin_;            // ... and the outline point's soft-step table position from it
};

}  // namespace stereo_pf
