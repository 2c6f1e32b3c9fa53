// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Tests of acquisition from a box (matchBox): depth and size from the box's match in the right image, on
// rendered scenes of several sizes, ranges, textures and encodings, and the errors for unusable boxes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <iostream>
#include <random>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "stereo_pf/core/acquisition.h"
#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/estimators.h"
#include "stereo_pf/core/local_search.h"
#include "stereo_pf/core/match_depth_filter.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/colour_contour.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/stereo_match.h"
#include "stereo_pf/plugins/template_match.h"
#include "stereo_pf/plugins/velocity_3d.h"

using stereo_pf::BoxMatch;
using stereo_pf::matchBox;
using stereo_pf::SceneDescription;
using stereo_pf::SceneRenderer;
using stereo_pf::SceneSphere;
using stereo_pf::StereoFrame;
using stereo_pf::Trajectory;

namespace
{
SceneSphere ball(double radius, const Eigen::Vector3d& at, const cv::Vec3d& bgr = cv::Vec3d(20, 120, 255))
{
  SceneSphere s;
  s.radius = radius;
  s.colour = bgr;
  s.trajectory = Trajectory::fixed(at);
  return s;
}

SceneDescription scene(const std::vector<SceneSphere>& objects, double background_depth, bool cluttered = false)
{
  SceneDescription d;
  d.frames = 1;
  d.noise_sigma = 2.0;
  d.seed = 3;
  d.objects = objects;
  d.background.depth = background_depth;
  if (cluttered)
    d.background.type = stereo_pf::SceneBackground::Type::Cluttered;
  return d;
}

// Renders frame 0 into `left`/`right` (kept alive by the caller) and returns the frame with the box.
StereoFrame render(const SceneDescription& d, cv::Mat& left, cv::Mat& right, cv::Rect& box)
{
  SceneRenderer r(d);
  r.render(0, left, right);
  box = r.targetRoi(0);
  StereoFrame f;
  f.left = left;
  f.right = right;
  f.geometry = r.geometry();
  return f;
}

// The size error a box quantised to whole pixels can explain: half a pixel on each side, at depth z.
double sizeTolerance(double radius, double z, double fx)
{
  return std::max(0.03 * radius, 0.6 * z / fx);
}
}  // namespace

TEST(MatchBox, DepthFromDisparityWhateverTheSize)
{
  // 2 cm, 3.5 cm and 8 cm balls at near, middle and far ranges: the depth comes from the disparity, so it
  // must not depend on the size (an assumed size would bias it by the size ratio).
  for (double radius : { 0.02, 0.035, 0.08 })
    for (double z : { 0.6, 1.3, 3.0 })
    {
      SCOPED_TRACE("radius " + std::to_string(radius) + " z " + std::to_string(z));
      cv::Mat l, r;
      cv::Rect box;
      const Eigen::Vector3d truth(0.1 * z, -0.05 * z, z);
      const StereoFrame f = render(scene({ ball(radius, truth) }, z + 1.5), l, r, box);
      const BoxMatch m = matchBox(f, box);
      ASSERT_TRUE(m.ok) << m.error;
      // The disparity measured is that of the two images' boxes (a near ball's image is displaced outward
      // from its centre's projection, differently in each camera); the boxes are whole pixels.
      const cv::Rect right_box =
          SceneRenderer(scene({ ball(radius, truth) }, z + 1.5)).objectRoi(0, 0, stereo_pf::View::Right);
      EXPECT_NEAR(m.disparity, (box.x + box.width / 2.0) - (right_box.x + right_box.width / 2.0), 0.75);
      EXPECT_LT(std::abs(m.centre.z() - z) / z, 0.01);
      EXPECT_LT((m.centre - truth).norm() / z, 0.015);
      EXPECT_NEAR(m.radius, radius, sizeTolerance(radius, z, f.geometry.fx()));
      EXPECT_GT(m.score, 0.9);
    }
}

TEST(MatchBox, AcquisitionWithinThreePercentOnARenderedScene)
{
  // The acceptance: depth and size within 3 %, here on a checkered ball in front of clutter.
  SceneSphere s = ball(0.05, Eigen::Vector3d(-0.15, 0.05, 1.4));
  s.checkered = true;
  s.colour2 = cv::Vec3d(240, 240, 240);
  cv::Mat l, r;
  cv::Rect box;
  const StereoFrame f = render(scene({ s }, 2.5, true), l, r, box);
  const BoxMatch m = matchBox(f, box);
  ASSERT_TRUE(m.ok) << m.error;
  EXPECT_LT(std::abs(m.centre.z() - 1.4) / 1.4, 0.03);
  EXPECT_LT(std::abs(m.radius - 0.05) / 0.05, 0.03);
  EXPECT_TRUE(m.warning.empty()) << m.warning;
}

TEST(MatchBox, GreyImagesAndAWhiteBall)
{
  // mono8, a white ball on a light grey wall: only the shading and the outline are there to match.
  cv::Mat l, r;
  cv::Rect box;
  StereoFrame f = render(scene({ ball(0.04, Eigen::Vector3d(0.05, 0.0, 1.3), cv::Vec3d(245, 245, 245)) }, 2.5), l,
                         r, box);
  cv::Mat gl, gr;
  cv::cvtColor(l, gl, cv::COLOR_BGR2GRAY);
  cv::cvtColor(r, gr, cv::COLOR_BGR2GRAY);
  f.left = gl;
  f.right = gr;
  const BoxMatch m = matchBox(f, box);
  ASSERT_TRUE(m.ok) << m.error;
  EXPECT_LT(std::abs(m.centre.z() - 1.3) / 1.3, 0.01);
}

TEST(MatchBox, GainDifferenceBetweenCamerasDoesNotMatter)
{
  cv::Mat l, r;
  cv::Rect box;
  StereoFrame f = render(scene({ ball(0.035, Eigen::Vector3d(0.0, 0.0, 1.0)) }, 2.5, true), l, r, box);
  cv::Mat darker;
  r.convertTo(darker, -1, 0.75, 10.0);
  f.right = darker;
  const BoxMatch m = matchBox(f, box);
  ASSERT_TRUE(m.ok) << m.error;
  EXPECT_NEAR(m.disparity, f.geometry.disparity(1.0), 0.3);
}

TEST(MatchBox, TwoLookalikesOnTheRowAreAnErrorNamingTheBox)
{
  // A second identical ball 5 cm to the left at the same depth: in the right image it sits where the first
  // one would be if it were nearer, so the match cannot tell which is which.
  cv::Mat l, r;
  cv::Rect box;
  const StereoFrame f = render(
      scene({ ball(0.02, Eigen::Vector3d(0.0, 0.0, 1.0)), ball(0.02, Eigen::Vector3d(-0.05, 0.0, 1.0)) }, 2.5), l, r,
      box);
  const BoxMatch m = matchBox(f, box);
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.error.find("ambiguous"), std::string::npos) << m.error;
  EXPECT_NE(m.error.find(stereo_pf::boxText(box)), std::string::npos) << m.error;
  // Seen alone, the same ball matches.
  cv::Mat l1, r1;
  const StereoFrame alone = render(scene({ ball(0.02, Eigen::Vector3d(0.0, 0.0, 1.0)) }, 2.5), l1, r1, box);
  EXPECT_TRUE(matchBox(alone, box).ok);
}

TEST(MatchBox, UnusableBoxesAreClearErrors)
{
  cv::Mat l, r;
  cv::Rect box;
  const StereoFrame f = render(scene({ ball(0.035, Eigen::Vector3d(0.0, 0.0, 1.0)) }, 2.5), l, r, box);
  const cv::Rect outside(600, 400, 80, 120);
  BoxMatch m = matchBox(f, outside);
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.error.find("600,400,80,120"), std::string::npos) << m.error;
  EXPECT_NE(m.error.find("not inside"), std::string::npos) << m.error;
  m = matchBox(f, cv::Rect(10, 10, 2, 2));
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.error.find("too small"), std::string::npos) << m.error;
  // A box on the flat wall: nothing to correlate.
  SceneDescription flat = scene({ ball(0.035, Eigen::Vector3d(0.0, 0.0, 1.0)) }, 2.5);
  flat.noise_sigma = 0.0;
  cv::Mat fl, fr;
  const StereoFrame ff = render(flat, fl, fr, box);
  m = matchBox(ff, cv::Rect(20, 20, 30, 30));
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.error.find("no contrast"), std::string::npos) << m.error;
}

TEST(MatchBox, ABoxWithNoCounterpartIsNoMatch)
{
  // The right image replaced by a different scene: nothing there correlates with the box.
  cv::Mat l, r, l2, r2;
  cv::Rect box, other;
  StereoFrame f = render(scene({ ball(0.035, Eigen::Vector3d(0.0, 0.0, 1.0)) }, 2.5, true), l, r, box);
  SceneDescription d = scene({ ball(0.035, Eigen::Vector3d(0.3, 0.2, 1.0), cv::Vec3d(200, 40, 40)) }, 2.5, true);
  d.background.seed = 9;
  const StereoFrame g = render(d, l2, r2, other);
  f.right = g.right;
  const BoxMatch m = matchBox(f, box);
  EXPECT_FALSE(m.ok);
  EXPECT_NE(m.error.find("no match in the right image"), std::string::npos) << m.error;
  // ... saying what its best candidate would mean (the depth, how far apart the two views of it are).
  EXPECT_NE(m.error.find(" m away, seen by the two cameras from "), std::string::npos) << m.error;
}

