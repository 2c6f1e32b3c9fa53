// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// rostest for the tracker nodelet / node: plays a make_scene bag into it frame by frame (lockstep: the next
// frame is published once ~status answered the previous one, so the test is independent of machine speed)
// and checks accuracy against the ground truth, the services, lazy debug images, robustness to bad frames
// and camera_info, the track status on the wire (no estimate while not tracking), reconfigure and target
// transactions, overload, and the explained error for an unknown plugin type.
//
// Private parameters: tracker (the tracker's node name, default /stereo_pf_tracker), manager (the nodelet
// manager, for the bad-plugin test). The bag is generated at build time (TEST_BAG).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <future>
#include <map>
#include <set>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/PointStamped.h>
#include <gtest/gtest.h>
#include <nodelet/NodeletList.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/RegionOfInterest.h>
#include <std_srvs/Empty.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include "stereo_pf/SetTarget.h"
#include "stereo_pf/TargetFile.h"
#include "stereo_pf/TrackStatus.h"

namespace
{
/// One stereo frame of the bag.
struct BagFrame
{
  sensor_msgs::Image left, right;
  sensor_msgs::CameraInfo left_info, right_info;
  geometry_msgs::Point truth;
  sensor_msgs::RegionOfInterest roi;
};

std::vector<BagFrame> readBag(const std::string& path)
{
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::map<ros::Time, BagFrame> frames;
  for (const rosbag::MessageInstance& m : rosbag::View(bag))
  {
    const std::string& t = m.getTopic();
    if (auto img = m.instantiate<sensor_msgs::Image>())
      (t.find("left") != std::string::npos ? frames[img->header.stamp].left : frames[img->header.stamp].right) = *img;
    else if (auto info = m.instantiate<sensor_msgs::CameraInfo>())
      (t.find("left") != std::string::npos ? frames[info->header.stamp].left_info :
                                              frames[info->header.stamp].right_info) = *info;
    else if (auto p = m.instantiate<geometry_msgs::PointStamped>())
      frames[p->header.stamp].truth = p->point;
    else if (auto roi = m.instantiate<sensor_msgs::RegionOfInterest>())
      frames[m.getTime()].roi = *roi;
  }
  std::vector<BagFrame> out;
  for (auto& kv : frames)
    out.push_back(kv.second);
  return out;
}

double distance(const geometry_msgs::Point& a, const geometry_msgs::Point& b)
{
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
}

/// Everything the tests talk to, shared by all tests of the process (one tracker instance).
class Harness
{
public:
  Harness() : pnh_("~")
  {
    pnh_.param<std::string>("tracker", tracker_, "/stereo_pf_tracker");
    pnh_.param<std::string>("manager", manager_, "/stereo_pf_manager");
    left_pub_ = nh_.advertise<sensor_msgs::Image>("stereo_camera/left/image_raw", 5);
    right_pub_ = nh_.advertise<sensor_msgs::Image>("stereo_camera/right/image_raw", 5);
    left_info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("stereo_camera/left/camera_info", 5);
    right_info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("stereo_camera/right/camera_info", 5);
    target_sub_ = nh_.subscribe(tracker_ + "/target", 100, &Harness::onTarget, this, ros::TransportHints().tcpNoDelay());
    status_sub_ = nh_.subscribe(tracker_ + "/status", 100, &Harness::onStatus, this, ros::TransportHints().tcpNoDelay());
    tf_sub_ = nh_.subscribe("/tf", 100, &Harness::onTf, this);
    diag_sub_ = nh_.subscribe("/diagnostics", 100, &Harness::onDiagnostics, this);
  }

  const std::string& tracker() const { return tracker_; }
  const std::string& manager() const { return manager_; }
  ros::NodeHandle& nh() { return nh_; }

  const std::vector<BagFrame>& frames()
  {
    if (frames_.empty())
      frames_ = readBag(TEST_BAG);
    return frames_;
  }

  /// Frame `k` of the bag, counted on from its end to its start again: an index that runs past the last frame
  /// (settleAt() may take up to 40 frames) reads the bag again instead of memory beyond it.
  const BagFrame& frame(size_t k) { return frames()[k % frames().size()]; }

  /// Wait until the tracker subscribes to all four inputs.
  bool waitForTracker(double timeout = 20.0)
  {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
    while (ros::WallTime::now() < end)
    {
      if (left_pub_.getNumSubscribers() > 0 && right_pub_.getNumSubscribers() > 0 &&
          left_info_pub_.getNumSubscribers() > 0 && right_info_pub_.getNumSubscribers() > 0 &&
          target_sub_.getNumPublishers() > 0 && status_sub_.getNumPublishers() > 0)
        return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }

  /// Publish a (possibly modified) frame with a fresh, increasing stamp, or with `at` when it is given; returns
  /// the stamp.
  ros::Time publish(BagFrame f, const ros::Time& at = ros::Time())
  {
    const ros::Time fresh(2000.0 + (count_++) / 30.0);
    const ros::Time stamp = at.isZero() ? fresh : at;
    f.left.header.stamp = f.right.header.stamp = f.left_info.header.stamp = f.right_info.header.stamp = stamp;
    left_info_pub_.publish(f.left_info);
    right_info_pub_.publish(f.right_info);
    left_pub_.publish(f.left);
    right_pub_.publish(f.right);
    return stamp;
  }

  /// Publish a frame whose right image (`left_info` false) or left camera_info (true) is stamped `skew` seconds
  /// after the other three messages.
  void publishSkewed(BagFrame f, double skew, bool left_info = false)
  {
    const ros::Time stamp(2000.0 + (count_++) / 30.0);
    f.left.header.stamp = f.left_info.header.stamp = f.right.header.stamp = f.right_info.header.stamp = stamp;
    (left_info ? f.left_info.header.stamp : f.right.header.stamp) = stamp + ros::Duration(skew);
    left_info_pub_.publish(f.left_info);
    right_info_pub_.publish(f.right_info);
    left_pub_.publish(f.left);
    right_pub_.publish(f.right);
  }

  /// Publish (stamped `at` when given, else afresh) and wait for ~status with the same stamp; false when none came
  /// within `timeout` (a dropped frame).
  bool stepStatus(const BagFrame& f, stereo_pf::TrackStatus& status, double timeout = 3.0,
                  const ros::Time& at = ros::Time())
  {
    const ros::Time stamp = publish(f, at);
    std::unique_lock<std::mutex> lock(mutex_);
    const bool got = cv_.wait_for(lock, std::chrono::duration<double>(timeout),
                                  [&] { return statuses_.count(stamp) > 0; });
    if (got)
      status = statuses_[stamp];
    last_stamp_ = stamp;
    if (getenv("STEREO_PF_TEST_VERBOSE"))  // one line per frame, to see why a run failed
      std::fprintf(stderr, "DBG frame %.3f got %d state %s support %s ev %.2f bg %.2f\n", stamp.toSec(), got,
                   got ? status.state_name.c_str() : "-", got ? status.support.c_str() : "-",
                   got ? status.evidence : 0.0, got ? status.background : 0.0);
    return got;
  }

  /// Publish and wait for ~status; true when the frame was tracked and its ~target came (in `estimate`).
  bool step(const BagFrame& f, geometry_msgs::Point& estimate, double timeout = 3.0)
  {
    stereo_pf::TrackStatus status;
    if (!stepStatus(f, status, timeout) || !status.estimate_valid)
      return false;
    return targetOf(last_stamp_, estimate);
  }

  /// The ~target with `stamp` (it is published just before ~status, on its own connection: allow a moment).
  bool targetOf(const ros::Time& stamp, geometry_msgs::Point& estimate, double timeout = 1.0)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool got = cv_.wait_for(lock, std::chrono::duration<double>(timeout),
                                  [&] { return targets_.count(stamp) > 0; });
    if (got)
      estimate = targets_[stamp];
    return got;
  }

