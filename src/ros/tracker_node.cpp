// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// tracker_node: the TrackerNodelet in a process of its own (same topics, parameters and services under ~).
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv)
{
  ros::init(argc, argv, "stereo_pf_tracker");
  nodelet::Loader loader(false);  // no manager ROS API: this process hosts exactly one nodelet
  const nodelet::M_string remappings(ros::names::getRemappings());
  if (!loader.load(ros::this_node::getName(), "stereo_pf/TrackerNodelet", remappings, nodelet::V_string()))
    return 1;  // pluginlib has logged why (is the package on ROS_PACKAGE_PATH?)
  ros::spin();
  return 0;
}
