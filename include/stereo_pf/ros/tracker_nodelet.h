// The tracker nodelet: camera1394stereo-style stereo topics in, 3D estimate, track status, particles, markers,
// debug images, TF and diagnostics out. See docs/ros_runtime.md for topics, parameters and services.
//
// Threading model:
//  - The synchronised image/camera_info sets and the ~target_roi_topic arrive on the nodelet's single-threaded
//    queue. That callback only stamps the set's arrival and puts it into a one-place slot (LatestSlot): it
//    never waits, so the subscriber queues do not overflow under load. A set still waiting in the slot when
//    the next one comes is replaced and counted as dropped (overload): the tracker always works on the
//    newest frame, and the latency it reports (arrival -> publish) includes the wait.
//  - One worker thread (the frame thread) takes sets from the slot, runs the engine's step() and publishes.
//    Only it runs the engine and writes the Parameters tree the plugins read.
//  - Services, dynamic_reconfigure and the diagnostics timer run on the multi-threaded queue. They never
//    touch the engine mid-step: a reconfigure value is checked at once on a copy of the configuration in force
//    (`accepted_`, under `pending_mutex_`; a rejected one changes nothing and the server is answered with the
//    values in force), then queued with set_target regions and applied by the frame thread before its next
//    step(); save/load target take `engine_mutex_`, which the frame thread holds from applying the queued
//    changes to the end of publishing; reset uses the engine's own thread-safe reset().
//  - Statistics for the diagnostics and ~status are guarded by `stats_mutex_`.
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/RegionOfInterest.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include "stereo_pf/SetTarget.h"
#include "stereo_pf/TargetFile.h"
#include "stereo_pf/TrackStatus.h"
#include "stereo_pf/TrackerEngineConfig.h"
#include "stereo_pf/TrackerObservationConfig.h"
#include "stereo_pf/TrackerStateModelConfig.h"
#include "stereo_pf/ros/debug_drawing.h"
#include "stereo_pf/ros/frame_slot.h"
#include "stereo_pf/ros/plugin_loader.h"
#include "stereo_pf/ros/stereo_input.h"
#include "stereo_pf/ros/tracker_outputs.h"

namespace stereo_pf
{
class TrackerNodelet : public nodelet::Nodelet
{
public:
  TrackerNodelet() = default;
  ~TrackerNodelet() override;

private:
  using Image = sensor_msgs::Image;
  using CameraInfo = sensor_msgs::CameraInfo;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, Image, CameraInfo, CameraInfo>;
  using ApproxPolicy = message_filters::sync_policies::ApproximateTime<Image, Image, CameraInfo, CameraInfo>;
  using ObservationServer = dynamic_reconfigure::Server<TrackerObservationConfig>;

  /// One synchronised stereo set as it arrived.
  struct FrameMessages
  {
    sensor_msgs::ImageConstPtr left, right;
    sensor_msgs::CameraInfoConstPtr left_info, right_info;
    ros::WallTime arrival;  ///< when the set was complete (the synchroniser's callback)
  };
  /// One queued target request (answered by the frame thread).
  struct RoiRequest
  {
    uint64_t id = 0;
    cv::Rect roi;
    /// The frame to learn from (a ROI topic's own frame); empty: the next frame tracked (set_target).
    std::optional<FrameMessages> source;
  };
  /// A ROI from ~target_roi_topic waiting for the set after it, to decide which frame it belongs to.
  struct TopicRoi
  {
    cv::Rect roi;
    ros::WallTime arrival;
    std::optional<FrameMessages> before;  ///< the set that arrived last before it
  };

  void onInit() override;
  /// Build the Tracker from the private parameters and read the start-up target; false (with the
  /// explanation logged and shown in the diagnostics) when the configuration is unusable.
  bool createTracker(const ros::NodeHandle& pnh);
  void setupReconfigure(const ros::NodeHandle& mt_pnh);

