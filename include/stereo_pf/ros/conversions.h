// ROS message <-> engine conversions: calibration from camera_info, images to 8-bit BGR/mono, rectification.
#pragma once

#include <string>

#include <image_geometry/stereo_camera_model.h>
#include <opencv2/core.hpp>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// Turns a left/right camera_info pair into the engine's rectified StereoGeometry and rectifies raw
/// images with maps built once per calibration (image_geometry caches them).
class StereoCalibration
{
public:
  /// (Re)load from camera_info. Returns false with `error` explaining what is wrong (zero focal length,
  /// zero/NaN baseline, size mismatch, missing P, ...). Cheap when the messages did not change.
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