  /// Whether a ~target or a TF to the object frame came with `stamp` (waits `timeout` for stragglers).
  bool anyEstimateAt(const ros::Time& stamp, double timeout = 0.2)
  {
    ros::WallDuration(timeout).sleep();
    std::lock_guard<std::mutex> lock(mutex_);
    return targets_.count(stamp) > 0 || tf_stamps_.count(stamp) > 0;
  }

  /// Whether a TF to the object frame came with `stamp` (waits `timeout` for stragglers).
  bool tfAt(const ros::Time& stamp, double timeout = 0.2)
  {
    ros::WallDuration(timeout).sleep();
    std::lock_guard<std::mutex> lock(mutex_);
    return tf_stamps_.count(stamp) > 0;
  }

  const ros::Time& lastStamp() const { return last_stamp_; }

  /// Publish frames (cycling through the bag) until `done` is ready or the timeout expires.
  template <class Future>
  bool publishUntil(Future& done, size_t first_frame, double timeout = 10.0)
  {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
    for (size_t k = first_frame; ros::WallTime::now() < end; ++k)
    {
      publish(frame(k));
      if (done.wait_for(std::chrono::milliseconds(100)) == std::future_status::ready)
        return true;
    }
    return false;
  }

  /// The latest diagnostics of the tracker whose "frames received" is at least `min_frames`.
  bool diagnostics(std::map<std::string, std::string>& out, uint64_t min_frames, double timeout = 5.0)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool got = cv_.wait_for(lock, std::chrono::duration<double>(timeout), [&] {
      return diag_.count("frames received") && std::stoull(diag_["frames received"]) >= min_frames;
    });
    out = diag_;
    return got;
  }

  /// The latest tracker diagnostics status matching `pred` (level, message).
  bool waitForStatus(const std::function<bool(int, const std::string&)>& pred, std::string& message, double timeout)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool got = cv_.wait_for(lock, std::chrono::duration<double>(timeout),
                                  [&] { return has_status_ && pred(status_level_, status_message_); });
    message = status_message_;
    return got;
  }

  uint64_t counter(const std::string& key, uint64_t min_frames)
  {
    std::map<std::string, std::string> d;
    EXPECT_TRUE(diagnostics(d, min_frames)) << "no diagnostics with " << min_frames << " frames received";
    return d.count(key) ? std::stoull(d[key]) : 0;
  }

  uint64_t published() const { return count_; }

  /// The diagnostics' counter `key` once it is at least `value`; its latest value when that takes over `timeout`.
  uint64_t counterReaching(const std::string& key, uint64_t value, double timeout = 5.0)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(timeout),
                 [&] { return diag_.count(key) && std::stoull(diag_[key]) >= value; });
    return diag_.count(key) ? std::stoull(diag_[key]) : 0;
  }

  /// Forget the ~status of `stamp` (to see whether another frame with that stamp gets one).
  void forgetStatus(const ros::Time& stamp)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    statuses_.erase(stamp);
  }

private:
  void onTarget(const geometry_msgs::PointStampedConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    targets_[msg->header.stamp] = msg->point;
    cv_.notify_all();
  }

  void onStatus(const stereo_pf::TrackStatusConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    statuses_[msg->header.stamp] = *msg;
    cv_.notify_all();
  }

  void onTf(const tf2_msgs::TFMessageConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& t : msg->transforms)
      if (t.child_frame_id == "tracked_object")
        tf_stamps_.insert(t.header.stamp);
  }

  void onDiagnostics(const diagnostic_msgs::DiagnosticArrayConstPtr& msg)
  {
    const std::string suffix = ": tracker";
    for (const auto& s : msg->status)
    {
      if (s.name.size() < suffix.size() || s.name.compare(s.name.size() - suffix.size(), suffix.size(), suffix) != 0)
        continue;
      std::lock_guard<std::mutex> lock(mutex_);
      diag_.clear();
      for (const auto& kv : s.values)
        diag_[kv.key] = kv.value;
      has_status_ = true;
      status_level_ = s.level;
      status_message_ = s.message;
      cv_.notify_all();
    }
  }

  ros::NodeHandle nh_, pnh_;
  std::string tracker_, manager_;
  ros::Publisher left_pub_, right_pub_, left_info_pub_, right_info_pub_;
  ros::Subscriber target_sub_, status_sub_, tf_sub_, diag_sub_;
  std::vector<BagFrame> frames_;
  uint64_t count_ = 0;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<ros::Time, geometry_msgs::Point> targets_;
  std::map<ros::Time, stereo_pf::TrackStatus> statuses_;
  std::set<ros::Time> tf_stamps_;
  ros::Time last_stamp_;
  std::map<std::string, std::string> diag_;
  bool has_status_ = false;
  int status_level_ = 0;
  std::string status_message_;
};

