// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The local search (a proposal policy of the engine while tracking): where, near the image position the
// object's last motion predicts or that motion reversed would take it to, the evidence cues see it best at its
// present apparent size; first in the left image on a grid scaled to the object, then along the same row of the
// right image over the disparities its depth motion allows (there also by how well the two views agree, when
// the engine has a cue comparing them). A fast object (a ball thrown at the camera gains pixels of disparity
// every frame) is found where a random walk would take many frames to get to; the particles it proposes carry
// the velocity of that jump. ROS-free.
#pragma once

#include <functional>

#include <Eigen/Core>

#include "stereo_pf/core/hypotheses.h"
#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Where the object was, and how it moved in the images in the frame before (zero when not known).
struct ImageTrack
{
  Pixel left;                 ///< centre in the left image, px
  double disparity = 0.0;     ///< left u - right u, px
  double radius = 0.0;        ///< apparent radius in the left image, px
  double du = 0.0, dv = 0.0;  ///< left image motion per frame, px (du, dv and dd all 0: no motion known yet)
  double dd = 0.0;            ///< disparity change per frame, px
  double reach = 0.0;         ///< px; with no motion known, how far the object may have gone since (0: two radii) ...
  double enough = 1.0;        ///< ... searched when nothing within two radii has this mean cue similarity
};

/// What the local search found.
struct LocalMatch
{
  bool found = false;
  Pixel left, right;        ///< the best pair (same row)
  double radius = 0.0;      ///< apparent radius there, px
  double similarity = 0.0;  ///< mean cue similarity of the pair, the smaller of the two views
  double step = 0.0;        ///< the final grid spacing in the left image, px (how well the place is known)
};

/// Scores hypotheses of one view: the sum of the evidence cues' log-likelihoods and their mean similarity.
using HypothesisScorer =
    std::function<void(const ImageHypotheses& hyp, Eigen::VectorXd& log_likelihood, Eigen::VectorXd& similarity)>;

/// Scores pairs of hypotheses (left i with right i) by how well the two views agree: adds its log-likelihoods.
using PairScorer =
    std::function<void(const ImageHypotheses& left, const ImageHypotheses& right, Eigen::VectorXd& log_likelihood)>;

class LocalSearch
{
public:
  /// Search near `track` in images of `width` x `height` px, scoring with `score` (and the right image's
  /// disparities also with `pair`, when given). Nothing is found when the track's motion takes its centre out of
  /// the image (the object has left the view).
  LocalMatch search(const ImageTrack& track, int width, int height, const HypothesisScorer& score,
                    const PairScorer& pair = PairScorer());

  /// Grid points per axis of the coarse left search over the window that reaches the prediction; the window
  /// also reaches back as far as the motion reversed would take the object, on more points of the same spacing
  /// (at most 1.5 times as many per axis). The spacing grows with the motion so that the cost stays bounded.
  static constexpr int kMaxGrid = 15;
  /// Grid points per axis at most when no motion is known and the window reaches as far as ImageTrack::reach.
  static constexpr int kMaxWideGrid = 41;
  /// A place within the object's apparent radius of where its motion takes it, scoring within this (mean cue
  /// similarity) of the best in the window, is taken rather than the best: a blurred object passing a sharp
  /// look-alike is followed.
  static constexpr double kTieMargin = 0.1;

private:
  /// Score `hyp_` and return the index of the best valid hypothesis (-1: none).
  int best(const HypothesisScorer& score, const PairScorer& pair = PairScorer());
  /// After best() gave `b`: the point nearest (pu, pv), within `rp` px of it, among those whose similarity is
  /// within kTieMargin of b's, moved to the best within rp + `step` of it; `b` when there is none.
  int preferPredicted(int b, double pu, double pv, double rp, double step) const;

  ImageHypotheses hyp_, left_hyp_;
  Eigen::VectorXd ll_, sim_;
};

}  // namespace stereo_pf
