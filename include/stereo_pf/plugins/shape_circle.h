// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The circle-contour observation model (thesis 5.2, eq. 5.8-5.11), pluginlib class stereo_pf/ShapeCircle.
// Declared here so tests can construct it directly; defined and exported in
// plugins/observation/shape_circle.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// Shape likelihood: does the image show a circular contour of the hypothesis's radius around its centre?
///
/// K = `lines` measurement lines cross the circle of radius r around the hypothesis (u, v) at angles
/// theta_k = 2 pi k / K, each along the normal through the contour point (u + r cos theta_k,
/// v + r sin theta_k) (eq. 5.8-5.9) and `line_half_length` L pixels to either side of it, sampled one pixel
/// per step along its dominant axis (a digital line). The 1-D edge detector along a line is the central
/// difference |I(j + 1) - I(j - 1)| of the 8-bit grey image I along it (the derivative along the line); its
/// peaks are local maxima of at least `edge_threshold` grey levels within L of the contour point, located
/// to a fraction of a pixel by a parabola through the three differences around them (unbiased to ~0.1 px
/// on an exactly anti-aliased disc). Line k then gives (eq. 5.10)
///   p_k = q0 U + (1 - q0) sum_i w_i N(d_i; 0, sigma),
/// with d_i the distance of peak i from the contour point along the line, w_i its strength normalised over
/// the line's peaks, U the uniform density over the line and q0 (`q0`) the prior that no peak is the
/// contour; lines are independent, p = prod_k p_k (5.11). The log-likelihood written is
/// sum_k log(p_k / (q0 U)): the constant is dropped so that a line without any peak (q0 -> 1: nothing
/// but clutter) and a line that leaves the image both contribute exactly 0 — no information, never a
/// reward for looking outside the image. It is therefore >= 0 and 0 means "no contour evidence".
/// The product is formed in double (each factor is bounded) and logged once per hypothesis.
///
/// Similarity: the mean over the lines inside the image of sum_i w_i exp(-d_i^2 / (2 sigma^2)) (0 for a
/// line without peaks): the mixture's contour term scaled to 1 for a single peak exactly on the contour.
/// A line scores high only when its edge evidence is concentrated near the contour, so clutter, which
/// puts some peak near any contour but rarely only there, scores low.
///
/// Radius: 3D hypotheses (radius > 0) use their apparent radius, at least `min_radius`. 2D hypotheses
/// (radius <= 0, stereo-constraints sets) use the parameter `radius` when > 0, otherwise the radius learned
/// by learnTarget(): half the smaller side of the region of interest.
///
/// Perspective (`perspective`, default true): a sphere off the optical axis does not image as a circle but
/// as an ellipse elongated away from the principal point (by 1 / cos(theta): 6 % at 20 deg off the axis),
/// and a circle fits it best with a larger radius, which a 3D state model reads as a closer depth (about
/// 2.5 cm at 1.1 m on the pendulum). So for 3D hypotheses, whose radius is f R / z by the state models'
/// convention, the contour is that ellipse (from the frame's focal length fx and principal point; square
/// pixels assumed) and the lines stay radial from its centre. 2D hypotheses keep the circle (their radius
/// is an image measurement).
///
/// Invalid hypotheses (valid == 0, non-finite position, no usable radius, or fewer than half of the lines
/// inside the image) get log-likelihood 0 and similarity 0.
///
/// Cost: per hypothesis K (2L + 5) byte reads of the grey image at precomputed offsets (the sample pattern
/// of a line is fixed; only its start moves), integer differences, and no transcendental function except
/// one log (the Gaussian is tabulated). Per image: only the cache's grey image (shared with every model).
/// Not thread-safe (scratch buffers are members).
///
/// Weight: 0.2 by default (the thesis's 1, with 16 lines, counts every line as independent evidence, far sharper
/// than a particle cloud can sample). Not evidence that the target is seen (identifiesTarget()).
///
/// Parameters (in the plugin's namespace, all re-read by reconfigure()): lines (8, 3..256; the thesis's 16),
/// line_half_length (5 px, 1..25), sigma (1.5 px, 0.1..50), q0 (0.1, 0.001..0.999), edge_threshold
/// (16 grey levels, 0..255), radius (0 = learn from the region of interest; px, 0..2000), min_radius (3 px,
/// 0.5..1000), perspective (true).
class ShapeCircle : public ObservationModel
{
public:
  ShapeCircle() = default;

