// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// make_scene: render a synthetic stereo scene (scenes/*.yaml) into a bag that looks like a
// camera1394stereo recording of a rectified pair, plus ground truth for evaluation.
//
// Topics (all stamps identical per stereo frame, frame_id "stereo_camera_optical_frame", the left
// rectified camera's optical frame; bag time = header stamp; frame k is stamped 1000 s + k / fps so
// the output is deterministic):
//   stereo_camera/left/image_raw, stereo_camera/right/image_raw      sensor_msgs/Image, bgr8 (or the
//       scene's sensor.encoding: rgb8, mono8, mono16, bayer_grbg8)
//   stereo_camera/left/camera_info, stereo_camera/right/camera_info  sensor_msgs/CameraInfo (rectified:
//       plumb_bob with zero D, R = I, P[3] = -fx * baseline on the right camera; with the scene's
//       sensor.camera_info: size_only, only width and height, as an uncalibrated camera1394stereo)
//   ground_truth/target          geometry_msgs/PointStamped, centre of the target (first object)
//   ground_truth/target_roi      sensor_msgs/RegionOfInterest, its bounding box in the left image
//   ground_truth/target_visible  std_msgs/Bool, present and at least half visible in both images
//   ground_truth/others          geometry_msgs/PoseArray, centres of the other objects present (scenes
//       with more than one object only; position only, identity orientation), for judging whether a
//       tracker locked onto the wrong object
// No roscore is needed.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/PoseArray.h>
#include <opencv2/imgcodecs.hpp>
#include <ros/time.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/RegionOfInterest.h>
#include <std_msgs/Bool.h>

#include "stereo_pf/sim/scene.h"
#include "stereo_pf/sim/scene_sensor.h"

namespace
{
const char* const kFrameId = "stereo_camera_optical_frame";
const uint64_t kEpochNsec = 1000ULL * 1000000000ULL;  // first stamp: 1000 s (fixed, not the wall clock)

void usage(std::ostream& out)
{
  out << "usage: make_scene SCENE.yaml OUTPUT.bag [options]\n"
         "  --frames N          render N frames instead of the scene's count\n"
         "  --seed S            sensor noise seed (overrides the scene's noise.seed)\n"
         "  --compression C     bag chunk compression: none (default), lz4 or bz2\n"
         "  --dump-png DIR      also write left/right PNGs (BGR, before sensor.encoding) of some frames into DIR\n"
         "  --dump-frames LIST  comma-separated frame indices for --dump-png (default: target_roi_frame)\n"
         "  --quiet             no progress output\n";
}

bool parseInt(const std::string& text, long long min, long long max, long long& out)
{
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < min || v > max)
    return false;
  out = v;
  return true;
}

sensor_msgs::CameraInfo cameraInfo(const stereo_pf::StereoGeometry& g, bool right, const std_msgs::Header& header,
                                   stereo_pf::SceneCameraInfo mode)
{
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = static_cast<uint32_t>(g.width());
  info.height = static_cast<uint32_t>(g.height());
  // What camera1394stereo publishes when its calibration file does not fit the camera: the size alone.
  if (mode == stereo_pf::SceneCameraInfo::SizeOnly)
    return info;
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  info.K = { g.fx(), 0.0, g.cx(), 0.0, g.fy(), g.cy(), 0.0, 0.0, 1.0 };
  info.R = { 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0 };
  // ROS convention: the right camera's projection carries Tx = -fx * baseline.
  info.P = { g.fx(), 0.0, g.cx(), right ? -g.fx() * g.baseline() : 0.0, 0.0, g.fy(), g.cy(), 0.0, 0.0, 0.0, 1.0, 0.0 };
  return info;
}

}  // namespace

