// The tracker nodelet (see the header for the threading model, docs/ros_runtime.md for the interface).
#include "stereo_pf/ros/tracker_nodelet.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <boost/bind/bind.hpp>
#include <boost/make_shared.hpp>
#include <cv_bridge/cv_bridge.h>
#include <pluginlib/class_list_macros.hpp>

#include "stereo_pf/ros/ros_parameters.h"

namespace stereo_pf
{
using namespace boost::placeholders;

namespace
{
constexpr size_t kTimingWindow = 300;  // frames kept for the median processing time / latency

double median(std::deque<double> values)
{
  if (values.empty())
    return 0.0;
  const auto mid = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

void pushWindow(std::deque<double>& window, double value)
{
  window.push_back(value);
  if (window.size() > kTimingWindow)
    window.pop_front();
}

// The -1 "unchanged" values of the reconfigure servers are written back to the parameter server by
// dynamic_reconfigure; they must not reach the plugins (which would reject them) when the tree is re-read,
// e.g. when the nodelet is reloaded into a running manager.
bool isReconfigureSentinel(const std::string& key, const XmlRpc::XmlRpcValue& value)
{
  const auto slash = key.rfind('/');
  const std::string leaf = slash == std::string::npos ? key : key.substr(slash + 1);
  if (leaf != "sigma" && leaf != "noise" && leaf != "acceleration_noise")
    return false;
  XmlRpc::XmlRpcValue& v = const_cast<XmlRpc::XmlRpcValue&>(value);
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    return static_cast<double>(v) == -1.0;
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt)
    return static_cast<int>(v) == -1;
  return false;
}

std::string joinNames(const std::vector<std::string>& names)
{
  std::string s;
  for (const auto& n : names)
    s += (s.empty() ? "" : ", ") + n;
  return s;
}

std::string formatNumber(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.15g", v);  // reads back as the same number
  return buf;
}

std::string joinChanges(const std::map<std::string, std::string>& changes)
{
  std::string s;
  for (const auto& [key, value] : changes)
    s += (s.empty() ? "" : ", ") + key + " = " + value;
  return s;
}
}  // namespace

TrackerNodelet::~TrackerNodelet()
{
  // Stop the callbacks before the engine they use goes away.
  diagnostics_timer_.stop();
  left_sub_.unsubscribe();
  right_sub_.unsubscribe();
  left_info_sub_.unsubscribe();
  right_info_sub_.unsubscribe();
  roi_sub_.shutdown();
  slot_.close();  // the worker finishes its frame and stops
  if (worker_.joinable())
    worker_.join();
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    done_roi_id_ = next_roi_id_;  // release any set_target waiter
    done_roi_message_ = "the tracker is shutting down";
  }
  roi_done_.notify_all();
}

