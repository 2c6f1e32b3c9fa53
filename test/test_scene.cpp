// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Tests of the synthetic scene generator: loading (shipped scenes and bad files), rendering geometry
// and colour in both views, ground truth (visibility, ROI), trajectories and determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/sim/scene.h"

using stereo_pf::loadScene;
using stereo_pf::SceneDescription;
using stereo_pf::SceneError;
using stereo_pf::SceneRenderer;
using stereo_pf::Trajectory;
using stereo_pf::View;

namespace
{
// The shipped scenes live next to this test's directory (CMake passes absolute source paths).
std::string scenesDir()
{
  const std::string file = __FILE__;
  return file.substr(0, file.find_last_of('/')) + "/../scenes/";
}

const std::vector<std::string> kShipped = { "pendulum_uncluttered", "pendulum_cluttered", "occlusion", "multi_object" };

// Mean BGR of the 3x3 block around (u, v) (averages the sensor noise down).
cv::Vec3d meanAround(const cv::Mat& img, double u, double v)
{
  const int c = static_cast<int>(std::lround(u)), r = static_cast<int>(std::lround(v));
  cv::Vec3d sum(0, 0, 0);
  int n = 0;
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc)
    {
      const int rr = r + dr, cc = c + dc;
      if (rr < 0 || cc < 0 || rr >= img.rows || cc >= img.cols)
        continue;
      const cv::Vec3b p = img.at<cv::Vec3b>(rr, cc);
      sum += cv::Vec3d(p[0], p[1], p[2]);
      ++n;
    }
  return n > 0 ? sum / n : sum;
}

// A shaded surface of albedo `a` shows s * a with s in [ambient, 1]: test that `p` is such a colour.
bool isShadeOf(const cv::Vec3d& p, const cv::Vec3d& a, double ambient)
{
  const double s = p.dot(a) / a.dot(a);
  if (s < ambient - 0.08 || s > 1.08)
    return false;
  return cv::norm(p - s * a) < 0.1 * s * cv::norm(a) + 8.0;
}

std::string writeTemp(const std::string& name, const std::string& text)
{
  const std::string path = testing::TempDir() + "stereo_pf_test_scene_" + name + ".yaml";
  std::ofstream(path) << text;
  return path;
}

// A minimal valid scene body (without the %YAML line) to break in one place per test.
const char* const kMinimal = "objects:\n"
                             "  - radius: 0.035\n"
                             "    colour: [255, 120, 20]\n"
                             "    trajectory:\n"
                             "      type: static\n"
                             "      position: [0.0, 0.0, 1.0]\n";

std::string loadError(const std::string& name, const std::string& text)
{
  const std::string path = writeTemp(name, text);
  try
  {
    loadScene(path);
  }
  catch (const SceneError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << "message does not name the file: " << what;
    return what;
  }
  ADD_FAILURE() << name << ": no exception for a malformed scene";
  return "";
}

// Columns [first, last] of the run of target-coloured pixels on `row` that contains column `u`.
bool targetRun(const cv::Mat& img, int row, int u, const cv::Vec3d& albedo, double ambient, int& first, int& last)
{
  auto is = [&](int c) {
    const cv::Vec3b p = img.at<cv::Vec3b>(row, c);
    return isShadeOf(cv::Vec3d(p[0], p[1], p[2]), albedo, ambient);
  };
  if (u < 0 || u >= img.cols || !is(u))
    return false;
  first = last = u;
  while (first > 0 && is(first - 1))
    --first;
  while (last + 1 < img.cols && is(last + 1))
    ++last;
  return true;
}

}  // namespace