TEST(MatchBox, AnObjectSeenAgainstOtherSurroundingsInEachViewIsMatchedAlone)
{
  // Close up, the two cameras see the object against different surroundings: here a textured patch in front of
  // a dark wall in the left image and of a bright one in the right, 30 px of disparity. The window with its ring
  // (the outline against the surroundings) correlates poorly; the object alone matches.
  cv::Mat left(240, 320, CV_8UC1, cv::Scalar(30)), right(240, 320, CV_8UC1, cv::Scalar(30));
  right(cv::Rect(100, 0, 120, 240)).setTo(cv::Scalar(230));
  cv::Mat patch(40, 40, CV_8UC1);
  cv::RNG rng(5);
  rng.fill(patch, cv::RNG::UNIFORM, 90, 170);
  cv::GaussianBlur(patch, patch, cv::Size(3, 3), 0.0);
  patch.copyTo(left(cv::Rect(160, 100, 40, 40)));
  patch.copyTo(right(cv::Rect(130, 100, 40, 40)));
  StereoFrame f;
  f.left = left;
  f.right = right;
  f.geometry = stereo_pf::StereoGeometry(400.0, 400.0, 160.0, 120.0, 0.1, 320, 240);
  const cv::Rect box(160, 100, 40, 40);
  // The window with its ring alone (no minimum, so no fallback): it scores below a match.
  stereo_pf::BoxMatchOptions with_ring;
  with_ring.min_score = -1.0;
  const BoxMatch ring = matchBox(f, box, with_ring);
  const BoxMatch m = matchBox(f, box);
  std::cout << "[ figures  ] with the ring: correlation " << ring.score << " at disparity " << ring.disparity
            << "; the object alone: " << m.score << " at " << m.disparity << "\n";
  EXPECT_LT(ring.score, stereo_pf::BoxMatchOptions().min_score);
  ASSERT_TRUE(m.ok) << m.error;
  EXPECT_NEAR(m.disparity, 30.0, 0.5);
  EXPECT_GT(m.score, 0.9);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

namespace
{
template <class Plugin>
std::shared_ptr<Plugin> plugin(const std::string& name)
{
  auto m = std::make_shared<Plugin>();
  m->initialize(name, stereo_pf::Parameters());
  return m;
}

// An engine with the target cues of the default configuration (colour, template, outline; no stereo match) on
// `state` (Position3D when none is given).
stereo_pf::FilterEngine defaultEngine(std::shared_ptr<stereo_pf::StateModel> state = nullptr,
                                      const stereo_pf::EngineConfig& config = stereo_pf::EngineConfig())
{
  using namespace stereo_pf;
  return FilterEngine(state ? state : plugin<Position3D>("state_model"),
                      { plugin<ColourHSI>("colour"), plugin<TemplateMatch>("template"),
                        plugin<ColourContour>("colour_contour") },
                      config);
}
}  // namespace

TEST(MatchBox, ACandidateTheLeftImageShowsElsewhereIsPassedOver)
{
  // The object (texture P, 40 px) at left x 300 is seen by the right camera at disparity 60 with noise on it (its
  // other side, other light). Something on the wall (texture Q, two parts P and one part another texture) lies
  // at disparity 30, at right x 100: in the right image it is where the object would be at disparity 200, and
  // there it correlates with the box better than the object's own right image does. Looked for in the left image,
  // that patch is found where it lies (left x 130), not at the box: the match is the object's, at 60.
  cv::RNG rng(11);
  auto texture = [&](cv::Mat& t) {
    t.create(40, 40, CV_32F);
    rng.fill(t, cv::RNG::UNIFORM, 60.0, 200.0);
    cv::GaussianBlur(t, t, cv::Size(5, 5), 0.0);
  };
  cv::Mat p, other, noise;
  texture(p);
  texture(other);
  noise.create(40, 40, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 12.0);
  const cv::Mat q = (2.0 * p + other) / 3.0, seen = p + noise;
  cv::Mat left(240, 640, CV_32F, cv::Scalar(128)), right(240, 640, CV_32F, cv::Scalar(128));
  p.copyTo(left(cv::Rect(300, 100, 40, 40)));
  q.copyTo(left(cv::Rect(130, 100, 40, 40)));
  seen.copyTo(right(cv::Rect(240, 100, 40, 40)));
  q.copyTo(right(cv::Rect(100, 100, 40, 40)));
  StereoFrame f;
  left.convertTo(f.left, CV_8U);
  right.convertTo(f.right, CV_8U);
  f.geometry = stereo_pf::StereoGeometry(400.0, 400.0, 320.0, 120.0, 0.1, 640, 240);
  const cv::Rect box(300, 100, 40, 40);
  const BoxMatch m = matchBox(f, box);
  ASSERT_TRUE(m.ok) << m.error;
  std::cout << "[ figures  ] correlation at disparity 200 (the wall's patch) " << m.scores[200] << ", at 60 (the object) "
            << m.scores[60] << "; matched at " << m.disparity << "\n";
  EXPECT_GT(m.scores[200], m.scores[60]) << "the wall's patch must correlate better for this to test anything";
  EXPECT_NEAR(m.disparity, 60.0, 0.5);
  // With the object's right image gone (the wall's patch the only candidate), no match is a clear error.
  cv::Mat hidden = right.clone();
  hidden(cv::Rect(240, 100, 40, 40)).setTo(cv::Scalar(128));
  hidden.convertTo(f.right, CV_8U);
  const BoxMatch none = matchBox(f, box);
  EXPECT_FALSE(none.ok);
  EXPECT_NE(none.error.find("no consistent match"), std::string::npos) << none.error;
  EXPECT_NE(none.error.find(stereo_pf::boxText(box)), std::string::npos) << none.error;
}

TEST(MatchBox, ABackdropFarBehindALooseBoxIsNotTakenForTheObject)
{
  // A plain dark disc (radius 14 px) in a loose 40 px box, at disparity 30, before a textured wall far behind it
  // (disparity 0: the same in both images) that has a dark patch of its own where the disc hides it. Most of what
  // the box holds that varies is the wall, and at disparity 0 the right image shows that patch where the disc
  // was: the wall matches best. Taken for the object, it puts the object infinitely far (a disparity of 1 px
  // would make it 40 baselines across); the disc's own match, which implies 1.3 baselines, is taken instead.
  cv::RNG rng(5);
  cv::Mat wall(240, 640, CV_32F);
  rng.fill(wall, cv::RNG::UNIFORM, 88.0, 168.0);
  cv::GaussianBlur(wall, wall, cv::Size(9, 9), 0.0);
  for (int y = 0; y < wall.rows; ++y)
    for (int x = 0; x < wall.cols; ++x)
    {
      const double r2 = (x - 420.0) * (x - 420.0) + (y - 120.0) * (y - 120.0);
      wall.at<float>(y, x) -= static_cast<float>(60.0 * std::exp(-r2 / 250.0));  // the dark patch behind the disc
    }
  cv::Mat left = wall.clone(), right = wall.clone();
  cv::circle(left, cv::Point(420, 120), 14, cv::Scalar(98), cv::FILLED);
  cv::circle(right, cv::Point(390, 120), 14, cv::Scalar(98), cv::FILLED);
  StereoFrame f;
  left.convertTo(f.left, CV_8U);
  right.convertTo(f.right, CV_8U);
  f.geometry = stereo_pf::StereoGeometry(400.0, 400.0, 320.0, 120.0, 0.1, 640, 240);
  const cv::Rect box(400, 100, 40, 40);
  // Without the preference the wall is taken (here: too far to measure), as before it.
  stereo_pf::BoxMatchOptions off;
  off.max_size_baselines = 0.0;
  const BoxMatch wall_match = matchBox(f, box, off);
  EXPECT_FALSE(wall_match.ok && std::abs(wall_match.disparity - 30.0) < 0.5) << "the disc is matched anyway";
  const BoxMatch m = matchBox(f, box);
  ASSERT_TRUE(m.ok) << m.error;
  std::cout << "[ figures  ] correlation at disparity 0 (the wall) " << m.scores[0] << ", at 30 (the disc) "
            << m.scores[30] << "; matched at " << m.disparity << "\n";
  EXPECT_GT(m.scores[0], m.scores[30]) << "the wall must correlate better for this to test anything";
  EXPECT_NEAR(m.disparity, 30.0, 0.5);
  EXPECT_NEAR(m.centre.z(), 400.0 * 0.1 / 30.0, 0.02);
  // The user hears of it: the box shows mostly the wall, and the cues learn from the box.
  EXPECT_NE(m.warning.find("box 400,100,40,40"), std::string::npos) << m.warning;
  EXPECT_NE(m.warning.find("tight"), std::string::npos) << m.warning;
  std::cout << "[ warning  ] " << m.warning << "\n";
}

namespace
{
/// The default cues and Velocity3D configured by `c`, learning the target from frame 0's box of `renderer`'s scene:
/// each of its first `frames` frames' error over the range (1 in a frame without an estimate).
std::vector<double> relativeErrors(stereo_pf::SceneRenderer& renderer, int frames, const stereo_pf::EngineConfig& c)
{
  using namespace stereo_pf;
  FilterEngine engine = defaultEngine(plugin<Velocity3D>("state_model"), c);
  cv::Mat l, r;
  auto frame = [&](int k) { return renderer.renderFrame(k, l, r); };
  std::string error;
  EXPECT_TRUE(engine.learnTarget(frame(0), renderer.targetRoi(0), error)) << error;
  std::vector<double> errors;
  for (int k = 0; k < frames; ++k)
  {
    const FrameResult res = engine.step(frame(k));
    const Eigen::Vector3d truth = renderer.targetPosition(k);
    errors.push_back(res.estimate.valid ? (res.estimate.position - truth).norm() / truth.norm() : 1.0);
  }
  return errors;
}
}  // namespace

TEST(Tracking, NoDepthBiasFromTheObjectsSize)
{
  // The default cues and Position3D on a static 2 cm and 8 cm ball in front of clutter: the learned size, and
  // the size band, leave depth to disparity (an assumed 3.5 cm made a 4 cm ball ~6 % short, an 8 cm cube ~17 %).
  // One run's mean depth moves by up to ~1 % from engine seed to engine seed (on a static scene the frames share
  // their error), so the bias is the mean over three seeds, and each run is held to twice the bound.
  using namespace stereo_pf;
  for (double radius : { 0.02, 0.08 })
  {
    SCOPED_TRACE("radius " + std::to_string(radius));
    const Eigen::Vector3d truth(0.08, -0.04, 1.2);
    SceneSphere s = ball(radius, truth);
    s.checkered = true;
    s.colour2 = cv::Vec3d(240, 240, 240);
    SceneDescription d = scene({ s }, 2.4, true);
    d.frames = 30;
    SceneRenderer renderer(d);
    double bias_sum = 0.0;
    const int seeds = 3;
    for (int seed = 1; seed <= seeds; ++seed)
    {
      EngineConfig config;
      config.seed = seed;
      FilterEngine engine = defaultEngine(plugin<Position3D>("state_model"), config);
      cv::Mat l, r;
      auto frame = [&](int k) { return renderer.renderFrame(k, l, r); };
      std::string error;
      ASSERT_TRUE(engine.learnTarget(frame(0), renderer.targetRoi(0), error)) << error;
      EXPECT_NEAR(engine.targetRadius(), radius, 0.03 * radius);
      double depth_sum = 0.0;
      int n = 0;
      for (int k = 0; k < d.frames; ++k)
      {
        const FrameResult res = engine.step(frame(k));
        ASSERT_EQ(res.state, TrackState::Tracking) << "seed " << seed << ", frame " << k;
        if (k >= 10)
        {
          depth_sum += res.estimate.position.z();
          ++n;
        }
      }
      const double bias = (depth_sum / n - truth.z()) / truth.z();
      std::printf("[ figures  ] radius %.2f m, seed %d: mean depth %.4f m for %.4f (%+.2f %%)\n", radius, seed,
                  depth_sum / n, truth.z(), 100.0 * bias);
      EXPECT_LT(std::abs(bias), 0.02) << "seed " << seed << ": mean depth " << depth_sum / n;
      bias_sum += bias;
    }
    std::printf("[ figures  ] radius %.2f m: depth bias %+.2f %% (mean of %d seeds)\n", radius,
                100.0 * bias_sum / seeds, seeds);
    EXPECT_LT(std::abs(bias_sum / seeds), 0.01);
  }
}

TEST(Tracking, ABallThrownAtTheCameraIsFollowedByTheLocalSearch)
{
  // A light grey ball thrown from 4 m to 1.2 m at 60 fps (about 11 m/s: its disparity grows by up to a radius
  // a frame, its image four-fold), in front of clutter, the default cues and
  // Velocity3D: with the local search's matches giving each arrival its velocity it follows; without, its
  // velocity catches up with the ball later. Over seeds 1-6: which seed is worse without is a draw (at
  // acceleration_noise 12 seed 1 was 4.8 times worse, seed 5 1.6 times).
  using namespace stereo_pf;
  SceneSphere s = ball(0.037, Eigen::Vector3d(0.0, 0.0, 4.0), cv::Vec3d(190, 190, 190));
  s.trajectory.type = Trajectory::Type::Waypoints;
  s.trajectory.times = { 0.0, 0.25 };
  s.trajectory.points = { Eigen::Vector3d(-0.1, -0.05, 4.0), Eigen::Vector3d(0.08, 0.04, 1.2) };
  SceneDescription d = scene({ s }, 6.0, true);
  d.fps = 60.0;
  d.frames = 16;
  SceneRenderer renderer(d);
  auto run = [&](double local_fraction, unsigned long seed, double& worst) {
    EngineConfig c;
    c.local_fraction = local_fraction;
    c.seed = seed;
    const std::vector<double> e = relativeErrors(renderer, d.frames, c);
    worst = *std::max_element(e.begin(), e.end());
    double sum2 = 0.0;
    for (double x : e)
      sum2 += x * x;
    return std::sqrt(sum2 / d.frames);
  };
  std::vector<double> ratios;
  for (unsigned long seed = 1; seed <= 6; ++seed)
  {
    double worst_local = 0.0, worst_walk = 0.0;
    const double local = run(0.1, seed, worst_local);
    const double walk = run(0.0, seed, worst_walk);
    EXPECT_LT(local, 0.02) << "RMS error / range with the local search (worst " << worst_local << "), seed " << seed;
    EXPECT_LT(worst_local, 0.05) << "seed " << seed;
    std::cout << "[ figures  ] seed " << seed << ", RMS error / range: local search " << local << " (worst "
              << worst_local << "), without " << walk << " (worst " << worst_walk << ")\n";
    EXPECT_GT(walk, local) << "seed " << seed << ": without it " << walk << " (worst " << worst_walk << ")";
    ratios.push_back(walk / local);
  }
  std::sort(ratios.begin(), ratios.end());
  EXPECT_GT(0.5 * (ratios[2] + ratios[3]), 1.5) << "the median seed is not 1.5 times worse without the local search";
}

TEST(Tracking, AnObjectAlreadyMovingFastWhenBoxedIsFollowedFromTheFirstFrame)
{
  // A ball 6.3 px in radius crossing the view at 6 m/s, 2.5 m away at 30 fps: 42 px (almost seven radii) a frame,
  // from the frame its box is drawn on. No motion is known at the first frame after the box; the local search
  // then reaches as far as start_speed (20 m/s) goes in a frame, and the track follows. With start_speed 0 (a
  // window of two radii) the ball is out of reach at once.
  using namespace stereo_pf;
  SceneSphere s = ball(0.03, Eigen::Vector3d(0.0, 0.0, 2.5));
  s.trajectory.type = Trajectory::Type::Waypoints;
  s.trajectory.times = { 0.0, 0.4 };
  s.trajectory.points = { Eigen::Vector3d(-1.2, 0.1, 2.5), Eigen::Vector3d(1.2, 0.1, 2.5) };
  SceneDescription d = scene({ s }, 5.0, true);
  d.frames = 12;
  SceneRenderer renderer(d);
  auto run = [&](double start_speed, unsigned long seed) {
    EngineConfig c;
    c.start_speed = start_speed;
    c.seed = seed;
    const std::vector<double> e = relativeErrors(renderer, d.frames, c);
    return *std::max_element(e.begin(), e.end());
  };
  for (unsigned long seed = 1; seed <= 3; ++seed)
  {
    const double followed = run(EngineConfig().start_speed, seed), two_radii = run(0.0, seed);
    std::cout << "[ figures  ] seed " << seed << ", worst error / range: start_speed " << EngineConfig().start_speed
              << " m/s " << followed << ", 0 (two radii) " << two_radii << "\n";
    EXPECT_LT(followed, 0.03) << "seed " << seed;
    EXPECT_GT(two_radii, 0.1) << "seed " << seed;
  }
}

namespace
{
/// The local search's input for an object last seen at left (300, 200), disparity 40 px, 10 px in radius, that
/// moved `du` px along the row in the last frame.
stereo_pf::ImageTrack trackAt300(double du)
{
  stereo_pf::ImageTrack track;
  track.left = stereo_pf::Pixel{ 300.0, 200.0 };
  track.du = du;
  track.disparity = 40.0;
  track.radius = 10.0;
  return track;
}

/// What a window of the object's size sees of an object at left (u, 200), disparity 40 px, 10 px in radius: the
/// object within a radius of its centre, then nothing.
stereo_pf::HypothesisScorer objectAt(double u)
{
  return [u](const stereo_pf::ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const double at = hyp.view == stereo_pf::View::Left ? u : u - 40.0;
      const double s = std::max(0.0, 1.0 - std::hypot(hyp.u[i] - at, hyp.v[i] - 200.0) / 10.0);
      ll[i] += 10.0 * s;
      sim[i] += s;
    }
  };
}
}  // namespace