void TrackerNodelet::onInit()
{
  // Handles: frames on the single-threaded queue, services/reconfigure/diagnostics on the multi-threaded one.
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  ros::NodeHandle& mt_pnh = getMTPrivateNodeHandle();

  // Static parameters (read once).
  StereoInputOptions input_options;
  bool approximate_sync = false;
  int queue_size = 5;
  pnh.param("approximate_sync", approximate_sync, false);
  pnh.param("queue_size", queue_size, 5);
  pnh.param("images_rectified", input_options.images_rectified, false);
  pnh.param("max_stamp_difference", input_options.max_stamp_difference, approximate_sync ? 0.005 : 0.0);
  pnh.param("publish_tf", publish_tf_, true);
  pnh.param<std::string>("object_frame", object_frame_, "tracked_object");
  pnh.param<std::string>("camera_frame", fallback_frame_, "stereo_camera_optical_frame");
  pnh.param<std::string>("camera_parent_frame", camera_parent_frame_, "");
  pnh.param("set_target_timeout", set_target_timeout_, 2.0);
  pnh.param("marker_radius", marker_options_.radius, 0.035);
  pnh.param("marker_sigma_scale", marker_options_.sigma_scale, 2.0);
  pnh.param("trajectory_length", marker_options_.trajectory_length, 90);
  pnh.param("publish_when_lost", publish_when_lost_, false);
  pnh.param<std::string>("target_roi_topic", roi_topic_, "");
  queue_size = std::max(queue_size, 1);
  input_options.max_stamp_difference = std::max(input_options.max_stamp_difference, 0.0);
  marker_options_.trajectory_length = std::max(marker_options_.trajectory_length, 0);
  input_ = std::make_unique<StereoInput>(input_options);
  source_input_ = std::make_unique<StereoInput>(input_options);
  trail_ = EstimateTrail(marker_options_.trajectory_length);

  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
  diagnostics_->setHardwareID("stereo_pf");
  diagnostics_->add("tracker", this, &TrackerNodelet::diagnose);
  reported_time_ = last_frame_time_ = ros::WallTime::now();
  // A wall timer: diagnostics keep coming when a bag's simulated clock stops. Started once the tracker
  // exists (or failed), since the diagnostics read it from another thread.
  double diagnostic_period = 1.0;
  pnh.param("diagnostic_period", diagnostic_period, 1.0);
  auto start_diagnostics = [&]() {
    diagnostics_timer_ = mt_pnh.createWallTimer(ros::WallDuration(std::max(diagnostic_period, 0.02)),
                                                [this](const ros::WallTimerEvent&) { diagnostics_->force_update(); });
  };

  // The engine and its plugins. A bad configuration leaves the nodelet inert but explained (never a crash).
  if (!createTracker(pnh))
  {
    diagnostics_->force_update();
    start_diagnostics();
    return;
  }
  has_target_ = tracker_->engine().hasTarget();

  // Synchroniser on unsubscribed filters.
  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  private_it_ = std::make_shared<image_transport::ImageTransport>(pnh);
  if (approximate_sync)
  {
    approx_sync_ = std::make_unique<message_filters::Synchronizer<ApproxPolicy>>(
        ApproxPolicy(queue_size), left_sub_, right_sub_, left_info_sub_, right_info_sub_);
    approx_sync_->registerCallback(boost::bind(&TrackerNodelet::frameCallback, this, _1, _2, _3, _4));
  }
  else
  {
    exact_sync_ = std::make_unique<message_filters::Synchronizer<ExactPolicy>>(
        ExactPolicy(queue_size), left_sub_, right_sub_, left_info_sub_, right_info_sub_);
    exact_sync_->registerCallback(boost::bind(&TrackerNodelet::frameCallback, this, _1, _2, _3, _4));
    exact_sync_->registerDropCallback(boost::bind(&TrackerNodelet::unpairedCallback, this, _1, _2, _3, _4));
  }

  setupReconfigure(mt_pnh);

  set_target_srv_ = mt_pnh.advertiseService("set_target", &TrackerNodelet::setTargetService, this);
  save_target_srv_ = mt_pnh.advertiseService("save_target", &TrackerNodelet::saveTargetService, this);
  load_target_srv_ = mt_pnh.advertiseService("load_target", &TrackerNodelet::loadTargetService, this);
  reset_srv_ = mt_pnh.advertiseService("reset", &TrackerNodelet::resetService, this);

  // Advertise last, then subscribe: no frame can arrive before its publishers exist.
  std::lock_guard<std::mutex> lock(connect_mutex_);
  target_pub_ = pnh.advertise<geometry_msgs::PointStamped>("target", 10);
  pose_pub_ = pnh.advertise<geometry_msgs::PoseWithCovarianceStamped>("target_pose", 10);
  status_pub_ = pnh.advertise<TrackStatus>("status", 10);
  particles_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("particles", 2);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 2);
  left_debug_pub_ = private_it_->advertise("left/debug_image", 1);
  right_debug_pub_ = private_it_->advertise("right/debug_image", 1);
  if (publish_tf_)
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  if (!camera_parent_frame_.empty())
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();

  // The frame thread, then the inputs: the estimate is always computed, so the camera is subscribed at once
  // (only debug images are lazy).
  worker_ = std::thread(&TrackerNodelet::workerLoop, this);
  const image_transport::TransportHints hints("raw", ros::TransportHints().tcpNoDelay(), pnh);
  left_sub_.subscribe(*it_, "stereo_camera/left/image_raw", queue_size, hints);
  right_sub_.subscribe(*it_, "stereo_camera/right/image_raw", queue_size, hints);
  left_info_sub_.subscribe(nh, "stereo_camera/left/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  right_info_sub_.subscribe(nh, "stereo_camera/right/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  if (!roi_topic_.empty() && !tracker_->engine().hasTarget())
    roi_sub_ = nh.subscribe(roi_topic_, 1, &TrackerNodelet::roiTopicCallback, this);
  start_diagnostics();

  NODELET_INFO("tracking '%s' and '%s' (%s sync%s) with %s; publishing %s", left_sub_.getTopic().c_str(),
               right_sub_.getTopic().c_str(), approximate_sync ? "approximate" : "exact",
               input_options.images_rectified ? ", images already rectified" : "",
               joinNames(tracker_->pluginTypes()).c_str(), target_pub_.getTopic().c_str());
}

bool TrackerNodelet::createTracker(const ros::NodeHandle& pnh)
{
  try
  {
    XmlRpc::XmlRpcValue tree;
    if (pnh.getParam(pnh.getNamespace(), tree))
      mergeXmlRpc(tree, "", params_, isReconfigureSentinel);
    tracker_ = std::make_unique<Tracker>(params_);
  }
  catch (const std::exception& e)  // PluginError, ParameterError, pluginlib
  {
    init_error_ = std::string("cannot create the tracker: ") + e.what();
    NODELET_FATAL("%s", init_error_.c_str());
    return false;
  }
  // A misspelt key is ignored by every component: say so, with the key meant.
  for (const std::string& m : unknownParameters(params_, kRosRuntimeParameters))
  {
    NODELET_WARN("%s", m.c_str());
    unknown_parameters_ += (unknown_parameters_.empty() ? "" : "; ") + m;
  }
  accepted_ = params_.copy();

  // Start-up target: a file, else a region of the first frame, else ~set_target / ~target_roi_topic later.
  pnh.param<std::string>("target_file", target_file_, "");
  std::vector<int> roi;
  pnh.param("target_roi", roi, std::vector<int>());
  if (!target_file_.empty())
  {
    std::string error;
    if (tracker_->engine().loadTarget(target_file_, error))
      NODELET_INFO("target loaded from '%s'", target_file_.c_str());
    else
      NODELET_ERROR("~target_file: %s; waiting for ~set_target", error.c_str());
  }
  if (!tracker_->engine().hasTarget() && !roi.empty())
  {
    if (roi.size() != 4 || roi[2] <= 0 || roi[3] <= 0)
      NODELET_ERROR("~target_roi must be [x, y, width, height] with positive width and height (got %zu values); "
                    "waiting for ~set_target",
                    roi.size());
    else
      pending_roi_ = RoiRequest{ next_roi_id_++, cv::Rect(roi[0], roi[1], roi[2], roi[3]), std::nullopt };
  }
  return true;
}

