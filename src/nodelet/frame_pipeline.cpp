// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The frame thread (see the header).
#include "frame_pipeline.h"

#include <algorithm>
#include <cmath>

#include <boost/make_shared.hpp>
#include <cv_bridge/cv_bridge.h>

#include "stereo_pf/TrackStatus.h"

namespace stereo_pf
{
FramePipeline::FramePipeline(const std::string& name, const NodeletOptions& options, EngineHost& host,
                             TrackerStatus& status, TargetRequests& requests, FrameInput& input)
  : name_(name)
  , options_(options)
  , host_(host)
  , status_(status)
  , requests_(requests)
  , input_(input)
  , stereo_input_(options.input)
  , source_input_(options.input)
  , trail_(options.markers.trajectory_length)
{
}

FramePipeline::~FramePipeline()
{
  stop();
}

void FramePipeline::advertise(ros::NodeHandle& pnh)
{
  private_it_ = std::make_shared<image_transport::ImageTransport>(pnh);
  target_pub_ = pnh.advertise<geometry_msgs::PointStamped>("target", 10);
  pose_pub_ = pnh.advertise<geometry_msgs::PoseWithCovarianceStamped>("target_pose", 10);
  status_pub_ = pnh.advertise<TrackStatus>("status", 10);
  particles_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("particles", 2);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 2);
  left_debug_pub_ = private_it_->advertise("left/debug_image", 1);
  right_debug_pub_ = private_it_->advertise("right/debug_image", 1);
  if (options_.publish_tf)
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  if (!options_.camera_parent_frame.empty())
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
}

void FramePipeline::start()
{
  worker_ = std::thread(&FramePipeline::workerLoop, this);
}

void FramePipeline::stop()
{
  slot_.close();  // the worker finishes its frame and stops
  if (worker_.joinable())
    worker_.join();
}

void FramePipeline::workerLoop()
{
  FrameMessages set;
  while (slot_.take(set))
  {
    try
    {
      processFrame(set);
    }
    catch (const std::exception& e)  // conversion, rectification or publishing: never let it end the thread
    {
      status_.drop(DropReason::ProcessingError, e.what());
    }
  }
}

void FramePipeline::processFrame(const FrameMessages& set)
{
  const ros::WallTime start = ros::WallTime::now();
  StereoFrame frame;
  DropReason reason = DropReason::BadImage;
  std::string why;
  if (!stereo_input_.assemble(set.left, set.right, set.left_info, set.right_info, frame, reason, why))
  {
    status_.drop(reason, why);
    return;
  }
  sayNotes(stereo_input_.notes());

  std::lock_guard<std::mutex> engine_lock(host_.mutex);
  applyPending(frame);
  const bool has_target = host_.engine().hasTarget();
  status_.setHasTarget(has_target);
  if (!has_target)
  {
    // At start-up the target usually comes a moment later (a ROI topic, a set_target call): be quiet for a
    // few seconds, then say what the tracker is waiting for.
    if (first_untargeted_.isZero())
      first_untargeted_ = start;
    const bool waited = (start - first_untargeted_).toSec() > 5.0;
    const std::string roi_topic = input_.roiTopic();
    status_.drop(DropReason::NoTarget,
                 !roi_topic.empty() ? "no target yet: waiting for a sensor_msgs/RegionOfInterest on '" + roi_topic +
                                          "' (~target_roi_topic); or call ~set_target with a region of the left image" :
                                      "no target yet: call ~set_target with a region of the left image, or set "
                                      "~target_file, ~target_roi or ~target_roi_topic",
                 waited);
    return;
  }
  first_untargeted_ = ros::WallTime();
  std::string late;
  switch (stamp_order_.check(frame.stamp, late))
  {
    case StampOrder::Verdict::Drop:
      status_.drop(DropReason::OutOfOrder, late);
      return;
    case StampOrder::Verdict::Restart:
      ROS_WARN_THROTTLE_NAMED(2.0, name_, "%s", late.c_str());
      host_.engine().reset();
      trail_.clear();
      last_tracked_.reset();
      break;
    case StampOrder::Verdict::Accept:
      break;
  }
  FrameResult result;
  if (!step(frame, result))
    return;

  std_msgs::Header header = set.left->header;
  if (header.frame_id.empty())
    header.frame_id = options_.fallback_frame;
  if (static_broadcaster_ && header.frame_id != static_child_)
  {
    // Place the optical frame (z forward, y down) under a body-style parent (x forward, z up) for rviz,
    // when nothing else (robot description, driver) does.
    geometry_msgs::TransformStamped t;
    t.header.stamp = header.stamp;
    t.header.frame_id = options_.camera_parent_frame;
    t.child_frame_id = header.frame_id;
    t.transform.rotation.x = -0.5;
    t.transform.rotation.y = 0.5;
    t.transform.rotation.z = -0.5;
    t.transform.rotation.w = 0.5;
    static_broadcaster_->sendTransform(t);
    static_child_ = header.frame_id;
  }
  publish(header, frame, result, set.arrival, start);
}