TEST(LocalSearch, AnObjectThatReversedItsMotionIsFound)
{
  // The object moved 40 px to the right in the last frame and now bounces back: it is 40 px to the left of where
  // it was, 80 px from where that motion predicts (a ball at the turning point of a fast pass, 10 px in radius).
  // It is found there, as is one that kept going, and one that went on at half again its speed.
  using namespace stereo_pf;
  const ImageTrack track = trackAt300(40.0);
  LocalSearch search;
  for (const double u : { 260.0, 340.0, 360.0 })
  {
    const LocalMatch m = search.search(track, 640, 480, objectAt(u));
    ASSERT_TRUE(m.found) << "object at u = " << u;
    // To the fine grid's spacing (m.step, 3 px here), which the right image's match inherits.
    EXPECT_NEAR(m.left.u, u, m.step) << "object at u = " << u;
    EXPECT_NEAR(m.left.v, 200.0, m.step) << "object at u = " << u;
    EXPECT_NEAR(m.right.u, u - 40.0, m.step + 0.5) << "object at u = " << u;
    EXPECT_GT(m.similarity, 0.8) << "object at u = " << u;
  }
}

TEST(LocalSearch, AnObjectItsMotionTookOutOfTheViewIsNotLookedForBehindIt)
{
  // The object moved 40 px to the right, to 300 px, in an image 330 px wide: its motion takes it out of the view. A
  // look-alike stands 40 px to its left, where the motion reversed would take it. In a wider image the search
  // finds that place (a bounce); here the object has left the view, and the search proposes nothing.
  using namespace stereo_pf;
  const ImageTrack track = trackAt300(40.0);
  LocalSearch search;
  EXPECT_TRUE(search.search(track, 640, 480, objectAt(260.0)).found);
  EXPECT_FALSE(search.search(track, 330, 480, objectAt(260.0)).found);
}

TEST(LocalSearch, AMovingObjectIsFollowedPastALookAlikeThatScoresBetter)
{
  // The object moved 30 px to the right in the last frame and went on; a sharp look-alike 40 px below where it went
  // scores 1, inside the window the search covers (a window's similarity falls off over a few radii of its
  // centre). A blurred object scoring 0.88, within LocalSearch::kTieMargin of the look-alike, is where its motion
  // took it: it is followed. Blurred beyond that (0.7), the look-alike is the best the search can tell.
  using namespace stereo_pf;
  const ImageTrack track = trackAt300(30.0);
  LocalSearch search;
  for (const auto& [object, expected_v] : { std::pair{ 0.88, 200.0 }, std::pair{ 0.7, 240.0 } })
  {
    const HypothesisScorer score = [&](const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
      for (int i = 0; i < hyp.size(); ++i)
      {
        const double shift = hyp.view == View::Left ? 0.0 : 40.0;
        auto bump = [&](double u, double v, double height) {
          return height * std::max(0.0, 1.0 - std::hypot(hyp.u[i] - (u - shift), hyp.v[i] - v) / 25.0);
        };
        const double s = std::max(bump(330.0, 200.0, object), bump(330.0, 240.0, 1.0));
        ll[i] += 10.0 * s;
        sim[i] += s;
      }
    };
    const LocalMatch m = search.search(track, 640, 480, score);
    ASSERT_TRUE(m.found) << "object scoring " << object;
    EXPECT_NEAR(m.left.u, 330.0, m.step) << "object scoring " << object;
    EXPECT_NEAR(m.left.v, expected_v, m.step) << "object scoring " << object;
  }
}

