// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Map proposals (a proposal policy of the engine while searching, and of its recovery search while tracking):
// stereo pairs drawn where the observation models' target maps agree, a left pixel where the target's
// appearance is, its partner along the same row of the right image. ROS-free.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/hypotheses.h"
#include "stereo_pf/core/random.h"
#include "stereo_pf/core/stereo_geometry.h"
#include "stereo_pf/observation_model.h"
#include "stereo_pf/state_model.h"

namespace stereo_pf
{
/// Draws (left pixel, right pixel) pairs from the product of the enabled, trusted models' target maps.
class MapProposals
{
public:
  /// What bounds the pairs' disparity.
  struct Bounds
  {
    double min_depth = 0.3;  ///< m; the nearest depth a pair may have (its largest disparity)
    /// While tracking, the estimate whose disparity bounds the pairs' within a factor `reach` (the maps see the
    /// target at about its present size, which a far smaller or larger disparity would contradict); else null.
    const StateEstimate* near = nullptr;
    double reach = 1.5;
    /// While searching for an object a track lost (else null): where the track last saw it, and how far from there
    /// it can be by now (m, reach_radius). Only left pixels whose ray passes within reach_radius of it, and
    /// partners at the disparities of the depths within it, are proposed: a look-alike elsewhere could not be taken
    /// for the object (the engine's re-acquisition reach), and the pairs drawn there would be lost on it.
    const Eigen::Vector3d* last_seen = nullptr;
    double reach_radius = 0.0;
  };

  /// Append up to `count` pairs to `pairs`: a left pixel drawn over 4x4-pixel cells in proportion to the
  /// squared product of the maps of the models that are enabled and trusted (`trust[k] > 0`, same order as
  /// `models`), its partner along the same row of the right product at a positive disparity within `bounds`
  /// (and, with `bounds.last_seen`, both within the image of the reach sphere, to a cell).
  /// Fewer (none) when no model has a map, the maps are empty, or they are empty within the reach.
  void draw(FeatureCache& cache, const std::vector<std::shared_ptr<ObservationModel>>& models,
            const std::vector<double>& trust, const StereoGeometry& geometry, int count, const Bounds& bounds,
            Rng& rng, std::vector<std::pair<Pixel, Pixel>>& pairs);

private:
  cv::Mat small_left_, small_right_;  ///< the maps' products on 4x4 cells
  cv::Mat cell_scratch_;               ///< one map on the cells
  std::vector<double> cdf_, row_cdf_;
};

}  // namespace stereo_pf