void TrackerNodelet::setupReconfigure(const ros::NodeHandle& mt_pnh)
{
  // Each server lives in the namespace of the parameters it changes (~engine, ~state_model, ~<cue>), so its
  // initial values are the configured ones. The engine's effective values are published first, so a
  // server never starts from its own defaults where the engine has different ones.
  const EngineConfig& c = tracker_->engine().config();
  ros::NodeHandle engine_nh(mt_pnh, "engine");
  auto seed = [&engine_nh](const std::string& key, const auto& value) {
    if (!engine_nh.hasParam(key))
      engine_nh.setParam(key, value);
  };
  seed("particles", c.particles);
  seed("resample_threshold", c.resample_threshold);
  seed("estimator", toString(c.estimator));
  seed("density_radius", c.density_radius);
  seed("found_similarity", c.found_similarity);
  seed("lost_similarity", c.lost_similarity);
  seed("respawn_fraction", c.respawn_fraction);
  seed("refine_jitter", c.refine_jitter);
  seed("refine_search_weight", c.refine_search_weight);
  seed("max_depth", c.max_depth);
  seed("background_margin", c.background_margin);

  engine_server_ = std::make_unique<dynamic_reconfigure::Server<TrackerEngineConfig>>(engine_server_mutex_, engine_nh);
  engine_server_->setCallback(boost::bind(&TrackerNodelet::engineReconfigure, this, _1, _2));
  state_server_ = std::make_unique<dynamic_reconfigure::Server<TrackerStateModelConfig>>(
      state_server_mutex_, ros::NodeHandle(mt_pnh, "state_model"));
  state_server_->setCallback(boost::bind(&TrackerNodelet::stateReconfigure, this, _1, _2));
  for (const auto& model : tracker_->engine().observationModels())
  {
    const std::string name = model->name();
    observation_server_mutexes_.push_back(std::make_unique<boost::recursive_mutex>());
    observation_servers_.push_back(
        std::make_unique<ObservationServer>(*observation_server_mutexes_.back(), ros::NodeHandle(mt_pnh, name)));
    observation_servers_.back()->setCallback(
        [this, name](TrackerObservationConfig& config, uint32_t level) { observationReconfigure(name, config, level); });
  }
}

// ---------------------------------------------------------------------------------------------------------
// Receiving (single-threaded queue): only hand the set over, never wait
// ---------------------------------------------------------------------------------------------------------

void TrackerNodelet::frameCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                                   const sensor_msgs::CameraInfoConstPtr& left_info,
                                   const sensor_msgs::CameraInfoConstPtr& right_info)
{
  const FrameMessages set{ left, right, left_info, right_info, ros::WallTime::now() };
  double processing = 0.0;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++frames_in_;
    last_frame_time_ = set.arrival;
    processing = processing_ms_.empty() ? 0.0 : processing_ms_.back();  // the load now, not the usual one
  }
  {
    // A ROI from the topic belongs to the set that arrived nearest to it in time: the one just before it or
    // this one (RegionOfInterest has no stamp; learning it on a later frame taught the tracker a box of wall).
    std::lock_guard<std::mutex> lock(pending_mutex_);
    if (topic_roi_ && !pending_roi_)
    {
      const bool before = topic_roi_->before &&
                          (topic_roi_->arrival - topic_roi_->before->arrival) < (set.arrival - topic_roi_->arrival);
      pending_roi_ = RoiRequest{ next_roi_id_++, topic_roi_->roi, before ? topic_roi_->before : set };
      topic_roi_.reset();
    }
    last_set_ = set;
  }
  if (slot_.put(set))
  {
    char why[300];
    std::snprintf(why, sizeof(why),
                  "the tracker is slower than the camera (the last frame took %.1f ms): a frame waiting to be tracked was "
                  "replaced by a newer one; use fewer particles (~engine/particles) or fewer or cheaper cues, or "
                  "lower the camera's frame rate",
                  processing);
    drop(DropReason::Overload, why);
  }
}

