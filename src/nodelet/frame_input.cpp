// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Receiving on the single-threaded queue: only hand the set over, never wait.
#include "frame_input.h"

#include <cstdio>

#include <boost/bind/bind.hpp>

namespace stereo_pf
{
using namespace boost::placeholders;

void FrameInput::connect(const NodeletOptions& options, LatestSlot<FrameMessages>& slot)
{
  slot_ = &slot;
  if (options.approximate_sync)
  {
    approx_sync_ = std::make_unique<message_filters::Synchronizer<ApproxPolicy>>(
        ApproxPolicy(options.queue_size), left_sub_, right_sub_, left_info_sub_, right_info_sub_);
    approx_sync_->registerCallback(boost::bind(&FrameInput::frameCallback, this, _1, _2, _3, _4));
  }
  else
  {
    exact_sync_ = std::make_unique<message_filters::Synchronizer<ExactPolicy>>(
        ExactPolicy(options.queue_size), left_sub_, right_sub_, left_info_sub_, right_info_sub_);
    exact_sync_->registerCallback(boost::bind(&FrameInput::frameCallback, this, _1, _2, _3, _4));
    exact_sync_->registerDropCallback(boost::bind(&FrameInput::unpairedCallback, this, _1, _2, _3, _4));
  }
}

void FrameInput::subscribe(ros::NodeHandle& nh, ros::NodeHandle& pnh, const NodeletOptions& options,
                           const std::string& roi_topic)
{
  // The estimate is always computed, so the camera is subscribed at once (only debug images are lazy).
  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  const int queue_size = options.queue_size;
  const image_transport::TransportHints hints("raw", ros::TransportHints().tcpNoDelay(), pnh);
  left_sub_.subscribe(*it_, "stereo_camera/left/image_raw", queue_size, hints);
  right_sub_.subscribe(*it_, "stereo_camera/right/image_raw", queue_size, hints);
  left_info_sub_.subscribe(nh, "stereo_camera/left/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  right_info_sub_.subscribe(nh, "stereo_camera/right/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  if (!roi_topic.empty())
    roi_sub_ = nh.subscribe(roi_topic, 1, &FrameInput::roiTopicCallback, this);
}

void FrameInput::shutdown()
{
  left_sub_.unsubscribe();
  right_sub_.unsubscribe();
  left_info_sub_.unsubscribe();
  right_info_sub_.unsubscribe();
  roi_sub_.shutdown();
}

void FrameInput::frameCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                               const sensor_msgs::CameraInfoConstPtr& left_info,
                               const sensor_msgs::CameraInfoConstPtr& right_info)
{
  const FrameMessages set{ left, right, left_info, right_info, ros::WallTime::now() };
  const double processing = status_.frameReceived(set.arrival);  // the load now, not the usual one
  requests_.frameArrived(set);
  if (slot_->put(set))
  {
    char why[300];
    std::snprintf(why, sizeof(why),
                  "the tracker is slower than the camera (the last frame took %.1f ms): a frame waiting to be tracked was "
                  "replaced by a newer one; use fewer particles (~engine/particles) or fewer or cheaper cues, or "
                  "lower the camera's frame rate",
                  processing);
    status_.drop(DropReason::Overload, why);
  }
}

void FrameInput::unpairedCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                                  const sensor_msgs::CameraInfoConstPtr& left_info,
                                  const sensor_msgs::CameraInfoConstPtr& right_info)
{
  // Some of the four messages never arrived (or arrived with another stamp).
  std::string missing;
  if (!left)
    missing += " left image";
  if (!right)
    missing += " right image";
  if (!left_info)
    missing += " left camera_info";
  if (!right_info)
    missing += " right camera_info";
  const bool paired_before = status_.unpaired();
  // One camera frame is one left message with an image: a right message whose stamp is skewed leaves a second,
  // right-only set, and a camera_info whose stamp is skewed a set of camera_info alone; neither is a second
  // dropped frame (each is counted as an unpaired set only).
  if ((!left && !left_info) || (!left && !right))
    return;
  status_.drop(DropReason::OutOfSync,
               "a stereo set never completed (missing:" + missing + ")" +
                   (paired_before ? std::string("; a message was lost or came with another stamp; if this repeats, "
                                                "raise ~queue_size or check the driver") :
                                    std::string("; no set has been complete yet: if the cameras are not hardware-"
                                                "synchronised (left and right stamps differ), set ~approximate_sync: "
                                                "true")));
}

void FrameInput::roiTopicCallback(const sensor_msgs::RegionOfInterestConstPtr& roi)
{
  requests_.topicRoi(cv::Rect(static_cast<int>(roi->x_offset), static_cast<int>(roi->y_offset),
                              static_cast<int>(roi->width), static_cast<int>(roi->height)),
                     ros::WallTime::now());
}

}  // namespace stereo_pf