TEST(SceneLoading, ShippedScenesLoad)
{
  for (const std::string& name : kShipped)
  {
    SCOPED_TRACE(name);
    SceneDescription d;
    ASSERT_NO_THROW(d = loadScene(scenesDir() + name + ".yaml"));
    EXPECT_EQ(d.name, name);
    EXPECT_EQ(d.frames, 300);
    EXPECT_DOUBLE_EQ(d.fps, 30.0);
    EXPECT_DOUBLE_EQ(d.camera.fx, 525.0);
    EXPECT_DOUBLE_EQ(d.camera.cx, 319.5);
    EXPECT_DOUBLE_EQ(d.camera.baseline, 0.09);
    ASSERT_FALSE(d.objects.empty());
    // Target is orange: RGB in the file, BGR in memory (red > green > blue).
    const cv::Vec3d c = d.objects[0].colour;
    EXPECT_GT(c[2], c[1]);
    EXPECT_GT(c[1], c[0]);
    EXPECT_EQ(d.objects[0].trajectory.type, Trajectory::Type::Pendulum);
    EXPECT_TRUE(d.geometry().valid()) << d.geometry().validate();
    EXPECT_NO_THROW(SceneRenderer r(d));
  }
  const SceneDescription multi = loadScene(scenesDir() + "multi_object.yaml");
  ASSERT_EQ(multi.objects.size(), 2u);
  EXPECT_GT(multi.objects[1].colour[0], multi.objects[1].colour[2]);  // blue
  EXPECT_EQ(loadScene(scenesDir() + "occlusion.yaml").occluders.size(), 1u);
  EXPECT_EQ(loadScene(scenesDir() + "pendulum_cluttered.yaml").background.type,
            stereo_pf::SceneBackground::Type::Cluttered);
}

TEST(SceneLoading, PlainYamlWithoutDirectiveLoadsWithDefaults)
{
  const SceneDescription d = loadScene(writeTemp("minimal", kMinimal));
  EXPECT_EQ(d.camera.width, 640);
  EXPECT_EQ(d.camera.height, 480);
  EXPECT_DOUBLE_EQ(d.camera.fy, 525.0);
  EXPECT_DOUBLE_EQ(d.camera.cy, 239.5);
  EXPECT_DOUBLE_EQ(d.fps, 30.0);
  EXPECT_EQ(d.frames, 300);
  EXPECT_EQ(d.name, "stereo_pf_test_scene_minimal");
  EXPECT_NEAR(d.objects[0].colour[0], 20.0, 1e-9);  // RGB [255, 120, 20] -> BGR
  EXPECT_NEAR(d.objects[0].colour[2], 255.0, 1e-9);
}

TEST(SceneLoading, MalformedScenesThrowUsefulMessages)
{
  std::string m = loadError("syntax", "%YAML:1.0\nfps: 30\nobjects: [\n  - a\n");
  EXPECT_NE(m.find("line"), std::string::npos) << m;

  m = loadError("radius", std::string(kMinimal) + "    radius: abc\n");
  EXPECT_NE(m.find("objects[0].radius"), std::string::npos) << m;

  std::string typo = kMinimal;
  typo.replace(typo.find("radius"), 6, "raduis");
  m = loadError("unknown_key", typo);
  EXPECT_NE(m.find("objects[0].raduis"), std::string::npos) << m;
  EXPECT_NE(m.find("unknown"), std::string::npos) << m;

  m = loadError("no_objects", "fps: 30\n");
  EXPECT_NE(m.find("objects"), std::string::npos) << m;

  m = loadError("pendulum_no_length", "objects:\n  - trajectory:\n      type: pendulum\n      pivot: [0, -1, 1]\n"
                                      "      amplitude_deg: 20\n");
  EXPECT_NE(m.find("objects[0].trajectory.length"), std::string::npos) << m;

  m = loadError("bad_type", "objects:\n  - trajectory:\n      type: orbit\n");
  EXPECT_NE(m.find("objects[0].trajectory.type"), std::string::npos) << m;
  EXPECT_NE(m.find("pendulum"), std::string::npos) << m;  // lists what is allowed

  m = loadError("bad_colour", std::string(kMinimal) + "background:\n  colour: [300, 0, 0]\n");
  EXPECT_NE(m.find("background.colour"), std::string::npos) << m;

  m = loadError("bad_fps", std::string(kMinimal) + "fps: -5\n");
  EXPECT_NE(m.find("fps"), std::string::npos) << m;

  m = loadError("roi_frame", std::string(kMinimal) + "frames: 10\ntarget_roi_frame: 10\n");
  EXPECT_NE(m.find("target_roi_frame"), std::string::npos) << m;

  m = loadError("occluder_size", std::string(kMinimal) + "occluders:\n  - size: [0.3]\n    trajectory:\n"
                                                         "      type: static\n      position: [0, 0, 0.5]\n");
  EXPECT_NE(m.find("occluders[0].size"), std::string::npos) << m;

  EXPECT_THROW(loadScene("/nonexistent/scene.yaml"), SceneError);
  try
  {
    loadScene("/nonexistent/scene.yaml");
  }
  catch (const SceneError& e)
  {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.yaml"), std::string::npos);
  }
}

