// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The ColourContour plugin constructed directly on rendered images: its mismatch must be smallest at the true
// outline, to a fraction of a pixel in position and radius, follow the sphere's perspective ellipse, and handle
// bad input, parameters and target files.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include <opencv2/imgproc.hpp>

#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/colour_contour.h"

using namespace stereo_pf;

namespace
{
constexpr int kWidth = 320, kHeight = 240;
constexpr float kU = 150.3f, kV = 118.6f, kRadius = 17.0f;

/// A disc of `radius` at (u, v) (anti-aliased by 4x4 supersampling, so its centre is sub-pixel), shaded like
/// a lit ball (darker towards the lower right), on a wall with a gentle pattern; noise of 2 grey levels.
cv::Mat renderDisc(float u, float v, float radius, const cv::Vec3d& ball_bgr, const cv::Vec3d& wall_bgr, unsigned seed)
{
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat img(kHeight, kWidth, CV_8UC3);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
    {
      double inside = 0.0, shade = 0.0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx)
        {
          const double dx = x + (sx + 0.5) / 4.0 - 0.5 - u, dy = y + (sy + 0.5) / 4.0 - 0.5 - v;
          if (dx * dx + dy * dy <= radius * radius)
          {
            inside += 1.0 / 16.0;
            shade += (0.8 - 0.2 * (dx + dy) / radius) / 16.0;
          }
        }
      const double pattern = 1.0 + 0.03 * std::sin(0.21 * x) * std::cos(0.17 * y);
      cv::Vec3b& p = img.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c)
        p[c] = cv::saturate_cast<uint8_t>(shade * ball_bgr[c] + (1.0 - inside) * wall_bgr[c] * pattern + noise(rng));
    }
  return img;
}

const cv::Vec3d kOrange(20, 120, 255), kWall(212, 220, 222);

StereoFrame frameOf(const cv::Mat& left, const cv::Mat& right)
{
  StereoFrame f;
  f.left = left;
  f.right = right;
  f.geometry = StereoGeometry(525.0, 525.0, (kWidth - 1) / 2.0, (kHeight - 1) / 2.0, 0.09, kWidth, kHeight);
  return f;
}

Parameters with(const std::string& key, const std::string& value)
{
  Parameters p;
  p.set(key, value);
  return p;
}

std::unique_ptr<ColourContour> makeModel(const Parameters& params = Parameters())
{
  auto m = std::make_unique<ColourContour>();
  m->initialize("colour_contour", params);
  return m;
}

cv::Rect boxOf(float u, float v, float r)
{
  return cv::Rect(static_cast<int>(std::floor(u - r)), static_cast<int>(std::floor(v - r)),
                  static_cast<int>(std::ceil(2 * r)) + 1, static_cast<int>(std::ceil(2 * r)) + 1);
}

// The offset in [-range, range] (steps of `step`) at which f(offset) is smallest.
template <class F>
double argmin(F f, double range, double step)
{
  double best = std::numeric_limits<double>::infinity(), at = 0.0;
  for (double d = -range; d <= range + 1e-9; d += step)
  {
    const double value = f(d);
    if (value < best)
    {
      best = value;
      at = d;
    }
  }
  return at;
}