Harness* harness = nullptr;

/// Teach the tracker the bag's target through ~set_target while frames flow.
void learnTarget()
{
  Harness& h = *harness;
  ros::ServiceClient client = h.nh().serviceClient<stereo_pf::SetTarget>(h.tracker() + "/set_target");
  ASSERT_TRUE(client.waitForExistence(ros::Duration(20.0)));
  stereo_pf::SetTarget srv;
  srv.request.roi = h.frame(0).roi;
  auto done = std::async(std::launch::async, [&] { return client.call(srv); });
  ASSERT_TRUE(h.publishUntil(done, 0)) << "set_target did not answer";
  ASSERT_TRUE(done.get());
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_EQ(srv.response.message.find("queued"), std::string::npos) << srv.response.message;
}

/// Track every frame of the bag; returns the errors (m) of the frames that got an estimate. `unanswered`: frames
/// without a ~status; `untracked`: frames answered but not tracked, after the first `settle` frames.
std::vector<double> trackBag(int& unanswered, int& untracked, size_t settle = 5)
{
  Harness& h = *harness;
  std::vector<double> errors;
  unanswered = untracked = 0;
  for (size_t k = 0; k < h.frames().size(); ++k)
  {
    const BagFrame& f = h.frame(k);
    stereo_pf::TrackStatus status;
    geometry_msgs::Point p;
    if (!h.stepStatus(f, status))
      ++unanswered;
    else if (status.estimate_valid && h.targetOf(h.lastStamp(), p))
      errors.push_back(distance(p, f.truth));
    else if (k >= settle)
      ++untracked;
  }
  return errors;
}

/// Step the bag from frame `k` until the tracker reports tracking for two frames in a row (the tests jump
/// around in the bag, and a jump of many centimetres is rightly a loss); returns the next frame's index, which can
/// lie past the bag's last frame (read it with Harness::frame()). Indexing frames() with it read beyond the bag: a
/// test stepping on from settleAt(50) or settleAt(60) threw std::length_error now and then (copying a frame there).
size_t settleAt(size_t k)
{
  Harness& h = *harness;
  int in_a_row = 0;
  for (size_t end = k + 40; k < end && in_a_row < 2; ++k)
  {
    stereo_pf::TrackStatus status;
    // Seen, not merely still "tracking" through the frames lost_frames allows after a jump.
    in_a_row = h.stepStatus(h.frame(k), status) && status.estimate_valid &&
                       status.support == "seen" ?
                   in_a_row + 1 :
                   0;
  }
  EXPECT_EQ(in_a_row, 2) << "not tracking again";
  return k;
}

/// Call ~set_target with the region (x, y, w, h) while frames from `first_frame` on are published (the service
/// answers between frames); `srv` holds the answer. Fails when the call does not go through.
testing::AssertionResult callSetTarget(int x, int y, int w, int height, size_t first_frame, stereo_pf::SetTarget& srv)
{
  Harness& h = *harness;
  ros::ServiceClient client = h.nh().serviceClient<stereo_pf::SetTarget>(h.tracker() + "/set_target");
  srv.request.roi.x_offset = x;
  srv.request.roi.y_offset = y;
  srv.request.roi.width = w;
  srv.request.roi.height = height;
  auto done = std::async(std::launch::async, [&] { return client.call(srv); });
  if (!h.publishUntil(done, first_frame))
    return testing::AssertionFailure() << "set_target did not answer";
  if (!done.get())
    return testing::AssertionFailure() << "the set_target call failed";
  return testing::AssertionSuccess();
}

double percentile(std::vector<double> v, double q)
{
  if (v.empty())
    return 1e9;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

/// The values of a dynamic_reconfigure server (its parameters are its component's table: no generated type).
struct ReconfigureValues
{
  std::map<std::string, double> numbers;  ///< ints and doubles
  std::map<std::string, std::string> strs;
  std::map<std::string, bool> bools;
};

/// dynamic_reconfigure's set_parameters on the server at `ns`: sends `values` and replaces them with the values the
/// server answers with (those in force). Empty `values`: only asks for them.
bool reconfigure(const std::string& ns, ReconfigureValues& values, double timeout = 5.0)
{
  const std::string service = ns + "/set_parameters";
  if (!ros::service::waitForService(service, ros::Duration(timeout)))
    return false;
  dynamic_reconfigure::Reconfigure srv;
  for (const auto& [name, value] : values.numbers)
  {
    dynamic_reconfigure::DoubleParameter p;
    p.name = name;
    p.value = value;
    srv.request.config.doubles.push_back(p);
  }
  for (const auto& [name, value] : values.strs)
  {
    dynamic_reconfigure::StrParameter p;
    p.name = name;
    p.value = value;
    srv.request.config.strs.push_back(p);
  }
  for (const auto& [name, value] : values.bools)
  {
    dynamic_reconfigure::BoolParameter p;
    p.name = name;
    p.value = value;
    srv.request.config.bools.push_back(p);
  }
  if (!ros::service::call(service, srv))
    return false;
  values = ReconfigureValues();
  for (const auto& p : srv.response.config.ints)
    values.numbers[p.name] = p.value;
  for (const auto& p : srv.response.config.doubles)
    values.numbers[p.name] = p.value;
  for (const auto& p : srv.response.config.strs)
    values.strs[p.name] = p.value;
  for (const auto& p : srv.response.config.bools)
    values.bools[p.name] = p.value;
  return true;
}

}  // namespace

TEST(Tracker, TracksTheBagWithinToleranceOfGroundTruth)
{
  Harness& h = *harness;
  ASSERT_TRUE(h.waitForTracker()) << "the tracker did not subscribe to the stereo topics";
  ASSERT_GE(h.frames().size(), 30u);
  learnTarget();
  int unanswered = 0, untracked = 0;
  const std::vector<double> errors = trackBag(unanswered, untracked);
  EXPECT_EQ(unanswered, 0) << "frames without a ~status";
  EXPECT_EQ(untracked, 0) << "frames not tracked after the first five";
  // Skip the first frames (convergence from the prior).
  const std::vector<double> settled(errors.begin() + std::min<size_t>(3, errors.size()), errors.end());
  std::printf("errors over %zu settled frames: median %.1f cm, 95%% %.1f cm, max %.1f cm\n", settled.size(),
              percentile(settled, 0.5) * 100, percentile(settled, 0.95) * 100, percentile(settled, 1.0) * 100);
  EXPECT_LT(percentile(settled, 0.5), 0.04);
  EXPECT_LT(percentile(settled, 0.95), 0.10);
}