TEST(SceneRender, TargetProjectsOntoItsColourWithConsistentDisparity)
{
  for (const char* name : { "pendulum_uncluttered", "pendulum_cluttered" })
  {
    SCOPED_TRACE(name);
    SceneRenderer r(loadScene(scenesDir() + name + ".yaml"));
    const stereo_pf::StereoGeometry g = r.geometry();
    const cv::Vec3d albedo = r.scene().objects[0].colour;
    const double ambient = r.scene().light.ambient;
    double z_min = 1e9, z_max = 0.0;
    for (int k = 0; k < r.frames(); ++k)
    {
      const Eigen::Vector3d p = r.targetPosition(k);
      z_min = std::min(z_min, p.z());
      z_max = std::max(z_max, p.z());
      EXPECT_TRUE(r.targetVisible(k)) << "frame " << k;
    }
    EXPECT_LT(z_max - z_min, 0.5);  // the swing also exercises depth
    EXPECT_GT(z_max - z_min, 0.2);

    cv::Mat left, right, left_clean, right_clean;
    for (int k : { 0, 15, 37, 100, 222, 299 })
    {
      SCOPED_TRACE(k);
      const Eigen::Vector3d p = r.targetPosition(k);
      const stereo_pf::Pixel pl = g.projectLeft(p), pr = g.projectRight(p);
      ASSERT_TRUE(g.inImage(pl, 5) && g.inImage(pr, 5));
      r.render(k, left, right);
      EXPECT_TRUE(isShadeOf(meanAround(left, pl.u, pl.v), albedo, ambient)) << meanAround(left, pl.u, pl.v);
      EXPECT_TRUE(isShadeOf(meanAround(right, pr.u, pr.v), albedo, ambient)) << meanAround(right, pr.u, pr.v);

      // The silhouette's row through the centre: its midpoint is where the centre projects, in both
      // images, so the measured disparity matches fx * b / z.
      r.render(k, left_clean, right_clean, false);
      const int row = static_cast<int>(std::lround(pl.v));
      int l0, l1, r0, r1;
      ASSERT_TRUE(targetRun(left_clean, row, static_cast<int>(std::lround(pl.u)), albedo, ambient, l0, l1));
      ASSERT_TRUE(targetRun(right_clean, row, static_cast<int>(std::lround(pr.u)), albedo, ambient, r0, r1));
      const double radius_px = g.apparentRadius(r.scene().objects[0].radius, p.z());
      EXPECT_NEAR(l1 - l0 + 1, 2.0 * radius_px, 2.5);
      EXPECT_NEAR((l0 + l1) / 2.0, pl.u, 1.0);
      EXPECT_NEAR((r0 + r1) / 2.0, pr.u, 1.0);
      EXPECT_NEAR((l0 + l1) / 2.0 - (r0 + r1) / 2.0, g.disparity(p.z()), 1.0);

      // ROI: around the projected centre, about two radii wide.
      const cv::Rect roi = r.targetRoi(k);
      EXPECT_TRUE(roi.contains(cv::Point(static_cast<int>(pl.u), static_cast<int>(pl.v))));
      EXPECT_NEAR(roi.width, 2.0 * radius_px, 2.0);
      EXPECT_NEAR(roi.height, 2.0 * radius_px, 2.0);
    }
  }

  // Far from the ball, the plain wall is not the target's colour.
  SceneRenderer r(loadScene(scenesDir() + "pendulum_uncluttered.yaml"));
  cv::Mat left, right;
  r.render(0, left, right);
  const stereo_pf::Pixel pl = r.geometry().projectLeft(r.targetPosition(0));
  const double u_far = pl.u > 320 ? pl.u - 250 : pl.u + 250;
  EXPECT_FALSE(isShadeOf(meanAround(left, u_far, pl.v), r.scene().objects[0].colour, r.scene().light.ambient));
  EXPECT_FALSE(isShadeOf(meanAround(right, u_far, pl.v), r.scene().objects[0].colour, r.scene().light.ambient));
}

