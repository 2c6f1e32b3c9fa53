// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Acquisition from a box: the user's box in the left image is matched along the same rows of the right
// image, which gives the object's disparity, hence its depth and metric size, before any particle exists.
// ROS-free (OpenCV core + Eigen).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/core/stereo_frame.h"

namespace stereo_pf
{
/// Settings of matchBox(). The defaults follow from the box and the camera; none depends on a scene.
struct BoxMatchOptions
{
  /// Weight of the ring around the box's inscribed ellipse (out to `ring_scale` times the box): the ring
  /// carries the object's outline against its surroundings, which is all an untextured grey object offers.
  double ring_weight = 0.3;
  /// Outer size of that ring, as a multiple of the box size.
  double ring_scale = 1.25;
  /// Below this normalised correlation the best match is no match at all.
  double min_score = 0.5;
  /// A second peak (away from the best by more than half the box width) scoring within this of the best
  /// makes the match ambiguous; and a candidate whose right-image window matches the left image elsewhere better
  /// than at the box by more than this fails the left-right check.
  double ambiguity_margin = 0.05;
  /// Smallest disparity accepted, pixels: below it depth is not measurable with this camera.
  double min_disparity = 0.5;
  /// Largest object, in stereo baselines across, that a candidate may imply before a smaller one is preferred: a
  /// box's width over a disparity is the object's width over the baseline, whatever the camera. A loose box
  /// around a plain object before a textured backdrop far behind it can match that backdrop best (the object's
  /// flat inside carries little of the correlation); taken for the object, the backdrop makes it tens of
  /// baselines across and as far away. A candidate passing the same checks that implies at most this is taken
  /// instead; when none does, the best stands. 0: off.
  double max_size_baselines = 20.0;
};

/// Outcome of matching a left-image box in the right image.
struct BoxMatch
{
  bool ok = false;              ///< false: `error` says why (no match, ambiguous, bad box, too far)
  std::string error;            ///< what went wrong, naming the box
  std::string warning;          ///< a match made, but one the user should hear of (naming the box); else empty
  double disparity = 0.0;       ///< sub-pixel disparity of the box centre, pixels (left u - right u)
  double score = 0.0;           ///< normalised correlation of the best match, [-1, 1]
  double second_score = -1.0;   ///< best score of any other peak (-1 when there is none)
  double second_disparity = 0.0;  ///< where that other peak is, pixels
  Pixel left;                   ///< box centre in the left image
  Pixel right;                  ///< its match in the right image (same row)
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< triangulated centre, left optical frame, metres
  double radius = 0.0;          ///< the object's metric half-size from the box size at that depth, metres
  double depth_sigma = 0.0;     ///< depth uncertainty of a quarter-pixel disparity error at that depth, metres
  std::vector<double> scores;   ///< score per integer disparity (index = disparity - first_disparity)
  int first_disparity = 0;      ///< disparity of scores[0]
};

/// Find `box` (left image of `frame`) in the right image along the same rows. Each candidate disparity is
/// scored by a normalised correlation over all channels, each channel's mean removed (so a gain or offset
/// difference between the cameras does not matter, and an object's colour counts through the structure it
/// makes against its surroundings: an orange disc is bright in red and dark in blue), weighted to the box's
/// inscribed ellipse plus a lighter ring around it (the outline, all an untextured grey object offers). The
/// best integer disparity is refined to a fraction of a pixel by a parabola through its neighbours. The
/// object is taken to be a sphere whose image bounding box is `box`: its centre and radius are solved for
/// exactly (a sphere's image is displaced outward from the projection of its centre).
///
/// Left-right check: the right image's window at a candidate disparity is looked for in the left image along the
/// same rows; when it matches somewhere else better (by more than `ambiguity_margin`) than at the box, it shows
/// something else (a patch of the surroundings at its own disparity that happens to resemble the box: on a drawn
/// scene, a small grey box seen 14 degrees apart by a 50 cm baseline scored 0.78 against a smooth backdrop at 4
/// times its disparity, below 0.5 at its own: it was tracked 1.5 m off from the first frame, and is now refused with
/// that reason), and the next candidate is taken. The peaks are checked best first, at most four of them.
///
/// Of the candidates that pass the check, one implying an object at most `max_size_baselines` across is preferred to
/// a better-scoring one implying a larger object.
///
/// The match fails, with an error naming the box, when the box is unusable, the best score is below `min_score`,
/// no candidate passes the left-right check, another peak that passes it (or was not checked) scores within
/// `ambiguity_margin` of the best, or the disparity is below `min_disparity`.
BoxMatch matchBox(const StereoFrame& frame, const cv::Rect& box, const BoxMatchOptions& options = BoxMatchOptions());

/// "x,y,w,h" of a box, for messages.
std::string boxText(const cv::Rect& box);

}  // namespace stereo_pf