class OrangeBall : public ::testing::Test
{
protected:
  void SetUp() override
  {
    image_ = renderDisc(kU, kV, kRadius, kOrange, kWall, 1);
    cache_.reset(frameOf(image_, image_));
    model_ = makeModel(with("perspective", "false"));  // a flat disc: the circle is its true outline
    std::string error;
    ASSERT_TRUE(model_->learnTarget(cache_, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  }
  /// Hypotheses at (u[i], kV) with the disc's radius, all valid.
  static ImageHypotheses onTheRow(const std::vector<float>& u)
  {
    ImageHypotheses h;
    h.view = View::Left;
    h.resize(static_cast<int>(u.size()));
    for (size_t i = 0; i < u.size(); ++i)
    {
      h.u[i] = u[i];
      h.v[i] = kV;
      h.radius[i] = kRadius;
      h.valid[i] = 1;
    }
    return h;
  }
  double at(float du, float dv, float dr = 0.0f)
  {
    return model_->mismatch(cache_, View::Left, kU + du, kV + dv, kRadius + dr);
  }
  cv::Mat image_;
  FeatureCache cache_;
  std::unique_ptr<ColourContour> model_;
};
}  // namespace

TEST_F(OrangeBall, SmallestAtTheTrueOutlineToAFractionOfAPixel)
{
  EXPECT_LT(at(0, 0), 0.05);
  EXPECT_NEAR(argmin([&](double d) { return at(static_cast<float>(d), 0); }, 3.0, 0.05), 0.0, 0.15);
  EXPECT_NEAR(argmin([&](double d) { return at(0, static_cast<float>(d)); }, 3.0, 0.05), 0.0, 0.15);
  EXPECT_NEAR(argmin([&](double d) { return at(0, 0, static_cast<float>(d)); }, 3.0, 0.05), 0.0, 0.3);
  // Also off by a few pixels in the other direction (where a colour histogram would not notice); the shading
  // then pulls it by a fraction of a pixel.
  EXPECT_NEAR(argmin([&](double d) { return at(static_cast<float>(d), 2.5f); }, 3.0, 0.05), 0.0, 0.6);
}

TEST_F(OrangeBall, VariesContinuouslyBelowOnePixel)
{
  // No rounding to whole pixels: shifts of 0.3 px apart are told apart, and grow monotonically.
  double previous = at(0, 0);
  for (const float d : { 0.3f, 0.6f, 0.9f, 1.5f, 3.0f })
  {
    const double m = at(d, 0);
    EXPECT_GT(m, previous) << d;
    previous = m;
  }
}

TEST_F(OrangeBall, LikelihoodSimilarityAndBadHypotheses)
{
  ImageHypotheses h =
      onTheRow({ kU, kU + 2.0f, 40.0f, kU, kU, std::numeric_limits<float>::quiet_NaN(), -30.0f, kU });
  h.valid[3] = 0;         // unobservable
  h.radius[4] = -1.0f;    // 2D: the learned radius (half the box's smaller side)
  h.radius[7] = 200.0f;   // a circle mostly outside the image
  Eigen::VectorXd ll(8), sim(8);
  model_->evaluate(cache_, h, ll, sim);
  const double sigma = 0.05;
  EXPECT_NEAR(ll[0], -at(0, 0) / (2 * sigma * sigma), 1e-4);
  EXPECT_GT(sim[0], 0.8);
  EXPECT_GT(ll[0], ll[1]);
  EXPECT_GT(sim[4], 0.5);   // the learned radius is within a pixel of the disc's
  EXPECT_LT(sim[2], 0.05);  // on the wall
  const double background = ll[2];
  for (const int i : { 3, 5, 6, 7 })  // invalid, NaN, half outside the image: like background, no evidence
  {
    EXPECT_NEAR(ll[i], background, 0.05 * std::abs(background)) << i;
    EXPECT_EQ(sim[i], 0.0) << i;
  }
  Eigen::VectorXd short_ll(3), short_sim(3);
  EXPECT_THROW(model_->evaluate(cache_, h, short_ll, short_sim), std::invalid_argument);
}

TEST_F(OrangeBall, ThePreviewScoresOnHalfTheLinesOnTheSameScale)
{
  // The engine screens particles by the preview (8 of the 16 lines by default): about evaluate()'s log-likelihood at
  // the outline and on the wall, and as sharp (a hypothesis off by 2 px scores lower); none with preview_lines 0.
  const ImageHypotheses h = onTheRow({ kU, kU + 2.0f, 40.0f });
  Parameters eight = with("perspective", "false");
  eight.set("preview_lines", 8);
  auto model = makeModel(eight);
  std::string error;
  ASSERT_TRUE(model->learnTarget(cache_, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  Eigen::VectorXd ll(3), sim(3), coarse(3);
  model->evaluate(cache_, h, ll, sim);
  ASSERT_TRUE(model->preview(cache_, h, coarse));
  EXPECT_GT(coarse[0], coarse[1]);
  EXPECT_GT(coarse[1], coarse[2]);
  for (const int i : { 0, 2 })
    EXPECT_NEAR(coarse[i], ll[i], 0.2 * std::abs(ll[2])) << i;
  auto off = makeModel(with("preview_lines", "0"));
  ASSERT_TRUE(off->learnTarget(cache_, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  EXPECT_FALSE(off->preview(cache_, h, coarse));
  EXPECT_THROW(makeModel(with("preview_lines", "2")), ParameterError);
}

TEST_F(OrangeBall, ForegroundMapAndBackgroundHistogram)
{
  ASSERT_TRUE(model_->background().valid());
  const cv::Mat& p = model_->foregroundMap(cache_, View::Left, 0, kHeight);
  EXPECT_GT(p.at<uint8_t>(cvRound(kV - 5), cvRound(kU - 5)), 200);  // lit part of the ball
  EXPECT_LT(p.at<uint8_t>(10, 10), 50);                              // wall
  // Computed once per view per frame: asking again, for fewer rows, computes nothing.
  const long before = cache_.computeCount();
  model_->foregroundMap(cache_, View::Left, 50, 60);
  EXPECT_EQ(cache_.computeCount(), before);
}

TEST(ColourContour, AFaceOfTheTargetColourInShadeCountsAsTargetWithIntensityTolerance)
{
  // A lit disc of the target's colour (intensity 0.62) to learn from; in a later frame, beside it, the same colour
  // in shade (every channel times 0.6: the same hue and saturation, one intensity slice lower), as a box face
  // turned from the light shows it.
  cv::Mat learning(kHeight, kWidth, CV_8UC3, cv::Scalar(212, 220, 222));
  cv::circle(learning, cv::Point(80, 120), 20, cv::Scalar(60, 160, 255), cv::FILLED);
  cv::Mat img = learning.clone();
  cv::circle(img, cv::Point(230, 120), 20, cv::Scalar(36, 96, 153), cv::FILLED);
  FeatureCache cache;
  cache.reset(frameOf(learning, learning));
  Parameters root;
  auto m = std::make_unique<ColourContour>();
  m->initialize("colour_contour", root.sub("colour_contour"));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, boxOf(80, 120, 20), error)) << error;
  cache.reset(frameOf(img, img));
  EXPECT_GE(m->foregroundMap(cache, View::Left, 0, kHeight).at<uint8_t>(120, 80), 250);
  EXPECT_EQ(m->foregroundMap(cache, View::Left, 0, kHeight).at<uint8_t>(120, 230), 128) << "seen in neither";

  root.set("colour_contour/intensity_tolerance", 0.5);
  m->reconfigure();
  cache.reset(frameOf(img, img));  // a new frame: the map is built with the new table
  const cv::Mat& p = m->foregroundMap(cache, View::Left, 0, kHeight);
  EXPECT_GE(p.at<uint8_t>(120, 80), 250);
  EXPECT_GE(p.at<uint8_t>(120, 230), 250) << "the shaded face is the target's colour";
  EXPECT_LT(p.at<uint8_t>(10, 10), 5) << "the wall is still background";
}

TEST(ColourContour, WhiteBallOnGreyWorksWithoutHue)
{
  const cv::Mat img = renderDisc(kU, kV, kRadius, cv::Vec3d(250, 250, 250), cv::Vec3d(128, 128, 128), 2);
  FeatureCache cache;
  cache.reset(frameOf(img, img));
  auto m = makeModel(with("perspective", "false"));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  // The shaded side of the white ball (down to 150 grey levels) is near the wall's 128: a slight pull.
  EXPECT_NEAR(argmin([&](double d) { return m->mismatch(cache, View::Left, kU + static_cast<float>(d), kV, kRadius); },
                     3.0, 0.05),
              0.0, 0.4);
}

// A real sphere off the optical axis (the shipped pendulum at its extreme, ~20 deg off), its hypotheses at the
// middles of its images as the 3D state models give them: with the perspective ellipse the depth whose outlines
// fit both images best is the true one; a circle would pull it closer.
TEST(ColourContour, PerspectiveOutlineGivesTheTrueDepth)
{
  SceneRenderer renderer(loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml"));
  cv::Mat left, right;
  const StereoFrame f = renderer.renderFrame(0, left, right);
  FeatureCache cache;
  cache.reset(f);
  const Eigen::Vector3d truth = renderer.targetPosition(0);
  double best_dz[2];
  for (const bool perspective : { true, false })
  {
    auto m = makeModel(with("perspective", perspective ? "true" : "false"));
    std::string error;
    ASSERT_TRUE(m->learnTarget(cache, View::Left, renderer.targetRoi(0), error)) << error;
    best_dz[perspective ? 0 : 1] = argmin(
        [&](double dz) {
          const Eigen::Vector3d p = truth * ((truth.z() + dz) / truth.z());  // along the left ray
          const float r = static_cast<float>(f.geometry.apparentRadius(0.035, p.z()));
          const Pixel l = f.geometry.projectSphere(p, 0.035, View::Left);
          const Pixel rr = f.geometry.projectSphere(p, 0.035, View::Right);
          return m->mismatch(cache, View::Left, static_cast<float>(l.u), static_cast<float>(l.v), r) +
                 m->mismatch(cache, View::Right, static_cast<float>(rr.u), static_cast<float>(rr.v), r);
        },
        0.08, 0.0025);
  }
  EXPECT_LT(std::abs(best_dz[0]), 0.01) << "perspective";
  EXPECT_LT(best_dz[1], best_dz[0] - 0.005) << "circle";  // the circle pulls the ball closer
}

TEST(ColourContour, ParametersAreCheckedAndReconfigureKeepsOldValuesOnError)
{
  EXPECT_THROW(makeModel(with("lines", "2")), ParameterError);
  EXPECT_THROW(makeModel(with("sigma", "0")), ParameterError);
  EXPECT_THROW(makeModel(with("softness", "nan")), ParameterError);
  EXPECT_THROW(makeModel(with("line_half_length", "11")), ParameterError);
  Parameters small_radius;
  small_radius.set("radius", 1.0);
  small_radius.set("min_radius", 3.0);
  try
  {
    makeModel(small_radius);
    FAIL() << "radius below min_radius accepted";
  }
  catch (const ParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("'radius' = 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'min_radius' = 3"), std::string::npos) << e.what();
  }
  Parameters bins;
  bins.set("hue_bins", 64);
  bins.set("saturation_bins", 64);
  EXPECT_THROW(makeModel(bins), ParameterError);

  Parameters p;
  p.set("refine", false);
  auto m = makeModel(p);
  EXPECT_FALSE(m->refine());
  EXPECT_TRUE(makeModel()->refine());
  const cv::Mat img = renderDisc(kU, kV, kRadius, kOrange, kWall, 3);
  FeatureCache cache;
  cache.reset(frameOf(img, img));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  const double before = m->mismatch(cache, View::Left, kU + 1.0f, kV, kRadius);
  p.set("lines", 1);
  EXPECT_THROW(m->reconfigure(), ParameterError);
  EXPECT_DOUBLE_EQ(m->mismatch(cache, View::Left, kU + 1.0f, kV, kRadius), before);
  p.set("lines", 32);
  m->reconfigure();
  EXPECT_NE(m->mismatch(cache, View::Left, kU + 1.0f, kV, kRadius), before);
}

TEST(ColourContour, LearnTargetRejectsBadRegions)
{
  const cv::Mat img = renderDisc(kU, kV, kRadius, kOrange, kWall, 4);
  FeatureCache cache;
  cache.reset(frameOf(img, img));
  auto m = makeModel();
  std::string error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(0, 0, 0, 10), error));
  EXPECT_NE(error.find("colour_contour"), std::string::npos) << error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(1000, 10, 20, 20), error));
  EXPECT_FALSE(m->hasTarget());
  // Without a target every hypothesis is unobservable, and the map is neutral.
  EXPECT_TRUE(std::isnan(m->mismatch(cache, View::Left, kU, kV, kRadius)));
  EXPECT_EQ(m->foregroundMap(cache, View::Left, 0, kHeight).at<uint8_t>(100, 100), 128);
}