TEST(SceneRender, ClutterSitsAtTheBackgroundDepthAndContainsTargetColour)
{
  SceneRenderer r(loadScene(scenesDir() + "pendulum_cluttered.yaml"));
  cv::Mat left, right;
  r.render(0, left, right, false);
  const int d = static_cast<int>(std::lround(r.geometry().disparity(r.scene().background.depth)));
  ASSERT_EQ(d, 19);
  // Left (u, v) shows what right (u - d, v) shows; without the shift they differ (it is textured).
  const cv::Rect band(100, 20, 200, 80);
  const double matched = cv::norm(left(band), right(band - cv::Point(d, 0)), cv::NORM_L1) / band.area();
  const double unshifted = cv::norm(left(band), right(band), cv::NORM_L1) / band.area();
  EXPECT_LT(matched, 6.0);
  EXPECT_GT(unshifted, 5.0 * matched);

  // Some wall pixels far from the ball have the target's colour (the distractor patches).
  const cv::Rect ball = r.targetRoi(0);
  int target_coloured = 0;
  for (int row = 0; row < left.rows; ++row)
    for (int col = 0; col < left.cols; ++col)
    {
      if (std::abs(col - (ball.x + ball.width / 2)) < 60 && std::abs(row - (ball.y + ball.height / 2)) < 60)
        continue;
      const cv::Vec3b p = left.at<cv::Vec3b>(row, col);
      target_coloured += isShadeOf(cv::Vec3d(p[0], p[1], p[2]), r.scene().objects[0].colour, 0.5) ? 1 : 0;
    }
  EXPECT_GT(target_coloured, 1000);
}

TEST(SceneRender, OcclusionHidesTheTargetOnceForAboutOneSecond)
{
  SceneRenderer r(loadScene(scenesDir() + "occlusion.yaml"));
  int first = -1, last = -1, hidden = 0;
  for (int k = 0; k < r.frames(); ++k)
  {
    if (r.targetVisible(k))
      continue;
    ++hidden;
    if (first < 0)
      first = k;
    last = k;
  }
  EXPECT_GE(hidden, 25);
  EXPECT_LE(hidden, 35);
  EXPECT_EQ(last - first + 1, hidden) << "one contiguous occlusion";
  EXPECT_GE(first, 60) << "visible for at least 60 frames before the occlusion";
  EXPECT_LT(last, r.frames() - 60);

  // In the middle of the occlusion the ball is completely hidden in both images; the board shows there.
  const int mid = (first + last) / 2;
  EXPECT_DOUBLE_EQ(r.visibleFraction(0, mid, View::Left), 0.0);
  EXPECT_DOUBLE_EQ(r.visibleFraction(0, mid, View::Right), 0.0);
  cv::Mat left, right;
  r.render(mid, left, right);
  const stereo_pf::Pixel pl = r.geometry().projectLeft(r.targetPosition(mid));
  EXPECT_FALSE(isShadeOf(meanAround(left, pl.u, pl.v), r.scene().objects[0].colour, r.scene().light.ambient));
  const cv::Vec3d board = r.scene().occluders[0].colour;
  EXPECT_LT(cv::norm(meanAround(left, pl.u, pl.v) - board), 8.0);
}