TEST(LocalSearch, WithNoMotionKnownItReachesAsFarAsItIsTold)
{
  // A track with no motion known yet (its first frame after the box) of an object 10 px in radius that has moved
  // 70 px along the row: the window of two radii around where it was misses it; told that it may have gone 80 px
  // (ImageTrack::reach, from the engine's start_speed) and finding nothing as similar as ImageTrack::enough (1 by
  // default) near, the search finds it.
  using namespace stereo_pf;
  const HypothesisScorer score = [&](const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const double at = hyp.view == View::Left ? 370.0 : 330.0;
      const double s = std::max(0.0, 1.0 - std::hypot(hyp.u[i] - at, hyp.v[i] - 200.0) / 10.0);
      ll[i] += 10.0 * s;
      sim[i] += s;
    }
  };
  LocalSearch search;
  ImageTrack still = trackAt300(0.0);
  const LocalMatch near = search.search(still, 640, 480, score);
  EXPECT_FALSE(near.found && near.similarity > 0.5) << "found at " << near.left.u;
  still.reach = 80.0;
  const LocalMatch far = search.search(still, 640, 480, score);
  ASSERT_TRUE(far.found);
  EXPECT_NEAR(far.left.u, 370.0, far.step);
  EXPECT_NEAR(far.left.v, 200.0, far.step);
  EXPECT_GT(far.similarity, 0.7);
  // The grid stays no coarser than the object's radius.
  EXPECT_LE(3.0 * far.step, 10.0 + 1e-9);

  // A slow object, 5 px from where it was, scores 0.8; a look-alike 70 px off scores 1. Whatever is within two
  // radii and as similar as the object should be (ImageTrack::enough) ends the search there.
  const HypothesisScorer two = [&](const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const double shift = hyp.view == View::Left ? 0.0 : 40.0;
      auto bump = [&](double at, double height) {
        return height * std::max(0.0, 1.0 - std::hypot(hyp.u[i] - (at - shift), hyp.v[i] - 200.0) / 10.0);
      };
      const double s = std::max(bump(305.0, 0.8), bump(370.0, 1.0));
      ll[i] += 10.0 * s;
      sim[i] += s;
    }
  };
  still.enough = 0.65;
  const LocalMatch slow = search.search(still, 640, 480, two);
  ASSERT_TRUE(slow.found);
  EXPECT_NEAR(slow.left.u, 305.0, slow.step);
  still.enough = 1.0;  // nothing is that similar: the look-alike, the best within reach, is taken
  const LocalMatch taken = search.search(still, 640, 480, two);
  ASSERT_TRUE(taken.found);
  EXPECT_NEAR(taken.left.u, 370.0, taken.step);
}

TEST(LocalSearch, AKnownMotionBoundsTheDisparitiesSearched)
{
  // The object is at left (300, 200) and its right image at disparity 100, where it scores weakly (its right view
  // against another background); a look-alike on the same row scores well at disparity 110. Still before (no
  // motion known), a sudden depth change of a tenth of the disparity is searched: the look-alike is taken. Known
  // to move along the row at constant depth, only a twentieth is: the object is kept.
  using namespace stereo_pf;
  auto bump = [](double x, double at, double height) { return height * std::exp(-0.5 * (x - at) * (x - at) / 4.0); };
  const HypothesisScorer score = [&](const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const double u = hyp.u[i], v = hyp.v[i];
      const double row = bump(v, 200.0, 1.0);
      const double s = row * (hyp.view == View::Left ? bump(u, 300.0, 1.0) :
                                                       std::max(bump(u, 200.0, 0.6), bump(u, 190.0, 0.9)));
      ll[i] += 10.0 * s;
      sim[i] += s;
    }
  };
  LocalSearch search;
  ImageTrack still = trackAt300(0.0);
  still.disparity = 100.0;
  const LocalMatch jumped = search.search(still, 640, 480, score);
  ASSERT_TRUE(jumped.found);
  EXPECT_NEAR(jumped.left.u - jumped.right.u, 110.0, 0.5) << "no motion known: a tenth of the disparity searched";
  // Moving along the row by 0.5 px a frame, arriving at 300.
  ImageTrack moving = still;
  moving.left.u -= 0.5;
  moving.du = 0.5;
  const LocalMatch kept = search.search(moving, 640, 480, score);
  ASSERT_TRUE(kept.found);
  EXPECT_NEAR(kept.left.u, 300.0, 1.0);
  EXPECT_NEAR(kept.left.u - kept.right.u, 100.0, 0.5) << "a known motion: a twentieth searched";
}

TEST(LocalSearch, TheRightViewsDisparityIsWhereTheTwoViewsAgree)
{
  // The object was at left (300, 200), disparity 40, and has not moved. Its right image looks less like the
  // target (another background behind it in that view) than a look-alike 4.5 px further left on the same row,
  // within the disparities searched: each view's own score alone takes the look-alike's disparity, 44.5; with a
  // scorer of the two views' agreement, which peaks where the left match's pixels are, the search keeps 40.
  using namespace stereo_pf;
  const ImageTrack track = trackAt300(0.0);
  const double true_right = 260.0, lookalike = 255.5;
  auto bump = [](double x, double at, double height) { return height * std::exp(-0.5 * (x - at) * (x - at) / 4.0); };
  const HypothesisScorer score = [&](const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim) {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const double u = hyp.u[i], v = hyp.v[i];
      const double s = hyp.view == View::Left ?
                           bump(u, 300.0, 1.0) * bump(v, 200.0, 1.0) :
                           std::max(bump(u, true_right, 0.7), bump(u, lookalike, 0.9)) * bump(v, 200.0, 1.0);
      ll[i] += 10.0 * s;
      sim[i] += s;
    }
  };
  const PairScorer agree = [&](const ImageHypotheses& left, const ImageHypotheses& right, Eigen::VectorXd& ll) {
    ASSERT_EQ(left.size(), right.size());
    for (int i = 0; i < right.size(); ++i)
    {
      EXPECT_EQ(left.view, View::Left);
      EXPECT_FLOAT_EQ(left.v[i], right.v[i]) << "a pair lies on one row";
      ll[i] += 10.0 * bump(left.u[i] - right.u[i], 40.0, 1.0);
    }
  };
  LocalSearch search;
  const LocalMatch alone = search.search(track, 640, 480, score);
  ASSERT_TRUE(alone.found);
  EXPECT_NEAR(alone.left.u - alone.right.u, 44.5, 0.5) << "each view alone: the look-alike";
  const LocalMatch paired = search.search(track, 640, 480, score, agree);
  ASSERT_TRUE(paired.found);
  EXPECT_NEAR(paired.left.u, 300.0, 1.0);
  EXPECT_NEAR(paired.left.v, 200.0, 1.0);
  EXPECT_NEAR(paired.left.u - paired.right.u, 40.0, 0.5) << "with the views' agreement: the object";
}

namespace
{
struct Coverage
{
  int frames = 0;            ///< tracking frames judged
  double published = 0.0;    ///< share with the truth inside the published 95 % ellipsoid
  double refined = 0.0;      ///< ... inside the ellipsoid of the refined cloud's own covariance
  double median_sigma = 0.0; ///< median of the published ellipsoid's largest standard deviation / range
};

/// Over a small corpus of rendered scenes (four balls of other sizes, ranges, surfaces and motions, tracked by
/// the default state model and cues), the tracking frames whose truth lies inside a 95 % ellipsoid (chi-square,
/// 3 degrees of freedom).
Coverage ellipsoidCoverage()
{
  using namespace stereo_pf;
  struct Case
  {
    SceneSphere ball;
    Eigen::Vector3d to;
    double seconds, fps, background;
    bool cluttered;
  };
  SceneSphere orange = ball(0.035, Eigen::Vector3d(-0.3, 0.0, 1.2));
  SceneSphere white = ball(0.02, Eigen::Vector3d(0.0, -0.1, 0.7), cv::Vec3d(235, 235, 235));
  SceneSphere checker = ball(0.08, Eigen::Vector3d(0.2, 0.1, 3.0));
  checker.checkered = true;
  checker.colour2 = cv::Vec3d(240, 240, 240);
  SceneSphere grey = ball(0.05, Eigen::Vector3d(-0.5, 0.0, 2.0), cv::Vec3d(150, 150, 150));
  const std::vector<Case> corpus = { { orange, Eigen::Vector3d(0.3, 0.1, 1.4), 1.5, 30.0, 2.5, true },
                                     { white, Eigen::Vector3d(0.1, 0.05, 0.8), 1.5, 30.0, 1.6, false },
                                     { checker, Eigen::Vector3d(-0.2, 0.0, 2.2), 1.5, 30.0, 4.5, true },
                                     { grey, Eigen::Vector3d(0.5, 0.0, 2.0), 0.6, 60.0, 3.5, true } };
  Coverage result;
  int inside = 0, refined_inside = 0;
  std::vector<double> sigma;
  for (const Case& c : corpus)
  {
    SceneSphere s = c.ball;
    s.trajectory.type = Trajectory::Type::Waypoints;
    s.trajectory.times = { 0.0, c.seconds };
    s.trajectory.points = { c.ball.trajectory.position, c.to };
    SceneDescription d = scene({ s }, c.background, c.cluttered);
    d.fps = c.fps;
    d.frames = 36;
    SceneRenderer renderer(d);
    FilterEngine engine(plugin<Velocity3D>("state_model"),
                        { plugin<ColourHSI>("colour"), plugin<TemplateMatch>("template"),
                          plugin<ColourContour>("colour_contour"), plugin<StereoMatch>("stereo") },
                        EngineConfig());
    cv::Mat l, r;
    std::string error;
    EXPECT_TRUE(engine.learnTarget(renderer.renderFrame(0, l, r), renderer.targetRoi(0), error)) << error;
    for (int k = 0; k < d.frames; ++k)
    {
      const FrameResult res = engine.step(renderer.renderFrame(k, l, r));
      if (res.state != TrackState::Tracking || !res.estimate.valid)
        continue;
      const Eigen::Vector3d truth = renderer.targetPosition(k);
      const Eigen::Vector3d e = res.estimate.position - truth;
      const ParticleSet& refined = engine.weightedSets().front();
      const Eigen::MatrixXd xyz = refined.states.leftCols(3);
      const Eigen::MatrixXd cloud = weightedCovariance(xyz, refined.weights, res.estimate.position);
      ++result.frames;
      inside += e.dot(res.estimate.covariance.ldlt().solve(e)) <= 7.815;
      refined_inside += e.dot(Eigen::Matrix3d(cloud).ldlt().solve(e)) <= 7.815;
      sigma.push_back(std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(res.estimate.covariance)
                                    .eigenvalues()
                                    .maxCoeff()) /
                      truth.norm());
    }
  }
  if (result.frames > 0)
  {
    result.published = static_cast<double>(inside) / result.frames;
    result.refined = static_cast<double>(refined_inside) / result.frames;
    std::nth_element(sigma.begin(), sigma.begin() + sigma.size() / 2, sigma.end());
    result.median_sigma = sigma[sigma.size() / 2];
  }
  return result;
}
}  // namespace