void FramePipeline::sayNotes(const std::vector<std::string>& notes)
{
  for (const std::string& note : notes)
    if (said_notes_.insert(note).second)
      ROS_WARN_NAMED(name_, "camera_info: %s", note.c_str());
}

void FramePipeline::applyPending(const StereoFrame& frame)
{
  const std::optional<RoiRequest> roi = requests_.take();
  if (clear_trail_.exchange(false))
  {
    trail_.clear();
    last_tracked_.reset();
  }
  if (roi)
    learnRequestedTarget(*roi, frame);
}

void FramePipeline::learnRequestedTarget(const RoiRequest& request, const StereoFrame& frame)
{
  FilterEngine& engine = host_.engine();
  std::string error;
  bool ok = false;
  double stamp = frame.stamp;
  if (request.source)
  {
    // The request's own frame (a ROI topic's): assembled with separate buffers, so `frame` stays intact.
    const FrameMessages& s = *request.source;
    StereoFrame source;
    DropReason reason = DropReason::BadImage;
    ok = source_input_.assemble(s.left, s.right, s.left_info, s.right_info, source, reason, error) &&
         engine.learnTarget(source, request.roi, error);
    stamp = source.stamp;
  }
  else
    ok = engine.learnTarget(frame, request.roi, error);
  const std::string& warning = engine.acquisition().warning;  // of this box when ok (learnTarget set it)
  if (ok)
  {
    engine.reset();  // a new target: start afresh (acquired at its box when engine/acquire, else searched for)
    trail_.clear();
    last_tracked_.reset();
    ROS_INFO_NAMED(name_, "target learned from %dx%d at (%d, %d) of the left image of the frame stamped %.3f",
                 request.roi.width, request.roi.height, request.roi.x, request.roi.y, stamp);
    if (!warning.empty())
      ROS_WARN_NAMED(name_, "%s", warning.c_str());
    input_.stopRoiTopic();
  }
  else
    ROS_ERROR_NAMED(name_, "cannot learn the target (the previous one, if any, is kept): %s", error.c_str());
  requests_.answer(request.id, ok,
                   ok ? "target learned from the frame stamped " + std::to_string(stamp) +
                            (warning.empty() ? std::string() : "; warning: " + warning) :
                        error + " (the previous target, if any, is kept)");
}

bool FramePipeline::step(const StereoFrame& frame, FrameResult& result)
{
  try
  {
    result = host_.engine().step(frame);
    return true;
  }
  catch (const std::exception& e)  // never let an exception reach the nodelet manager
  {
    status_.drop(DropReason::ProcessingError, e.what());
    return false;
  }
}

