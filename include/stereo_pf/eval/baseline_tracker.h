// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// OpenCV's 2D trackers (CSRT, KCF, CamShift) as stereo baselines for the particle filters: one tracker
// per image, both started from the same target box, box centres triangulated with StereoGeometry.
// ROS-free; track_bag --baseline runs it over a bag so its rows compare directly with the filters'.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Which OpenCV tracker runs in each image.
enum class BaselineType
{
  Csrt,     ///< cv::TrackerCSRT (opencv_contrib tracking: discriminative correlation filter, spatial reliability)
  Kcf,      ///< cv::TrackerKCF (opencv_contrib tracking: kernelised correlation filter)
  CamShift  ///< cv::CamShift (video module) on the back-projection of a hue histogram learned from the box
};

/// "csrt", "kcf" or "camshift" (the names parseBaselineType() accepts).
std::string toString(BaselineType type);
/// The type called `name` (lower case, as toString()). Throws std::invalid_argument naming the value
/// given and the allowed ones.
BaselineType parseBaselineType(const std::string& name);

/// Tunables of the baselines (defaults suit 640x480 images of the synthetic scenes).
struct BaselineConfig
{
  int max_disparity = 160;        ///< right-box search range, pixels (160 px is 0.3 m for fx 525, baseline 0.09 m)
  double min_match_score = 0.5;   ///< lowest TM_CCOEFF_NORMED score accepted for the right box at init
  double max_row_difference = 8.0;  ///< the box centres' rows may differ this much (pixels) in a rectified
                                    ///< pair; more means a tracker is on something else (no 3D estimate)
  int hue_bins = 30;              ///< CamShift: hue histogram bins over OpenCV's hue range 0..180
  int min_saturation = 60;        ///< CamShift: pixels below this saturation (0..255) carry no reliable hue
  int min_value = 32;             ///< CamShift: pixels below this value (0..255) carry no reliable hue
  double min_mass_ratio = 0.2;    ///< CamShift: lost when the window's back-projection mass falls below this
                                  ///< fraction of the mass at init (occluded, or drifted off the target)
};

/// Where the left box was found in the right image (same rows: the pair is rectified).
struct RightMatch
{
  bool found = false;      ///< a match scored at least min_match_score with disparity in [0, max_disparity]
  cv::Rect roi;            ///< the right box (left box shifted by the rounded disparity)
  double disparity = 0.0;  ///< u_left - u_right of the best match, sub-pixel (parabola through the scores)
  double score = 0.0;      ///< its TM_CCOEFF_NORMED score, [-1, 1]
};

/// One stereo frame's result.
struct BaselineEstimate
{
  bool valid = false;             ///< both trackers succeeded, their rows agree and the disparity is positive:
                                  ///< `position` is usable
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< triangulated box centres, left optical frame, m
  bool left_found = false;        ///< the left tracker reported success (`left`, `left_box` are its output)
  bool right_found = false;       ///< the right tracker reported success (`right`, `right_box` are its output)
  Pixel left, right;              ///< box centres (OpenCV pixel-centre convention)
  cv::Rect left_box, right_box;   ///< the boxes the trackers reported
};

/// Two independent 2D trackers of the same type, one per rectified image, and their triangulation.
/// A frame without a valid estimate (a tracker failed, the centres' rows differ by more than
/// max_row_difference, or the disparity is not positive) is "lost"; the trackers keep running and may pick
/// the target up again. Not thread-safe; not copyable.
class StereoBaselineTracker
{
public:
  /// A tracker of `type`; nothing runs before init().
  explicit StereoBaselineTracker(BaselineType type, const BaselineConfig& config = BaselineConfig());
  /// The type by name (see parseBaselineType(); throws std::invalid_argument for an unknown one).
  explicit StereoBaselineTracker(const std::string& type, const BaselineConfig& config = BaselineConfig());
  ~StereoBaselineTracker();
  StereoBaselineTracker(const StereoBaselineTracker&) = delete;
  StereoBaselineTracker& operator=(const StereoBaselineTracker&) = delete;

  /// Start both trackers from `left_roi` (a box of the left image; clipped to it): the left one on it, the
  /// right one on matchRight()'s box. Returns false with `error` (frame unusable, box empty, no right match,
  /// CamShift on a mono image or a box without saturated colour); a failed init leaves the tracker unstarted.
  bool init(const StereoFrame& frame, const cv::Rect& left_roi, std::string& error);
  /// True after a successful init().
  bool initialised() const { return initialised_; }
  /// Track both images of the next frame and triangulate. Throws std::logic_error before init() and
  /// std::invalid_argument for a frame that fails StereoFrame::validate().
  BaselineEstimate update(const StereoFrame& frame);

  /// The type running.
  BaselineType type() const { return type_; }
  /// The configuration.
  const BaselineConfig& config() const { return config_; }
  /// The right box init() started from (empty before init()).
  const cv::Rect& initialRightRoi() const { return initial_right_roi_; }

  /// Find `left_roi` (clipped to the image) in the right image by TM_CCOEFF_NORMED template matching along
  /// the same rows, over disparities 0..max_disparity (the right box lies left of the left one).
  static RightMatch matchRight(const StereoFrame& frame, const cv::Rect& left_roi, int max_disparity,
                               double min_score);

private:
  class ViewTracker;  ///< one image's tracker (hides the OpenCV tracker types)

  BaselineType type_;
  BaselineConfig config_;
  bool initialised_ = false;
  cv::Rect initial_right_roi_;
  std::unique_ptr<ViewTracker> left_, right_;
};

}  // namespace stereo_pf