  /// Learn the radius for 2D hypotheses: half the smaller side of `roi` clipped to the image. False with
  /// `error` set when the region is empty or outside the image.
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override;
  /// True once a radius has been learned or loaded, or when the `radius` parameter is > 0.
  bool hasTarget() const override { return learned_radius_ > 0.0 || tunables_.radius > 0.0; }
  /// False: an outline of the target's size is not the target (a round patch of the wall fits it as well), so its
  /// similarity is no evidence that the target is seen; on a real pitch (a small, blurred ball) it scored far below
  /// the appearance cues and held the evidence under found_similarity.
  bool identifiesTarget() const override { return false; }
  /// Log-likelihood and similarity of every hypothesis (see the class comment).
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override;
  /// Write a map named name() holding the learned radius (nothing when none was learned).
  void saveTarget(cv::FileStorage& fs) const override;
  /// Read a radius written by saveTarget. `node` is either that map itself or a map containing it under
  /// name(). When it is absent, succeeds only if the `radius` parameter is > 0 (nothing to load).
  bool loadTarget(const cv::FileNode& node, std::string& error) override;
  /// Re-read the common parameters and every shape parameter; on a bad value throws ParameterError and
  /// keeps the previous settings.
  void reconfigure() override;

  /// Radius used for 2D hypotheses: the `radius` parameter when > 0, else the learned radius (0 if none).
  double radius2D() const { return tunables_.radius > 0.0 ? tunables_.radius : learned_radius_; }
  /// The radius learned from the region of interest (0 before learning).
  double learnedRadius() const { return learned_radius_; }
  /// Number of measurement lines K.
  int lines() const { return tunables_.lines; }

protected:
  /// Read and validate every parameter and build the line geometry.
  void onInitialize() override;
  /// 0.2 (see the class comment).
  double defaultWeight() const override { return 0.2; }

private:
  struct Tunables
  {
    int lines = 8;
    int line_half_length = 5;
    double sigma = 1.5;
    double q0 = 0.1;
    double edge_threshold = 16.0;
    double radius = 0.0;
    double min_radius = 3.0;
    bool perspective = true;
  };
  /// Geometry of one measurement line (independent of the hypothesis).
  struct Line
  {
    float c = 1.0f;        // cos theta_k
    float s = 0.0f;        // sin theta_k
    float spacing = 1.0f;  // distance along the line between consecutive samples, px
    double gain = 1.0;     // (1 - q0) / (q0 U): weight of the Gaussian term relative to the clutter term
    int dx_min = 0, dx_max = 0, dy_min = 0, dy_max = 0;  // extent of the sample offsets, px
  };
  Tunables readTunables() const;
  void applyTunables(const Tunables& t);
  /// Recompute offsets_ for images with `stride` elements per row.
  void buildOffsets(size_t stride);

  Tunables tunables_;
  double learned_radius_ = 0.0;
  int samples_per_line_ = 0;            // 2 L + 5: L each side of the contour point, two guards each end
  std::vector<Line> lines_;
  std::vector<int> dx_, dy_;            // [k * samples_per_line_ + j]: pixel offset of sample j of line k
  std::vector<float> projection_;       // the same offset projected on the line's direction, px
  std::vector<float> difference_position_;  // where central difference t lies along the line (sample t + 1), px
  std::vector<std::ptrdiff_t> offsets_;  // the same as byte offsets dy * stride + dx, offsets_row_ per line
  int offsets_row_ = 0;                 // entries per line in offsets_: max(samples_per_line_, 16)
  size_t offsets_stride_ = 0;           // stride offsets_ was built for (0: not built)
  float lut_scale_ = 1.0f;              // table entries per pixel of distance
  std::vector<float> gauss_lut_;        // N(d; 0, sigma) by quantised |d|
  std::vector<float> similarity_lut_;   // exp(-d^2 / (2 sigma^2)) by quantised |d|
  std::vector<float> half_reciprocal_;  // 1 / (2 x) for x = 0 .. 510 (sub-pixel peak positions)
  std::vector<float> line_c_, line_s_;  // cos, sin theta_k, padded to a multiple of 4 lines
  /// The contour of one hypothesis: centre, axis direction and semi-axes (a circle: a = b = r, e = (1, 0)).
  struct Contour
  {
    float cu, cv, ex, ey, a, b, r;
    bool ellipse;  ///< the contour is the sphere's projected ellipse, not the circle of radius r
    bool usable;   ///< false when the hypothesis is invalid or cannot be measured
  };
  std::vector<Contour> contours_;       // scratch: the contour of every hypothesis of one batch
  std::vector<int> start_x_, start_y_;  // scratch: rounded contour point of each line of one hypothesis
  std::vector<float> start_e_;          // scratch: its rounding offset along the line, px
  std::vector<uint8_t> intensity_;      // scratch: grey levels along one line (padded for vector loads)
  std::vector<uint8_t> derivative_;     // scratch: central differences of the samples
};

}  // namespace stereo_pf