TEST(SceneRender, SecondObjectEntersAndLeaves)
{
  SceneRenderer r(loadScene(scenesDir() + "multi_object.yaml"));
  const stereo_pf::StereoGeometry g = r.geometry();
  int in_view = 0;
  bool seen_before = false, seen_after = false;
  for (int k = 0; k < r.frames(); ++k)
  {
    const bool present = r.objectPresent(1, k);
    EXPECT_EQ(present, r.stamp(k) >= 3.0 && r.stamp(k) < 8.0) << k;
    const bool shown = r.visibleFraction(1, k, View::Left) > 0.5 && r.visibleFraction(1, k, View::Right) > 0.5;
    in_view += shown ? 1 : 0;
    seen_before = seen_before || (shown && in_view == 1 && k > 90);
    seen_after = seen_after || (!shown && in_view > 0);
    EXPECT_TRUE(r.targetVisible(k)) << "the second ball never hides the target, frame " << k;
  }
  EXPECT_GT(in_view, 60);
  EXPECT_TRUE(seen_before);
  EXPECT_TRUE(seen_after);

  const int k = 165;  // t = 5.5 s: the blue ball is mid-way
  ASSERT_GT(r.visibleFraction(1, k, View::Left), 0.99);
  cv::Mat left, right;
  r.render(k, left, right);
  const Eigen::Vector3d p = r.objectPosition(1, k);
  const cv::Vec3d blue = r.scene().objects[1].colour;
  EXPECT_TRUE(isShadeOf(meanAround(left, g.projectLeft(p).u, g.projectLeft(p).v), blue, r.scene().light.ambient));
  EXPECT_TRUE(isShadeOf(meanAround(right, g.projectRight(p).u, g.projectRight(p).v), blue, r.scene().light.ambient));
}

