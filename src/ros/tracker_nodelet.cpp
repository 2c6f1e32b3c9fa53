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
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
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
  std::string roi_topic;
  pnh.param<std::string>("target_roi_topic", roi_topic, "");
  queue_size = std::max(queue_size, 1);
  input_options.max_stamp_difference = std::max(input_options.max_stamp_difference, 0.0);
  marker_options_.trajectory_length = std::max(marker_options_.trajectory_length, 0);
  input_ = std::make_unique<StereoInput>(input_options);
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
  particles_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("particles", 2);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 2);
  left_debug_pub_ = private_it_->advertise("left/debug_image", 1);
  right_debug_pub_ = private_it_->advertise("right/debug_image", 1);
  if (publish_tf_)
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  if (!camera_parent_frame_.empty())
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();

  // The estimate is always computed, so the camera is subscribed at once (only debug images are lazy).
  const image_transport::TransportHints hints("raw", ros::TransportHints().tcpNoDelay(), pnh);
  left_sub_.subscribe(*it_, "stereo_camera/left/image_raw", queue_size, hints);
  right_sub_.subscribe(*it_, "stereo_camera/right/image_raw", queue_size, hints);
  left_info_sub_.subscribe(nh, "stereo_camera/left/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  right_info_sub_.subscribe(nh, "stereo_camera/right/camera_info", queue_size, ros::TransportHints().tcpNoDelay());
  if (!roi_topic.empty() && !tracker_->engine().hasTarget())
    roi_sub_ = nh.subscribe(roi_topic, 1, &TrackerNodelet::roiTopicCallback, this);
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
      pending_roi_ = RoiRequest{ next_roi_id_++, cv::Rect(roi[0], roi[1], roi[2], roi[3]) };
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
// Frame thread
// ---------------------------------------------------------------------------------------------------------

void TrackerNodelet::frameCallback(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                                   const sensor_msgs::CameraInfoConstPtr& left_info,
                                   const sensor_msgs::CameraInfoConstPtr& right_info)
{
  const ros::WallTime arrival = ros::WallTime::now();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++frames_in_;
    last_frame_time_ = arrival;
  }
  try
  {
    processFrame(left, right, left_info, right_info, arrival);
  }
  catch (const std::exception& e)  // conversion, rectification or publishing: never let it reach the manager
  {
    drop(DropReason::ProcessingError, e.what());
  }
}

void TrackerNodelet::processFrame(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                                  const sensor_msgs::CameraInfoConstPtr& left_info,
                                  const sensor_msgs::CameraInfoConstPtr& right_info, const ros::WallTime& arrival)
{
  StereoFrame frame;
  DropReason reason = DropReason::BadImage;
  std::string why;
  if (!input_->assemble(left, right, left_info, right_info, frame, reason, why))
  {
    drop(reason, why);
    return;
  }

  std::lock_guard<std::mutex> engine_lock(engine_mutex_);
  applyPending(frame);
  const bool has_target = tracker_->engine().hasTarget();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    has_target_ = has_target;
  }
  if (!has_target)
  {
    drop(DropReason::NoTarget, "no target yet: call ~set_target with a region of the left image, or set "
                               "~target_file, ~target_roi or ~target_roi_topic");
    return;
  }
  FrameResult result;
  if (!step(frame, result))
    return;

  std_msgs::Header header = left->header;
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
  publish(header, frame, result, arrival);
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
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++unpaired_;
  }
  drop(DropReason::OutOfSync, "no partner with the same stamp for a stereo set (missing:" + missing +
                                  "); if the cameras are not hardware-synchronised set ~approximate_sync");
}

void TrackerNodelet::roiTopicCallback(const sensor_msgs::RegionOfInterestConstPtr& roi)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  if (roi_topic_done_ || pending_roi_ || roi->width == 0 || roi->height == 0)
    return;
  pending_roi_ = RoiRequest{ next_roi_id_++, cv::Rect(static_cast<int>(roi->x_offset), static_cast<int>(roi->y_offset),
                                                      static_cast<int>(roi->width), static_cast<int>(roi->height)) };
}

