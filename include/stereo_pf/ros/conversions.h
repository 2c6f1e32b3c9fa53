// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// ROS message <-> engine conversions: calibration from camera_info, images to 8-bit BGR/mono, rectification.
#pragma once

#include <string>
#include <vector>

#include <image_geometry/stereo_camera_model.h>
#include <opencv2/core.hpp>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// What is wrong with one camera_info on its own, or "" when it is usable: no image size, NaN or infinity in
/// K, D, R or P, no calibration (P all zero), a focal length in P (or, unless `rectified`, in K) that is not
/// positive, an R that is not a rotation. `side` ("left", "right") names it. The message says what to do.
std::string checkCameraInfo(const sensor_msgs::CameraInfo& info, const std::string& side, bool rectified);
/// What is wrong with a pair of camera_infos that each passed checkCameraInfo, or "": sizes that differ,
/// rectified focal lengths or principal-point rows that differ (not a rectified stereo pair), a baseline that
/// is zero or of the wrong sign (left and right swapped).
std::string checkCameraInfoPair(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right);
/// What is odd about a usable pair but does not stop tracking, one sentence each: frame_ids that differ, K all
/// zero while the images are rectified (K unused), principal-point columns that differ.
std::vector<std::string> cameraInfoNotes(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right,
                                         bool rectified);

/// Turns a left/right camera_info pair into the engine's rectified StereoGeometry and rectifies raw
/// images with maps built once per calibration (image_geometry caches them).
class StereoCalibration
{
public:
  /// (Re)load from camera_info. Returns false with `error` explaining what is wrong (zero focal length,
  /// zero/NaN baseline, size mismatch, missing P, ...). Cheap when the messages did not change. A rejected pair
  /// leaves nothing behind: the next good pair loads whatever came before.
  bool update(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right, std::string& error);
  /// True after a successful update().
  bool valid() const { return valid_; }
  /// The rectified geometry.
  const StereoGeometry& geometry() const { return geometry_; }
  /// Rectify one raw image of `view` into `out` (no-op share when the calibration has no distortion and
  /// no rotation, i.e. the images are already rectified).
  void rectify(View view, const cv::Mat& raw, cv::Mat& out) const;
  /// True when rectify() is the identity.
  bool identity() const { return identity_; }

private:
  image_geometry::StereoCameraModel model_;
  sensor_msgs::CameraInfo last_left_, last_right_;
  StereoGeometry geometry_;
  bool valid_ = false;
  bool identity_ = true;
};

/// View `msg` as an 8-bit BGR or mono cv::Mat, sharing the message's data when it already is one
/// (bgr8, mono8) and converting otherwise (rgb8, bgra8, rgba8, bayer_*, mono16). `keep_alive` holds what
/// the Mat points into. Returns false with `error` for unsupported encodings or inconsistent sizes.
bool toEngineImage(const sensor_msgs::ImageConstPtr& msg, cv::Mat& out, std::shared_ptr<const void>& keep_alive,
                   std::string& error);

}  // namespace stereo_pf