TEST(SceneRender, DeterministicPerSeed)
{
  SceneDescription d = loadScene(scenesDir() + "pendulum_cluttered.yaml");
  SceneRenderer a(d), b(d);
  cv::Mat la, ra, lb, rb;
  a.render(42, la, ra);
  a.render(7, lb, rb);  // rendering other frames first does not change frame 42
  b.render(42, lb, rb);
  EXPECT_EQ(cv::norm(la, lb, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(ra, rb, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(la, ra, cv::NORM_L1), 0.0);

  d.seed += 1;
  SceneRenderer c(d);
  cv::Mat lc, rc;
  c.render(42, lc, rc);
  EXPECT_GT(cv::norm(la, lc, cv::NORM_L1), 0.0);
  // The difference is the noise only: about sigma per value, nowhere huge.
  cv::Mat diff;
  cv::absdiff(la, lc, diff);
  EXPECT_NEAR(cv::mean(diff.reshape(1))[0], 2.0 * d.noise_sigma / std::sqrt(M_PI), 0.5);
  // Noise-free renders do not depend on the seed.
  a.render(42, la, ra, false);
  c.render(42, lc, rc, false);
  EXPECT_EQ(cv::norm(la, lc, cv::NORM_INF), 0.0);
  // Consecutive frames get different noise.
  a.render(43, lb, rb);
  a.render(42, la, ra);
  cv::Mat top_a = la(cv::Rect(0, 0, 640, 40)), top_b = lb(cv::Rect(0, 0, 640, 40));
  EXPECT_GT(cv::norm(top_a, top_b, cv::NORM_L1), 0.0);
}

TEST(Trajectories, ClosedForms)
{
  const Eigen::Vector3d pivot(0.1, -0.8, 1.2);
  const double a = 0.4, psi = 0.3;
  const Trajectory p = Trajectory::pendulum(pivot, 1.0, a, 2.0, 0.0, psi);
  const Eigen::Vector3d expected =
      pivot + Eigen::Vector3d(std::sin(a) * std::cos(psi), std::cos(a), std::sin(a) * std::sin(psi));
  EXPECT_LT((p.at(0.0) - expected).norm(), 1e-12);
  EXPECT_LT((p.at(2.0) - expected).norm(), 1e-9);           // one period later
  EXPECT_LT((p.at(0.5) - (pivot + Eigen::Vector3d(0, 1, 0))).norm(), 1e-9);  // bottom at a quarter period
  for (double t = 0.0; t < 4.0; t += 0.1)
    EXPECT_NEAR((p.at(t) - pivot).norm(), 1.0, 1e-12);

  const Trajectory l = Trajectory::linear(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 2), 1.0, 3.0);
  EXPECT_LT((l.at(0.0) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  EXPECT_LT((l.at(2.0) - Eigen::Vector3d(0.5, 0, 1.5)).norm(), 1e-12);
  EXPECT_LT((l.at(9.0) - Eigen::Vector3d(1, 0, 2)).norm(), 1e-12);

  const Trajectory b = Trajectory::bounce(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.5, -0.3, 0.2),
                                          Eigen::Vector3d(-0.2, -0.1, 0.8), Eigen::Vector3d(0.2, 0.1, 1.2));
  EXPECT_LT((b.at(0.2) - Eigen::Vector3d(0.1, -0.06, 1.04)).norm(), 1e-12);
  EXPECT_NEAR(b.at(0.6).x(), 0.1, 1e-12);  // 0.3 -> reflected at 0.2 back to 0.1
  for (double t = 0.0; t < 20.0; t += 0.037)
  {
    const Eigen::Vector3d q = b.at(t);
    EXPECT_TRUE((q.array() >= b.box_min.array() - 1e-12).all() && (q.array() <= b.box_max.array() + 1e-12).all());
  }

  Trajectory w = Trajectory::fixed(Eigen::Vector3d(0, 0, 1));
  w.t_enter = 1.0;
  w.t_leave = 2.0;
  EXPECT_FALSE(w.present(0.99));
  EXPECT_TRUE(w.present(1.0));
  EXPECT_FALSE(w.present(2.0));
}

TEST(SceneRender, CheckeredBallAndOccluderInCode)
{
  SceneDescription d;
  d.frames = 2;
  d.noise_sigma = 0.0;
  stereo_pf::SceneSphere ball;
  ball.radius = 0.1;
  ball.checkered = true;
  ball.colour = cv::Vec3d(0, 0, 255);
  ball.colour2 = cv::Vec3d(255, 255, 255);
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.0, 0.0, 1.0));
  d.objects.push_back(ball);
  SceneRenderer r(d);
  cv::Mat left, right;
  r.render(0, left, right);
  // Both checker colours appear inside the ball's silhouette.
  int red = 0, white = 0;
  const cv::Rect roi = r.targetRoi(0);
  for (int row = roi.y; row < roi.y + roi.height; ++row)
    for (int col = roi.x; col < roi.x + roi.width; ++col)
    {
      const cv::Vec3b p = left.at<cv::Vec3b>(row, col);
      red += (p[2] > 60 && p[0] < 10 && p[1] < 10) ? 1 : 0;
      white += (p[0] > 60 && std::abs(p[0] - p[2]) < 3 && std::abs(p[1] - p[2]) < 3) ? 1 : 0;
    }
  EXPECT_GT(red, 1000);
  EXPECT_GT(white, 1000);
  EXPECT_DOUBLE_EQ(r.visibleFraction(0, 0, View::Left), 1.0);

  // A board covering the left half of the ball (as seen from the left camera).
  stereo_pf::SceneOccluder board;
  board.width = 0.25;
  board.height = 0.5;
  board.trajectory = Trajectory::fixed(Eigen::Vector3d(-0.125, 0.0, 0.5));  // right edge at x = 0
  d.occluders.push_back(board);
  SceneRenderer half(d);
  EXPECT_NEAR(half.visibleFraction(0, 0, View::Left), 0.5, 0.05);
  // The board in front of everything: a full cover hides the ball in both images.
  d.occluders[0].width = 1.0;
  SceneRenderer full(d);
  EXPECT_DOUBLE_EQ(full.visibleFraction(0, 0, View::Left), 0.0);
  EXPECT_DOUBLE_EQ(full.visibleFraction(0, 0, View::Right), 0.0);
  EXPECT_FALSE(full.targetVisible(0));
  full.render(0, left, right);
  const cv::Vec3b centre = left.at<cv::Vec3b>(240, 320);
  EXPECT_EQ(cv::Vec3d(centre[0], centre[1], centre[2]), board.colour);
}

