// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Cue trust: how well each cue tells the boxed object from the rest of the frame it was learned on, measured
// once at acquisition. A cue the background matches as well as the object (the intensity histogram of a grey
// ball in front of grey clutter, the outline of a colour a mono image does not have) adds noise of several
// nats to every particle and drowns the cues that do see the object; its weight is scaled by its trust. The
// defaults follow from the box and the frame, not from a scene. ROS-free.
#pragma once

#include <memory>
#include <vector>

#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/hypotheses.h"
#include "stereo_pf/observation_model.h"

namespace stereo_pf
{
/// Settings of measureCueTrust().
struct CueTrustOptions
{
  int columns = 16;        ///< background places: a grid of this many columns ...
  int rows = 12;           ///< ... and rows over the image
  double exclusion = 3.0;  ///< places nearer the object than this many apparent radii are not background
  /// The background's similarity is this quantile over the places: the close competitors, not the typical
  /// place (a cue that sees the object's colour in a tenth of the frame is a poor guide to where it is).
  double quantile = 0.9;
  /// A cue whose similarity at the object beats the background's by this much is trusted fully; by less, in
  /// proportion; by nothing, not at all.
  double margin = 0.2;
};

/// Trust in [0, 1] of each of `models` (same order), from their similarity at the object (`left`, `right`: its
/// centre in each view, `radius_px` its apparent radius) against the background places, averaged over the views
/// measured (a view the object fills has no background places). Models not measured (disabled, comparing
/// views) get 1. When no measured model tells the object apart at all, every model gets 1: the cues then share
/// the work as configured, and the background check decides whether the object is seen.
std::vector<double> measureCueTrust(FeatureCache& cache, const std::vector<std::shared_ptr<ObservationModel>>& models,
                                    const Pixel& left, const Pixel& right, double radius_px,
                                    const CueTrustOptions& options = CueTrustOptions());

}  // namespace stereo_pf