void TrackerNodelet::unpairedCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                                      const sensor_msgs::CameraInfoConstPtr& left_info,
                                      const sensor_msgs::CameraInfoConstPtr& right_info)
{
  // ExactTime gave up on a stamp: some of the four messages never arrived (or arrived with another stamp).
  std::string missing;
  if (!left)
    missing += " left image";
  if (!right)
    missing += " right image";
  if (!left_info)
    missing += " left camera_info";
  if (!right_info)
    missing += " right camera_info";
  bool paired_before = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++unpaired_;
    paired_before = frames_in_ > 0;
  }
  // One camera frame is one left message with an image: a right message whose stamp is skewed leaves a second,
  // right-only set, and a camera_info whose stamp is skewed a set of camera_info alone; neither is a second
  // dropped frame (each is counted as an unpaired set only).
  if ((!left && !left_info) || (!left && !right))
    return;
  drop(DropReason::OutOfSync,
       "a stereo set never completed (missing:" + missing + ")" +
           (paired_before ? std::string("; a message was lost or came with another stamp; if this repeats, raise "
                                        "~queue_size or check the driver") :
                            std::string("; no set has been complete yet: if the cameras are not hardware-"
                                        "synchronised (left and right stamps differ), set ~approximate_sync: true")));
}

void TrackerNodelet::roiTopicCallback(const sensor_msgs::RegionOfInterestConstPtr& roi)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  if (roi_topic_done_ || pending_roi_ || topic_roi_ || roi->width == 0 || roi->height == 0)
    return;
  // Which frame it belongs to is decided when the next set arrives (frameCallback).
  topic_roi_ = TopicRoi{ cv::Rect(static_cast<int>(roi->x_offset), static_cast<int>(roi->y_offset),
                                  static_cast<int>(roi->width), static_cast<int>(roi->height)),
                         ros::WallTime::now(), last_set_ };
}

// ---------------------------------------------------------------------------------------------------------
// Frame thread (the worker)
// ---------------------------------------------------------------------------------------------------------

void TrackerNodelet::workerLoop()
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
      drop(DropReason::ProcessingError, e.what());
    }
  }
}

void TrackerNodelet::processFrame(const FrameMessages& set)
{
  const ros::WallTime start = ros::WallTime::now();
  StereoFrame frame;
  DropReason reason = DropReason::BadImage;
  std::string why;
  if (!input_->assemble(set.left, set.right, set.left_info, set.right_info, frame, reason, why))
  {
    drop(reason, why);
    return;
  }
  sayNotes(input_->notes());

  std::lock_guard<std::mutex> engine_lock(engine_mutex_);
  applyPending(frame);
  const bool has_target = tracker_->engine().hasTarget();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    has_target_ = has_target;
  }
  if (!has_target)
  {
    // At start-up the target usually comes a moment later (a ROI topic, a set_target call): be quiet for a
    // few seconds, then say what the tracker is waiting for.
    if (first_untargeted_.isZero())
      first_untargeted_ = start;
    const bool waited = (start - first_untargeted_).toSec() > 5.0;
    drop(DropReason::NoTarget,
         roi_sub_ ? "no target yet: waiting for a sensor_msgs/RegionOfInterest on '" + roi_sub_.getTopic() +
                        "' (~target_roi_topic); or call ~set_target with a region of the left image" :
                    "no target yet: call ~set_target with a region of the left image, or set ~target_file, "
                    "~target_roi or ~target_roi_topic",
         waited);
    return;
  }
  first_untargeted_ = ros::WallTime();
  FrameResult result;
  if (!step(frame, result))
    return;

  std_msgs::Header header = set.left->header;
  if (header.frame_id.empty())
    header.frame_id = fallback_frame_;
  if (static_broadcaster_ && header.frame_id != static_child_)
  {
    // Place the optical frame (z forward, y down) under a body-style parent (x forward, z up) for rviz,
    // when nothing else (robot description, driver) does.
    geometry_msgs::TransformStamped t;
    t.header.stamp = header.stamp;
    t.header.frame_id = camera_parent_frame_;
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

void TrackerNodelet::sayNotes(const std::vector<std::string>& notes)
{
  for (const std::string& note : notes)
    if (said_notes_.insert(note).second)
      NODELET_WARN("camera_info: %s", note.c_str());
}

void TrackerNodelet::applyPending(const StereoFrame& frame)
{
  std::optional<RoiRequest> roi;
  std::map<std::string, std::string> changes;
  std::optional<EngineConfig> engine_config;
  bool plugins = false;
  bool clear_trail = false;
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    roi.swap(pending_roi_);
    changes.swap(pending_changes_);
    engine_config.swap(pending_engine_config_);
    std::swap(plugins, pending_plugins_);
    std::swap(clear_trail, pending_clear_trail_);
  }
  if (clear_trail)
  {
    trail_.clear();
    last_tracked_.reset();
  }
  // Reconfigure values were checked when they were accepted: here they are written into the tree the plugins
  // read, and the engine applies them at the start of its next step.
  for (const auto& [key, value] : changes)
  {
    NODELET_INFO("reconfigure applied: %s = %s (was %s)", key.c_str(), value.c_str(),
                 params_.has(key) ? params_.raw(key).c_str() : "the default");
    params_.set(key, value);
  }
  FilterEngine& engine = tracker_->engine();
  if (engine_config)
    engine.setConfig(*engine_config);
  if (plugins)
    engine.requestPluginReconfigure();
  if (roi)
    learnRequestedTarget(*roi, frame);
}

