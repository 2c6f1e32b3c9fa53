// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The stereo-constraints (SC) state model (thesis 5.1, 5.3, 5.4): two 2D particle sets, one per image,
// coupled by the soft epipolar and vergence constraints of eq. 5.15. Plugin `stereo_pf/StereoConstraints`.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "stereo_pf/plugins/stereo_coupling.h"
#include "stereo_pf/state_model.h"

namespace stereo_pf
{
/// Set 0 holds {u, v} in the left image, set 1 {u, v} in the right image (pixels). Each set is observed in
/// its own image only; couple() multiplies each set's weights by the eq. 5.15 agreement with the other set.
///
/// Parameters (in the model's namespace; ranges are checked, a bad value throws ParameterError naming it):
///  - `noise` (px, default 18, [0, 1000]: a 30 fps pendulum moves up to ~20 px per frame): alpha of eq. 5.12-5.13, std of the random walk per frame on u and v.
///    It is per frame, not per second: predict() ignores dt, as the thesis does.
///  - `epipolar_sigma` (px, default 2, [0.5, 100]): sigma of the Gaussian across rows.
///  - `max_disparity` (px, 0 or [1, 1e5]): d_max of the vergence window. When absent or 0 it is derived from
///    `min_depth` at coupling time: d_max = fx * baseline / min_depth, clamped to the image width.
///  - `min_depth` (m, default 0.3, [1e-3, 1e3]): nearest depth of interest (used when max_disparity is absent).
///  - `vergence_softness` (px, default 2, [0.5, 100]): Gaussian smoothing of the window's edges.
///  - `radius` (px, default 0, [0, 1e4]): a fixed apparent radius written into the hypotheses. 0 means: use
///    `object_radius` at the depth the two sets currently agree on (their weighted mean disparity, updated in
///    couple()), and before that is known, let the observation models use their fixed window.
///  - `object_radius` (m, default 0.035, [0, 10]): radius of the tracked sphere; 0 = always the fixed window
///    (the thesis's 11x11). The SC sets are not paired per particle, so the radius is one per frame, not per
///    particle; with it the colour model's window and surround ring follow the ball's size (2.0-2.3 cm RMS on
///    the synthetic pendulum instead of ~3 cm with the fixed window).
///  - `coupling` ("fast" | "naive", default "fast"): StereoCoupling or the O(N^2) reference (benchmarks).
///  - `density_radius_px` (px, default 10, [0.1, 1e4]): radius of the Density estimator on the 2D sets. The
///    engine's own density_radius is in metres for the 3D models and is therefore not used here.
class StereoConstraints : public StateModel
{
public:
  StereoConstraints() = default;

  /// Two sets: 0 = left image, 1 = right image.
  int numSets() const override { return 2; }
  /// 2 ({u, v}) for both sets; throws std::out_of_range for another set index.
  int dimension(int set) const override;
  /// {Left} for set 0, {Right} for set 1.
  std::vector<View> views(int set) const override;

  /// Uniform over the image: u in [-0.5, width - 0.5), v in [-0.5, height - 0.5) (pixel-centre convention).
  void samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin, int end,
                   Rng& rng) const override;
  /// Gaussian random walk with std `noise` per frame on u and v (dt is ignored, see the class comment).
  void predict(int set, double dt, ParticleSet& particles, Rng& rng) const override;
  /// Left set: the left pixel; right set: the right pixel (false for a non-positive disparity).
  bool seedFromStereo(const StereoGeometry& geometry, int set, ParticleSet& particles, int row, const Pixel& left,
                      const Pixel& right) const override;
  /// The particle itself is the hypothesis; radius = `radius`; valid = inside the image. A view other than
  /// the set's own (a caller error) yields hypotheses that are all invalid.
  void project(const StereoGeometry& geometry, int set, const ParticleSet& particles,
               ImageHypotheses& hyp) const override;
  /// Eq. 5.15: both factors from the current normalised weights of both sets, then
  /// log_weights += log(factor + 1e-300) and both sets renormalised.
  void couple(const StereoGeometry& geometry, std::vector<ParticleSet>& sets) override;
  /// The estimator on each 2D set (pixels; `density_radius_px` for Density), then triangulation:
  /// z = fx b / (uL - uR), row = mean of vL and vR; valid = false when uL - uR <= 0. The covariance is the
  /// two weighted 2D covariances (about each set's weighted mean, sets independent) propagated through the
  /// triangulation's Jacobian. `density_radius` (engine units) is ignored in favour of `density_radius_px`.
  StateEstimate estimate(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets, Estimator estimator,
                         double density_radius) const override;
  /// Pairs the sets by row: both sorted by v and matched rank to rank (rows agree after rectification),
  /// min(N_left, N_right) pairs, each triangulated with weight wL * wR (normalised over the pairs). A pair
  /// with non-positive disparity gets weight 0 and the weighted mean of the valid pairs as its position
  /// (never NaN, so consumers need no special case); with no valid pair at all every point is at the origin
  /// and every weight 0.
  void cloud(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets, Eigen::MatrixX3d& points,
             Eigen::VectorXd& weights) const override;

  /// The coupling parameters in force for `geometry` (max_disparity derived from min_depth when not set).
  CouplingParams couplingParams(const StereoGeometry& geometry) const;
  /// Random-walk std per frame (px).
  double noise() const { return noise_; }
  /// True when the O(N^2) reference is used for couple().
  bool naiveCoupling() const { return naive_; }

protected:
  /// Read and validate the parameters listed in the class comment.
  void onInitialize() override;

private:
  /// Throws std::out_of_range unless set is 0 or 1.
  void checkSet(int set) const;

  double noise_ = 18.0;              ///< `noise`, px per frame
  double epipolar_sigma_ = 2.0;      ///< `epipolar_sigma`, px
  double max_disparity_ = 0.0;       ///< `max_disparity`, px; 0: derive from min_depth_ and the geometry
  double min_depth_ = 0.3;           ///< `min_depth`, m
  double vergence_softness_ = 2.0;   ///< `vergence_softness`, px
  double radius_ = 0.0;              ///< `radius`, px (0: from object_radius and the current depth)
  double object_radius_ = 0.035;     ///< `object_radius`, m
  double apparent_radius_ = 0.0;     ///< px, from the last couple(); 0 until the sets agree on a depth
  double density_radius_px_ = 10.0;  ///< `density_radius_px`, px
  bool naive_ = false;               ///< `coupling` == "naive"

  StereoCoupling coupling_;                        ///< fast evaluator (keeps its grid between frames)
  Eigen::VectorXd left_factor_, right_factor_;     ///< scratch
};

}  // namespace stereo_pf
