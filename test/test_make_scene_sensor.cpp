// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// make_scene's sensor options through the command-line tools: every sensor.encoding is published with the
// right layout, reads back (through the conversion track_bag and the nodelet use) to what the bgr8 bag
// holds, and track_bag tracks it; sensor.camera_info: size_only publishes the size alone, and track_bag
// stops with a message naming the camera_info instead of crashing. Small images, few frames.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>
#include <sys/stat.h>

#include <opencv2/imgproc.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "stereo_pf/ros/conversions.h"

#include "run_command.h"

namespace
{
using stereo_pf_test::run;

// A 160x120 scene of a ball swinging in front of a plain wall, 12 frames, with the given sensor block.
std::string makeBag(const std::string& name, const std::string& sensor)
{
  mkdir(TEST_OUT_DIR, 0755);
  const std::string base = std::string(TEST_OUT_DIR) + "/sensor_" + name;
  std::ofstream(base + ".yaml") << "frames: 12\n"
                                   "camera: {width: 160, height: 120, fx: 150, baseline: 0.09}\n"
                                   "noise: {sigma: 2, seed: 3}\n"
                                   "background: {colour: [200, 205, 210]}\n"
                                   "objects:\n"
                                   "  - radius: 0.06\n"
                                   "    colour: [255, 120, 20]\n"
                                   "    trajectory: {type: pendulum, pivot: [0, -0.6, 0.9], length: 0.6,"
                                   " amplitude_deg: 15, period: 2}\n"
                                   "sensor: {" +
                                       sensor + "}\n";
  int status = 0;
  const std::string out = run(std::string(MAKE_SCENE_BIN) + " " + base + ".yaml " + base + ".bag --quiet", status);
  EXPECT_EQ(status, 0) << out;
  return base + ".bag";
}

struct BagContents
{
  std::vector<sensor_msgs::ImageConstPtr> left, right;
  std::vector<sensor_msgs::CameraInfoConstPtr> left_info, right_info;
};

BagContents readBag(const std::string& path)
{
  BagContents c;
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag))
  {
    if (m.getTopic() == "stereo_camera/left/image_raw")
      c.left.push_back(m.instantiate<sensor_msgs::Image>());
    else if (m.getTopic() == "stereo_camera/right/image_raw")
      c.right.push_back(m.instantiate<sensor_msgs::Image>());
    else if (m.getTopic() == "stereo_camera/left/camera_info")
      c.left_info.push_back(m.instantiate<sensor_msgs::CameraInfo>());
    else if (m.getTopic() == "stereo_camera/right/camera_info")
      c.right_info.push_back(m.instantiate<sensor_msgs::CameraInfo>());
  }
  return c;
}

cv::Mat engineImage(const sensor_msgs::ImageConstPtr& msg)
{
  cv::Mat out;
  std::shared_ptr<const void> keep;
  std::string error;
  EXPECT_TRUE(stereo_pf::toEngineImage(msg, out, keep, error)) << msg->encoding << ": " << error;
  return out.clone();
}
}  // namespace