void TrackerNodelet::learnRequestedTarget(const RoiRequest& request, const StereoFrame& frame)
{
  FilterEngine& engine = tracker_->engine();
  std::string error;
  bool ok = false;
  double stamp = frame.stamp;
  if (request.source)
  {
    // The request's own frame (a ROI topic's): assembled with separate buffers, so `frame` stays intact.
    const FrameMessages& s = *request.source;
    StereoFrame source;
    DropReason reason = DropReason::BadImage;
    ok = source_input_->assemble(s.left, s.right, s.left_info, s.right_info, source, reason, error) &&
         engine.learnTarget(source, request.roi, error);
    stamp = source.stamp;
  }
  else
    ok = engine.learnTarget(frame, request.roi, error);
  if (ok)
  {
    engine.reset();  // a new target: start afresh (acquired at its box when engine/acquire, else searched for)
    trail_.clear();
    last_tracked_.reset();
    NODELET_INFO("target learned from %dx%d at (%d, %d) of the left image of the frame stamped %.3f",
                 request.roi.width, request.roi.height, request.roi.x, request.roi.y, stamp);
    roi_topic_done_ = true;
    roi_sub_.shutdown();
  }
  else
    NODELET_ERROR("cannot learn the target (the previous one, if any, is kept): %s", error.c_str());
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    done_roi_id_ = std::max(done_roi_id_, request.id);
    done_roi_ok_ = ok;
    done_roi_message_ = ok ? "target learned from the frame stamped " + std::to_string(stamp) :
                             error + " (the previous target, if any, is kept)";
  }
  roi_done_.notify_all();
}

bool TrackerNodelet::step(const StereoFrame& frame, FrameResult& result)
{
  try
  {
    result = tracker_->engine().step(frame);
    return true;
  }
  catch (const std::exception& e)  // never let an exception reach the nodelet manager
  {
    drop(DropReason::ProcessingError, e.what());
    return false;
  }
}

void TrackerNodelet::publish(const std_msgs::Header& header, const StereoFrame& frame, const FrameResult& result,
                             const ros::WallTime& arrival, const ros::WallTime& start)
{
  const StateEstimate& e = result.estimate;
  // An estimate is published only while tracking: a searching or lost filter's mean is no position.
  const bool tracking = result.state == TrackState::Tracking && e.valid;
  if (tracking)
  {
    // The target first: it is what latency is measured on.
    target_pub_.publish(boost::make_shared<geometry_msgs::PointStamped>(toPointStamped(header, e)));
    pose_pub_.publish(boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>(toPose(header, e)));
    if (tf_broadcaster_)
      tf_broadcaster_->sendTransform(toTransform(header, object_frame_, e));
    last_tracked_ = e;
  }
  else if (publish_when_lost_ && last_tracked_)
  {
    // The last tracked position, marked: its pose covariance says "unknown" and ~status says estimate_valid
    // false. No TF: a transform cannot be marked.
    StateEstimate held = *last_tracked_;
    held.covariance = Eigen::Matrix3d::Identity() * 1e6;
    target_pub_.publish(boost::make_shared<geometry_msgs::PointStamped>(toPointStamped(header, held)));
    pose_pub_.publish(boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>(toPose(header, held)));
  }

  trail_.update(header.stamp.toSec(), e.position, tracking);  // restarts while not tracking

  const EngineConfig& config = tracker_->engine().config();
  const std::string message = describeTrack(result, config, tracker_->engine().viewingVolume());
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
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++frames_tracked_;  // before ~status goes out: a client that saw it finds it counted
    estimates_published_ += tracking ? 1 : 0;
    status->frames_received = frames_in_;
    uint64_t dropped = 0;
    for (size_t r = 0; r < drops_.size(); ++r)
      if (static_cast<DropReason>(r) != DropReason::NoTarget)
        dropped += drops_[r];
    status->frames_dropped = dropped;
    status->frames_dropped_overload = drops_[static_cast<size_t>(DropReason::Overload)];
  }
  status_pub_.publish(status);

  const bool want_markers = markers_pub_.getNumSubscribers() > 0, want_cloud = particles_pub_.getNumSubscribers() > 0;
  if (want_markers || want_cloud)
  {
    // The set as weighed, before the step's resampling left copies of a few particles, all weighing 1/N.
    const FilterEngine& engine = tracker_->engine();
    engine.stateModel().cloud(frame.geometry, engine.weightedSets(), cloud_raw_, cloud_raw_weights_);
    mergeDuplicates(cloud_raw_, cloud_raw_weights_, cloud_points_, cloud_weights_);
  }
  if (want_markers)  // the particles too: rviz then draws them in the same update as the estimate
    markers_pub_.publish(boost::make_shared<visualization_msgs::MarkerArray>(
        toMarkers(header, result, trail_, marker_options_, &cloud_points_, &cloud_weights_)));
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
    drawing_.draw(frame, view, tracker_->engine(), result, debug_image_);
    auto msg = boost::make_shared<sensor_msgs::Image>();
    cv_bridge::CvImage(header, "bgr8", debug_image_).toImageMsg(*msg);
    pub->publish(msg);
    ++drawn;
  }

  const double processing_ms = (ros::WallTime::now() - start).toSec() * 1e3;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  debug_images_ += drawn;
  pushWindow(processing_ms_, processing_ms);
  pushWindow(latency_ms_, latency_ms);
  if (std::isfinite(age_ms))
    pushWindow(age_ms_, age_ms);
  last_result_ = result;
  last_message_ = message;
  has_result_ = true;
}