int main(int argc, char** argv)
{
  std::vector<std::string> positional;
  long long frames = -1, seed = -1;
  bool quiet = false;
  std::string compression = "none", dump_dir, dump_list;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc)
      {
        std::cerr << "make_scene: " << name << " needs a value\n";
        usage(std::cerr);
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help")
    {
      usage(std::cout);
      return 0;
    }
    else if (arg == "--frames")
    {
      const std::string v = value("--frames");
      if (!parseInt(v, 1, 100000000, frames))
      {
        std::cerr << "make_scene: --frames must be a positive integer, got '" << v << "'\n";
        return 2;
      }
    }
    else if (arg == "--seed")
    {
      const std::string v = value("--seed");
      if (!parseInt(v, 0, (1LL << 62), seed))
      {
        std::cerr << "make_scene: --seed must be a non-negative integer, got '" << v << "'\n";
        return 2;
      }
    }
    else if (arg == "--compression")
    {
      compression = value("--compression");
      if (compression != "none" && compression != "lz4" && compression != "bz2")
      {
        std::cerr << "make_scene: --compression must be none, lz4 or bz2, got '" << compression << "'\n";
        return 2;
      }
    }
    else if (arg == "--dump-png")
      dump_dir = value("--dump-png");
    else if (arg == "--dump-frames")
      dump_list = value("--dump-frames");
    else if (arg == "--quiet" || arg == "-q")
      quiet = true;
    else if (!arg.empty() && arg[0] == '-')
    {
      std::cerr << "make_scene: unknown option '" << arg << "'\n";
      usage(std::cerr);
      return 2;
    }
    else
      positional.push_back(arg);
  }
  if (positional.size() != 2)
  {
    usage(std::cerr);
    return 2;
  }
  const std::string scene_path = positional[0], bag_path = positional[1];

  stereo_pf::SceneDescription scene;
  try
  {
    scene = stereo_pf::loadScene(scene_path);
  }
  catch (const std::exception& e)
  {
    std::cerr << "make_scene: " << e.what() << "\n";  // "cannot read scene '<file>': field '...': ..."
    return 1;
  }
  if (frames > 0)
    scene.frames = static_cast<int>(frames);
  if (seed >= 0)
    scene.seed = static_cast<uint64_t>(seed);
  if (scene.target_roi_frame >= scene.frames)
  {
    std::cerr << "make_scene: the scene's target_roi_frame " << scene.target_roi_frame << " is beyond --frames "
              << scene.frames << "\n";
    return 1;
  }

  std::set<int> dump_frames;
  if (!dump_dir.empty())
  {
    std::stringstream list(dump_list.empty() ? std::to_string(scene.target_roi_frame) : dump_list);
    std::string item;
    while (std::getline(list, item, ','))
    {
      long long k = 0;
      if (!parseInt(item, 0, scene.frames - 1, k))
      {
        std::cerr << "make_scene: --dump-frames: '" << item << "' is not a frame index in [0, " << scene.frames - 1
                  << "]\n";
        return 2;
      }
      dump_frames.insert(static_cast<int>(k));
    }
  }

  std::unique_ptr<stereo_pf::SceneRenderer> renderer;
  try
  {
    renderer.reset(new stereo_pf::SceneRenderer(scene));
  }
  catch (const std::exception& e)
  {
    std::cerr << "make_scene: " << e.what() << "\n";
    return 1;
  }

  ros::Time::init();  // no roscore: stamps are computed, never read from a clock
  rosbag::Bag bag;
  try
  {
    bag.open(bag_path, rosbag::bagmode::Write);
    bag.setCompression(compression == "lz4" ? rosbag::compression::LZ4 :
                       compression == "bz2" ? rosbag::compression::BZ2 :
                                              rosbag::compression::Uncompressed);
  }
  catch (const rosbag::BagException& e)
  {
    std::cerr << "make_scene: cannot write bag '" << bag_path << "': " << e.what() << "\n";
    return 1;
  }

  const stereo_pf::StereoGeometry geometry = renderer->geometry();
  const auto start = std::chrono::steady_clock::now();
  cv::Mat left, right, encoded;
  const std::string encoding = stereo_pf::encodingName(scene.sensor.encoding);
  int visible = 0;
  try
  {
    for (int k = 0; k < scene.frames; ++k)
    {
      renderer->render(k, left, right);

      std_msgs::Header header;
      header.seq = static_cast<uint32_t>(k);
      header.frame_id = kFrameId;
      // Integer nanoseconds: k / fps rounded once, so stamps do not drift or depend on float summation.
      header.stamp.fromNSec(kEpochNsec + static_cast<uint64_t>(std::llround(k * 1e9 / scene.fps)));
      const ros::Time time = header.stamp;

      sensor_msgs::Image image;
      stereo_pf::encodeImage(left, scene.sensor.encoding, encoded);
      cv_bridge::CvImage(header, encoding, encoded).toImageMsg(image);
      bag.write("stereo_camera/left/image_raw", time, image);
      stereo_pf::encodeImage(right, scene.sensor.encoding, encoded);
      cv_bridge::CvImage(header, encoding, encoded).toImageMsg(image);
      bag.write("stereo_camera/right/image_raw", time, image);
      bag.write("stereo_camera/left/camera_info", time, cameraInfo(geometry, false, header, scene.sensor.camera_info));
      bag.write("stereo_camera/right/camera_info", time, cameraInfo(geometry, true, header, scene.sensor.camera_info));

      const Eigen::Vector3d p = renderer->targetPosition(k);
      geometry_msgs::PointStamped target;
      target.header = header;
      target.point.x = p.x();
      target.point.y = p.y();
      target.point.z = p.z();
      bag.write("ground_truth/target", time, target);

      const cv::Rect box = renderer->targetRoi(k);
      sensor_msgs::RegionOfInterest roi;
      roi.x_offset = static_cast<uint32_t>(box.x);
      roi.y_offset = static_cast<uint32_t>(box.y);
      roi.width = static_cast<uint32_t>(box.width);
      roi.height = static_cast<uint32_t>(box.height);
      roi.do_rectify = false;
      bag.write("ground_truth/target_roi", time, roi);

      std_msgs::Bool shown;
      shown.data = renderer->targetVisible(k);
      visible += shown.data ? 1 : 0;
      bag.write("ground_truth/target_visible", time, shown);

      if (scene.objects.size() > 1)
      {
        geometry_msgs::PoseArray others;
        others.header = header;
        for (size_t i = 1; i < scene.objects.size(); ++i)
        {
          if (!renderer->objectPresent(i, k))
            continue;
          const Eigen::Vector3d q = renderer->objectPosition(i, k);
          geometry_msgs::Pose pose;
          pose.position.x = q.x();
          pose.position.y = q.y();
          pose.position.z = q.z();
          pose.orientation.w = 1.0;
          others.poses.push_back(pose);
        }
        bag.write("ground_truth/others", time, others);
      }

      if (dump_frames.count(k))
      {
        char name[64];
        std::snprintf(name, sizeof(name), "%s_%04d_", scene.name.c_str(), k);
        const std::string base = dump_dir + "/" + name;
        if (!cv::imwrite(base + "left.png", left) || !cv::imwrite(base + "right.png", right))
        {
          std::cerr << "make_scene: cannot write PNGs '" << base << "left/right.png'\n";
          return 1;
        }
      }
      if (!quiet && (k + 1) % 50 == 0 && k + 1 < scene.frames)
        std::cout << "make_scene: " << (k + 1) << "/" << scene.frames << " frames" << std::endl;
    }
    bag.close();
  }
  catch (const std::exception& e)
  {
    std::cerr << "make_scene: cannot write bag '" << bag_path << "': " << e.what() << "\n";
    return 1;
  }

  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!quiet)
  {
    std::printf("make_scene: wrote %d stereo frames of '%s' (%dx%d, %.1f s at %g fps, target visible in %d) to '%s' "
                "in %.1f s\n",
                scene.frames, scene.name.c_str(), geometry.width(), geometry.height(), scene.frames / scene.fps,
                scene.fps, visible, bag_path.c_str(), seconds);
  }
  return 0;
}