void FramePipeline::publish(const std_msgs::Header& header, const StereoFrame& frame, const FrameResult& result,
                             const ros::WallTime& arrival, const ros::WallTime& start)
{
  const StateEstimate& e = result.estimate;
  const bool tracking = result.published();
  if (tracking)
  {
    // The target first: it is what latency is measured on.
    target_pub_.publish(boost::make_shared<geometry_msgs::PointStamped>(toPointStamped(header, e)));
    pose_pub_.publish(boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>(toPose(header, e)));
    if (tf_broadcaster_)
      tf_broadcaster_->sendTransform(toTransform(header, options_.object_frame, e));
    last_tracked_ = e;
  }
  else if (options_.publish_when_lost && last_tracked_)
  {
    // The last tracked position, marked: its pose covariance says "unknown" and ~status says estimate_valid
    // false. No TF: a transform cannot be marked.
    StateEstimate held = *last_tracked_;
    held.covariance = Eigen::Matrix3d::Identity() * 1e6;
    target_pub_.publish(boost::make_shared<geometry_msgs::PointStamped>(toPointStamped(header, held)));
    pose_pub_.publish(boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>(toPose(header, held)));
  }

  trail_.update(header.stamp.toSec(), e.position, tracking);  // restarts where no estimate is given

  const EngineConfig& config = host_.engine().config();
  const std::string message = describeTrack(result, config, host_.engine().viewingVolume());
  auto status = boost::make_shared<TrackStatus>();
  status->header = header;
  status->state = result.state == TrackState::Tracking ? TrackStatus::TRACKING :
                  result.state == TrackState::Lost     ? TrackStatus::LOST :
                                                         TrackStatus::SEARCHING;
  status->state_name = toString(result.state);
  status->estimate_valid = tracking;
  status->support = toString(result.support);
  status->message = message;
  status->evidence = result.evidence;
  status->background = result.background;
  status->ess = result.ess;
  status->frames_in_state = static_cast<uint32_t>(std::max(result.state_frames, 0));
  const ros::WallTime now = ros::WallTime::now();
  const double latency_ms = (now - arrival).toSec() * 1e3;
  const double age_ms = (ros::Time::now() - header.stamp).toSec() * 1e3;
  status->latency = latency_ms * 1e-3;
  status->processing_time = (now - start).toSec();
  status_.frameTracked(tracking, *status);  // before ~status goes out: a client that saw it finds it counted
  status_pub_.publish(status);

  const bool want_markers = markers_pub_.getNumSubscribers() > 0, want_cloud = particles_pub_.getNumSubscribers() > 0;
  if (want_markers || want_cloud)
  {
    // The set as weighed, before the step's resampling left copies of a few particles, all weighing 1/N.
    const FilterEngine& engine = host_.engine();
    engine.stateModel().cloud(frame.geometry, engine.weightedSets(), cloud_raw_, cloud_raw_weights_);
    mergeDuplicates(cloud_raw_, cloud_raw_weights_, cloud_points_, cloud_weights_);
  }
  if (want_markers)  // the particles too: rviz then draws them in the same update as the estimate
    markers_pub_.publish(boost::make_shared<visualization_msgs::MarkerArray>(
        toMarkers(header, result, trail_, options_.markers, &cloud_points_, &cloud_weights_)));
  if (want_cloud)
  {
    auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
    toCloud(header, cloud_points_, cloud_weights_, *cloud);
    particles_pub_.publish(cloud);
  }

  // Debug images: drawn only while someone is subscribed.
  int drawn = 0;
  const std::pair<image_transport::Publisher*, View> debug[2] = { { &left_debug_pub_, View::Left },
                                                                  { &right_debug_pub_, View::Right } };
  for (const auto& [pub, view] : debug)
  {
    if (pub->getNumSubscribers() == 0)
      continue;
    drawing_.draw(frame, view, host_.engine(), result, debug_image_);
    auto msg = boost::make_shared<sensor_msgs::Image>();
    cv_bridge::CvImage(header, "bgr8", debug_image_).toImageMsg(*msg);
    pub->publish(msg);
    ++drawn;
  }

  const double processing_ms = (ros::WallTime::now() - start).toSec() * 1e3;
  status_.framePublished(processing_ms, latency_ms, age_ms, drawn, result, message);
}

}  // namespace stereo_pf