TEST(Tracker, DebugImagesOnlyWhileSubscribed)
{
  Harness& h = *harness;
  geometry_msgs::Point p;
  settleAt(0);
  EXPECT_EQ(h.counter("debug images drawn", h.published()), 0u) << "drawn without a subscriber";

  std::mutex m;
  std::condition_variable cv;
  int received = 0;
  sensor_msgs::Image last;
  ros::Subscriber sub = h.nh().subscribe<sensor_msgs::Image>(h.tracker() + "/left/debug_image", 5,
                                                             [&](const sensor_msgs::ImageConstPtr& img) {
                                                               std::lock_guard<std::mutex> lock(m);
                                                               last = *img;
                                                               ++received;
                                                               cv.notify_all();
                                                             });
  for (size_t k = 5; k < 60; ++k)
  {
    stereo_pf::TrackStatus status;
    ASSERT_TRUE(h.stepStatus(h.frame(k), status));
    std::unique_lock<std::mutex> lock(m);
    if (cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return received >= 3; }))
      break;
  }
  {
    std::lock_guard<std::mutex> lock(m);
    ASSERT_GE(received, 3) << "no debug images while subscribed";
    EXPECT_EQ(last.width, h.frame(0).left.width);
    EXPECT_EQ(last.height, h.frame(0).left.height);
    EXPECT_EQ(last.encoding, "bgr8");
  }
  sub.shutdown();
  ros::WallDuration(1.0).sleep();  // let the disconnect reach the tracker
  stereo_pf::TrackStatus status;
  for (int k = 0; k < 3; ++k)
    ASSERT_TRUE(h.stepStatus(h.frame(k), status));
  const uint64_t drawn = h.counter("debug images drawn", h.published());
  EXPECT_GE(drawn, 3u);
  for (int k = 3; k < 10; ++k)
    ASSERT_TRUE(h.stepStatus(h.frame(k), status));
  EXPECT_EQ(h.counter("debug images drawn", h.published()), drawn) << "still drawing after the unsubscribe";
}

TEST(Tracker, BadFramesAreDroppedCountedAndTrackingContinues)
{
  Harness& h = *harness;
  geometry_msgs::Point p;
  for (size_t k = settleAt(0); k <= 10; ++k)
    ASSERT_TRUE(h.step(h.frame(k), p)) << "not tracking before the test";
  const uint64_t before_size = h.counter("dropped: size mismatch", h.published());
  const uint64_t before_image = h.counter("dropped: bad image", h.published());
  const uint64_t before_info = h.counter("dropped: bad camera_info", h.published());

  // Wrong size: the right image is half as wide as the left one and its camera_info.
  BagFrame small = h.frame(11);
  small.right.width /= 2;
  small.right.step /= 2;
  small.right.data.resize(static_cast<size_t>(small.right.step) * small.right.height);
  EXPECT_FALSE(h.step(small, p, 0.5)) << "a frame with a wrong-size image was tracked";
  // Truncated data (claims 640x480 but carries half the bytes).
  BagFrame truncated = h.frame(12);
  truncated.left.data.resize(truncated.left.data.size() / 2);
  EXPECT_FALSE(h.step(truncated, p, 0.5));
  // Unsupported encoding.
  BagFrame float_image = h.frame(13);
  float_image.left.encoding = "32FC1";
  EXPECT_FALSE(h.step(float_image, p, 0.5));
  // NaN calibration.
  BagFrame nan_info = h.frame(14);
  nan_info.right_info.P[0] = std::nan("");
  EXPECT_FALSE(h.step(nan_info, p, 0.5));

  // Tracking continues on good frames: the scene resumes where it was (frame 11) so the test measures the
  // robustness to the bad frames, not how fast the filter catches up after a gap in the motion.
  int good = 0;
  for (size_t k = 11; k < 25; ++k)
  {
    ASSERT_TRUE(h.step(h.frame(k), p)) << "no estimate after the bad frames (frame " << k << ")";
    if (distance(p, h.frame(k).truth) < 0.10)
      ++good;
  }
  EXPECT_GE(good, 12) << "tracking degraded after the bad frames";
  EXPECT_EQ(h.counter("dropped: size mismatch", h.published()), before_size + 1);
  EXPECT_EQ(h.counter("dropped: bad image", h.published()), before_image + 2);
  EXPECT_EQ(h.counter("dropped: bad camera_info", h.published()), before_info + 1);
}

TEST(Tracker, ResetRestartsTheSearchAndRecovers)
{
  Harness& h = *harness;
  ros::ServiceClient client = h.nh().serviceClient<std_srvs::Empty>(h.tracker() + "/reset");
  std_srvs::Empty srv;
  ASSERT_TRUE(client.call(srv));
  geometry_msgs::Point p;
  int good = 0;
  stereo_pf::TrackStatus status;
  ASSERT_TRUE(h.stepStatus(h.frame(0), status));
  EXPECT_EQ(status.state, stereo_pf::TrackStatus::SEARCHING) << "the first frame after ~reset";
  EXPECT_FALSE(status.estimate_valid);
  for (size_t k = 1; k < 40; ++k)
    if (h.step(h.frame(k), p) && k >= 15 && distance(p, h.frame(k).truth) < 0.08)
      ++good;
  EXPECT_GE(good, 20) << "did not re-acquire the target after ~reset";
}