void TrackerNodelet::applyPending(const StereoFrame& frame)
{
  std::optional<RoiRequest> roi;
  std::optional<TrackerEngineConfig> engine_config;
  std::optional<TrackerStateModelConfig> state_config;
  std::map<std::string, TrackerObservationConfig> observation_configs;
  bool clear_trail = false;
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    roi.swap(pending_roi_);
    engine_config.swap(pending_engine_);
    state_config.swap(pending_state_);
    observation_configs.swap(pending_observations_);
    std::swap(clear_trail, pending_clear_trail_);
  }
  if (clear_trail)
    trail_.clear();
  if (engine_config || state_config || !observation_configs.empty())
    applyReconfigure(engine_config, state_config, observation_configs);

  if (roi)
  {
    FilterEngine& engine = tracker_->engine();
    std::string error;
    const bool ok = engine.learnTarget(frame, roi->roi, error);
    if (ok)
    {
      engine.reset();  // a new target: search for it afresh
      trail_.clear();
      NODELET_INFO("target learned from %dx%d at (%d, %d) of the left image", roi->roi.width, roi->roi.height,
                   roi->roi.x, roi->roi.y);
      roi_topic_done_ = true;
      roi_sub_.shutdown();
    }
    else
      NODELET_ERROR("cannot learn the target: %s", error.c_str());
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      done_roi_id_ = std::max(done_roi_id_, roi->id);
      done_roi_ok_ = ok;
      done_roi_message_ = ok ? "target learned from the frame stamped " + std::to_string(frame.stamp) : error;
    }
    roi_done_.notify_all();
  }
}

void TrackerNodelet::applyReconfigure(const std::optional<TrackerEngineConfig>& engine_config,
                                      const std::optional<TrackerStateModelConfig>& state_config,
                                      const std::map<std::string, TrackerObservationConfig>& observation_configs)
{
  // The new values are first written into a private copy of the tree and checked there (the engine config
  // parsed, each changed plugin constructed once), so a rejected value never reaches the running filter.
  std::map<std::string, std::string> changes;
  if (engine_config)
  {
    const TrackerEngineConfig& c = *engine_config;
    changes["engine/particles"] = std::to_string(c.particles);
    changes["engine/resample_threshold"] = formatNumber(c.resample_threshold);
    changes["engine/estimator"] = c.estimator;
    changes["engine/density_radius"] = formatNumber(c.density_radius);
    changes["engine/found_similarity"] = formatNumber(c.found_similarity);
    changes["engine/lost_similarity"] = formatNumber(c.lost_similarity);
    changes["engine/respawn_fraction"] = formatNumber(c.respawn_fraction);
    changes["engine/refine_jitter"] = formatNumber(c.refine_jitter);
    changes["engine/refine_search_weight"] = formatNumber(c.refine_search_weight);
  }
  if (state_config && state_config->noise >= 0.0)
    changes["state_model/noise"] = formatNumber(state_config->noise);
  if (state_config && state_config->acceleration_noise >= 0.0)
    changes["state_model/acceleration_noise"] = formatNumber(state_config->acceleration_noise);
  for (const auto& [name, c] : observation_configs)
  {
    changes[name + "/enabled"] = c.enabled ? "true" : "false";
    changes[name + "/weight"] = formatNumber(c.weight);
    if (c.sigma >= 0.0)
      changes[name + "/sigma"] = formatNumber(c.sigma);
  }

  Parameters trial;
  for (const auto& key : params_.keys())
    trial.set(key, params_.raw(key));
  for (const auto& [key, value] : changes)
    trial.set(key, value);

  FilterEngine& engine = tracker_->engine();
  EngineConfig new_engine_config;
  try
  {
    new_engine_config = EngineConfig::fromParameters(trial.sub("engine"));
    const std::vector<std::string>& types = tracker_->pluginTypes();  // state model first, then the cues in order
    if (state_config)
      tracker_->createStateModel(types.at(0), "state_model", trial.sub("state_model"));
    const auto& models = engine.observationModels();
    for (size_t i = 0; i < models.size(); ++i)
      if (observation_configs.count(models[i]->name()))
        tracker_->createObservationModel(types.at(i + 1), models[i]->name(), trial.sub(models[i]->name()));
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR("reconfigure rejected, keeping the previous values: %s", e.what());
    return;
  }

  for (const auto& [key, value] : changes)
    params_.set(key, value);
  if (engine_config)
    engine.setConfig(new_engine_config);
  if (state_config || !observation_configs.empty())
    engine.requestPluginReconfigure();
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
                             const ros::WallTime& arrival)
{
  const StateEstimate& e = result.estimate;
  double latency_ms = -1.0;
  if (e.valid)
  {
    // The target first: it is what latency is measured on.
    target_pub_.publish(boost::make_shared<geometry_msgs::PointStamped>(toPointStamped(header, e)));
    latency_ms = (ros::WallTime::now() - arrival).toSec() * 1e3;
    pose_pub_.publish(boost::make_shared<geometry_msgs::PoseWithCovarianceStamped>(toPose(header, e)));
    if (tf_broadcaster_)
      tf_broadcaster_->sendTransform(toTransform(header, object_frame_, e));
    trail_.update(header.stamp.toSec(), e.position, result.state == TrackState::Tracking);
  }

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

  const double processing_ms = (ros::WallTime::now() - arrival).toSec() * 1e3;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++frames_tracked_;
  debug_images_ += drawn;
  pushWindow(processing_ms_, processing_ms);
  if (latency_ms >= 0.0)
    pushWindow(latency_ms_, latency_ms);
  last_result_ = result;
  has_result_ = true;
}

