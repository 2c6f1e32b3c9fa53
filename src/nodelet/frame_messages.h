// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// One synchronised stereo set as the nodelet received it (the pieces of the nodelet pass it along).
#pragma once

#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

namespace stereo_pf
{
/// The four messages of one stereo frame and when the set was complete.
struct FrameMessages
{
  sensor_msgs::ImageConstPtr left, right;
  sensor_msgs::CameraInfoConstPtr left_info, right_info;
  ros::WallTime arrival;  ///< when the set was complete (the synchroniser's callback)
};

}  // namespace stereo_pf
