// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The tracker nodelet's own parameters: structural, read once at start-up (docs/ros_runtime.md, config/tracker.yaml's
// "ROS runtime" section).
#pragma once

#include <string>
#include <vector>

#include <ros/node_handle.h>

#include "stereo_pf/ros/stereo_input.h"
#include "stereo_pf/ros/tracker_outputs.h"

namespace stereo_pf
{
struct NodeletOptions
{
  bool approximate_sync = false;     ///< ApproximateTime instead of ExactTime
  int queue_size = 5;                ///< per input topic and for the synchroniser
  StereoInputOptions input;          ///< images_rectified, max_stamp_difference
  bool publish_tf = true;
  std::string object_frame;          ///< child frame of the TF
  std::string fallback_frame;        ///< frame_id when the images have none
  std::string camera_parent_frame;   ///< when set: publish parent -> camera optical frame (static)
  std::string target_file;           ///< start-up target; default path of save/load_target
  std::vector<int> target_roi;       ///< start-up target region of the first frame (empty: none)
  double set_target_timeout = 2.0;   ///< how long set_target waits for a frame, seconds
  bool publish_when_lost = false;    ///< repeat the last given estimate whenever none is given (marked)
  std::string roi_topic;             ///< ~target_roi_topic (empty: none)
  MarkerOptions markers;
  double diagnostic_period = 1.0;    ///< s

  /// Read from the private namespace; out-of-range values are brought into range.
  static NodeletOptions read(const ros::NodeHandle& pnh);
};

}  // namespace stereo_pf
