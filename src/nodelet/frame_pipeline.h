// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The frame thread: takes the newest stereo set from the slot, turns it into a rectified StereoFrame, applies what
// was queued for it (a target request, a trail to clear), runs the engine's step() (which applies what was queued
// for the engine: reconfigured values, a reset) and
// publishes the estimate, ~status, the particles, markers and the debug images (those only while subscribed).
// Only this thread runs the engine; it holds EngineHost::mutex for each whole step.
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include "engine_host.h"
#include "frame_input.h"
#include "frame_messages.h"
#include "nodelet_options.h"
#include "stereo_pf/ros/debug_drawing.h"
#include "stereo_pf/ros/frame_slot.h"
#include "stereo_pf/ros/stereo_input.h"
#include "stereo_pf/ros/tracker_outputs.h"
#include "target_requests.h"
#include "tracker_status.h"

namespace stereo_pf
{
class FramePipeline
{
public:
  FramePipeline(const std::string& name, const NodeletOptions& options, EngineHost& host, TrackerStatus& status,
                TargetRequests& requests, FrameInput& input);
  ~FramePipeline();

  /// The slot the receiving side puts sets into.
  LatestSlot<FrameMessages>& slot() { return slot_; }
  /// Advertise the outputs under `pnh`.
  void advertise(ros::NodeHandle& pnh);
  /// The topic of the estimate (~target).
  std::string targetTopic() const { return target_pub_.getTopic(); }
  /// Start the frame thread.
  void start();
  /// Stop it: the frame in hand is finished, nothing waiting is tracked.
  void stop();
  /// Forget the trail and the last tracked estimate before the next frame (thread-safe: reset, load_target).
  void clearTrail() { clear_trail_ = true; }

private:
  void workerLoop();
  /// Track one set (workerLoop catches whatever it throws).
  void processFrame(const FrameMessages& set);
  /// Apply a queued target request and trail clearing (host mutex held).
  void applyPending(const StereoFrame& frame);
  /// Learn a queued target request from `frame` or from the request's own frame, and answer it.
  void learnRequestedTarget(const RoiRequest& request, const StereoFrame& frame);
  /// Run one step; false (frame counted as dropped) when the engine throws.
  bool step(const StereoFrame& frame, FrameResult& result);
  void publish(const std_msgs::Header& header, const StereoFrame& frame, const FrameResult& result,
               const ros::WallTime& arrival, const ros::WallTime& start);
  /// Warn once about each calibration oddity the input reports (StereoInput::notes()).
  void sayNotes(const std::vector<std::string>& notes);

  std::string name_;
  const NodeletOptions& options_;
  EngineHost& host_;
  TrackerStatus& status_;
  TargetRequests& requests_;
  FrameInput& input_;

  LatestSlot<FrameMessages> slot_;
  std::thread worker_;
  std::atomic<bool> clear_trail_{ false };

  StereoInput stereo_input_;
  StereoInput source_input_;                   ///< assembles a target request's own frame (own buffers)
  StampOrder stamp_order_;                     ///< late and repeated frames are dropped; time gone back restarts
  std::optional<StateEstimate> last_tracked_;  ///< for ~publish_when_lost
  std::set<std::string> said_notes_;           ///< calibration notes already warned about
  ros::WallTime first_untargeted_;             ///< first frame without a target (zero: has one)
  DebugDrawing drawing_;
  EstimateTrail trail_;
  cv::Mat debug_image_;
  std::vector<Eigen::Vector3f> cloud_points_;
  std::vector<float> cloud_weights_;
  Eigen::MatrixX3d cloud_raw_;
  Eigen::VectorXd cloud_raw_weights_;

  std::shared_ptr<image_transport::ImageTransport> private_it_;
  ros::Publisher target_pub_, pose_pub_, status_pub_, particles_pub_, markers_pub_;
  image_transport::Publisher left_debug_pub_, right_debug_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
  std::string static_child_;  ///< camera frame the static transform was sent for
};

}  // namespace stereo_pf
