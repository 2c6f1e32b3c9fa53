// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// scene_publisher: render a synthetic scene (scenes/*.yaml, as make_scene) live, in real time, on
// camera1394stereo's topics, so the tracker, rviz and the tests run without a camera.
//
// Publishes (stamps = the wall/ROS time of publishing, identical for the four camera messages of a frame,
// so ExactTime sync works and ~target's header stamp measures the pipeline latency):
//   <camera>/left/image_raw, <camera>/right/image_raw       sensor_msgs/Image bgr8 (image_transport)
//   <camera>/left/camera_info, <camera>/right/camera_info   sensor_msgs/CameraInfo of the rectified pair
//   ground_truth/target          geometry_msgs/PointStamped, the target's centre (left optical frame)
//   ground_truth/target_roi      sensor_msgs/RegionOfInterest, its box in the left image
//   ground_truth/target_visible  std_msgs/Bool
// Parameters (private): scene (file; default: this package's scenes/pendulum_uncluttered.yaml), rate (Hz;
// default the scene's fps), loop (true: start again after the last frame), frames (0: the scene's count),
// noise (true), camera ("stereo_camera": topic namespace), frame_id ("stereo_camera_optical_frame").
#include <cmath>
#include <memory>
#include <string>

#include <geometry_msgs/PointStamped.h>
#include <image_transport/image_transport.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/RegionOfInterest.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/Bool.h>

#include "stereo_pf/sim/scene.h"