  // --- receiving (single-threaded queue) ------------------------------------------------------------
  /// A complete stereo set: into the slot (a set still waiting there is dropped as overload).
  void frameCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                     const sensor_msgs::CameraInfoConstPtr& left_info, const sensor_msgs::CameraInfoConstPtr& right_info);
  void unpairedCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                        const sensor_msgs::CameraInfoConstPtr& left_info,
                        const sensor_msgs::CameraInfoConstPtr& right_info);
  void roiTopicCallback(const sensor_msgs::RegionOfInterestConstPtr& roi);

  // --- frame thread (the worker) ---------------------------------------------------------------------
  void workerLoop();
  /// Track one set (workerLoop catches whatever it throws).
  void processFrame(const FrameMessages& set);
  /// Apply queued reconfigure values and target requests (engine_mutex_ held).
  void applyPending(const StereoFrame& frame);
  /// Learn a queued target request from `frame` or from the request's own frame, and answer it.
  void learnRequestedTarget(const RoiRequest& request, const StereoFrame& frame);
  /// Run one step; false (frame counted as dropped) when the engine throws.
  bool step(const StereoFrame& frame, FrameResult& result);
  void publish(const std_msgs::Header& header, const StereoFrame& frame, const FrameResult& result,
               const ros::WallTime& arrival, const ros::WallTime& start);
  /// Count a dropped frame and say why (throttled per reason); `warn` false counts it silently.
  void drop(DropReason reason, const std::string& why, bool warn = true);
  /// Warn once about each calibration oddity the input reports (StereoInput::notes()).
  void sayNotes(const std::vector<std::string>& notes);

  // --- other threads --------------------------------------------------------------------------------
  bool setTargetService(SetTarget::Request& req, SetTarget::Response& res);
  bool saveTargetService(TargetFile::Request& req, TargetFile::Response& res);
  bool loadTargetService(TargetFile::Request& req, TargetFile::Response& res);
  bool resetService(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);
  void engineReconfigure(TrackerEngineConfig& config, uint32_t level);
  void stateReconfigure(TrackerStateModelConfig& config, uint32_t level);
  void observationReconfigure(const std::string& name, TrackerObservationConfig& config, uint32_t level);
  /// The reconfigure values in force (from `accepted_`, pending_mutex_ held).
  TrackerEngineConfig engineInForce() const;
  TrackerStateModelConfig stateInForce() const;
  TrackerObservationConfig observationInForce(const std::string& name) const;
  /// Check `changes` (tree key -> value) of the server `server` ("engine", "state_model" or a cue's name) on
  /// a copy of the configuration in force: the engine config parsed, the changed plugin constructed. On success
  /// they become the configuration in force and are queued for the frame thread; otherwise nothing changes and
  /// `error` says why (pending_mutex_ held).
  bool acceptReconfigure(const std::string& server, const std::map<std::string, std::string>& changes,
                         std::string& error);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  // --- configuration (read once) ----------------------------------------------------------------------
  std::string init_error_;          ///< why the tracker could not be built (empty when fine)
  std::string unknown_parameters_;  ///< the parameters nothing reads, with the nearest known key (for diagnostics)
  bool publish_tf_ = true;
  std::string object_frame_;        ///< child frame of the TF
  std::string fallback_frame_;      ///< frame_id when the images have none
  std::string camera_parent_frame_; ///< when set: publish parent -> camera optical frame (static)
  std::string target_file_;         ///< default path of save/load_target
  double set_target_timeout_ = 2.0; ///< how long set_target waits for a frame, seconds
  bool publish_when_lost_ = false;  ///< repeat the last tracked estimate while not tracking (marked)
  std::string roi_topic_;           ///< ~target_roi_topic (empty: none)
  MarkerOptions marker_options_;

  // --- the engine (ClassLoaders inside Tracker outlive the plugins) -------------------------------------
  Parameters params_;               ///< the whole private tree; written by the frame thread only
  std::unique_ptr<Tracker> tracker_;
  std::mutex engine_mutex_;
  std::unique_ptr<StereoInput> input_;
  std::unique_ptr<StereoInput> source_input_;  ///< assembles a target request's own frame (own buffers)
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

  // --- queued requests (pending_mutex_) --------------------------------------------------------------------
  std::mutex pending_mutex_;
  std::condition_variable roi_done_;
  std::optional<RoiRequest> pending_roi_;
  uint64_t next_roi_id_ = 1;
  uint64_t done_roi_id_ = 0;
  bool done_roi_ok_ = false;
  std::string done_roi_message_;
  Parameters accepted_;                               ///< the configuration in force plus accepted changes
  std::map<std::string, std::string> pending_changes_;  ///< accepted, not yet applied: key -> value
  std::optional<EngineConfig> pending_engine_config_;
  bool pending_plugins_ = false;                      ///< a plugin's parameters changed
  bool pending_clear_trail_ = false;
  bool roi_topic_done_ = false;
  std::optional<TopicRoi> topic_roi_;
  std::optional<FrameMessages> last_set_;             ///< the last set received (for topic_roi_)

  // --- the frame slot and its worker ----------------------------------------------------------------------
  LatestSlot<FrameMessages> slot_;
  std::thread worker_;

  // --- ROS interfaces ---------------------------------------------------------------------------------------
  std::mutex connect_mutex_;
  std::shared_ptr<image_transport::ImageTransport> it_, private_it_;
  image_transport::SubscriberFilter left_sub_, right_sub_;
  message_filters::Subscriber<CameraInfo> left_info_sub_, right_info_sub_;
  std::unique_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::unique_ptr<message_filters::Synchronizer<ApproxPolicy>> approx_sync_;
  ros::Subscriber roi_sub_;
  ros::Publisher target_pub_, pose_pub_, status_pub_, particles_pub_, markers_pub_;
  image_transport::Publisher left_debug_pub_, right_debug_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
  std::string static_child_;        ///< camera frame the static transform was sent for
  ros::ServiceServer set_target_srv_, save_target_srv_, load_target_srv_, reset_srv_;
  boost::recursive_mutex engine_server_mutex_, state_server_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<TrackerEngineConfig>> engine_server_;
  std::unique_ptr<dynamic_reconfigure::Server<TrackerStateModelConfig>> state_server_;
  std::vector<std::unique_ptr<boost::recursive_mutex>> observation_server_mutexes_;
  std::vector<std::unique_ptr<ObservationServer>> observation_servers_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer diagnostics_timer_;

  // --- statistics (stats_mutex_) ------------------------------------------------------------------------------
  std::mutex stats_mutex_;
  uint64_t frames_in_ = 0, frames_tracked_ = 0, estimates_published_ = 0, unpaired_ = 0, debug_images_ = 0;
  std::array<uint64_t, static_cast<size_t>(DropReason::Count)> drops_{};
  std::array<ros::WallTime, static_cast<size_t>(DropReason::Count)> last_warning_{};  ///< per-reason throttle
  uint64_t reported_frames_in_ = 0, reported_frames_tracked_ = 0, reported_drops_ = 0, reported_overload_ = 0;
  ros::WallTime reported_time_, last_frame_time_;
  /// Recent processing times (worker start -> published), latencies (arrival -> published, waiting included)
  /// and ages (image stamp -> published, on the ROS clock), ms.
  std::deque<double> processing_ms_, latency_ms_, age_ms_;
  FrameResult last_result_;
  std::string last_message_;          ///< the last ~status message text
  bool has_result_ = false;
  bool has_target_ = false;           ///< the engine has a target (as of the last frame or load)
  std::string last_drop_;
};

}  // namespace stereo_pf
