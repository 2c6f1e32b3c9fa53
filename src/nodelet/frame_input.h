// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Receiving: the four stereo topics through a synchroniser, and ~target_roi_topic. Runs on the nodelet's
// single-threaded queue and never waits: a complete set only gets its arrival stamped and goes into the frame
// slot (a set still waiting there is replaced and counted as overload), so the subscriber queues never overflow.
#pragma once

#include <memory>
#include <string>

#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/RegionOfInterest.h>

#include "frame_messages.h"
#include "nodelet_options.h"
#include "stereo_pf/ros/frame_slot.h"
#include "target_requests.h"
#include "tracker_status.h"

namespace stereo_pf
{
class FrameInput
{
public:
  FrameInput(const std::string& name, TargetRequests& requests, TrackerStatus& status)
    : name_(name), requests_(requests), status_(status)
  {
  }

  /// The synchroniser on the (still unsubscribed) filters; complete sets go into `slot`.
  void connect(const NodeletOptions& options, LatestSlot<FrameMessages>& slot);
  /// Subscribe the inputs (and ~target_roi_topic when `roi_topic` is not empty).
  void subscribe(ros::NodeHandle& nh, ros::NodeHandle& pnh, const NodeletOptions& options, const std::string& roi_topic);
  /// Unsubscribe everything (no callback runs after this returns).
  void shutdown();

  /// The ROI topic while it is still listened to, else "".
  std::string roiTopic() const { return roi_sub_ ? roi_sub_.getTopic() : std::string(); }
  /// A target was learned: stop listening to the ROI topic.
  void stopRoiTopic() { roi_sub_.shutdown(); }
  std::string leftTopic() const { return left_sub_.getTopic(); }
  std::string rightTopic() const { return right_sub_.getTopic(); }

private:
  using Image = sensor_msgs::Image;
  using CameraInfo = sensor_msgs::CameraInfo;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, Image, CameraInfo, CameraInfo>;
  using ApproxPolicy = message_filters::sync_policies::ApproximateTime<Image, Image, CameraInfo, CameraInfo>;

  /// A complete stereo set: into the slot (a set still waiting there is dropped as overload).
  void frameCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                     const sensor_msgs::CameraInfoConstPtr& left_info, const sensor_msgs::CameraInfoConstPtr& right_info);
  /// ExactTime gave up on a stamp.
  void unpairedCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                        const sensor_msgs::CameraInfoConstPtr& left_info,
                        const sensor_msgs::CameraInfoConstPtr& right_info);
  void roiTopicCallback(const sensor_msgs::RegionOfInterestConstPtr& roi);

  std::string name_;
  LatestSlot<FrameMessages>* slot_ = nullptr;
  TargetRequests& requests_;
  TrackerStatus& status_;
  std::shared_ptr<image_transport::ImageTransport> it_;
  image_transport::SubscriberFilter left_sub_, right_sub_;
  message_filters::Subscriber<CameraInfo> left_info_sub_, right_info_sub_;
  std::unique_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::unique_ptr<message_filters::Synchronizer<ApproxPolicy>> approx_sync_;
  ros::Subscriber roi_sub_;
};

}  // namespace stereo_pf