namespace
{
// The rectified pair as ROS camera_info (same convention as make_scene: zero distortion, R = I,
// the right camera's P[3] = -fx * baseline).
sensor_msgs::CameraInfoPtr cameraInfo(const stereo_pf::StereoGeometry& g, bool right, const std_msgs::Header& header)
{
  auto info = boost::make_shared<sensor_msgs::CameraInfo>();
  info->header = header;
  info->width = static_cast<uint32_t>(g.width());
  info->height = static_cast<uint32_t>(g.height());
  info->distortion_model = "plumb_bob";
  info->D.assign(5, 0.0);
  info->K = { g.fx(), 0.0, g.cx(), 0.0, g.fy(), g.cy(), 0.0, 0.0, 1.0 };
  info->R = { 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0 };
  info->P = { g.fx(), 0.0, g.cx(), right ? -g.fx() * g.baseline() : 0.0, 0.0, g.fy(), g.cy(), 0.0, 0.0, 0.0, 1.0, 0.0 };
  return info;
}

// Render one view straight into a new message's buffer (no copy; a new message per frame because
// subscribers in the same process may still hold the previous one).
sensor_msgs::ImagePtr renderImage(stereo_pf::SceneRenderer& renderer, int k, stereo_pf::View view, bool noise,
                                  const std_msgs::Header& header)
{
  const stereo_pf::StereoGeometry g = renderer.geometry();
  auto msg = boost::make_shared<sensor_msgs::Image>();
  msg->header = header;
  msg->width = static_cast<uint32_t>(g.width());
  msg->height = static_cast<uint32_t>(g.height());
  msg->encoding = sensor_msgs::image_encodings::BGR8;
  msg->step = msg->width * 3;
  msg->data.resize(static_cast<size_t>(msg->step) * msg->height);
  cv::Mat view_of_msg(g.height(), g.width(), CV_8UC3, msg->data.data(), msg->step);
  renderer.renderView(k, view, view_of_msg, noise);
  return msg;
}
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "scene_publisher");
  ros::NodeHandle nh, pnh("~");

  std::string scene_path, camera, frame_id;
  double rate = 0.0;
  bool loop = true, noise = true;
  int frames = 0;
  pnh.param<std::string>("scene", scene_path, ros::package::getPath("stereo_pf") + "/scenes/pendulum_uncluttered.yaml");
  pnh.param("rate", rate, 0.0);
  pnh.param("loop", loop, true);
  pnh.param("frames", frames, 0);
  pnh.param("noise", noise, true);
  pnh.param<std::string>("camera", camera, "stereo_camera");
  pnh.param<std::string>("frame_id", frame_id, "stereo_camera_optical_frame");

  std::unique_ptr<stereo_pf::SceneRenderer> renderer;
  try
  {
    stereo_pf::SceneDescription scene = stereo_pf::loadScene(scene_path);
    if (frames > 0)
      scene.frames = frames;
    scene.target_roi_frame = std::min(scene.target_roi_frame, scene.frames - 1);
    renderer = std::make_unique<stereo_pf::SceneRenderer>(scene);
  }
  catch (const std::exception& e)
  {
    ROS_FATAL("scene_publisher: %s", e.what());
    return 1;
  }
  if (!(rate > 0.0))
    rate = renderer->scene().fps;

  ros::NodeHandle camera_nh(nh, camera);
  image_transport::ImageTransport it(camera_nh);
  image_transport::CameraPublisher left_pub = it.advertiseCamera("left/image_raw", 2);
  image_transport::CameraPublisher right_pub = it.advertiseCamera("right/image_raw", 2);
  ros::Publisher truth_pub = nh.advertise<geometry_msgs::PointStamped>("ground_truth/target", 10);
  ros::Publisher roi_pub = nh.advertise<sensor_msgs::RegionOfInterest>("ground_truth/target_roi", 10);
  ros::Publisher visible_pub = nh.advertise<std_msgs::Bool>("ground_truth/target_visible", 10);

  ROS_INFO("scene_publisher: '%s' (%d frames, %dx%d) at %.1f Hz on %s/{left,right}/image_raw%s",
           renderer->scene().name.c_str(), renderer->frames(), renderer->geometry().width(),
           renderer->geometry().height(), rate, camera_nh.getNamespace().c_str(), loop ? ", looping" : "");

  const stereo_pf::StereoGeometry geometry = renderer->geometry();
  ros::Rate period(rate);
  uint32_t seq = 0;
  for (int k = 0; ros::ok(); ++seq)
  {
    std_msgs::Header header;
    header.seq = seq;
    header.frame_id = frame_id;
    // Render first, stamp last: the stamp is the moment the frame "leaves the camera".
    sensor_msgs::ImagePtr left = renderImage(*renderer, k, stereo_pf::View::Left, noise, header);
    sensor_msgs::ImagePtr right = renderImage(*renderer, k, stereo_pf::View::Right, noise, header);
    header.stamp = ros::Time::now();
    left->header.stamp = right->header.stamp = header.stamp;

    // Ground truth (and the region the tracker may learn the target from) before the images.
    const cv::Rect box = renderer->targetRoi(k);
    auto roi = boost::make_shared<sensor_msgs::RegionOfInterest>();
    roi->x_offset = static_cast<uint32_t>(std::max(box.x, 0));
    roi->y_offset = static_cast<uint32_t>(std::max(box.y, 0));
    roi->width = static_cast<uint32_t>(std::max(box.width, 0));
    roi->height = static_cast<uint32_t>(std::max(box.height, 0));
    roi_pub.publish(roi);
    const Eigen::Vector3d p = renderer->targetPosition(k);
    auto truth = boost::make_shared<geometry_msgs::PointStamped>();
    truth->header = header;
    truth->point.x = p.x();
    truth->point.y = p.y();
    truth->point.z = p.z();
    truth_pub.publish(truth);
    auto visible = boost::make_shared<std_msgs::Bool>();
    visible->data = renderer->targetVisible(k);
    visible_pub.publish(visible);

    left_pub.publish(left, cameraInfo(geometry, false, header));
    right_pub.publish(right, cameraInfo(geometry, true, header));

    ros::spinOnce();
    period.sleep();
    if (++k >= renderer->frames())
    {
      if (!loop)
        break;
      k = 0;
    }
  }
  return 0;
}
