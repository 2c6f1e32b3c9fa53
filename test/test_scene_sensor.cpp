// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Tests of the synthetic scenes' camera and sensor model: the right camera's row offset, shot noise,
// vignetting, per-frame gains, JPEG, motion blur, the published encodings, the YAML keys and their
// validation, and that a scene without these options renders exactly as before. Small images, few frames.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stereo_pf/sim/scene.h"
#include "stereo_pf/sim/scene_sensor.h"

using stereo_pf::encodeImage;
using stereo_pf::loadScene;
using stereo_pf::SceneCameraInfo;
using stereo_pf::SceneDescription;
using stereo_pf::SceneEncoding;
using stereo_pf::SceneError;
using stereo_pf::SceneRenderer;
using stereo_pf::SceneSensor;
using stereo_pf::SceneSensorModel;
using stereo_pf::SceneSphere;
using stereo_pf::Trajectory;
using stereo_pf::View;

namespace
{
std::string scenesDir()
{
  const std::string file = __FILE__;
  return file.substr(0, file.find_last_of('/')) + "/../scenes/";
}

// A small scene: 200x150 camera, plain grey wall, one orange ball at (x, y, 1 m).
SceneDescription smallScene(double x = 0.0, double y = 0.0)
{
  SceneDescription d;
  d.name = "sensor_test";
  d.camera.width = 200;
  d.camera.height = 150;
  d.camera.fx = d.camera.fy = 200.0;
  d.camera.cx = 99.5;
  d.camera.cy = 74.5;
  d.frames = 10;
  d.noise_sigma = 0.0;
  d.seed = 7;
  d.background.colour = cv::Vec3d(100, 100, 100);
  SceneSphere ball;
  ball.radius = 0.05;
  ball.colour = cv::Vec3d(20, 120, 255);
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(x, y, 1.0));
  d.objects.push_back(ball);
  return d;
}

// Intensity-weighted centroid (col, row) of where `img` differs from the plain wall colour `wall`.
cv::Point2d centroid(const cv::Mat& img, const cv::Vec3d& wall)
{
  double sum = 0.0, su = 0.0, sv = 0.0;
  for (int row = 0; row < img.rows; ++row)
    for (int col = 0; col < img.cols; ++col)
    {
      const cv::Vec3b p = img.at<cv::Vec3b>(row, col);
      const double w = std::abs(p[0] - wall[0]) + std::abs(p[1] - wall[1]) + std::abs(p[2] - wall[2]);
      sum += w;
      su += w * col;
      sv += w * row;
    }
  return sum > 0.0 ? cv::Point2d(su / sum, sv / sum) : cv::Point2d(-1, -1);
}

// First and last columns on `row` that differ from the wall by more than `threshold` in some channel.
std::pair<int, int> extentOnRow(const cv::Mat& img, int row, const cv::Vec3d& wall, double threshold)
{
  int first = -1, last = -1;
  for (int col = 0; col < img.cols; ++col)
  {
    const cv::Vec3b p = img.at<cv::Vec3b>(row, col);
    if (std::abs(p[0] - wall[0]) > threshold || std::abs(p[1] - wall[1]) > threshold ||
        std::abs(p[2] - wall[2]) > threshold)
    {
      if (first < 0)
        first = col;
      last = col;
    }
  }
  return { first, last };
}

// Same along a column.
std::pair<int, int> extentOnColumn(const cv::Mat& img, int col, const cv::Vec3d& wall, double threshold)
{
  cv::Mat column = img.col(col).clone().reshape(3, 1);
  return extentOnRow(column, 0, wall, threshold);
}

std::string writeTemp(const std::string& name, const std::string& text)
{
  const std::string path = testing::TempDir() + "stereo_pf_test_scene_sensor_" + name + ".yaml";
  std::ofstream(path) << text;
  return path;
}

const char* const kMinimal = "objects:\n"
                             "  - radius: 0.035\n"
                             "    trajectory:\n"
                             "      type: static\n"
                             "      position: [0.0, 0.0, 1.0]\n";