TEST(Uncertainty, TheTruthLiesInsideThePublished95PercentEllipsoid)
{
  // The acceptance, on a corpus small enough for a unit test: in at least 85 % of tracked frames. The
  // refining cues' likelihoods leave a cloud narrower than the error (the ellipsoid published before: 85-87 % here,
  // far less on the stress suite; untempered, the refined cloud's own held the truth in 83 % of these frames, and
  // with engine/refine_min_ess's floor in 92 %); the published one adds the region the other cues allow, holds the
  // truth at least as often, and is still informative (its largest standard deviation a few per cent of the range
  // at most). Until refine_min_ess this asked the published ellipsoid for 10 points more than the refined cloud's
  // own: that margin was the refined cloud's over-confidence, which the floor took away; the refined cloud is now
  // asked to reach 85 % itself (83 % untempered).
  const Coverage c = ellipsoidCoverage();
  std::cout << "[ figures  ] inside the published 95 % ellipsoid: " << 100.0 * c.published << " % of " << c.frames
            << " tracking frames (the refined cloud's own: " << 100.0 * c.refined
            << " %); median largest sigma / range " << 100.0 * c.median_sigma << " %\n";
  EXPECT_GE(c.frames, 4 * 30) << "the corpus is tracked";
  EXPECT_GE(c.published, 0.85);
  EXPECT_GE(c.refined, 0.85);
  EXPECT_LT(c.median_sigma, 0.03);
}

namespace
{
// The default cues (colour, template, outline) and Position3D, as the tracker loads them.
}  // namespace

TEST(CueTrust, ACueTheBackgroundMatchesAsWellAsTheObjectIsNotTrusted)
{
  // A disc of grey noise in front of grey noise of the same distribution, mono8: its intensity histogram is the
  // background's, and it has no outline of a colour, but its pattern (the template) is its own.
  using namespace stereo_pf;
  const int width = 320, height = 240;
  const double fx = 300.0, baseline = 0.12, z = 1.5, radius = 0.06;
  const double disparity = fx * baseline / z, r_px = fx * radius / z;
  cv::RNG rng(7);
  cv::Mat l(height, width, CV_8UC1), r(height, width, CV_8UC1), pattern(height, width, CV_8UC1);
  rng.fill(l, cv::RNG::UNIFORM, 0, 256);
  rng.fill(r, cv::RNG::UNIFORM, 0, 256);
  rng.fill(pattern, cv::RNG::UNIFORM, 0, 256);
  for (cv::Mat* m : { &l, &r, &pattern })
    cv::GaussianBlur(*m, *m, cv::Size(0, 0), 1.5);
  cv::normalize(l, l, 0, 255, cv::NORM_MINMAX);
  cv::normalize(r, r, 0, 255, cv::NORM_MINMAX);
  cv::normalize(pattern, pattern, 0, 255, cv::NORM_MINMAX);
  const cv::Point at(180, 110);
  cv::Mat disc = cv::Mat::zeros(height, width, CV_8UC1);
  cv::circle(disc, at, static_cast<int>(r_px), cv::Scalar(255), cv::FILLED);
  pattern.copyTo(l, disc);
  // The right view sees the same disc `disparity` pixels to the left.
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, -disparity, 0, 1, 0);
  cv::Mat pattern_right, disc_right;
  cv::warpAffine(pattern, pattern_right, shift, pattern.size());
  cv::warpAffine(disc, disc_right, shift, disc.size(), cv::INTER_NEAREST);
  pattern_right.copyTo(r, disc_right);
  StereoFrame f;
  f.left = l;
  f.right = r;
  f.geometry = StereoGeometry(fx, fx, width / 2.0, height / 2.0, baseline, width, height);
  const cv::Rect box(at.x - static_cast<int>(r_px), at.y - static_cast<int>(r_px), 2 * static_cast<int>(r_px) + 1,
                     2 * static_cast<int>(r_px) + 1);
  FilterEngine engine = defaultEngine();
  std::string error;
  ASSERT_TRUE(engine.learnTarget(f, box, error)) << error;
  const std::vector<double>& trust = engine.cueTrust();
  ASSERT_EQ(trust.size(), 3u);
  std::cout << "[ figures  ] trust colour " << trust[0] << ", template " << trust[1] << ", outline " << trust[2]
            << "\n";
  EXPECT_LT(trust[0], 0.2);
  EXPECT_GT(trust[1], 0.8);
  EXPECT_LT(trust[2], 0.5);

  // The trust is part of the target: saved with it and restored by loading it.
  const std::string path = testing::TempDir() + "/cue_trust_target.yaml";
  ASSERT_TRUE(engine.saveTarget(path, error)) << error;
  FilterEngine other = defaultEngine();
  ASSERT_TRUE(other.loadTarget(path, error)) << error;
  for (size_t k = 0; k < trust.size(); ++k)
    EXPECT_NEAR(other.cueTrust()[k], trust[k], 1e-9) << "cue " << k;
}

TEST(CueTrust, InColourEveryDefaultCueIsTrusted)
{
  // An orange ball in front of the same clutter, in colour: every cue tells it apart.
  using namespace stereo_pf;
  cv::Mat l, r;
  cv::Rect box;
  const StereoFrame f = render(scene({ ball(0.04, Eigen::Vector3d(0.05, 0.0, 1.3)) }, 2.5, true), l, r, box);
  FilterEngine engine = defaultEngine();
  std::string error;
  ASSERT_TRUE(engine.learnTarget(f, box, error)) << error;
  std::cout << "[ figures  ] trust colour " << engine.cueTrust()[0] << ", template " << engine.cueTrust()[1]
            << ", outline " << engine.cueTrust()[2] << "\n";
  for (double t : engine.cueTrust())
    EXPECT_GT(t, 0.8);
}

namespace
{
/// A light grey 4 cm ball at (-0.1, 0.05, 1.1) m, and a TemplateMatch that learned it from its box in the left
/// image (through `cache`, reset to that frame).
struct LearnedGreyBall
{
  explicit LearnedGreyBall(double depth = 1.1) : truth(-0.1, 0.05, depth)
  {
    f = render(scene({ ball(0.04, truth, cv::Vec3d(200, 200, 200)) }, 2.2, true), l, r, box);
    cache.reset(f);
    learned = m->learnTarget(cache, stereo_pf::View::Left, box, error);
  }
  const Eigen::Vector3d truth;
  cv::Mat l, r;
  cv::Rect box;
  stereo_pf::StereoFrame f;
  stereo_pf::FeatureCache cache;
  std::shared_ptr<stereo_pf::TemplateMatch> m = plugin<stereo_pf::TemplateMatch>("template");
  std::string error;
  bool learned = false;
};
}  // namespace