// ---------------------------------------------------------------------------------------------------
// Square patches (shape: square), added for the colour-distractor scene.

TEST(SceneSquare, NewShippedScenesLoad)
{
  // The two scenes shipped with the texture and shape cues follow the shipped-scene conventions too.
  for (const std::string name : { "checkered_cluttered", "colour_distractor" })
  {
    SCOPED_TRACE(name);
    SceneDescription d;
    ASSERT_NO_THROW(d = loadScene(scenesDir() + name + ".yaml"));
    EXPECT_EQ(d.name, name);
    EXPECT_EQ(d.frames, 300);
    ASSERT_FALSE(d.objects.empty());
    EXPECT_EQ(d.objects[0].shape, stereo_pf::SceneSphere::Shape::Sphere);
    EXPECT_EQ(d.objects[0].trajectory.type, Trajectory::Type::Pendulum);
    EXPECT_NO_THROW(SceneRenderer r(d));
  }
  const SceneDescription checkered = loadScene(scenesDir() + "checkered_cluttered.yaml");
  EXPECT_TRUE(checkered.objects[0].checkered);
  EXPECT_EQ(checkered.background.type, stereo_pf::SceneBackground::Type::Cluttered);
  const SceneDescription distractor = loadScene(scenesDir() + "colour_distractor.yaml");
  ASSERT_EQ(distractor.objects.size(), 2u);
  EXPECT_EQ(distractor.objects[1].shape, stereo_pf::SceneSphere::Shape::Square);
  EXPECT_EQ(distractor.objects[1].colour, distractor.objects[0].colour);  // the target's colour
  EXPECT_TRUE(distractor.objects[1].checkered);
}

TEST(SceneSquare, ShapeKeyIsChecked)
{
  const SceneDescription d = loadScene(writeTemp("square_ok", std::string(kMinimal) + "    shape: square\n"));
  EXPECT_EQ(d.objects[0].shape, stereo_pf::SceneSphere::Shape::Square);
  EXPECT_EQ(loadScene(writeTemp("sphere_default", kMinimal)).objects[0].shape,
            stereo_pf::SceneSphere::Shape::Sphere);
  const std::string e = loadError("square_bad_shape", std::string(kMinimal) + "    shape: cube\n");
  EXPECT_NE(e.find("objects[0].shape"), std::string::npos) << e;
  EXPECT_NE(e.find("sphere, square"), std::string::npos) << e;
}