TEST(ColourContour, SaveLoadRoundTripAndBadFiles)
{
  const cv::Mat img = renderDisc(kU, kV, kRadius, kOrange, kWall, 5);
  FeatureCache cache;
  cache.reset(frameOf(img, img));
  auto m = makeModel();
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, boxOf(kU, kV, kRadius), error)) << error;
  cv::FileStorage out(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  m->saveTarget(out);
  const std::string text = out.releaseAndGetString();

  auto loaded = makeModel();
  cv::FileStorage in(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  ASSERT_TRUE(loaded->loadTarget(in.root(), error)) << error;
  EXPECT_DOUBLE_EQ(loaded->radius2D(), m->radius2D());
  for (const float du : { 0.0f, 0.7f, 2.0f })
    EXPECT_NEAR(loaded->mismatch(cache, View::Left, kU + du, kV, kRadius),
                m->mismatch(cache, View::Left, kU + du, kV, kRadius), 1e-6)
        << du;

  // Another binning, a missing background, or nothing under this name: refused with a reason.
  auto other = makeModel(with("hue_bins", "6"));
  EXPECT_FALSE(other->loadTarget(in.root(), error));
  EXPECT_NE(error.find("binning"), std::string::npos) << error;
  std::string no_background = text;
  const auto at = no_background.find("background");
  ASSERT_NE(at, std::string::npos);
  no_background.replace(at, 10, "backdrop__");
  cv::FileStorage in2(no_background, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  EXPECT_FALSE(makeModel()->loadTarget(in2.root(), error));
  EXPECT_NE(error.find("background"), std::string::npos) << error;
  auto renamed = std::make_unique<ColourContour>();
  renamed->initialize("outline", Parameters());
  EXPECT_FALSE(renamed->loadTarget(in.root(), error));
  EXPECT_NE(error.find("outline"), std::string::npos) << error;
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
