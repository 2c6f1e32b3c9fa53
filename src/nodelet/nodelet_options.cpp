// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "nodelet_options.h"

#include <algorithm>

namespace stereo_pf
{
NodeletOptions NodeletOptions::read(const ros::NodeHandle& pnh)
{
  NodeletOptions o;
  pnh.param("approximate_sync", o.approximate_sync, false);
  pnh.param("queue_size", o.queue_size, 5);
  pnh.param("images_rectified", o.input.images_rectified, false);
  pnh.param("max_stamp_difference", o.input.max_stamp_difference, o.approximate_sync ? 0.005 : 0.0);
  pnh.param("publish_tf", o.publish_tf, true);
  pnh.param<std::string>("object_frame", o.object_frame, "tracked_object");
  pnh.param<std::string>("camera_frame", o.fallback_frame, "stereo_camera_optical_frame");
  pnh.param<std::string>("camera_parent_frame", o.camera_parent_frame, "");
  pnh.param("set_target_timeout", o.set_target_timeout, 2.0);
  pnh.param("marker_radius", o.markers.radius, 0.035);
  pnh.param("marker_sigma_scale", o.markers.sigma_scale, 2.0);
  pnh.param("trajectory_length", o.markers.trajectory_length, 90);
  pnh.param("publish_when_lost", o.publish_when_lost, false);
  pnh.param<std::string>("target_roi_topic", o.roi_topic, "");
  pnh.param("diagnostic_period", o.diagnostic_period, 1.0);
  pnh.param<std::string>("target_file", o.target_file, "");
  pnh.param("target_roi", o.target_roi, std::vector<int>());
  o.queue_size = std::max(o.queue_size, 1);
  o.input.max_stamp_difference = std::max(o.input.max_stamp_difference, 0.0);
  o.markers.trajectory_length = std::max(o.markers.trajectory_length, 0);
  return o;
}

}  // namespace stereo_pf