TEST(SceneSquare, RendersAFlatShadedPatchWithGroundTruth)
{
  SceneDescription d;
  d.frames = 1;
  d.noise_sigma = 0.0;
  stereo_pf::SceneSphere square;
  square.shape = stereo_pf::SceneSphere::Shape::Square;
  square.radius = 0.05;  // 10 cm side
  square.colour = cv::Vec3d(20, 120, 255);
  square.trajectory = Trajectory::fixed(Eigen::Vector3d(0.1, -0.05, 1.0));
  d.objects.push_back(square);
  SceneRenderer r(d);
  cv::Mat left, right;
  r.render(0, left, right);

  // An axis-aligned box of 2 r f / z = 52.5 px a side around the projected centre.
  const cv::Rect roi = r.objectRoi(0, 0, View::Left);
  EXPECT_NEAR(roi.width, 52.5, 1.0);
  EXPECT_NEAR(roi.height, 52.5, 1.0);
  const double u = d.camera.cx + d.camera.fx * 0.1, v = d.camera.cy - d.camera.fy * 0.05;
  EXPECT_NEAR(roi.x + roi.width / 2.0, u + 0.5, 1.0);
  EXPECT_NEAR(roi.y + roi.height / 2.0, v + 0.5, 1.0);
  EXPECT_DOUBLE_EQ(r.visibleFraction(0, 0, View::Left), 1.0);
  // One flat face, one Lambertian shade: the same colour everywhere inside, a shade of the albedo.
  const cv::Vec3b a = left.at<cv::Vec3b>(cvRound(v), cvRound(u));
  const cv::Vec3b b = left.at<cv::Vec3b>(roi.y + 3, roi.x + 3);
  EXPECT_EQ(a, b);
  EXPECT_TRUE(isShadeOf(cv::Vec3d(a[0], a[1], a[2]), square.colour, d.light.ambient));
  // Outside the box: background.
  const cv::Vec3b bg = left.at<cv::Vec3b>(roi.y + roi.height / 2, roi.x + roi.width + 3);
  EXPECT_EQ(cv::Vec3d(bg[0], bg[1], bg[2]), d.background.colour);
  // The right camera sees it shifted by the disparity f b / z.
  const cv::Rect roi_r = r.objectRoi(0, 0, View::Right);
  EXPECT_NEAR(roi.x - roi_r.x, d.camera.fx * d.camera.baseline / 1.0, 1.0);

  // A checker pattern: both colours inside; [4, 1] gives vertical stripes (constant down a column).
  d.objects[0].checkered = true;
  d.objects[0].colour2 = cv::Vec3d(255, 255, 255);
  d.objects[0].checker_longitude = 4;
  d.objects[0].checker_latitude = 1;
  SceneRenderer striped(d);
  striped.render(0, left, right);
  const cv::Vec3b top = left.at<cv::Vec3b>(roi.y + 4, roi.x + roi.width / 8);
  const cv::Vec3b bottom = left.at<cv::Vec3b>(roi.y + roi.height - 5, roi.x + roi.width / 8);
  const cv::Vec3b next = left.at<cv::Vec3b>(roi.y + 4, roi.x + 3 * roi.width / 8);
  EXPECT_EQ(top, bottom);
  EXPECT_NE(top, next);
}

TEST(SceneSquare, OccludesABallBehindIt)
{
  SceneDescription d;
  d.frames = 1;
  d.noise_sigma = 0.0;
  stereo_pf::SceneSphere ball;
  ball.radius = 0.035;
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.0, 0.0, 1.2));
  d.objects.push_back(ball);
  stereo_pf::SceneSphere square;
  square.shape = stereo_pf::SceneSphere::Shape::Square;
  square.radius = 0.05;
  square.colour = cv::Vec3d(200, 60, 60);
  // Nearer, covering the ball's left half in the left image.
  square.trajectory = Trajectory::fixed(Eigen::Vector3d(-0.05, 0.0, 1.0));
  d.objects.push_back(square);
  SceneRenderer r(d);
  EXPECT_NEAR(r.visibleFraction(0, 0, View::Left), 0.5, 0.08);
  EXPECT_DOUBLE_EQ(r.visibleFraction(1, 0, View::Left), 1.0);  // nothing hides the square
  cv::Mat left, right;
  r.render(0, left, right);
  const double u = d.camera.cx, v = d.camera.cy;  // the ball's centre: covered by the square
  const cv::Vec3b p = left.at<cv::Vec3b>(cvRound(v), cvRound(u) - 5);
  EXPECT_TRUE(isShadeOf(cv::Vec3d(p[0], p[1], p[2]), square.colour, d.light.ambient));
  // Moved behind the ball, the square is the one hidden.
  d.objects[1].trajectory = Trajectory::fixed(Eigen::Vector3d(-0.05, 0.0, 1.5));
  SceneRenderer behind(d);
  EXPECT_DOUBLE_EQ(behind.visibleFraction(0, 0, View::Left), 1.0);
  EXPECT_LT(behind.visibleFraction(1, 0, View::Left), 0.9);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