void TrackerNodelet::drop(DropReason reason, const std::string& why, bool warn_now)
{
  // Throttled per reason, so one kind of bad frame cannot hide another.
  const ros::WallTime now = ros::WallTime::now();
  bool warn = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    const size_t r = static_cast<size_t>(reason);
    ++drops_[r];
    last_drop_ = std::string(toString(reason)) + ": " + why;
    const double period = reason == DropReason::NoTarget ? 10.0 : 2.0;
    if (warn_now && (last_warning_[r].isZero() || (now - last_warning_[r]).toSec() >= period))
    {
      last_warning_[r] = now;
      warn = true;
    }
  }
  if (!warn)
    return;
  if (reason == DropReason::NoTarget)
    NODELET_WARN("frame skipped: %s", why.c_str());
  else
    NODELET_WARN("frame dropped (%s): %s", toString(reason), why.c_str());
}

// ---------------------------------------------------------------------------------------------------------
// Services, reconfigure, diagnostics (multi-threaded queue)
// ---------------------------------------------------------------------------------------------------------

bool TrackerNodelet::setTargetService(SetTarget::Request& req, SetTarget::Response& res)
{
  if (req.roi.width == 0 || req.roi.height == 0)
  {
    res.success = false;
    res.message = "the region is empty (width and height must be positive)";
    return true;
  }
  std::unique_lock<std::mutex> lock(pending_mutex_);
  const uint64_t id = next_roi_id_++;
  pending_roi_ = RoiRequest{ id, cv::Rect(static_cast<int>(req.roi.x_offset), static_cast<int>(req.roi.y_offset),
                                          static_cast<int>(req.roi.width), static_cast<int>(req.roi.height)),
                             std::nullopt };
  const bool answered = roi_done_.wait_for(lock, std::chrono::duration<double>(std::max(set_target_timeout_, 0.0)),
                                           [this, id] { return done_roi_id_ >= id; });
  if (!answered)
  {
    res.success = true;
    res.message = "queued: no frame arrived within " + formatNumber(set_target_timeout_) +
                  " s; the target will be learned from the next frame";
  }
  else if (done_roi_id_ > id)
  {
    res.success = false;
    res.message = "superseded by a later set_target request";
  }
  else
  {
    res.success = done_roi_ok_;
    res.message = done_roi_message_;
  }
  return true;
}

bool TrackerNodelet::saveTargetService(TargetFile::Request& req, TargetFile::Response& res)
{
  const std::string path = req.path.empty() ? target_file_ : req.path;
  if (path.empty())
  {
    res.success = false;
    res.message = "no path given and ~target_file is not set";
    return true;
  }
  std::lock_guard<std::mutex> lock(engine_mutex_);
  std::string error;
  if (!tracker_->engine().hasTarget())
  {
    res.success = false;
    res.message = "no target learned yet";
    return true;
  }
  res.success = tracker_->engine().saveTarget(path, error);
  res.message = res.success ? "target saved to '" + path + "'" : error;
  return true;
}

bool TrackerNodelet::loadTargetService(TargetFile::Request& req, TargetFile::Response& res)
{
  const std::string path = req.path.empty() ? target_file_ : req.path;
  if (path.empty())
  {
    res.success = false;
    res.message = "no path given and ~target_file is not set";
    return true;
  }
  std::lock_guard<std::mutex> lock(engine_mutex_);  // between two steps, never during one
  std::string error;
  res.success = tracker_->engine().loadTarget(path, error);
  res.message = res.success ? "target loaded from '" + path + "'" : error;
  if (res.success)
  {
    {
      std::lock_guard<std::mutex> stats(stats_mutex_);
      has_target_ = tracker_->engine().hasTarget();
    }
    tracker_->engine().reset();
    std::lock_guard<std::mutex> pending(pending_mutex_);
    pending_clear_trail_ = true;
  }
  return true;
}

bool TrackerNodelet::resetService(std_srvs::Empty::Request&, std_srvs::Empty::Response&)
{
  tracker_->engine().reset();  // thread-safe: applied at the start of the next step
  std::lock_guard<std::mutex> lock(pending_mutex_);
  pending_clear_trail_ = true;
  NODELET_INFO("reset: the particles are re-drawn from the prior at the next frame");
  return true;
}

// Reconfigure transactions. A server's callback answers with the configuration it is given back, and the
// server keeps it: so a value a component rejects is replaced by the one in force, and nothing changes.
namespace
{
bool sameNumber(double a, double b)
{
  return std::fabs(a - b) <= 1e-12 * std::max(1.0, std::fabs(a));
}
}  // namespace