TEST(Tracker, SetTargetRejectsARegionOutsideTheImage)
{
  Harness& h = *harness;
  stereo_pf::SetTarget srv;
  ASSERT_TRUE(callSetTarget(5000, 5000, 20, 20, 0, srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_FALSE(srv.response.message.empty());
  // The previous target is kept: tracking goes on.
  const size_t k = settleAt(0);
  geometry_msgs::Point p;
  int tracked = 0;
  for (size_t j = k; j < k + 10; ++j)
    tracked += h.step(h.frame(j), p) ? 1 : 0;
  EXPECT_EQ(tracked, 10);
}

TEST(Tracker, SaveAndLoadTarget)
{
  Harness& h = *harness;
  const std::string path = "/tmp/stereo_pf_rostest_target_" + std::to_string(getpid()) + ".yaml";
  ros::ServiceClient save = h.nh().serviceClient<stereo_pf::TargetFile>(h.tracker() + "/save_target");
  ros::ServiceClient load = h.nh().serviceClient<stereo_pf::TargetFile>(h.tracker() + "/load_target");
  stereo_pf::TargetFile srv;
  srv.request.path = path;
  ASSERT_TRUE(save.call(srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  ASSERT_TRUE(load.call(srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  srv.request.path = "/nonexistent/target.yaml";
  ASSERT_TRUE(load.call(srv));
  EXPECT_FALSE(srv.response.success);
  std::remove(path.c_str());
  geometry_msgs::Point p;
  int good = 0;
  for (size_t k = 0; k < 30; ++k)
    if (h.step(h.frame(k), p) && k >= 10 && distance(p, h.frame(k).truth) < 0.08)
      ++good;
  EXPECT_GE(good, 15) << "not tracking with the reloaded target";
}

TEST(Tracker, ReconfigureParticlesAndRejectAnOutOfRangeSigma)
{
  Harness& h = *harness;
  std::mutex m;
  std::condition_variable cv;
  uint32_t cloud_points = 0;
  int clouds = 0;
  ros::Subscriber sub = h.nh().subscribe<sensor_msgs::PointCloud2>(h.tracker() + "/particles", 5,
                                                                   [&](const sensor_msgs::PointCloud2ConstPtr& c) {
                                                                     std::lock_guard<std::mutex> lock(m);
                                                                     cloud_points = c->width * c->height;
                                                                     ++clouds;
                                                                     cv.notify_all();
                                                                   });
  // Connected before the frames go out (the tracker publishes the cloud only while it has subscribers).
  for (int tries = 0; tries < 100 && sub.getNumPublishers() == 0; ++tries)
    ros::WallDuration(0.05).sleep();
  const std::string engine = h.tracker() + "/engine";
  ReconfigureValues config;
  ASSERT_TRUE(reconfigure(engine, config));
  const ReconfigureValues original = config;
  config.numbers["particles"] = 50;
  config.numbers["resample_threshold"] = 0.0;  // never resample: every particle stays a distinct point
  ASSERT_TRUE(reconfigure(engine, config));
  EXPECT_EQ(config.numbers["particles"], 50) << "the server answered with other values";
  stereo_pf::TrackStatus status;
  for (size_t k = 0; k < 20; ++k)
    ASSERT_TRUE(h.stepStatus(h.frame(k), status));  // a new particle count restarts the search
  {
    std::unique_lock<std::mutex> lock(m);
    ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(3), [&] { return clouds > 0; }));
    EXPECT_LE(cloud_points, 50u);
    EXPECT_GT(cloud_points, 10u);
  }

  // ColourHSI accepts sigma up to 10: 40 is rejected whole (with the valid weight sent beside it), and the server is
  // answered with the values in force, so a later valid change is not refused with it.
  const std::string colour = h.tracker() + "/colour";
  ReconfigureValues cue;
  ASSERT_TRUE(reconfigure(colour, cue));
  ASSERT_EQ(cue.numbers.count("sigma"), 1u) << "ColourHSI's sigma is not served";
  const double sigma = cue.numbers["sigma"];
  cue.numbers["sigma"] = 40.0;
  cue.numbers["weight"] = 0.9;
  ASSERT_TRUE(reconfigure(colour, cue));
  EXPECT_DOUBLE_EQ(cue.numbers["sigma"], sigma) << "the rejected sigma stayed in the server";
  EXPECT_DOUBLE_EQ(cue.numbers["weight"], 1.0) << "part of a rejected change was applied";
  for (size_t k = 20; k < 30; ++k)
    ASSERT_TRUE(h.stepStatus(h.frame(k), status)) << "no status after a rejected reconfigure";
  EXPECT_EQ(h.counter("dropped: processing error", h.published()), 0u);
  cue.numbers["weight"] = 0.9;  // valid alone: accepted
  ASSERT_TRUE(reconfigure(colour, cue));
  EXPECT_DOUBLE_EQ(cue.numbers["weight"], 0.9);
  ReconfigureValues shown;
  ASSERT_TRUE(reconfigure(colour, shown));
  EXPECT_DOUBLE_EQ(shown.numbers["weight"], 0.9);
  EXPECT_DOUBLE_EQ(shown.numbers["sigma"], sigma);
  cue.numbers["weight"] = 1.0;
  ASSERT_TRUE(reconfigure(colour, cue));

  // An estimator the engine does not know: refused, the server shows the one in force; then a valid change works.
  config.strs["estimator"] = "bogus";
  ASSERT_TRUE(reconfigure(engine, config));
  EXPECT_EQ(config.strs["estimator"], original.strs.at("estimator"));
  EXPECT_EQ(config.numbers["particles"], 50);
  config.numbers["resample_threshold"] = 0.5;
  ASSERT_TRUE(reconfigure(engine, config));
  EXPECT_DOUBLE_EQ(config.numbers["resample_threshold"], 0.5);
  EXPECT_EQ(config.strs["estimator"], original.strs.at("estimator"));

  config = original;
  ASSERT_TRUE(reconfigure(engine, config));
  EXPECT_EQ(config.numbers["particles"], original.numbers.at("particles"));
  geometry_msgs::Point p;
  int tracked = 0;
  for (size_t k = 0; k < 30; ++k)
    tracked += h.step(h.frame(k), p) && distance(p, h.frame(k).truth) < 0.08 ? 1 : 0;
  EXPECT_GE(tracked, 20) << "not tracking again with the original configuration";
}

// Issue 12: three frames with an all-zero calibration (or left/right sizes that differ) stopped tracking
// for good. Each bad frame is dropped and counted; the next good frame is tracked.
TEST(Tracker, BadCameraInfoDropsThatFrameOnly)
{
  Harness& h = *harness;
  geometry_msgs::Point p;
  for (size_t k = settleAt(30); k <= 42; ++k)
    ASSERT_TRUE(h.step(h.frame(k), p)) << "not tracking before the test";
  const uint64_t before = h.counter("dropped: bad camera_info", h.published());
  // The bad sets carry frame 43's images and the good one after them too, so the test measures the recovery
  // from the bad camera_info, not from a gap in the motion.
  for (int k = 0; k < 3; ++k)
  {
    BagFrame zero = h.frame(43);
    std::fill(zero.right_info.K.begin(), zero.right_info.K.end(), 0.0);
    std::fill(zero.right_info.P.begin(), zero.right_info.P.end(), 0.0);
    stereo_pf::TrackStatus status;
    EXPECT_FALSE(h.stepStatus(zero, status, 0.5)) << "a frame with an all-zero camera_info was tracked";
  }
  ASSERT_TRUE(h.step(h.frame(43), p)) << "the first good frame after bad camera_info was not tracked";
  EXPECT_LT(distance(p, h.frame(43).truth), 0.10);
  for (int k = 0; k < 3; ++k)
  {
    BagFrame small = h.frame(44);
    small.right_info.width /= 2;
    stereo_pf::TrackStatus status;
    EXPECT_FALSE(h.stepStatus(small, status, 0.5));
  }
  ASSERT_TRUE(h.step(h.frame(44), p)) << "the first good frame after camera_info sizes that differ";
  EXPECT_LT(distance(p, h.frame(44).truth), 0.10);
  EXPECT_EQ(h.counter("dropped: bad camera_info", h.published()), before + 6);
}

// The estimate is on the wire only while tracking: a target learned from a patch of wall (the background
// explains it as well) is never tracked, and neither ~target nor TF is published; ~status says why.
TEST(Tracker, NoEstimateOrTfWhileNotTracking)
{
  Harness& h = *harness;
  stereo_pf::SetTarget wall;
  ASSERT_TRUE(callSetTarget(20, 20, 40, 40, 0, wall));
  bool acquire = true;
  ros::NodeHandle("~").getParam(h.tracker() + "/engine/acquire", acquire);
  if (acquire)
  {
    // Acquisition (the default) matches the box in the right image first: a box of wall has no match, so it is
    // refused, naming the box, and the previous target is kept.
    EXPECT_FALSE(wall.response.success);
    EXPECT_NE(wall.response.message.find("box 20,20,40,40"), std::string::npos) << wall.response.message;
    EXPECT_NE(wall.response.message.find("previous target"), std::string::npos) << wall.response.message;
  }
  else
    ASSERT_TRUE(wall.response.success) << wall.response.message;
  int like_background = 0;
  for (size_t k = 0; k < 30 && !acquire; ++k)
  {
    stereo_pf::TrackStatus status;
    ASSERT_TRUE(h.stepStatus(h.frame(k), status)) << "no ~status for frame " << k;
    EXPECT_NE(status.state, stereo_pf::TrackStatus::TRACKING) << "frame " << k << ": " << status.message;
    EXPECT_FALSE(status.estimate_valid);
    EXPECT_FALSE(h.anyEstimateAt(h.lastStamp(), 0.05)) << "an estimate or TF while " << status.state_name;
    like_background += status.support == "like background" ? 1 : 0;
    EXPECT_FALSE(status.message.empty());
  }
  EXPECT_TRUE(acquire || like_background > 0);
  std::string message;
  EXPECT_TRUE(acquire || h.waitForStatus([](int level, const std::string&) { return level == diagnostic_msgs::DiagnosticStatus::WARN; },
                              message, 5.0))
      << message;

  // The right target again: tracked, with ~target, TF and the frames since acquisition counting up.
  learnTarget();
  geometry_msgs::Point p;
  stereo_pf::TrackStatus status;
  uint32_t frames_in_state = 0;
  int tracked = 0;
  for (size_t k = 0; k < 20; ++k)
  {
    ASSERT_TRUE(h.stepStatus(h.frame(k), status));
    if (status.state == stereo_pf::TrackStatus::TRACKING)
    {
      ++tracked;
      EXPECT_TRUE(status.estimate_valid);
      EXPECT_TRUE(h.targetOf(h.lastStamp(), p));
      EXPECT_GT(status.frames_in_state, frames_in_state);
      frames_in_state = status.frames_in_state;
      EXPECT_GT(status.latency, 0.0);
      EXPECT_GE(status.latency, status.processing_time);
    }
  }
  EXPECT_GE(tracked, 15);
  EXPECT_TRUE(h.anyEstimateAt(h.lastStamp())) << "no TF while tracking";
}

// ~load_target is all or nothing: a file without one cue's entry answers success: false and changes nothing.
TEST(Tracker, LoadTargetWithoutACueChangesNothing)
{
  Harness& h = *harness;
  const std::string path = "/tmp/stereo_pf_rostest_partial_" + std::to_string(getpid()) + ".yaml";
  ros::ServiceClient save = h.nh().serviceClient<stereo_pf::TargetFile>(h.tracker() + "/save_target");
  ros::ServiceClient load = h.nh().serviceClient<stereo_pf::TargetFile>(h.tracker() + "/load_target");
  stereo_pf::TargetFile srv;
  srv.request.path = path;
  ASSERT_TRUE(save.call(srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  std::string full;
  {
    std::ifstream in(path);
    full.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const size_t contour = full.find("\ncolour_contour:");
  ASSERT_NE(contour, std::string::npos) << full.substr(0, 200);
  // The colour histogram of a wall patch, without the outline's entry: a file from another configuration.
  {
    std::ofstream out(path);
    out << full.substr(0, contour + 1);
  }
  ASSERT_TRUE(load.call(srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_NE(srv.response.message.find("colour_contour"), std::string::npos) << srv.response.message;
  // Nothing changed: the target saved now is the one saved before.
  srv.request.path = path + ".after";
  ASSERT_TRUE(save.call(srv));
  std::string after;
  {
    std::ifstream in(path + ".after");
    after.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  EXPECT_EQ(after, full) << "a failed ~load_target changed the target";
  std::remove(path.c_str());
  std::remove((path + ".after").c_str());
  geometry_msgs::Point p;
  int good = 0;
  const size_t k0 = settleAt(50);
  for (size_t k = k0; k < k0 + 15; ++k)
    good += h.step(h.frame(k), p) && distance(p, h.frame(k).truth) < 0.08 ? 1 : 0;
  EXPECT_GE(good, 14) << "tracking worse after a failed ~load_target";
}

// Overload: frames arriving faster than the tracker works are dropped on purpose (the newest is kept),
// counted, and the diagnostics say what to do; the latency includes the wait.
TEST(Tracker, OverloadIsCountedAndExplained)
{
  Harness& h = *harness;
  const std::string engine = h.tracker() + "/engine";
  ReconfigureValues config;
  ASSERT_TRUE(reconfigure(engine, config));
  const ReconfigureValues original = config;
  config.numbers["particles"] = 40000;
  ASSERT_TRUE(reconfigure(engine, config));
  stereo_pf::TrackStatus status;
  ASSERT_TRUE(h.stepStatus(h.frame(0), status, 10.0));  // applied
  // Counters at rest: every set received is tracked or dropped (none in flight).
  auto at_rest = [&h](std::map<std::string, std::string>& d, uint64_t received) {
    for (int tries = 0; tries < 100; ++tries)
    {
      if (h.diagnostics(d, received) &&
          std::stoull(d["frames tracked"]) + std::stoull(d["dropped frames"]) + std::stoull(d["dropped: no target"]) ==
              std::stoull(d["frames received"]))
        return true;
      ros::WallDuration(0.1).sleep();
    }
    return false;
  };
  std::map<std::string, std::string> d;
  ASSERT_TRUE(at_rest(d, h.published()));
  const uint64_t received = std::stoull(d["frames received"]), tracked = std::stoull(d["frames tracked"]),
                 overload = std::stoull(d["dropped: overload"]);
  const int burst = 12;
  for (int k = 1; k <= burst; ++k)
  {
    h.publish(h.frame(k));
    ros::WallDuration(0.01).sleep();  // 100 Hz: far faster than 40000 particles are weighed
  }
  std::string message;
  const bool warned = h.waitForStatus(
      [](int level, const std::string& text) {
        return level == diagnostic_msgs::DiagnosticStatus::WARN && text.find("overloaded") != std::string::npos;
      },
      message, 15.0);
  EXPECT_TRUE(warned) << message;
  EXPECT_NE(message.find("fewer particles"), std::string::npos) << message;
  ASSERT_TRUE(at_rest(d, received + burst));
  const uint64_t new_tracked = std::stoull(d["frames tracked"]) - tracked;
  const uint64_t new_overload = std::stoull(d["dropped: overload"]) - overload;
  EXPECT_EQ(std::stoull(d["frames received"]), received + burst);
  EXPECT_GT(new_overload, 0u) << "no frame dropped although the tracker could not keep up";
  EXPECT_GE(new_tracked, 1u);
  EXPECT_EQ(new_tracked + new_overload, static_cast<uint64_t>(burst)) << "a frame vanished uncounted";

  config = original;
  ASSERT_TRUE(reconfigure(engine, config));
  geometry_msgs::Point p;
  int good = 0;
  for (size_t k = 0; k < 30; ++k)
    good += h.step(h.frame(k), p) && distance(p, h.frame(k).truth) < 0.08 ? 1 : 0;
  EXPECT_GE(good, 20);
}

// A right image stamped 1 ms off leaves two incomplete ExactTime sets (left at t, right at t + 1 ms): one
// camera frame, one dropped frame (it was counted twice). So does a left camera_info stamped 1 ms off (the
// images and the right camera_info at t, the left camera_info alone at t + 1 ms; it was counted twice too).
TEST(Tracker, ASkewedFrameIsCountedOnce)
{
  Harness& h = *harness;
  uint64_t skewed = 0;  // sets published that never completed
  for (const bool left_info : { false, true })
  {
    SCOPED_TRACE(left_info ? "left camera_info skewed" : "right image skewed");
    const size_t k = settleAt(60);
    const uint64_t unpaired = h.counter("unpaired stereo sets", h.published() - skewed);
    const uint64_t out_of_sync = h.counter("dropped: out of sync", h.published() - skewed);
    h.publishSkewed(h.frame(k), 0.001, left_info);
    ++skewed;
    // ExactTime gives up on the two incomplete sets once later sets push them out of its queue.
    stereo_pf::TrackStatus status;
    for (size_t j = k + 1; j < k + 11; ++j)
      h.stepStatus(h.frame(j), status);
    const uint64_t complete = h.published() - skewed;
    EXPECT_EQ(h.counter("unpaired stereo sets", complete), unpaired + 2);
    EXPECT_EQ(h.counter("dropped: out of sync", complete), out_of_sync + 1);
  }
}

// Frames are tracked in the order of their stamps. A late frame (stamped before the last one tracked) and a
// repeated one show the pendulum far from where it is: both are dropped and counted, and the track goes on where the
// object is. Stamps that go back and stay back (the bag played again, 100 s earlier) are taken from the third such
// frame on: the track starts afresh there and finds the object again.
TEST(Tracker, LateFramesAreDroppedAndTimeGoneBackRestarts)
{
  Harness& h = *harness;
  geometry_msgs::Point p;
  size_t k = settleAt(10);
  ASSERT_TRUE(h.step(h.frame(k), p)) << "not tracking before the test";
  const ros::Time tracked = h.lastStamp();
  const uint64_t before = h.counter("dropped: out of order", 0);
  // The bag's frame farthest from k (half the bag away was only 10 cm off for some k: which k settleAt() returns
  // depends on the tests before).
  size_t away = 0;
  for (size_t j = 1; j < h.frames().size(); ++j)
    if (distance(h.frame(j).truth, h.frame(k).truth) > distance(h.frame(away).truth, h.frame(k).truth))
      away = j;
  ASSERT_GT(distance(h.frame(away).truth, h.frame(k).truth), 0.2) << "the test needs a frame far from k";
  stereo_pf::TrackStatus status;
  // (0.5 ms off the stamps of 30 Hz: no earlier frame had this one.)
  EXPECT_FALSE(h.stepStatus(h.frame(away), status, 1.0, tracked - ros::Duration(0.5005))) << "a late frame tracked";
  h.forgetStatus(tracked);
  EXPECT_FALSE(h.stepStatus(h.frame(away), status, 1.0, tracked)) << "a repeated frame tracked";
  for (int i = 1; i <= 5; ++i)
  {
    ASSERT_TRUE(h.stepStatus(h.frame(k + i), status)) << "no ~status after the late frames";
    EXPECT_EQ(status.state, stereo_pf::TrackStatus::TRACKING);
    ASSERT_TRUE(h.targetOf(h.lastStamp(), p));
    // (What the frame said, for a failure seen once in CI and not reproduced since: the track 1.0-1.6 m off from
    // the first frame after the late ones on, then lost.)
    EXPECT_LT(distance(p, h.frame(k + i).truth), 0.05)
        << "the track moved after the late frames: frame k + " << i << " (k = " << k << "), " << status.support
        << ", evidence " << status.evidence << ", ESS " << status.ess << ", " << status.frames_in_state
        << " frames in this state; dropped " << status.frames_dropped << " of " << status.frames_received;
  }
  EXPECT_EQ(h.counterReaching("dropped: out of order", before + 2), before + 2);

  // The bag again from its first frame, stamped 100 s before the last frame tracked.
  const ros::Time back = h.lastStamp() - ros::Duration(100.0005);
  int answered = 0, good = 0;
  for (size_t j = 0; j < 40; ++j)
  {
    const bool got = h.stepStatus(h.frame(j), status, j < 2 ? 1.0 : 3.0, back + ros::Duration(j / 30.0));
    answered += got ? 1 : 0;
    if (j < 2)
      EXPECT_FALSE(got) << "frame " << j << " of the stamps gone back was tracked";
    else if (j == 2)
    {
      EXPECT_TRUE(got) << "the stamps gone back were not taken after three frames";
      EXPECT_EQ(status.state, stereo_pf::TrackStatus::SEARCHING) << "the track did not start afresh";
    }
    else if (j >= 20 && got && status.estimate_valid && h.targetOf(h.lastStamp(), p) &&
             distance(p, h.frame(j).truth) < 0.05)
      ++good;
  }
  EXPECT_EQ(answered, 38);
  EXPECT_GE(good, 18) << "not tracked again after the stamps went back";
  EXPECT_EQ(h.counterReaching("dropped: out of order", before + 4), before + 4);
}

// ~publish_when_lost (the node test sets it): whenever no estimate is given (not tracking, or a frame of the track
// that does not see the object), ~target repeats the last given position, ~status marks it invalid, and no TF goes
// out.
TEST(Tracker, HeldEstimateWhileNotTrackingIsMarked)
{
  Harness& h = *harness;
  bool held = false;
  ros::NodeHandle("~").getParam(h.tracker() + "/publish_when_lost", held);
  if (!held)
    GTEST_SKIP() << "~publish_when_lost is not set for this tracker";
  geometry_msgs::Point last;
  const size_t k = settleAt(20);
  ASSERT_TRUE(h.step(h.frame(k), last));
  stereo_pf::SetTarget wall;
  ASSERT_TRUE(callSetTarget(20, 20, 40, 40, k + 1, wall));
  ASSERT_TRUE(wall.response.success) << wall.response.message;
  // A new target clears the held one: nothing to repeat until something is tracked.
  stereo_pf::TrackStatus status;
  geometry_msgs::Point p;
  for (size_t j = 0; j < 5; ++j)
  {
    ASSERT_TRUE(h.stepStatus(h.frame(j), status));
    EXPECT_FALSE(status.estimate_valid);
    EXPECT_FALSE(h.anyEstimateAt(h.lastStamp(), 0.05)) << "an estimate held across a new target";
  }
  // Track the right target again, then lose it: the frames go blank (the object gone from view).
  learnTarget();
  const size_t t = settleAt(0);
  ASSERT_TRUE(h.step(h.frame(t), last));
  BagFrame blank = h.frame(t + 1);
  std::fill(blank.left.data.begin(), blank.left.data.end(), 128);
  std::fill(blank.right.data.begin(), blank.right.data.end(), 128);
  int repeated = 0;
  for (size_t j = 0; j < 10; ++j)
  {
    ASSERT_TRUE(h.stepStatus(blank, status));
    // The track is kept over the first blank frames (engine/lost_frames), but they see nothing: no estimate of theirs.
    EXPECT_FALSE(status.estimate_valid) << "an estimate given on blank frame " << j << " (" << status.support << ")";
    ASSERT_TRUE(h.targetOf(h.lastStamp(), p)) << "no held estimate while " << status.state_name;
    EXPECT_FALSE(h.tfAt(h.lastStamp(), 0.05)) << "a TF of a held estimate";
    EXPECT_EQ(p.x, last.x);
    EXPECT_EQ(p.z, last.z);
    ++repeated;
  }
  EXPECT_GT(repeated, 0) << "blank frames were not a loss";
  learnTarget();
}

TEST(Tracker, MisspeltParametersAreNamedInTheDiagnostics)
{
  Harness& h = *harness;
  std::map<std::string, std::string> d;
  ASSERT_TRUE(h.diagnostics(d, 0));
  EXPECT_NE(d["unknown parameters"].find("'publish_tff' (ignored): did you mean 'publish_tf'?"), std::string::npos)
      << d["unknown parameters"];
}

TEST(BadPlugin, UnknownTypeIsExplainedAndTheManagerSurvives)
{
  Harness& h = *harness;
  std::string message;
  const bool explained = h.waitForStatus(
      [](int level, const std::string& text) {
        return level == diagnostic_msgs::DiagnosticStatus::ERROR && text.find("unknown type") != std::string::npos;
      },
      message, 20.0);
  ASSERT_TRUE(explained) << "no ERROR diagnostics explaining the unknown type; last: " << message;
  EXPECT_NE(message.find("stereo_pf/NoSuchCue"), std::string::npos) << message;
  EXPECT_NE(message.find("stereo_pf/ColourHSI"), std::string::npos) << "the declared types are not listed: " << message;

  // The manager is alive and still lists the (inert) tracker.
  ros::ServiceClient list = h.nh().serviceClient<nodelet::NodeletList>(h.manager() + "/list");
  ASSERT_TRUE(list.waitForExistence(ros::Duration(10.0)));
  nodelet::NodeletList srv;
  ASSERT_TRUE(list.call(srv));
  EXPECT_NE(std::find(srv.response.nodelets.begin(), srv.response.nodelets.end(), h.tracker()),
            srv.response.nodelets.end());
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_ros_tracker");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  Harness h;
  harness = &h;
  const int result = RUN_ALL_TESTS();
  harness = nullptr;
  spinner.stop();
  ros::shutdown();
  return result;
}