std::string loadError(const std::string& name, const std::string& text)
{
  try
  {
    loadScene(writeTemp(name, text));
  }
  catch (const SceneError& e)
  {
    return e.what();
  }
  ADD_FAILURE() << name << ": no exception";
  return "";
}

// SplitMix64 finaliser and the per-frame noise the renderer added before the sensor model existed: the
// reference the default path must still match bit for bit.
uint64_t mix64(uint64_t x)
{
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}
void legacyNoise(uint64_t seed, int k, View view, double sigma, cv::Mat& img)
{
  cv::RNG rng(mix64(seed ^ mix64(static_cast<uint64_t>(k) * 2 + static_cast<uint64_t>(view) + 1)));
  cv::Mat noise(img.rows, img.cols, CV_16SC3);
  rng.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(sigma));
  cv::add(img, noise, img, cv::noArray(), CV_8U);
}

double meanOf(const cv::Mat& img)
{
  const cv::Scalar m = cv::mean(img);
  return (m[0] + m[1] + m[2]) / 3.0;
}
}  // namespace

// ------------------------------------------------------------------------------------------------
// Defaults

TEST(SceneSensorDefaults, ShippedSceneRendersAsBefore)
{
  // The default sensor adds exactly the noise the renderer always added to the clean render.
  SceneDescription d = loadScene(scenesDir() + "pendulum_cluttered.yaml");
  d.frames = 5;
  SceneRenderer r(d);
  EXPECT_EQ(r.blurSamples(3), 1);
  cv::Mat clean, noisy;
  for (View view : { View::Left, View::Right })
  {
    r.renderView(3, view, clean, false);
    r.renderView(3, view, noisy, true);
    legacyNoise(d.seed, 3, view, d.noise_sigma, clean);
    EXPECT_EQ(cv::norm(clean, noisy, cv::NORM_INF), 0.0);
  }

  // A sensor block that spells out every default changes nothing.
  const std::string text = std::string(kMinimal) +
                           "camera: {width: 160, height: 120, fx: 150, row_offset: 0}\n"
                           "noise: {sigma: 3, seed: 4, shot: 0}\n"
                           "sensor: {exposure: 0, blur_samples: 0, vignetting: 0, gain_jitter: 0, right_gain: 1,\n"
                           "         right_gain_jitter: 0, jpeg_quality: 0, encoding: bgr8, camera_info: full}\n";
  const std::string plain = std::string(kMinimal) + "camera: {width: 160, height: 120, fx: 150}\n"
                                                    "noise: {sigma: 3, seed: 4}\n";
  SceneRenderer a(loadScene(writeTemp("explicit_defaults", text))), b(loadScene(writeTemp("no_block", plain)));
  cv::Mat al, ar, bl, br;
  a.render(2, al, ar);
  b.render(2, bl, br);
  EXPECT_EQ(cv::norm(al, bl, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(ar, br, cv::NORM_INF), 0.0);
}

// ------------------------------------------------------------------------------------------------
// camera.row_offset

TEST(SceneSensorRowOffset, MovesTheRightImageContentDownByThatManyRows)
{
  // Every shape is drawn through the right view's imaging camera, so every shape moves.
  using Shape = stereo_pf::SceneSphere::Shape;
  for (const Shape shape : { Shape::Sphere, Shape::Box, Shape::Cylinder })
  {
    SCOPED_TRACE(static_cast<int>(shape));
    SceneDescription base = smallScene(0.02, -0.03);
    base.objects[0].shape = shape;
    base.objects[0].size = Eigen::Vector3d(0.06, 0.05, 0.04);
    base.objects[0].height = 0.06;
    base.objects[0].yaw = 0.4;
    SceneRenderer ideal(base);
    cv::Mat l0, r0;
    ideal.render(0, l0, r0, false);
    const cv::Point2d cl0 = centroid(l0, base.background.colour), cr0 = centroid(r0, base.background.colour);

    for (double offset : { 0.5, -1.25, 2.3, 5.0 })
    {
      SCOPED_TRACE(offset);
      SceneDescription d = base;
      d.camera.row_offset = offset;
      SceneRenderer r(d);
      cv::Mat l, rt;
      r.render(0, l, rt, false);
      EXPECT_EQ(cv::norm(l, l0, cv::NORM_INF), 0.0) << "the left image must not change";
      const cv::Point2d cl = centroid(l, d.background.colour), cr = centroid(rt, d.background.colour);
      EXPECT_NEAR(cl.y, cl0.y, 1e-9);
      EXPECT_NEAR(cr.y - cr0.y, offset, 0.03);
      EXPECT_NEAR(cr.x, cr0.x, 0.03);
      // Ground truth and calibration stay the ideal ones.
      EXPECT_EQ(r.objectRoi(0, 0, View::Right), ideal.objectRoi(0, 0, View::Right));
      EXPECT_DOUBLE_EQ(r.visibleFraction(0, 0, View::Right), ideal.visibleFraction(0, 0, View::Right));
      EXPECT_DOUBLE_EQ(r.geometry().cy(), ideal.geometry().cy());
    }
  }
}

TEST(SceneSensorRowOffset, WholeRowsShiftTheClutteredWallExactly)
{
  SceneDescription d = smallScene();
  d.background.type = stereo_pf::SceneBackground::Type::Cluttered;
  d.background.rectangles = 20;
  d.background.blobs = 10;
  d.background.lines = 5;
  d.background.target_patches = 2;
  SceneRenderer ideal(d);
  d.camera.row_offset = 2.0;
  SceneRenderer shifted(d);
  cv::Mat a, b;
  ideal.renderView(0, View::Right, a, false);
  shifted.renderView(0, View::Right, b, false);
  // Row v of the shifted right image is row v - 2 of the ideal one: the wall and the ball.
  const cv::Rect below(0, 2, a.cols, a.rows - 2), above(0, 0, a.cols, a.rows - 2);
  EXPECT_EQ(cv::norm(b(below), a(above), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(b, a, cv::NORM_L1), 0.0);
}

// ------------------------------------------------------------------------------------------------
// noise.shot, vignetting, gains, JPEG (the sensor model on its own and through the renderer)

TEST(SceneSensorNoise, ShotNoiseVarianceGrowsWithIntensity)
{
  const cv::Size size(256, 256);
  cv::Mat light(size, CV_8UC3, cv::Scalar::all(20));
  light(cv::Rect(128, 0, 128, 256)).setTo(cv::Scalar::all(200));
  for (double shot : { 0.0, 1.0, 4.0 })
  {
    SCOPED_TRACE(shot);
    SceneSensorModel model(SceneSensor(), 2.0, shot, 3, size, 127.5, 127.5);
    cv::Mat out;
    model.apply(0, View::Left, light, out, true);
    cv::Scalar mean_dark, sd_dark, mean_bright, sd_bright;
    cv::meanStdDev(out(cv::Rect(0, 0, 128, 256)), mean_dark, sd_dark);
    cv::meanStdDev(out(cv::Rect(128, 0, 128, 256)), mean_bright, sd_bright);
    for (int ch = 0; ch < 3; ++ch)
    {
      // sigma^2 = read^2 + shot * I (+ 1/12 from rounding on the float path); 32768 samples: ~2 % on the SD.
      const double rounding = shot > 0.0 ? 1.0 / 12.0 : 0.0;
      EXPECT_NEAR(sd_dark[ch], std::sqrt(4.0 + shot * 20.0 + rounding), 0.06 * std::sqrt(4.0 + shot * 20.0));
      EXPECT_NEAR(sd_bright[ch], std::sqrt(4.0 + shot * 200.0 + rounding), 0.06 * std::sqrt(4.0 + shot * 200.0));
      EXPECT_NEAR(mean_dark[ch], 20.0, 0.2);
      EXPECT_NEAR(mean_bright[ch], 200.0, 0.5);
    }
  }
}

TEST(SceneSensorNoise, NoiseDependsOnSeedFrameAndViewOnly)
{
  SceneDescription d = smallScene();
  d.noise_sigma = 3.0;
  d.noise_shot = 0.5;
  d.sensor.vignetting = 0.2;
  SceneRenderer a(d), b(d);
  cv::Mat a3, b3, a4, al, ar;
  a.renderView(4, View::Left, a4);  // rendering other frames first must not matter
  a.renderView(3, View::Left, a3);
  b.renderView(3, View::Left, b3);
  EXPECT_EQ(cv::norm(a3, b3, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a3, a4, cv::NORM_L1), 0.0);
  d.seed = 8;
  SceneRenderer c(d);
  cv::Mat c3;
  c.renderView(3, View::Left, c3);
  EXPECT_GT(cv::norm(a3, c3, cv::NORM_L1), 0.0);
}

TEST(SceneSensorVignetting, DarkensTheCornersByTheStatedFraction)
{
  SceneDescription d = smallScene(0.0, 0.0);
  d.background.colour = cv::Vec3d(200, 200, 200);
  d.sensor.vignetting = 0.3;
  SceneRenderer r(d);
  cv::Mat img;
  r.renderView(0, View::Left, img, false);
  const int w = img.cols - 1, h = img.rows - 1;
  for (const cv::Point& corner : { cv::Point(0, 0), cv::Point(w, 0), cv::Point(0, h), cv::Point(w, h) })
    EXPECT_EQ(img.at<cv::Vec3b>(corner), cv::Vec3b(140, 140, 140)) << corner;  // 200 * (1 - 0.3)
  // Smooth and radial: halfway to a corner loses a quarter of it (quadratic fall-off), the edge midpoints
  // in between, and the ball in the centre keeps its colour.
  const cv::Vec3b half = img.at<cv::Vec3b>(cv::Point(std::lround(w * 0.25), std::lround(h * 0.25)));
  EXPECT_NEAR(half[0], 200.0 * (1.0 - 0.3 * 0.25), 1.0);
  const cv::Vec3b edge = img.at<cv::Vec3b>(cv::Point(0, h / 2));
  EXPECT_GT(edge[0], 140);
  EXPECT_LT(edge[0], 200);
  cv::Mat sharp;
  SceneRenderer(smallScene(0.0, 0.0)).renderView(0, View::Left, sharp, false);
  const cv::Point centre(100, 75);
  EXPECT_LE(cv::norm(cv::Vec3d(img.at<cv::Vec3b>(centre)) - cv::Vec3d(sharp.at<cv::Vec3b>(centre)), cv::NORM_INF),
            1.0);
}

TEST(SceneSensorGain, GainScalesTheMeanAndIsSharedByBothViews)
{
  SceneDescription d = smallScene();
  d.sensor.gain_jitter = 0.2;
  SceneRenderer r(d);
  SceneRenderer flat(smallScene());
  cv::Mat ref_l, ref_r, l, rt;
  flat.render(0, ref_l, ref_r, false);
  std::vector<double> gains;
  for (int k = 0; k < 6; ++k)
  {
    const double g = r.sensorModel().gain(k, View::Left);
    EXPECT_DOUBLE_EQ(r.sensorModel().gain(k, View::Right), g) << "shared by both cameras";
    r.render(k, l, rt, false);
    EXPECT_NEAR(meanOf(l) / meanOf(ref_l), g, 0.01) << "frame " << k;
    EXPECT_NEAR(meanOf(rt) / meanOf(ref_r), g, 0.01) << "frame " << k;
    gains.push_back(g);
  }
  EXPECT_GT(*std::max_element(gains.begin(), gains.end()) - *std::min_element(gains.begin(), gains.end()), 0.05);

  // Over many frames: mean 1, SD the jitter.
  double sum = 0.0, sum2 = 0.0;
  const int n = 2000;
  for (int k = 0; k < n; ++k)
  {
    const double g = r.sensorModel().gain(k, View::Left);
    sum += g;
    sum2 += g * g;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 1.0, 0.02);
  EXPECT_NEAR(sd, 0.2, 0.02);
}

TEST(SceneSensorGain, RightGainScalesTheRightViewOnly)
{
  SceneRenderer flat(smallScene());
  cv::Mat ref_l, ref_r;
  flat.render(1, ref_l, ref_r, false);

  SceneDescription d = smallScene();
  d.sensor.right_gain = 1.5;
  SceneRenderer r(d);
  cv::Mat l, rt;
  r.render(1, l, rt, false);
  EXPECT_EQ(cv::norm(l, ref_l, cv::NORM_INF), 0.0);
  // The wall 100 -> 150 exactly; saturated channels of the ball stay at 255.
  EXPECT_EQ(rt.at<cv::Vec3b>(5, 5), cv::Vec3b(150, 150, 150));
  EXPECT_NEAR(meanOf(rt) / meanOf(ref_r), 1.5, 0.03);

  // Its own jitter: the right/left ratio varies around right_gain, the left view stays put.
  d.sensor.right_gain_jitter = 0.1;
  SceneRenderer j(d);
  double sum = 0.0, sum2 = 0.0;
  const int n = 2000;
  for (int k = 0; k < n; ++k)
  {
    EXPECT_DOUBLE_EQ(j.sensorModel().gain(k, View::Left), 1.0);
    const double ratio = j.sensorModel().gain(k, View::Right) / 1.5;
    sum += ratio;
    sum2 += ratio * ratio;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 1.0, 0.01);
  EXPECT_NEAR(sd, 0.1, 0.01);
  j.render(1, l, rt, false);
  EXPECT_EQ(cv::norm(l, ref_l, cv::NORM_INF), 0.0);
  EXPECT_NEAR(meanOf(rt) / meanOf(ref_r), j.sensorModel().gain(1, View::Right), 0.02);
}

TEST(SceneSensorJpeg, ChangesPixelsButKeepsTheMean)
{
  SceneDescription d = smallScene();
  d.background.type = stereo_pf::SceneBackground::Type::Cluttered;
  d.noise_sigma = 2.0;
  SceneRenderer plain(d);
  cv::Mat ref, out;
  plain.renderView(0, View::Left, ref);
  double last_error = 1e9;
  for (int quality : { 20, 60, 95 })
  {
    SCOPED_TRACE(quality);
    d.sensor.jpeg_quality = quality;
    SceneRenderer r(d);
    r.renderView(0, View::Left, out);
    ASSERT_EQ(out.type(), CV_8UC3);
    ASSERT_EQ(out.size(), ref.size());
    cv::Mat diff;
    cv::absdiff(out, ref, diff);
    const double changed = cv::countNonZero(diff.reshape(1)) / static_cast<double>(diff.total() * 3);
    EXPECT_GT(changed, 0.3) << "JPEG must alter most pixels";
    const cv::Scalar mo = cv::mean(out), mr = cv::mean(ref);
    for (int ch = 0; ch < 3; ++ch)
      EXPECT_NEAR(mo[ch], mr[ch], 1.5);
    const double error = cv::norm(out, ref, cv::NORM_L1) / static_cast<double>(ref.total() * 3);
    EXPECT_LT(error, last_error) << "higher quality is closer to the original";
    last_error = error;
  }
  d.sensor.jpeg_quality = 0;
  SceneRenderer off(d);
  off.renderView(0, View::Left, out);
  EXPECT_EQ(cv::norm(out, ref, cv::NORM_INF), 0.0) << "quality 0 is off";
}

// ------------------------------------------------------------------------------------------------
// Motion blur

TEST(SceneSensorExposure, BlursAMovingBallAlongItsMotionOnly)
{
  // Ball A moves along +x at 1.2 m/s at 1 m (240 px/s); ball B is static. Exposure 1/30 s: 8 px of blur.
  SceneDescription d = smallScene();
  d.objects[0].trajectory = Trajectory::linear(Eigen::Vector3d(-0.3, -0.1, 1.0), Eigen::Vector3d(0.3, -0.1, 1.0), 0.0,
                                               0.5);
  SceneSphere fixed = d.objects[0];
  fixed.colour = cv::Vec3d(255, 80, 40);
  fixed.trajectory = Trajectory::fixed(Eigen::Vector3d(0.0, 0.12, 1.0));
  d.objects.push_back(fixed);
  const double exposure = 1.0 / 30.0, blur_px = 1.2 * exposure * d.camera.fx / 1.0;
  const int k = 7;
  SceneRenderer sharp(d);
  cv::Mat s;
  sharp.renderView(k, View::Left, s, false);

  for (int samples : { 0, 16 })
  {
    SCOPED_TRACE(samples);
    SceneDescription b = d;
    b.sensor.exposure = exposure;
    b.sensor.blur_samples = samples;
    SceneRenderer r(b);
    const int n = r.blurSamples(k);
    if (samples == 0)
    {
      EXPECT_GE(n, 8);  // about a pixel of motion between renders: 8 px need 8..9
      EXPECT_LE(n, 10);
    }
    else
      EXPECT_EQ(n, samples);
    cv::Mat img;
    r.renderView(k, View::Left, img, false);

    // Along the motion the moving ball's extent grows by about the blur length (the n renders' centres
    // span (n - 1) / n of it, their anti-aliased rims a little more); across the motion it does not.
    const cv::Rect roi = r.objectRoi(0, k, View::Left);
    const int row = roi.y + roi.height / 2, col = roi.x + roi.width / 2;
    const auto a0 = extentOnRow(s, row, d.background.colour, 2.0), a1 = extentOnRow(img, row, d.background.colour, 2.0);
    const double grown = (a1.second - a1.first) - (a0.second - a0.first);
    EXPECT_NEAR(grown, blur_px, 1.0);
    const auto v0 = extentOnColumn(s, col, d.background.colour, 2.0);
    const auto v1 = extentOnColumn(img, col, d.background.colour, 2.0);
    EXPECT_LE(std::abs((v1.second - v1.first) - (v0.second - v0.first)), 1);
    // Mid-exposure ground truth: the blurred ball is centred where the sharp one is.
    EXPECT_NEAR((a1.first + a1.second) / 2.0, (a0.first + a0.second) / 2.0, 0.6);
    EXPECT_EQ(r.objectRoi(0, k, View::Left), sharp.objectRoi(0, k, View::Left));
    EXPECT_EQ(r.targetPosition(k), sharp.targetPosition(k));

    // The static ball is untouched.
    const cv::Rect still = r.objectRoi(1, k, View::Left) + cv::Size(2, 2) - cv::Point(1, 1);
    EXPECT_EQ(cv::norm(img(still), s(still), cv::NORM_INF), 0.0);
  }

  // Nothing moves: one render even with an exposure; no exposure: one render.
  SceneDescription still = smallScene();
  still.sensor.exposure = exposure;
  EXPECT_EQ(SceneRenderer(still).blurSamples(0), 1);
  EXPECT_EQ(SceneRenderer(d).blurSamples(k), 1);
  // Very fast: capped at 16.
  SceneDescription fast = d;
  fast.objects[0].trajectory = Trajectory::linear(Eigen::Vector3d(-3, 0, 1), Eigen::Vector3d(3, 0, 1), 0.0, 0.5);
  fast.sensor.exposure = exposure;
  EXPECT_EQ(SceneRenderer(fast).blurSamples(k), 16);
}

// ------------------------------------------------------------------------------------------------
// Encodings

TEST(SceneSensorEncoding, EveryEncodingHoldsTheRightChannelValues)
{
  cv::Mat bgr(6, 8, CV_8UC3);
  cv::RNG rng(5);
  rng.fill(bgr, cv::RNG::UNIFORM, 0, 256);
  cv::Mat out;

  encodeImage(bgr, SceneEncoding::Bgr8, out);
  ASSERT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(out, bgr, cv::NORM_INF), 0.0);
  EXPECT_NE(out.data, bgr.data);

  encodeImage(bgr, SceneEncoding::Rgb8, out);
  ASSERT_EQ(out.type(), CV_8UC3);
  cv::Mat mono8;
  for (int row = 0; row < bgr.rows; ++row)
    for (int col = 0; col < bgr.cols; ++col)
    {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(row, col), q = out.at<cv::Vec3b>(row, col);
      EXPECT_EQ(q, cv::Vec3b(p[2], p[1], p[0]));
    }

  encodeImage(bgr, SceneEncoding::Mono8, mono8);
  ASSERT_EQ(mono8.type(), CV_8UC1);
  for (int row = 0; row < bgr.rows; ++row)
    for (int col = 0; col < bgr.cols; ++col)
    {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(row, col);
      EXPECT_NEAR(mono8.at<uchar>(row, col), 0.114 * p[0] + 0.587 * p[1] + 0.299 * p[2], 0.51);
    }

  encodeImage(bgr, SceneEncoding::Mono16, out);
  ASSERT_EQ(out.type(), CV_16UC1);
  for (int row = 0; row < bgr.rows; ++row)
    for (int col = 0; col < bgr.cols; ++col)
      EXPECT_EQ(out.at<uint16_t>(row, col), 257 * mono8.at<uchar>(row, col));
  const cv::Mat white(1, 1, CV_8UC3, cv::Scalar::all(255));
  encodeImage(white, SceneEncoding::Mono16, out);
  EXPECT_EQ(out.at<uint16_t>(0, 0), 65535);

  // bayer_grbg8: row 0 G R G R ..., row 1 B G B G ...
  encodeImage(bgr, SceneEncoding::BayerGrbg8, out);
  ASSERT_EQ(out.type(), CV_8UC1);
  ASSERT_EQ(out.size(), bgr.size());
  for (int row = 0; row < bgr.rows; ++row)
    for (int col = 0; col < bgr.cols; ++col)
    {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(row, col);
      const int channel = row % 2 == 0 ? (col % 2 == 0 ? 1 : 2) : (col % 2 == 0 ? 0 : 1);
      EXPECT_EQ(out.at<uchar>(row, col), p[channel]) << row << "," << col;
    }
  // OpenCV's demosaicing of this layout (cv_bridge's choice for bayer_grbg8) gives a flat colour back.
  const cv::Mat flat(8, 8, CV_8UC3, cv::Scalar(30, 140, 220));
  cv::Mat mosaic, back;
  encodeImage(flat, SceneEncoding::BayerGrbg8, mosaic);
  cv::cvtColor(mosaic, back, cv::COLOR_BayerGB2BGR);
  EXPECT_EQ(back.at<cv::Vec3b>(4, 4), cv::Vec3b(30, 140, 220));

  EXPECT_THROW(encodeImage(mono8, SceneEncoding::Bgr8, out), std::invalid_argument);

  for (const std::string& name : stereo_pf::encodingNames())
  {
    SceneEncoding e;
    ASSERT_TRUE(stereo_pf::encodingFromName(name, e));
    EXPECT_EQ(stereo_pf::encodingName(e), name);
  }
  SceneEncoding e;
  EXPECT_FALSE(stereo_pf::encodingFromName("yuv422", e));
}

// ------------------------------------------------------------------------------------------------
// YAML

TEST(SceneSensorYaml, KeysAreReadIntoTheDescription)
{
  const SceneDescription d = loadScene(writeTemp(
      "all_keys", std::string(kMinimal) + "camera: {row_offset: -0.75}\n"
                                          "noise: {sigma: 1.5, shot: 0.8}\n"
                                          "sensor:\n  exposure: 0.01\n  blur_samples: 5\n  vignetting: 0.25\n"
                                          "  gain_jitter: 0.05\n  right_gain: 1.1\n  right_gain_jitter: 0.02\n"
                                          "  jpeg_quality: 80\n  encoding: bayer_grbg8\n  camera_info: size_only\n"));
  EXPECT_DOUBLE_EQ(d.camera.row_offset, -0.75);
  EXPECT_DOUBLE_EQ(d.noise_shot, 0.8);
  EXPECT_DOUBLE_EQ(d.sensor.exposure, 0.01);
  EXPECT_EQ(d.sensor.blur_samples, 5);
  EXPECT_DOUBLE_EQ(d.sensor.vignetting, 0.25);
  EXPECT_DOUBLE_EQ(d.sensor.gain_jitter, 0.05);
  EXPECT_DOUBLE_EQ(d.sensor.right_gain, 1.1);
  EXPECT_DOUBLE_EQ(d.sensor.right_gain_jitter, 0.02);
  EXPECT_EQ(d.sensor.jpeg_quality, 80);
  EXPECT_EQ(d.sensor.encoding, SceneEncoding::BayerGrbg8);
  EXPECT_EQ(d.sensor.camera_info, SceneCameraInfo::SizeOnly);

  const SceneDescription plain = loadScene(writeTemp("no_keys", kMinimal));
  EXPECT_DOUBLE_EQ(plain.camera.row_offset, 0.0);
  EXPECT_DOUBLE_EQ(plain.noise_shot, 0.0);
  EXPECT_EQ(plain.sensor.encoding, SceneEncoding::Bgr8);
  EXPECT_EQ(plain.sensor.camera_info, SceneCameraInfo::Full);
  EXPECT_EQ(plain.sensor.jpeg_quality, 0);
}

TEST(SceneSensorYaml, BadValuesAreRejectedNamingTheField)
{
  struct Case
  {
    const char* yaml;
    const char* field;
  };
  const Case cases[] = {
    { "camera: {row_offset: 5.5}\n", "camera.row_offset" },
    { "camera: {row_offset: abc}\n", "camera.row_offset" },
    { "noise: {shot: -1}\n", "noise.shot" },
    { "noise: {shot: 11}\n", "noise.shot" },
    { "sensor: {exposure: -0.01}\n", "sensor.exposure" },
    { "sensor: {exposure: 0.05}\n", "sensor.exposure" },  // longer than 1/30 s between frames
    { "sensor: {blur_samples: 65}\n", "sensor.blur_samples" },
    { "sensor: {blur_samples: 2.5}\n", "sensor.blur_samples" },
    { "sensor: {vignetting: 0.95}\n", "sensor.vignetting" },
    { "sensor: {gain_jitter: 0.6}\n", "sensor.gain_jitter" },
    { "sensor: {right_gain: 0.4}\n", "sensor.right_gain" },
    { "sensor: {right_gain: 2.5}\n", "sensor.right_gain" },
    { "sensor: {right_gain_jitter: 0.7}\n", "sensor.right_gain_jitter" },
    { "sensor: {jpeg_quality: 101}\n", "sensor.jpeg_quality" },
    { "sensor: {jpeg_quality: -1}\n", "sensor.jpeg_quality" },
    { "sensor: {encoding: yuv422}\n", "sensor.encoding" },
    { "sensor: {camera_info: none}\n", "sensor.camera_info" },
    { "sensor: {exposur: 0.01}\n", "sensor.exposur" },
    { "sensor: 3\n", "sensor" },
  };
  int i = 0;
  for (const Case& c : cases)
  {
    const std::string m = loadError("bad" + std::to_string(i++), std::string(kMinimal) + c.yaml);
    EXPECT_NE(m.find(c.field), std::string::npos) << c.yaml << " -> " << m;
  }
  const std::string enc = loadError("bad_enc_list", std::string(kMinimal) + "sensor: {encoding: yuv422}\n");
  EXPECT_NE(enc.find("bayer_grbg8"), std::string::npos) << "lists the allowed encodings: " << enc;
  const std::string typo = loadError("bad_typo", std::string(kMinimal) + "sensor: {exposur: 0.01}\n");
  EXPECT_NE(typo.find("unknown key"), std::string::npos) << typo;

  // The same checks on descriptions built in code.
  SceneDescription d = smallScene();
  d.sensor.vignetting = 0.95;
  d.sensor.right_gain = 3.0;
  d.camera.row_offset = -6.0;
  d.noise_shot = -0.5;
  const std::string problems = d.validate();
  for (const char* field : { "sensor.vignetting", "sensor.right_gain", "camera.row_offset", "noise.shot" })
    EXPECT_NE(problems.find(field), std::string::npos) << problems;
  EXPECT_THROW(SceneRenderer r(d), SceneError);
  d = smallScene();
  d.sensor.exposure = 0.5;  // at 30 fps
  EXPECT_NE(d.validate().find("sensor.exposure"), std::string::npos);
  d.fps = 1.0;
  EXPECT_EQ(d.validate(), "");
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