TEST(TemplateMatch, PeaksAtTheObjectInBothViewsAndSurvivesSaveAndLoad)
{
  using namespace stereo_pf;
  LearnedGreyBall g;
  ASSERT_TRUE(g.learned) << g.error;
  const Eigen::Vector3d& truth = g.truth;
  const StereoFrame& f = g.f;
  FeatureCache& cache = g.cache;
  auto& m = g.m;
  std::string& error = g.error;
  const float radius = static_cast<float>(f.geometry.apparentRadius(0.04, truth.z()));
  // At the object in each view, and 1, 2 and 3 radii beside it on the same row.
  auto score = [&](const TemplateMatch& model, View view, Eigen::VectorXd& ll) {
    const Pixel at = view == View::Left ? f.geometry.projectLeft(truth) : f.geometry.projectRight(truth);
    ImageHypotheses h;
    h.view = view;
    h.resize(4);
    for (int i = 0; i < 4; ++i)
    {
      h.u[i] = static_cast<float>(at.u) + i * radius;
      h.v[i] = static_cast<float>(at.v);
      h.radius[i] = radius;
      h.valid[i] = 1;
    }
    Eigen::VectorXd sim(4);
    ll.resize(4);
    const_cast<TemplateMatch&>(model).evaluate(cache, h, ll, sim);
    return sim;
  };
  for (View view : { View::Left, View::Right })
  {
    Eigen::VectorXd ll;
    const Eigen::VectorXd sim = score(*m, view, ll);
    EXPECT_GT(sim[0], 0.8) << "view " << static_cast<int>(view);
    for (int i = 1; i < 4; ++i)
    {
      EXPECT_GT(sim[0] - sim[i], 0.3) << "view " << static_cast<int>(view) << ", " << i << " radii aside";
      EXPECT_GT(ll[0], ll[i]);
    }
  }
  // The saved template evaluates as the learned one.
  cv::FileStorage out(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  m->saveTarget(out);
  const std::string text = out.releaseAndGetString();
  cv::FileStorage in(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  auto loaded = plugin<TemplateMatch>("template");
  ASSERT_TRUE(loaded->loadTarget(in[loaded->name()], error)) << error;  // as FilterEngine::loadTarget passes it
  Eigen::VectorXd ll_learned, ll_loaded;
  score(*m, View::Left, ll_learned);
  score(*loaded, View::Left, ll_loaded);
  EXPECT_LT((ll_learned - ll_loaded).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(TemplateMatch, ConvertsOnlyTheRowsItsWindowsReadAndScoresAsOnTheWholeImage)
{
  // evaluate() and adapt() ask the cache for the grey rows their windows reach only. Scores must be those on the
  // whole grey image, also for windows reaching over the image's edges (sample() clamps them to the edge rows).
  // The band's cache first holds a black frame's grey rows, so a row it left out would read 0.
  using namespace stereo_pf;
  LearnedGreyBall g;
  ASSERT_TRUE(g.learned) << g.error;
  const Eigen::Vector3d& truth = g.truth;
  const StereoFrame& f = g.f;
  FeatureCache& whole = g.cache;
  auto& m = g.m;
  whole.gray(View::Left);
  StereoFrame black = f;
  black.left = cv::Mat(f.left.size(), f.left.type(), cv::Scalar::all(0));  // new buffers, not f's
  black.right = cv::Mat(f.right.size(), f.right.type(), cv::Scalar::all(0));
  const float w = static_cast<float>(f.left.cols), h = static_cast<float>(f.left.rows);
  const Pixel at = f.geometry.projectLeft(truth);
  const float radius = static_cast<float>(f.geometry.apparentRadius(0.04, truth.z()));
  const std::vector<std::array<float, 3>> places = { { static_cast<float>(at.u), static_cast<float>(at.v), radius },
                                                      { 5.0f, 2.0f, 10.0f },
                                                      { w - 3.0f, h - 1.5f, 10.0f },
                                                      { 0.5f * w, -4.0f, 8.0f },
                                                      { 0.5f * w, h + 3.0f, 8.0f },
                                                      { 0.3f * w, 0.5f * h, 300.0f } };
  Eigen::VectorXd sim_whole(1);
  for (size_t i = 0; i < places.size(); ++i)
  {
    ImageHypotheses one;  // one at a time: together their band would be the union
    one.view = View::Left;
    one.resize(1);
    one.u[0] = places[i][0];
    one.v[0] = places[i][1];
    one.radius[0] = places[i][2];
    one.valid[0] = 1;
    FeatureCache band;
    band.reset(black);
    band.gray(View::Left);
    band.reset(f);
    Eigen::VectorXd ll_band(1), sim_band(1), ll_whole(1);
    m->evaluate(band, one, ll_band, sim_band);
    m->evaluate(whole, one, ll_whole, sim_whole);
    EXPECT_EQ(ll_band[0], ll_whole[0]) << "hypothesis " << i;
    if (i == 0)
    {
      EXPECT_GT(sim_whole[0], 0.8);
    }
  }
}

TEST(TemplateMatch, TheMapsCorrelationIsOpenCVsNormalisedCorrelationCoefficient)
{
  // The map's correlation is computed with OpenCV's filters (faster than cv::matchTemplate for its small templates):
  // it must give what matchTemplate does, on texture, on flat patches, and for templates of the map's sizes.
  using namespace stereo_pf;
  cv::Mat grey(150, 200, CV_8UC1);
  cv::randu(grey, 0, 256);
  cv::GaussianBlur(grey, grey, cv::Size(5, 5), 1.5);
  grey(cv::Rect(20, 30, 40, 30)).setTo(90);  // no contrast: both give 0 inside
  cv::Mat image;
  grey.convertTo(image, CV_32F);
  for (int side : { 5, 7, 9 })
  {
    const cv::Mat templ = image(cv::Rect(120, 70, side, side + 2)).clone();
    cv::Mat ours, opencv;
    normalisedCorrelation(image, templ, ours);
    cv::matchTemplate(image, templ, opencv, cv::TM_CCOEFF_NORMED);
    ASSERT_EQ(ours.size(), opencv.size()) << side;
    double worst = 0.0;
    cv::minMaxLoc(cv::abs(ours - opencv), nullptr, &worst);
    EXPECT_LT(worst, 1e-3) << "template " << side;
    EXPECT_NEAR(ours.at<float>(70, 120), 1.0f, 1e-4) << "the template's own place";
    EXPECT_EQ(ours.at<float>(35, 25), 0.0f) << "a window without contrast";
  }
}

TEST(TemplateMatch, AdaptsWhenTheObjectMatchesNearTheEstimateNotOnlyAtIt)
{
  // The object changes its look (a dark band across the grey ball, as a turning object shows another side) while the
  // track's estimate lies a quarter of a radius beside its centre. There the window correlates less with the template
  // than adapt_min (0.6 by default) asks, but the window within adapt_align radii that matches it best does: the
  // template adapts to it and comes to score the banded ball higher. Held to the window at the estimate, it never
  // adapted (the drawn turning box was lost by frame 60 at 6 of 21 engine seeds that way). An estimate
  // three radii off, on the backdrop, has nothing near it like the template: no adaptation.
  using namespace stereo_pf;
  LearnedGreyBall g;
  ASSERT_TRUE(g.learned) << g.error;
  const float radius = static_cast<float>(g.f.geometry.apparentRadius(0.04, g.truth.z()));
  const Pixel at = g.f.geometry.projectLeft(g.truth);
  cv::Mat banded_left = g.f.left.clone();
  cv::rectangle(banded_left, cv::Point(cvRound(at.u - radius), cvRound(at.v - 0.35 * radius)),
                cv::Point(cvRound(at.u + radius), cvRound(at.v + 0.35 * radius)), cv::Scalar::all(40), cv::FILLED);
  StereoFrame banded = g.f;
  banded.left = banded_left;
  FeatureCache cache;
  cache.reset(banded);
  ImageHypotheses centre;
  centre.view = View::Left;
  centre.resize(1);
  centre.u[0] = static_cast<float>(at.u);
  centre.v[0] = static_cast<float>(at.v);
  centre.radius[0] = radius;
  centre.valid[0] = 1;
  Eigen::VectorXd ll(1), before(1), beside_sim(1), far_sim(1);
  g.m->evaluate(cache, centre, ll, before);
  auto adaptedAt = [&](float offset) {
    auto m = plugin<TemplateMatch>("template");
    std::string error;
    EXPECT_TRUE(m->learnTarget(g.cache, View::Left, g.box, error)) << error;
    ImageHypotheses estimate = centre;
    estimate.u[0] += offset * radius;
    for (int k = 0; k < 20; ++k)
      m->adapt(cache, estimate);
    Eigen::VectorXd l(1), sim(1);
    m->evaluate(cache, centre, l, sim);
    return sim[0];
  };
  const double beside = adaptedAt(0.25f), far = adaptedAt(3.0f);
  std::printf("banded ball: %.3f before adapting, %.3f adapted beside it, %.3f adapted 3 radii off\n", before[0], beside,
              far);
  EXPECT_LT(before[0], 0.8) << "the band must change the look: else this tests nothing";
  EXPECT_GT(beside, before[0] + 0.1) << "adapted to the banded ball found near the estimate";
  EXPECT_NEAR(far, before[0], 1e-9) << "nothing near an estimate on the backdrop to adapt to";
}

TEST(TemplateMatch, AdaptsToTheObjectNotToAnEstimateBesideIt)
{
  // A track's estimate a quarter of a radius beside the object's centre, frame after frame: the template adapts to
  // the window there that matches it best (adapt_align), so it stays centred on the object and keeps scoring the
  // object's centre above the estimate's place. Adapted at the estimate itself (adapt_align 0) it learns the window
  // beside the object, and the place beside it comes to score best: the next estimate would lie farther off. At 1.1 m
  // (~20 px in radius) every pixel within reach is tried; at 0.35 m (~60 px) a coarse grid first, then every pixel
  // around its best.
  using namespace stereo_pf;
  for (double depth : { 1.1, 0.35 })
  {
    SCOPED_TRACE("ball at " + std::to_string(depth) + " m");
    LearnedGreyBall g(depth);
    ASSERT_TRUE(g.learned) << g.error;
    const float radius = static_cast<float>(g.f.geometry.apparentRadius(0.04, g.truth.z()));
    const Pixel at = g.f.geometry.projectLeft(g.truth);
    ImageHypotheses places;  // the object's centre, then the estimate beside it
    places.view = View::Left;
    places.resize(2);
    for (int i = 0; i < 2; ++i)
    {
      places.u[i] = static_cast<float>(at.u) + i * 0.25f * radius;
      places.v[i] = static_cast<float>(at.v);
      places.radius[i] = radius;
      places.valid[i] = 1;
    }
    ImageHypotheses estimate = places;
    estimate.resize(1);
    estimate.u[0] = places.u[1];
    auto adaptedScores = [&](const Parameters& params) {
      auto m = std::make_shared<TemplateMatch>();
      m->initialize("template", params);
      std::string error;
      EXPECT_TRUE(m->learnTarget(g.cache, View::Left, g.box, error)) << error;
      for (int k = 0; k < 40; ++k)
        m->adapt(g.cache, estimate);
      Eigen::VectorXd ll(2), sim(2);
      m->evaluate(g.cache, places, ll, sim);
      return sim;
    };
    Parameters params;
    params.set("adapt_min", 0.3);  // a plain ball's window a quarter of a radius off correlates ~0.5 with the template
    const Eigen::VectorXd aligned = adaptedScores(params);
    Parameters at_estimate = params;
    at_estimate.set("adapt_align", 0.0);
    const Eigen::VectorXd unaligned = adaptedScores(at_estimate);
    std::printf("radius %.1f px, after 40 adaptations: centre %.3f, estimate's place %.3f aligned; %.3f, %.3f at the "
                "estimate\n",
                radius, aligned[0], aligned[1], unaligned[0], unaligned[1]);
    EXPECT_GT(aligned[0], aligned[1] + 0.05);
    EXPECT_GT(aligned[0], 0.8);
    EXPECT_GT(unaligned[1], unaligned[0]) << "adapted at the estimate the template must drift: else this tests nothing";
  }
}

TEST(TemplateMatch, TwoTemplatesInOneTrackerHaveTargetMapsOfTheirOwn)
{
  // The recovery search's maps come through the frame's cache. Two templates (two TemplateMatch cues in one
  // tracker, each with its target) shared one map under one key: the second was given the first's. Each now has its
  // own, and a template that changes (learned again) has its map computed again in the same frame.
  using namespace stereo_pf;
  LearnedGreyBall g;
  ASSERT_TRUE(g.learned) << g.error;
  auto other = plugin<TemplateMatch>("other_template");
  const cv::Rect wall(20, 20, g.box.width, g.box.height);  // a patch of the backdrop, away from the ball
  ASSERT_TRUE(other->learnTarget(g.cache, View::Left, wall, g.error)) << g.error;
  cv::Mat ball_map, wall_map;
  ASSERT_TRUE(g.m->targetMap(g.cache, View::Left, ball_map));
  ball_map = ball_map.clone();
  ASSERT_TRUE(other->targetMap(g.cache, View::Left, wall_map));
  wall_map = wall_map.clone();
  EXPECT_GT(cv::norm(ball_map, wall_map, cv::NORM_L1), 0.0) << "the second template was given the first's map";
  // The maps are coarser than the image: compare them at the ball's centre, scaled to the map.
  const Pixel at = g.f.geometry.projectLeft(g.truth);
  const cv::Point ball(static_cast<int>(at.u * ball_map.cols / g.f.left.cols),
                       static_cast<int>(at.v * ball_map.rows / g.f.left.rows));
  EXPECT_GT(ball_map.at<uint8_t>(ball), wall_map.at<uint8_t>(ball));
  // The first learned again, from the wall: its map follows within the frame.
  ASSERT_TRUE(g.m->learnTarget(g.cache, View::Left, wall, g.error)) << g.error;
  cv::Mat again;
  ASSERT_TRUE(g.m->targetMap(g.cache, View::Left, again));
  EXPECT_EQ(cv::norm(again, wall_map, cv::NORM_L1), 0.0);
}

namespace
{
/// A cue whose scores a test scripts (evaluate()): it learns nothing and saves nothing.
class TestCue : public stereo_pf::ObservationModel
{
public:
  bool learnTarget(stereo_pf::FeatureCache&, stereo_pf::View, const cv::Rect&, std::string&) override { return true; }
  bool hasTarget() const override { return true; }
  void saveTarget(cv::FileStorage&) const override {}
  bool loadTarget(const cv::FileNode&, std::string&) override { return true; }

protected:
  void onInitialize() override {}
};

/// Two identical balls 24 cm apart, the object left of the image centre and its look-alike right of it, and an
/// engine configuration with the recovery search on every frame and the scripted cues counting fully (without
/// cue_trust: they score the object below the background).
struct TwoBalls
{
  static stereo_pf::SceneDescription describe(int frames)
  {
    stereo_pf::SceneDescription d = scene({ ball(0.03, target), ball(0.03, look_alike) }, 2.4, true);
    d.frames = frames;
    return d;
  }
  explicit TwoBalls(int frames) : frames(frames), renderer(describe(frames))
  {
    config.recovery_period = 1;
    config.cue_trust = false;
  }
  /// Learns the object from its box in frame 0 and tracks every frame (`before(k)` runs before frame k), which must
  /// stay Tracking; `distances` gets, per frame, the estimate's distance to the object and to the look-alike.
  void track(stereo_pf::FilterEngine& engine, std::vector<std::pair<double, double>>& distances,
             const std::function<void(int)>& before = {})
  {
    cv::Mat l, r;
    std::string error;
    ASSERT_TRUE(engine.learnTarget(renderer.renderFrame(0, l, r), renderer.targetRoi(0), error)) << error;
    for (int k = 0; k < frames; ++k)
    {
      if (before)
        before(k);
      const stereo_pf::FrameResult res = engine.step(renderer.renderFrame(k, l, r));
      ASSERT_EQ(res.state, stereo_pf::TrackState::Tracking) << "frame " << k;
      distances.emplace_back((res.estimate.position - target).norm(), (res.estimate.position - look_alike).norm());
    }
  }
  static inline const Eigen::Vector3d target{ -0.12, 0.0, 1.2 }, look_alike{ 0.12, 0.0, 1.2 };
  int frames;
  SceneRenderer renderer;
  stereo_pf::EngineConfig config;
};

/// A refining cue that, like stereo agreement on a surface seen against different backgrounds in the two views,
/// scores one place much better than the object: every hypothesis right of the image centre.
class FavouringTheRightHalf : public TestCue
{
public:
  void evaluate(stereo_pf::FeatureCache& cache, const stereo_pf::ImageHypotheses& hyp,
                Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    const double centre = 0.5 * cache.geometry().width();
    for (int i = 0; i < hyp.size(); ++i)
    {
      similarity[i] = hyp.valid[i] && hyp.u[i] > centre ? 1.0 : 0.3;
      log_likelihood[i] = (similarity[i] - 1.0) / 0.02;  // e^-35 for the object: as sharp as the stereo cue
    }
  }

protected:
  bool refinesByDefault() const override { return true; }
};
}  // namespace

namespace
{
/// A cue that scores every hypothesis alike (similarity 0.1, log-likelihood 0: it moves no particle), and says
/// whether it identifies the target (learns its look) as `Identifies`.
template <bool Identifies>
class Flat : public TestCue
{
public:
  void evaluate(stereo_pf::FeatureCache&, const stereo_pf::ImageHypotheses& hyp,
                Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    for (int i = 0; i < hyp.size(); ++i)
    {
      log_likelihood[i] = 0.0;
      similarity[i] = kSimilarity;
    }
  }
  bool identifiesTarget() const override { return Identifies; }
  static constexpr double kSimilarity = 0.1;
};
}  // namespace

TEST(Tracking, ACueThatLearnsNoLookOfTheTargetIsNoEvidenceThatItIsSeen)
{
  // The evidence that the target is seen (FrameResult::evidence, what found_ and lost_similarity judge) is the mean
  // similarity of the cues that compare each view with the target. A cue that learns nothing of its look (the
  // shape cue: any round outline of its size) weighs the particles but is not part of that mean: beside the
  // colour histogram, a flat cue scoring 0.1 everywhere leaves every frame's evidence as the histogram alone gives
  // it; the same flat cue claiming to identify the target halves the histogram's distance to 0.1. Alone, it is
  // all there is, and counts.
  using namespace stereo_pf;
  TwoBalls balls(6);
  auto run = [&](std::vector<std::shared_ptr<ObservationModel>> cues, const EngineConfig& config) {
    FilterEngine engine(plugin<Position3D>("state_model"), std::move(cues), config);
    cv::Mat l, r;
    std::string error;
    EXPECT_TRUE(engine.learnTarget(balls.renderer.renderFrame(0, l, r), balls.renderer.targetRoi(0), error)) << error;
    std::vector<FrameResult> results;
    for (int k = 0; k < balls.frames; ++k)
      results.push_back(engine.step(balls.renderer.renderFrame(k, l, r)));
    return results;
  };
  const std::vector<FrameResult> alone = run({ plugin<ColourHSI>("colour") }, balls.config);
  const std::vector<FrameResult> beside =
      run({ plugin<ColourHSI>("colour"), plugin<Flat<false>>("outline") }, balls.config);
  const std::vector<FrameResult> claiming =
      run({ plugin<ColourHSI>("colour"), plugin<Flat<true>>("outline") }, balls.config);
  ASSERT_EQ(alone.size(), beside.size());
  for (size_t k = 0; k < alone.size(); ++k)
  {
    EXPECT_EQ(alone[k].state, TrackState::Tracking) << "frame " << k;
    EXPECT_DOUBLE_EQ(beside[k].evidence, alone[k].evidence) << "frame " << k;
    EXPECT_EQ(beside[k].state, alone[k].state) << "frame " << k;
  }
  EXPECT_GT(alone[0].evidence, 0.6);
  // The first frame's particles are the same in all three (the flat cue moves none).
  EXPECT_NEAR(claiming[0].evidence, 0.5 * (alone[0].evidence + Flat<true>::kSimilarity), 1e-12);

  EngineConfig search = balls.config;
  search.acquire = false;  // nothing to match the box with
  cv::Mat l, r;
  FilterEngine engine(plugin<Position3D>("state_model"), { plugin<Flat<false>>("outline") }, search);
  std::string error;
  ASSERT_TRUE(engine.learnTarget(balls.renderer.renderFrame(0, l, r), balls.renderer.targetRoi(0), error)) << error;
  EXPECT_DOUBLE_EQ(engine.step(balls.renderer.renderFrame(0, l, r)).evidence, Flat<false>::kSimilarity);
}

TEST(Tracking, ARefiningCueDoesNotHandTheTrackToALookAlike)
{
  // Two identical balls, the target left of the centre and its look-alike right of it. The recovery search (here
  // on every frame) keeps proposing particles on the look-alike, which the colour histogram scores as well as
  // the object. A refining cue preferring the look-alike by e^35 must not give it the track: the refining cues
  // weigh the recovery's jumps and the predicted particles each within the share the evidence cues gave them.
  // (Before, the jumps took the whole weight on the first frame of the search.)
  using namespace stereo_pf;
  TwoBalls balls(30);
  FilterEngine engine(plugin<Position3D>("state_model"),
                      { plugin<ColourHSI>("colour"), plugin<FavouringTheRightHalf>("favour") }, balls.config);
  std::vector<std::pair<double, double>> distances;
  balls.track(engine, distances);
  ASSERT_EQ(static_cast<int>(distances.size()), balls.frames);
  // Colour alone pins the object to a few centimetres; the look-alike is 24 cm away.
  double worst = 0.0;
  for (int k = 0; k < balls.frames; ++k)
  {
    worst = std::max(worst, distances[k].first);
    EXPECT_LT(distances[k].first, 0.5 * distances[k].second)
        << "frame " << k << ": the estimate left the object for the look-alike";
  }
  std::printf("[ figures  ] largest distance from the object %.1f cm (the look-alike is 24 cm away)\n", 100.0 * worst);
}

namespace
{
/// A refining cue as sharp as the stereo match and knowing nothing: each hypothesis's log-likelihood is a hash of
/// its image position spread over 40 nats, so whichever particle the jitter happens to put on a high value would
/// take all the weight.
class SharpNoise : public TestCue
{
public:
  void evaluate(stereo_pf::FeatureCache&, const stereo_pf::ImageHypotheses& hyp,
                Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    for (int i = 0; i < hyp.size(); ++i)
    {
      const uint32_t h = static_cast<uint32_t>(std::lround(hyp.u[i] * 64.0f)) * 2654435761u ^
                         static_cast<uint32_t>(std::lround(hyp.v[i] * 64.0f)) * 40503u;
      similarity[i] = static_cast<double>((h >> 7) % 10007u) / 10007.0;
      log_likelihood[i] = -40.0 * (1.0 - similarity[i]);
    }
  }

protected:
  bool refinesByDefault() const override { return true; }
};
}  // namespace

TEST(Tracking, ARefiningCueCannotLeaveTheEstimateToAHandfulOfParticles)
{
  // engine/refine_min_ess: the refining stage is tempered to leave an ESS of at least 1 % of the particles, so the
  // estimate stays a mean over what the other cues allowed, not the one or two particles a sharp refining cue
  // happened to favour (on a drawn scene, one particle 7 cm off a small box took 0.96 of the weight and the track
  // ran 22 % of range short). Without it this cue leaves a handful.
  using namespace stereo_pf;
  TwoBalls balls(20);
  auto run = [&](double refine_min_ess) {
    std::vector<double> ess;
    EngineConfig config = balls.config;
    config.refine_min_ess = refine_min_ess;
    FilterEngine engine(plugin<Position3D>("state_model"), { plugin<ColourHSI>("colour"), plugin<SharpNoise>("noise") },
                        config);
    cv::Mat l, r;
    std::string error;
    EXPECT_TRUE(engine.learnTarget(balls.renderer.renderFrame(0, l, r), balls.renderer.targetRoi(0), error)) << error;
    for (int k = 0; k < balls.frames; ++k)
    {
      const FrameResult res = engine.step(balls.renderer.renderFrame(k, l, r));
      EXPECT_EQ(res.state, TrackState::Tracking) << "frame " << k;
      ess.push_back(res.ess);
    }
    std::sort(ess.begin(), ess.end());
    return ess;
  };
  const std::vector<double> tempered = run(0.01), untempered = run(0.0);
  const double floor = 0.01 * balls.config.particles;
  EXPECT_GE(tempered.front(), 0.99 * floor);  // every frame (to rounding; jumps keep their group shares after it)
  EXPECT_LT(untempered[untempered.size() / 2], 0.6 * floor);
  std::printf("[ figures  ] refined ESS: smallest %.1f, median %.1f (untempered %.1f, %.1f)\n", tempered.front(),
              tempered[tempered.size() / 2], untempered.front(), untempered[untempered.size() / 2]);
}

namespace
{
/// An evidence cue under a script: near the object's image (within half its apparent radius) it scores 0.95,
/// near a look-alike's 0.7, elsewhere 0.2; on `sunk` frames the object scores 0.5 (its appearance lost against a
/// new background). Its target map shows both.
class SinkingObject : public TestCue
{
public:
  int frame = 0;
  int sunk_from = 0, sunk_to = 0;  ///< frames [sunk_from, sunk_to)
  Eigen::Vector3d object, look_alike;
  double radius = 0.0;  ///< m
  void evaluate(stereo_pf::FeatureCache& cache, const stereo_pf::ImageHypotheses& hyp,
                Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    const stereo_pf::StereoGeometry& g = cache.geometry();
    const stereo_pf::Pixel o = g.project(object, hyp.view), a = g.project(look_alike, hyp.view);
    const double near = 0.5 * g.apparentRadius(radius, object.z());
    const double object_score = frame >= sunk_from && frame < sunk_to ? 0.5 : 0.95;
    for (int i = 0; i < hyp.size(); ++i)
    {
      similarity[i] = 0.2;
      if (hyp.valid[i] && std::hypot(hyp.u[i] - o.u, hyp.v[i] - o.v) < near)
        similarity[i] = object_score;
      else if (hyp.valid[i] && std::hypot(hyp.u[i] - a.u, hyp.v[i] - a.v) < near)
        similarity[i] = 0.7;
      log_likelihood[i] = (similarity[i] - 1.0) / 0.02;
    }
  }
  bool targetMap(stereo_pf::FeatureCache& cache, stereo_pf::View view, cv::Mat& map) override
  {
    const stereo_pf::StereoGeometry& g = cache.geometry();
    map = cv::Mat(g.height(), g.width(), CV_8UC1, cv::Scalar(0));
    for (const Eigen::Vector3d& p : { object, look_alike })
    {
      const stereo_pf::Pixel c = g.project(p, view);
      cv::circle(map, cv::Point(cvRound(c.u), cvRound(c.v)), cvRound(g.apparentRadius(radius, p.z())), cv::Scalar(255),
                 cv::FILLED);
    }
    return true;
  }
};
}  // namespace

TEST(Tracking, ARecoveryJumpToALookAlikeScoringBelowTheObjectIsRefused)
{
  // The object scores 0.95 and a look-alike 0.7 (above found_similarity); for five frames the object sinks to 0.5
  // (unsure: the track goes on). The recovery search (on every frame here) proposes the look-alike, which then
  // explains the images e^10 better, but like a re-acquisition a jump counts only where the evidence is within
  // reacquire_margin of what the object scores: the track stays on the object. (Before, it went to the
  // look-alike.)
  using namespace stereo_pf;
  TwoBalls balls(25);
  ASSERT_TRUE(0.7 >= balls.config.found_similarity && 0.7 < 0.95 - balls.config.reacquire_margin);
  auto cue = plugin<SinkingObject>("scripted");
  cue->sunk_from = 10;
  cue->sunk_to = 15;
  cue->object = balls.target;
  cue->look_alike = balls.look_alike;
  cue->radius = 0.03;
  FilterEngine engine(plugin<Position3D>("state_model"), { cue }, balls.config);
  std::vector<std::pair<double, double>> distances;
  balls.track(engine, distances, [&cue](int k) { cue->frame = k; });
  ASSERT_EQ(static_cast<int>(distances.size()), balls.frames);
  for (int k = 0; k < balls.frames; ++k)
    EXPECT_LT(distances[k].first, distances[k].second) << "frame " << k << ": the estimate went to the look-alike";
}

// The local search's depth filter (engine/local_depth_acceleration): a far object's per-frame disparity error is
// averaged over frames, an approaching one is followed without lag, a jump starts it again at the match.
TEST(MatchDepthFilter, AFarObjectsDisparityErrorIsAveragedOverFrames)
{
  // A ball 12.6 m away (fx b = 139 px m: 11 px of disparity) moving slowly along the depth, its match 0.35 px off
  // per frame at random (what the far drawn ball's matches show); 25 fps.
  const double fb = 139.0, fps = 25.0;
  stereo_pf::MatchDepthFilter filter(60.0, 0.5, 20.0);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.35);
  double raw = 0.0, filtered = 0.0;
  int n = 0;
  for (int k = 0; k < 200; ++k)
  {
    const double t = k / fps, z = 12.6 + 0.2 * t;
    const double d = fb / z;
    const auto r = filter.update(d + noise(rng), fb, t, 3.5 / fps);
    if (k < 20)
      continue;  // settling
    raw += std::pow(fb / (d + noise(rng)) - z, 2);
    filtered += std::pow(fb / r.disparity - z, 2);
    EXPECT_GT(r.sigma, 0.0);
    EXPECT_LT(r.sigma, 0.5);
    ++n;
  }
  raw = std::sqrt(raw / n);
  filtered = std::sqrt(filtered / n);
  std::cout << "far object's depth error: per match " << raw << " m, filtered " << filtered << " m\n";
  EXPECT_LT(filtered, 0.6 * raw);
}

TEST(MatchDepthFilter, ABallThrownAtTheCameraIsFollowedWithoutLag)
{
  // A ball thrown at 12 m/s from 11 m towards a camera of fx b = 600 px m (a 640-wide rig with 0.6 m baseline) at
  // 60 fps, its matches 0.3 px off: near the camera the matches themselves are good to millimetres, and the
  // filter must not trail them.
  const double fb = 600.0, fps = 60.0;
  stereo_pf::MatchDepthFilter filter(60.0, 0.5, 20.0);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.3);
  double bias = 0.0;
  int n = 0;
  for (int k = 0; k < 50; ++k)
  {
    const double t = k / fps, z = 11.0 - 12.0 * t;
    const auto r = filter.update(fb / z + noise(rng), fb, t, 3.5 / fps);
    const double e = fb / r.disparity - z;
    if (k >= 10)
    {
      bias += e;
      ++n;
    }
    if (z < 5.0)
    {
      EXPECT_LT(std::fabs(e), 0.02 * z) << "frame " << k << " at " << z << " m";
    }
  }
  EXPECT_LT(std::fabs(bias / n), 0.05) << "mean depth error " << bias / n << " m";
}

TEST(MatchDepthFilter, AJumpBeyondThePredictionStartsItAgainAtTheMatch)
{
  const double fb = 139.0, fps = 25.0;
  stereo_pf::MatchDepthFilter filter(60.0, 0.5, 20.0);
  for (int k = 0; k < 20; ++k)
    filter.update(11.0, fb, k / fps, 3.5 / fps);
  // Another object's match at twice the disparity: taken as it is, not blended with the old track.
  auto r = filter.update(22.0, fb, 20 / fps, 3.5 / fps);
  EXPECT_DOUBLE_EQ(r.disparity, 22.0);
  EXPECT_DOUBLE_EQ(r.sigma, 0.5);
  // A gap longer than max_gap, time going back, or an unusable match start it again too.
  filter.update(22.0, fb, 21 / fps, 3.5 / fps);
  r = filter.update(21.0, fb, 30 / fps, 3.5 / fps);
  EXPECT_DOUBLE_EQ(r.disparity, 21.0);
  r = filter.update(20.5, fb, 29 / fps, 3.5 / fps);
  EXPECT_DOUBLE_EQ(r.disparity, 20.5);
  r = filter.update(std::nan(""), fb, 31 / fps, 3.5 / fps);
  EXPECT_FALSE(filter.known());
  r = filter.update(20.0, 0.0, 32 / fps, 3.5 / fps);
  EXPECT_FALSE(filter.known());
  EXPECT_DOUBLE_EQ(r.disparity, 20.0);
  filter.update(20.0, fb, 33 / fps, 3.5 / fps);
  EXPECT_TRUE(filter.known());
  filter.reset();
  EXPECT_FALSE(filter.known());
}
