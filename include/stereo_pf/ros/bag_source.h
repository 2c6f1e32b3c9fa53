// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Reading synchronised stereo frames (and optional ground truth) from a bag, without a roscore.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/ros/conversions.h"

namespace stereo_pf
{
/// Topic names (camera1394stereo's by default, plus the ground truth written by make_scene).
struct BagTopics
{
  std::string left_image = "stereo_camera/left/image_raw";
  std::string right_image = "stereo_camera/right/image_raw";
  std::string left_info = "stereo_camera/left/camera_info";
  std::string right_info = "stereo_camera/right/camera_info";
  std::string truth = "ground_truth/target";            ///< geometry_msgs/PointStamped (optional)
  std::string truth_roi = "ground_truth/target_roi";    ///< sensor_msgs/RegionOfInterest (optional)
  std::string truth_visible = "ground_truth/target_visible";  ///< std_msgs/Bool (optional)
};

/// One stereo frame from the bag with whatever ground truth shares its stamp.
struct BagFrame
{
  int index = 0;                  ///< 0-based index among the frames delivered
  StereoFrame frame;              ///< rectified images (sharing the messages' data where possible)
  std::shared_ptr<const void> keep_left, keep_right;  ///< own the image data
  bool has_truth = false;
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();
  bool has_roi = false;
  cv::Rect roi;                   ///< target bounding box in the left image
  bool has_visible = false;
  bool visible = true;
};

class BagSource
{
public:
  /// Open `path`. Throws std::runtime_error when the bag cannot be opened or an image/camera_info topic is
  /// missing (the message lists the topics the bag has). With `assume_rectified` images are used as they
  /// are (e.g. stereo_image_proc's image_rect_color); otherwise raw images are rectified from camera_info.
  BagSource(const std::string& path, const BagTopics& topics, bool assume_rectified);
  ~BagSource();

  /// The next usable frame; false at the end of the bag. Unusable pairs (unsupported encoding, size
  /// mismatch, invalid calibration, a left or right image without its partner) are skipped and counted.
  bool next(BagFrame& out);
  /// Frames skipped so far.
  int dropped() const { return dropped_; }
  /// Why frames were skipped: reason -> count.
  const std::map<std::string, int>& dropReasons() const { return drop_reasons_; }
  /// True when the bag has a ground-truth topic.
  bool hasTruth() const { return !truth_.empty(); }

private:
  void drop(const std::string& reason, int count = 1);
  bool assemble(uint64_t stamp, BagFrame& out);

  rosbag::Bag bag_;
  BagTopics topics_;
  bool assume_rectified_;
  std::unique_ptr<rosbag::View> view_;
  rosbag::View::iterator it_;
  std::map<uint64_t, sensor_msgs::ImageConstPtr> left_, right_;
  sensor_msgs::CameraInfoConstPtr left_info_, right_info_;
  StereoCalibration calibration_;
  std::map<uint64_t, Eigen::Vector3d> truth_;
  std::map<uint64_t, cv::Rect> roi_;
  std::map<uint64_t, bool> visible_;
  int delivered_ = 0;
  int dropped_ = 0;
  std::map<std::string, int> drop_reasons_;
};

}  // namespace stereo_pf