void TrackerNodelet::drop(DropReason reason, const std::string& why)
{
  // Throttled per reason, so one kind of bad frame cannot hide another.
  const ros::WallTime now = ros::WallTime::now();
  bool warn = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    const size_t r = static_cast<size_t>(reason);
    ++drops_[r];
    last_drop_ = std::string(toString(reason)) + ": " + why;
    const double period = reason == DropReason::NoTarget ? 5.0 : 2.0;
    if (last_warning_[r].isZero() || (now - last_warning_[r]).toSec() >= period)
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
                                          static_cast<int>(req.roi.width), static_cast<int>(req.roi.height)) };
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

void TrackerNodelet::engineReconfigure(TrackerEngineConfig& config, uint32_t)
{
  if (config.lost_similarity > config.found_similarity)
  {
    NODELET_WARN("lost_similarity %.3f > found_similarity %.3f: lowered to %.3f", config.lost_similarity,
                 config.found_similarity, config.found_similarity);
    config.lost_similarity = config.found_similarity;  // sanitised values are echoed back to the client
  }
  std::lock_guard<std::mutex> lock(pending_mutex_);
  pending_engine_ = config;
}

void TrackerNodelet::stateReconfigure(TrackerStateModelConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  pending_state_ = config;
}

void TrackerNodelet::observationReconfigure(const std::string& name, TrackerObservationConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(pending_mutex_);
  pending_observations_[name] = config;
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
  uint64_t dropped = 0;
  for (size_t r = 0; r < drops_.size(); ++r)
    if (static_cast<DropReason>(r) != DropReason::NoTarget)
      dropped += drops_[r];
  const bool new_drops = dropped > reported_drops_;
  reported_frames_in_ = frames_in_;
  reported_drops_ = dropped;
  reported_time_ = now;

  status.add("input rate (Hz)", rate);
  status.add("frames received", frames_in_);
  status.add("frames tracked", frames_tracked_);
  status.add("dropped frames", dropped);
  for (size_t r = 0; r < drops_.size(); ++r)
    status.add(std::string("dropped: ") + toString(static_cast<DropReason>(r)), drops_[r]);
  status.add("unpaired stereo sets", unpaired_);
  status.add("last drop", last_drop_);
  status.add("processing time median (ms)", median(processing_ms_));
  status.add("processing time max (ms)",
             processing_ms_.empty() ? 0.0 : *std::max_element(processing_ms_.begin(), processing_ms_.end()));
  status.add("latency to ~target median (ms)", median(latency_ms_));
  status.add("debug images drawn", debug_images_);
  status.add("plugins", joinNames(tracker_->pluginTypes()));
  if (has_result_)
  {
    status.add("track state", toString(last_result_.state));
    status.add("ESS", last_result_.ess);
    status.add("evidence", last_result_.evidence);
    const auto& p = last_result_.estimate.position;
    status.addf("estimate (m)", "%.3f %.3f %.3f", p.x(), p.y(), p.z());
  }
  else
    status.add("track state", "no frame tracked yet");

  if ((now - last_frame_time_).toSec() > 3.0)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no stereo frames received");
  else if (!has_target_)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no target: call ~set_target");
  else if (new_drops)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropping frames: " + last_drop_);
  else if (has_result_ && last_result_.state != TrackState::Tracking)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "target " + toString(last_result_.state));
  else
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "tracking");
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::TrackerNodelet, nodelet::Nodelet)
