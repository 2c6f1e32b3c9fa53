// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// ground_truth_matcher: republish the ground truth of the frame each estimate was computed from, when that
// estimate arrives, so rviz draws the truth and the estimate of one and the same frame.
//
// scene_publisher (and a make_scene bag) publishes a frame's ground truth just before its images; the
// tracker's estimate of that frame follows milliseconds later, or frames later when the machine is busy
// (rviz itself takes a core). rviz draws the newest message of each topic, and takes one or two more of its
// update cycles for a marker than for a point, so the truth it showed ran ahead of the estimate: on the
// pendulum it was drawn 5-8 cm away from an estimate that was within 1 cm of the truth of its own frame.
// Here the truth is published as markers too, with the estimate's stamp, when the estimate arrives: rviz
// takes them through the same steps as the tracker's estimate markers and draws the two together.
//
// Subscribes: ground_truth/target  geometry_msgs/PointStamped (the scene's ground truth)
//             estimate             geometry_msgs/PointStamped (remap to the tracker's ~target)
// Publishes (each once the estimate is in, with the estimate's stamp):
//             ground_truth/matched geometry_msgs/PointStamped: the truth of the estimate's frame
//             ground_truth/markers visualization_msgs/MarkerArray: that truth as a white sphere ("ground_truth",
//                                  ~radius) and a magenta line from the estimate to it ("error")
//             ground_truth/error   std_msgs/Float64: the distance between the two, metres
// Parameters (private): history (frames of ground truth or estimates kept while waiting for their match,
// default 300), radius (of the truth's sphere, m, default 0.012).
#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>

#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <visualization_msgs/MarkerArray.h>

namespace
{
class GroundTruthMatcher
{
public:
  explicit GroundTruthMatcher(ros::NodeHandle& nh, ros::NodeHandle& pnh)
  {
    pnh.param("history", history_, 300);
    pnh.param("radius", radius_, 0.012);
    history_ = std::max(history_, 1);
    matched_pub_ = nh.advertise<geometry_msgs::PointStamped>("ground_truth/matched", 10);
    markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>("ground_truth/markers", 10);
    error_pub_ = nh.advertise<std_msgs::Float64>("ground_truth/error", 10);
    truth_sub_ = nh.subscribe("ground_truth/target", 100, &GroundTruthMatcher::onTruth, this,
                              ros::TransportHints().tcpNoDelay());
    estimate_sub_ = nh.subscribe("estimate", 100, &GroundTruthMatcher::onEstimate, this,
                                 ros::TransportHints().tcpNoDelay());
  }

private:
  using Point = geometry_msgs::PointStamped;

  void onTruth(const Point::ConstPtr& truth)
  {
    // Usually the truth comes first; an estimate that was faster waits for it.
    const auto waiting = estimates_.find(truth->header.stamp);
    if (waiting != estimates_.end())
    {
      publish(*truth, *waiting->second);
      estimates_.erase(waiting);
      return;
    }
    remember(truths_, truth);
  }

  void onEstimate(const Point::ConstPtr& estimate)
  {
    const auto truth = truths_.find(estimate->header.stamp);
    if (truth == truths_.end())
    {
      remember(estimates_, estimate);
      return;
    }
    publish(*truth->second, *estimate);
    // Older truths will not be matched any more (estimates come in stamp order).
    truths_.erase(truths_.begin(), std::next(truth));
  }

  // A time going backwards (a bag played again) leaves old entries; the size bound removes them.
  void remember(std::map<ros::Time, Point::ConstPtr>& store, const Point::ConstPtr& msg)
  {
    store[msg->header.stamp] = msg;
    while (static_cast<int>(store.size()) > history_)
      store.erase(store.begin());
  }

  void publish(const Point& truth, const Point& estimate)
  {
    auto matched = boost::make_shared<Point>(truth);
    matched->header.stamp = estimate.header.stamp;
    matched_pub_.publish(matched);
    auto error = boost::make_shared<std_msgs::Float64>();
    const double dx = truth.point.x - estimate.point.x, dy = truth.point.y - estimate.point.y,
                 dz = truth.point.z - estimate.point.z;
    error->data = std::sqrt(dx * dx + dy * dy + dz * dz);
    error_pub_.publish(error);

    if (markers_pub_.getNumSubscribers() == 0)
      return;
    auto markers = boost::make_shared<visualization_msgs::MarkerArray>();
    visualization_msgs::Marker sphere;
    sphere.header = matched->header;
    sphere.ns = "ground_truth";
    sphere.type = visualization_msgs::Marker::SPHERE;
    sphere.action = visualization_msgs::Marker::ADD;
    sphere.pose.position = truth.point;
    sphere.pose.orientation.w = 1.0;
    sphere.scale.x = sphere.scale.y = sphere.scale.z = 2.0 * radius_;
    sphere.color.r = sphere.color.g = sphere.color.b = sphere.color.a = 1.0f;
    markers->markers.push_back(sphere);
    visualization_msgs::Marker line = sphere;
    line.ns = "error";
    line.type = visualization_msgs::Marker::LINE_LIST;
    line.pose.position = geometry_msgs::Point();
    line.scale.x = 0.003;
    line.scale.y = line.scale.z = 0.0;
    line.color.g = 0.0f;  // magenta
    line.points = { estimate.point, truth.point };
    markers->markers.push_back(line);
    markers_pub_.publish(markers);
  }

  int history_ = 300;
  double radius_ = 0.012;
  std::map<ros::Time, Point::ConstPtr> truths_, estimates_;
  ros::Publisher matched_pub_, markers_pub_, error_pub_;
  ros::Subscriber truth_sub_, estimate_sub_;
};
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "ground_truth_matcher");
  ros::NodeHandle nh, pnh("~");
  GroundTruthMatcher matcher(nh, pnh);
  ros::spin();
  return 0;
}