TEST(MakeSceneSensor, EveryEncodingReadsBackAndTracks)
{
  const BagContents ref = readBag(makeBag("bgr8", "encoding: bgr8"));
  ASSERT_EQ(ref.left.size(), 12u);
  ASSERT_EQ(ref.right.size(), 12u);
  const std::map<std::string, int> bytes_per_pixel = { { "rgb8", 3 }, { "mono8", 1 }, { "mono16", 2 },
                                                        { "bayer_grbg8", 1 } };
  for (const auto& [name, bytes] : bytes_per_pixel)
  {
    SCOPED_TRACE(name);
    const std::string path = makeBag(name, "encoding: " + name);
    const BagContents c = readBag(path);
    ASSERT_EQ(c.left.size(), ref.left.size());
    for (size_t k = 0; k < c.left.size(); k += 5)
      for (int v = 0; v < 2; ++v)
      {
        const sensor_msgs::ImageConstPtr& msg = v == 0 ? c.left[k] : c.right[k];
        EXPECT_EQ(msg->encoding, name);
        EXPECT_EQ(msg->width, 160u);
        EXPECT_EQ(msg->height, 120u);
        EXPECT_EQ(msg->step, 160u * bytes);
        const cv::Mat got = engineImage(msg), want = engineImage(v == 0 ? ref.left[k] : ref.right[k]);
        ASSERT_EQ(want.type(), CV_8UC3);
        if (name == "rgb8")
          EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0.0) << "frame " << k;
        else if (name != "bayer_grbg8")
        {
          cv::Mat grey;
          cv::cvtColor(want, grey, cv::COLOR_BGR2GRAY);
          ASSERT_EQ(got.type(), CV_8UC1);
          EXPECT_EQ(cv::norm(got, grey, cv::NORM_INF), 0.0) << "frame " << k;  // mono16 comes back exactly
        }
        else
        {
          // Demosaiced back to colour: close to the original away from edges (noise is interpolated), and
          // the orange ball stays orange (a wrong pattern would swap red and blue).
          ASSERT_EQ(got.type(), CV_8UC3);
          const cv::Rect inner(2, 2, 156, 116);
          EXPECT_LT(cv::norm(got(inner), want(inner), cv::NORM_L1) / (inner.area() * 3.0), 3.0) << "frame " << k;
          cv::Mat diff;
          cv::absdiff(got, want, diff);
          const cv::Scalar m = cv::mean(diff);
          for (int ch = 0; ch < 3; ++ch)
            EXPECT_LT(m[ch], 3.0) << "channel " << ch << " frame " << k;
        }
      }
    int status = 0;
    const std::string out = run(std::string(TRACK_BAG_BIN) + " " + path + " --quiet --seed 1", status);
    EXPECT_EQ(status, 0) << out;
    EXPECT_NE(out.find("summary: frames=12 "), std::string::npos) << out;
    EXPECT_EQ(out.find("dropped"), std::string::npos) << out;
  }
}

TEST(MakeSceneSensor, SizeOnlyCameraInfoCarriesTheSizeAloneAndTrackBagSaysSo)
{
  const BagContents full = readBag(makeBag("info_full", "camera_info: full"));
  ASSERT_FALSE(full.right_info.empty());
  EXPECT_DOUBLE_EQ(full.right_info[0]->P[0], 150.0);
  EXPECT_DOUBLE_EQ(full.right_info[0]->P[3], -150.0 * 0.09);
  EXPECT_EQ(full.right_info[0]->distortion_model, "plumb_bob");

  const std::string path = makeBag("info_size_only", "camera_info: size_only");
  const BagContents c = readBag(path);
  ASSERT_EQ(c.left_info.size(), 12u);
  ASSERT_EQ(c.right_info.size(), 12u);
  for (const auto& info : { c.left_info[0], c.right_info[0] })
  {
    EXPECT_EQ(info->width, 160u);
    EXPECT_EQ(info->height, 120u);
    EXPECT_EQ(info->header.stamp, c.left[0]->header.stamp);
    EXPECT_TRUE(info->D.empty());
    EXPECT_TRUE(info->distortion_model.empty());
    for (double v : info->K)
      EXPECT_EQ(v, 0.0);
    for (double v : info->P)
      EXPECT_EQ(v, 0.0);
  }
  stereo_pf::StereoCalibration calibration;
  std::string error;
  EXPECT_FALSE(calibration.update(*c.left_info[0], *c.right_info[0], error));
  EXPECT_FALSE(error.empty());

  int status = 0;
  const std::string out = run(std::string(TRACK_BAG_BIN) + " " + path + " --quiet --seed 1", status);
  EXPECT_TRUE(WIFEXITED(status)) << "track_bag must exit, not crash: " << out;
  EXPECT_NE(WEXITSTATUS(status), 0) << out;
  EXPECT_NE(out.find("camera_info"), std::string::npos) << "the message must say what is wrong: " << out;
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