TrackerEngineConfig TrackerNodelet::engineInForce() const
{
  const EngineConfig e = EngineConfig::fromParameters(accepted_.sub("engine"));  // accepted values parse
  TrackerEngineConfig c;
  c.particles = e.particles;
  c.resample_threshold = e.resample_threshold;
  c.estimator = toString(e.estimator);
  c.density_radius = e.density_radius;
  c.found_similarity = e.found_similarity;
  c.lost_similarity = e.lost_similarity;
  c.respawn_fraction = e.respawn_fraction;
  c.refine_jitter = e.refine_jitter;
  c.refine_search_weight = e.refine_search_weight;
  c.max_depth = e.max_depth;
  c.background_margin = e.background_margin;
  return c;
}

TrackerStateModelConfig TrackerNodelet::stateInForce() const
{
  // -1: the model's own default (nothing configured).
  TrackerStateModelConfig c;
  const Parameters p = accepted_.sub("state_model");
  c.noise = p.has("noise") ? p.getDouble("noise", -1.0, -1e300, 1e300) : -1.0;
  c.acceleration_noise = p.has("acceleration_noise") ? p.getDouble("acceleration_noise", -1.0, -1e300, 1e300) : -1.0;
  return c;
}

TrackerObservationConfig TrackerNodelet::observationInForce(const std::string& name) const
{
  TrackerObservationConfig c;
  const Parameters p = accepted_.sub(name);
  c.enabled = p.getBool("enabled", true);
  c.weight = p.getDouble("weight", 1.0, -1e300, 1e300);
  c.sigma = p.has("sigma") ? p.getDouble("sigma", -1.0, -1e300, 1e300) : -1.0;
  return c;
}

bool TrackerNodelet::acceptReconfigure(const std::string& server, const std::map<std::string, std::string>& changes,
                                       std::string& error)
{
  Parameters trial = accepted_.copy();
  for (const auto& [key, value] : changes)
    trial.set(key, value);
  EngineConfig engine_config;
  try
  {
    engine_config = EngineConfig::fromParameters(trial.sub("engine"));
    const std::vector<std::string>& types = tracker_->pluginTypes();  // state model first, then the cues in order
    if (server == "state_model")
      tracker_->createStateModel(types.at(0), "state_model", trial.sub("state_model"));
    const auto& models = tracker_->engine().observationModels();  // the list itself never changes
    for (size_t i = 0; i < models.size(); ++i)
      if (models[i]->name() == server)
        tracker_->createObservationModel(types.at(i + 1), server, trial.sub(server));
  }
  catch (const std::exception& e)
  {
    error = e.what();
    return false;
  }
  accepted_ = trial;
  for (const auto& [key, value] : changes)
    pending_changes_[key] = value;
  if (server == "engine")
    pending_engine_config_ = engine_config;
  else
    pending_plugins_ = true;
  return true;
}

void TrackerNodelet::engineReconfigure(TrackerEngineConfig& config, uint32_t)
{
  if (config.lost_similarity > config.found_similarity)
  {
    NODELET_WARN("lost_similarity %.3f > found_similarity %.3f: lowered to %.3f", config.lost_similarity,
                 config.found_similarity, config.found_similarity);
    config.lost_similarity = config.found_similarity;  // sanitised values are echoed back to the client
  }
  std::lock_guard<std::mutex> lock(pending_mutex_);
  const TrackerEngineConfig now = engineInForce();
  std::map<std::string, std::string> changes;
  auto number = [&](const char* key, double value, double in_force) {
    if (!sameNumber(value, in_force))
      changes[std::string("engine/") + key] = formatNumber(value);
  };
  if (config.particles != now.particles)
    changes["engine/particles"] = std::to_string(config.particles);
  if (config.estimator != now.estimator)
    changes["engine/estimator"] = config.estimator;
  number("resample_threshold", config.resample_threshold, now.resample_threshold);
  number("density_radius", config.density_radius, now.density_radius);
  number("found_similarity", config.found_similarity, now.found_similarity);
  number("lost_similarity", config.lost_similarity, now.lost_similarity);
  number("respawn_fraction", config.respawn_fraction, now.respawn_fraction);
  number("refine_jitter", config.refine_jitter, now.refine_jitter);
  number("refine_search_weight", config.refine_search_weight, now.refine_search_weight);
  number("max_depth", config.max_depth, now.max_depth);
  number("background_margin", config.background_margin, now.background_margin);
  if (changes.empty())
    return;
  std::string error;
  if (acceptReconfigure("engine", changes, error))
    NODELET_INFO("reconfigure ~engine accepted (applied at the next frame): %s", joinChanges(changes).c_str());
  else
  {
    NODELET_ERROR("reconfigure ~engine rejected, nothing changed (the server keeps the values in force): %s",
                  error.c_str());
    config = now;
  }
}

void TrackerNodelet::stateReconfigure(TrackerStateModelConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  const TrackerStateModelConfig now = stateInForce();
  std::map<std::string, std::string> changes;
  // -1 means "leave it": the server then shows the value in force.
  if (config.noise >= 0.0 && !sameNumber(config.noise, now.noise))
    changes["state_model/noise"] = formatNumber(config.noise);
  if (config.acceleration_noise >= 0.0 && !sameNumber(config.acceleration_noise, now.acceleration_noise))
    changes["state_model/acceleration_noise"] = formatNumber(config.acceleration_noise);
  std::string error;
  if (changes.empty())
    config = now;
  else if (acceptReconfigure("state_model", changes, error))
    NODELET_INFO("reconfigure ~state_model accepted (applied at the next frame): %s", joinChanges(changes).c_str());
  else
  {
    NODELET_ERROR("reconfigure ~state_model rejected, nothing changed (the server keeps the values in force): %s",
                  error.c_str());
    config = now;
  }
}

void TrackerNodelet::observationReconfigure(const std::string& name, TrackerObservationConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  const TrackerObservationConfig now = observationInForce(name);
  std::map<std::string, std::string> changes;
  if (config.enabled != now.enabled)
    changes[name + "/enabled"] = config.enabled ? "true" : "false";
  if (!sameNumber(config.weight, now.weight))
    changes[name + "/weight"] = formatNumber(config.weight);
  if (config.sigma >= 0.0 && !sameNumber(config.sigma, now.sigma))
    changes[name + "/sigma"] = formatNumber(config.sigma);
  std::string error;
  if (changes.empty())
  {
    if (config.sigma < 0.0)
      config.sigma = now.sigma;
  }
  else if (acceptReconfigure(name, changes, error))
  {
    NODELET_INFO("reconfigure ~%s accepted (applied at the next frame): %s", name.c_str(), joinChanges(changes).c_str());
    if (config.sigma < 0.0)
      config.sigma = now.sigma;
  }
  else
  {
    NODELET_ERROR("reconfigure ~%s rejected, nothing changed (the server keeps the values in force): %s",
                  name.c_str(), error.c_str());
    config = now;
  }
}

void TrackerNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status)
{
  if (!init_error_.empty())
  {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, init_error_);
    return;
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double period = std::max((now - reported_time_).toSec(), 1e-3);
  const double rate = static_cast<double>(frames_in_ - reported_frames_in_) / period;
  const double output_rate = static_cast<double>(frames_tracked_ - reported_frames_tracked_) / period;
  uint64_t dropped = 0;
  for (size_t r = 0; r < drops_.size(); ++r)
    if (static_cast<DropReason>(r) != DropReason::NoTarget)
      dropped += drops_[r];
  const uint64_t overload = drops_[static_cast<size_t>(DropReason::Overload)];
  const bool new_drops = dropped > reported_drops_;
  const uint64_t new_overload = overload - reported_overload_;
  const uint64_t period_frames = frames_in_ - reported_frames_in_;
  reported_frames_in_ = frames_in_;
  reported_frames_tracked_ = frames_tracked_;
  reported_drops_ = dropped;
  reported_overload_ = overload;
  reported_time_ = now;

  status.add("input rate (Hz)", rate);
  status.add("output rate (Hz)", output_rate);
  status.add("frames received", frames_in_);
  status.add("frames tracked", frames_tracked_);
  status.add("estimates published", estimates_published_);
  status.add("dropped frames", dropped);
  for (size_t r = 0; r < drops_.size(); ++r)
    status.add(std::string("dropped: ") + toString(static_cast<DropReason>(r)), drops_[r]);
  status.add("unpaired stereo sets", unpaired_);
  status.add("last drop", last_drop_);
  const double processing = median(processing_ms_);
  status.add("processing time median (ms)", processing);
  status.add("processing time max (ms)",
             processing_ms_.empty() ? 0.0 : *std::max_element(processing_ms_.begin(), processing_ms_.end()));
  status.add("latency from arrival median (ms)", median(latency_ms_));
  status.add("age from image stamp median (ms)", median(age_ms_));
  status.add("debug images drawn", debug_images_);
  status.add("plugins", joinNames(tracker_->pluginTypes()));
  status.add("unknown parameters", unknown_parameters_.empty() ? std::string("none") : unknown_parameters_);
  if (has_result_)
  {
    status.add("track state", toString(last_result_.state));
    status.add("support", toString(last_result_.support));
    status.add("frames in state", last_result_.state_frames);
    status.add("ESS", last_result_.ess);
    status.add("evidence", last_result_.evidence);
    status.add("background", last_result_.background);
    const auto& p = last_result_.estimate.position;
    status.addf("estimate (m)", "%.3f %.3f %.3f", p.x(), p.y(), p.z());
    status.add("status", last_message_);
  }
  else
    status.add("track state", "no frame tracked yet");

  if ((now - last_frame_time_).toSec() > 3.0)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no stereo frames received");
  else if (!has_target_)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no target: call ~set_target");
  else if (new_overload > 0)
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN,
                    "overloaded: %llu of %llu frames dropped in the last %.1f s (the last frame took %.1f ms, input %.1f Hz): "
                    "use fewer particles (~engine/particles) or fewer or cheaper cues, or lower the camera rate",
                    static_cast<unsigned long long>(new_overload), static_cast<unsigned long long>(period_frames),
                    period, processing_ms_.empty() ? 0.0 : processing_ms_.back(), rate);
  else if (new_drops)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropping frames: " + last_drop_);
  else if (has_result_ && last_result_.state != TrackState::Tracking)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_message_);
  else
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "tracking");
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::TrackerNodelet, nodelet::Nodelet)
