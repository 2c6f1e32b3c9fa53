// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The StereoMatch plugin constructed directly on rendered stereo pairs: it must peak at the true
// disparity with sub-pixel precision, and handle bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <memory>
#include <random>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/stereo_match.h"

using namespace stereo_pf;

namespace
{
constexpr int kWidth = 320, kHeight = 240;
constexpr float kRadius = 17.0f;
constexpr float kLeftU = 170.3f, kV = 121.6f;
constexpr float kDisparity = 43.37f;

/// A shaded ball (brightness falling off towards the lower right, like a lit sphere) on a lightly textured
/// wall, anti-aliased by 4x4 supersampling: the ball's centre is at (u, v) with sub-pixel precision.
/// Gaussian noise of 2 grey levels per channel.
cv::Mat renderView(float u, float v, unsigned seed, float radius = kRadius)
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
            shade += (0.75 - 0.25 * (dx + dy) / radius) / 16.0;
          }
        }
      // The wall: a gentle pattern fixed to the image (it is far away: no disparity to speak of).
      const double wall = 215.0 + 6.0 * std::sin(0.21 * x) * std::cos(0.17 * y);
      const double ball[3] = { 20.0, 120.0, 255.0 };  // BGR orange, scaled by the shade
      cv::Vec3b& p = img.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c)
        p[c] = cv::saturate_cast<uint8_t>(inside > 0.0 ? shade * ball[c] + (1.0 - inside) * wall + noise(rng) :
                                                         wall + noise(rng));
    }
  return img;
}

StereoFrame makeFrame(const cv::Mat& left, const cv::Mat& right)
{
  StereoFrame f;
  f.left = left;
  f.right = right;
  f.geometry = StereoGeometry(525.0, 525.0, kWidth / 2.0, kHeight / 2.0, 0.09, kWidth, kHeight);
  return f;
}

Parameters with(const std::string& key, const std::string& value)
{
  Parameters p;
  p.set(key, value);
  return p;
}

std::unique_ptr<StereoMatch> makeModel(const Parameters& params = Parameters())
{
  auto m = std::make_unique<StereoMatch>();
  m->initialize("stereo", params);
  return m;
}

class RenderedPair : public ::testing::Test
{
protected:
  void SetUp() override
  {
    left_ = renderView(kLeftU, kV, 1);
    right_ = renderView(kLeftU - kDisparity, kV, 2);
    cache_.reset(makeFrame(left_, right_));
  }
  cv::Mat left_, right_;
  FeatureCache cache_;
};

ImageHypotheses pairs(View view, const std::vector<float>& u, float v, float radius)
{
  ImageHypotheses h;
  h.view = view;
  h.resize(static_cast<int>(u.size()));
  for (size_t i = 0; i < u.size(); ++i)
  {
    h.u[i] = u[i];
    h.v[i] = v;
    h.radius[i] = radius;
    h.valid[i] = 1;
  }
  return h;
}
}  // namespace

TEST_F(RenderedPair, PeaksAtTheTrueDisparityWithSubPixelPrecision)
{
  auto m = makeModel();
  const double at_truth = m->zncc(cache_, kLeftU, kLeftU - kDisparity, kV, kRadius);
  EXPECT_GT(at_truth, 0.9);
  for (const float off : { -1.0f, 1.0f })
    EXPECT_LT(m->zncc(cache_, kLeftU, kLeftU - kDisparity - off, kV, kRadius), at_truth - 0.02) << off;
  for (const float off : { -0.5f, 0.5f })
    EXPECT_LT(m->zncc(cache_, kLeftU, kLeftU - kDisparity - off, kV, kRadius), at_truth) << off;
  // Scan the disparity in 0.05 px steps: the best one is within a fraction of a pixel of the truth, also when
  // the hypothesised centre is a few pixels off in both images (the colour cue's plateau) or the radius is 5%
  // off. One hypothesis with the default sampling (two rows, about 48 samples) sees the noise of a few edge samples
  // (the filter averages many); dense sampling shows the peak itself.
  Parameters dense;
  dense.set("rows", 7);
  dense.set("column_step", 1);
  auto m_dense = makeModel(dense);
  for (StereoMatch* model : { m.get(), m_dense.get() })
  {
    const double tolerance = model == m.get() ? 0.35 : 0.15;
    for (const float shift : { 0.0f, 3.0f, -2.5f })
      for (const float scale : { 1.0f, 1.05f })
      {
        double best = -2.0, best_d = 0.0;
        for (double d = kDisparity - 3.0; d <= kDisparity + 3.0; d += 0.05)
        {
          const double z = model->zncc(cache_, kLeftU + shift, static_cast<float>(kLeftU + shift - d), kV + shift / 2,
                                       kRadius * scale);
          if (z > best)
          {
            best = z;
            best_d = d;
          }
        }
        EXPECT_NEAR(best_d, kDisparity, tolerance)
            << "shift " << shift << " scale " << scale << (model == m.get() ? " default" : " dense");
      }
  }
}

/// The disparity at which one hypothesis's ZNCC peaks, scanned in 0.02 px steps within 2 px of the truth.
double peakDisparity(StereoMatch& model, FeatureCache& cache, float radius)
{
  double best = -2.0, best_d = 0.0;
  for (double d = kDisparity - 2.0; d <= kDisparity + 2.0; d += 0.02)
  {
    const double z = model.zncc(cache, kLeftU, static_cast<float>(kLeftU - d), kV, radius);
    if (z > best)
    {
      best = z;
      best_d = d;
    }
  }
  return best_d;
}

TEST(StereoMatch, ASmallBallSampledBySizeHasItsDisparityMeasuredMorePrecisely)
{
  // A 4 px ball (a far one: at 10 disparity pixels, 0.25 px is 2.5 % of its depth). A fixed sampling of two rows
  // with a sample every third pixel sees 6 samples of it per view; column_step 0 (the default) aims at `samples`
  // per view, one pixel apart at this size (22 samples). Over 24 noise draws its peak lies closer to the truth.
  constexpr float kSmall = 4.0f;
  Parameters sparse, dense;
  sparse.set("rows", 2);
  sparse.set("column_step", 3);
  dense.set("column_step", 0);
  auto dense_model = makeModel(dense);
  auto sparse_model = makeModel(sparse);
  double dense_sq = 0.0, sparse_sq = 0.0;
  constexpr int kDraws = 24;
  for (int k = 0; k < kDraws; ++k)
  {
    FeatureCache cache;
    cache.reset(makeFrame(renderView(kLeftU, kV, 100 + 2 * k, kSmall),
                          renderView(kLeftU - kDisparity, kV, 101 + 2 * k, kSmall)));
    dense_sq += std::pow(peakDisparity(*dense_model, cache, kSmall) - kDisparity, 2);
    sparse_sq += std::pow(peakDisparity(*sparse_model, cache, kSmall) - kDisparity, 2);
  }
  const double dense_rms = std::sqrt(dense_sq / kDraws), sparse_rms = std::sqrt(sparse_sq / kDraws);
  std::cout << "small ball: peak disparity RMS " << dense_rms << " px (column_step 0), " << sparse_rms
            << " px (2 rows, every 3rd px)" << std::endl;
  EXPECT_LT(dense_rms, 0.7 * sparse_rms);
  EXPECT_LT(dense_rms, 0.15);
}

TEST_F(RenderedPair, LikelihoodVariesContinuouslyBelowOnePixel)
{
  auto m = makeModel();
  // Sub-pixel: hypotheses a fraction of a pixel apart are told apart (no rounding to whole pixels).
  const double a = m->zncc(cache_, kLeftU, kLeftU - kDisparity, kV, kRadius);
  const double b = m->zncc(cache_, kLeftU, kLeftU - kDisparity - 0.3f, kV, kRadius);
  const double c = m->zncc(cache_, kLeftU, kLeftU - kDisparity - 0.6f, kV, kRadius);
  EXPECT_GT(a, b);
  EXPECT_GT(b, c);
}

TEST_F(RenderedPair, EvaluatePairMatchesZnccAndHandlesBadHypotheses)
{
  // surface_depth 0: each pair is compared where its centres project (the default's shift is checked below).
  Parameters flat = with("sigma", "0.2");
  flat.set("surface_depth", 0.0);
  auto m = makeModel(flat);
  const std::vector<float> ul = { kLeftU, kLeftU, kLeftU, kLeftU, kLeftU, -500.0f, kLeftU };
  const std::vector<float> ur = { kLeftU - kDisparity, kLeftU - kDisparity + 1.0f, kLeftU - kDisparity,
                                  kLeftU - kDisparity, std::numeric_limits<float>::quiet_NaN(), -540.0f,
                                  kLeftU - kDisparity };
  ImageHypotheses l = pairs(View::Left, ul, kV, kRadius);
  ImageHypotheses r = pairs(View::Right, ur, kV, kRadius);
  l.valid[2] = 0;       // unobservable in the left image
  r.radius[3] = 0.0f;   // the right radius is not used: the pair shares the left one
  l.radius[6] = 0.0f;   // a 2D hypothesis: no radius, no disc
  Eigen::VectorXd ll(7), sim(7);
  m->evaluatePair(cache_, l, r, ll, sim);
  const double floor_ll = -1.0 / (2.0 * 0.2 * 0.2);
  const double z0 = m->zncc(cache_, ul[0], ur[0], kV, kRadius);
  EXPECT_NEAR(ll[0], -(1.0 - z0) / (2.0 * 0.2 * 0.2), 1e-9);  // the region-only grey gives the same values
  EXPECT_NEAR(sim[0], z0, 1e-9);
  EXPECT_GT(ll[0], ll[1]);
  EXPECT_DOUBLE_EQ(ll[3], ll[0]);
  for (const int i : { 2, 4, 5, 6 })
  {
    EXPECT_DOUBLE_EQ(ll[i], floor_ll) << i;
    EXPECT_DOUBLE_EQ(sim[i], 0.0) << i;
  }
  // By default the right window is centred on the near side's image: 0.15 radii in front of the centre, so the
  // disparity compared is d / (1 - 0.15 R / fx).
  auto near_side = makeModel(with("sigma", "0.2"));
  near_side->evaluatePair(cache_, l, r, ll, sim);
  const float shifted = kLeftU - kDisparity / static_cast<float>(1.0 - 0.15 * kRadius / 525.0);
  EXPECT_GT(kLeftU - kDisparity - shifted, 0.2f);
  EXPECT_NEAR(ll[0], -(1.0 - m->zncc(cache_, kLeftU, shifted, kV, kRadius)) / (2.0 * 0.2 * 0.2), 1e-6);
  EXPECT_DOUBLE_EQ(ll[4], floor_ll);
  // Wrong sizes or views are refused.
  Eigen::VectorXd short_ll(3), short_sim(3);
  EXPECT_THROW(m->evaluatePair(cache_, l, r, short_ll, short_sim), std::invalid_argument);
  EXPECT_THROW(m->evaluatePair(cache_, r, l, ll, sim), std::invalid_argument);
  // One view alone cannot be matched: a constant.
  m->evaluate(cache_, l, ll, sim);
  EXPECT_TRUE((ll.array() == floor_ll).all());
  EXPECT_TRUE((sim.array() == 0.0).all());
}

TEST(StereoMatch, FeaturelessPatchesDoNotCorrelate)
{
  // Plain walls with sensor noise only: the contrast floor keeps the noise from looking like a match.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat left(kHeight, kWidth, CV_8UC1), right(kHeight, kWidth, CV_8UC1);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
    {
      left.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(200.0 + noise(rng));
      right.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(200.0 + noise(rng));
    }
  FeatureCache cache;
  cache.reset(makeFrame(left, right));
  auto m = makeModel();
  for (float d = 20.0f; d < 60.0f; d += 3.7f)
    EXPECT_LT(std::abs(m->zncc(cache, 150.0f, 150.0f - d, 120.0f, kRadius)), 0.3) << d;
}

/// A plain grey ball (grey level `ball`) on a plain wall (`wall`), anti-aliased by 4x4 supersampling, with
/// Gaussian noise of 2 grey levels: all it shows is its outline against the wall.
cv::Mat renderPlain(float u, float v, double ball, double wall, unsigned seed)
{
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat img(kHeight, kWidth, CV_8UC1);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
    {
      double inside = 0.0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx)
        {
          const double dx = x + (sx + 0.5) / 4.0 - 0.5 - u, dy = y + (sy + 0.5) / 4.0 - 0.5 - v;
          inside += dx * dx + dy * dy <= kRadius * kRadius ? 1.0 / 16.0 : 0.0;
        }
      img.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(inside * ball + (1.0 - inside) * wall + noise(rng));
    }
  return img;
}

TEST(StereoMatch, AnOutlineTheBackgroundsInvertStillMatchesOnItsEdges)
{
  // A grey ball before a dark curtain in the left view and before a bright panel in the right one (catch_test1's
  // last frames, where the ball is near enough for the two views to see different things behind it): brighter
  // than its surround in one view, darker in the other, so the grey levels of its outline correlate negatively
  // at the true disparity. Their gradient magnitudes do not care which side is brighter.
  FeatureCache cache;
  cache.reset(makeFrame(renderPlain(kLeftU, kV, 120.0, 40.0, 11),
                        renderPlain(kLeftU - kDisparity, kV, 120.0, 220.0, 12)));
  auto grey_only = makeModel(with("edges", "false"));
  const double grey = grey_only->zncc(cache, kLeftU, kLeftU - kDisparity, kV, kRadius);
  EXPECT_LT(grey, 0.0) << "the inverted outline should anti-correlate in grey levels";
  auto m = makeModel();
  const double at_truth = m->zncc(cache, kLeftU, kLeftU - kDisparity, kV, kRadius);
  EXPECT_GT(at_truth, 0.6);
  for (float off : { -6.0f, -3.0f, -1.5f, 1.5f, 3.0f, 6.0f })
    EXPECT_LT(m->zncc(cache, kLeftU, kLeftU - kDisparity - off, kV, kRadius), at_truth) << off;
  // Where the views agree the grey correlation is kept: the edges only add a way to match.
  cache.reset(makeFrame(renderView(kLeftU, kV, 1), renderView(kLeftU - kDisparity, kV, 2)));
  EXPECT_GE(m->zncc(cache, kLeftU, kLeftU - kDisparity, kV, kRadius),
            grey_only->zncc(cache, kLeftU, kLeftU - kDisparity, kV, kRadius));
}

// A textured ball near the cameras: what the two views match is its surface, whose near side lies up to a radius
// in front of the centre (the texture is fixed to the surface, so its disparity is the surface's). Scanned along
// the line of sight through the true centre, the flat comparison peaks at the near side (7.5-9.6 % of the depth
// short, the near pole being 10.9 % short); centred on the near side's image (surface_depth 0.15) the peak moves
// back towards the centre, by 0.9 % here. The default stays well short of the 2/3 of a radius a textured ball's
// visible surface lies in front of its centre on average: the outline, which plain objects match by, lies at the
// centre's depth.
TEST(StereoMatch, ATexturedBallNearTheCamerasIsComparedOnItsNearSide)
{
  SceneDescription scene;
  scene.frames = 1;
  scene.background.type = SceneBackground::Type::Cluttered;
  scene.background.depth = 2.0;
  SceneSphere ball;
  ball.radius = 0.06;
  ball.textured = true;
  ball.colour = cv::Vec3d(60, 140, 200);
  ball.colour2 = cv::Vec3d(230, 230, 230);
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.03, -0.02, 0.55));
  auto state = std::make_shared<Position3D>();
  state->initialize("state_model", Parameters());
  auto flat = makeModel(with("surface_depth", "0"));
  auto near_side = makeModel();
  for (const uint64_t seed : { 1u, 2u, 3u })
  {
    ball.texture_seed = seed;
    scene.objects = { ball };
    scene.seed = seed;
    SceneRenderer renderer(scene);
    cv::Mat left, right;
    const StereoFrame frame = renderer.renderFrame(0, left, right);
    FeatureCache cache;
    cache.reset(frame);
    const Eigen::Vector3d truth = renderer.targetPosition(0);
    // Depths 0.9..1.1 times the truth's, 0.1 % apart, on the ray through the true centre.
    const int n = 201;
    ParticleSet set;
    set.resize(n, state->dimension(0));
    set.states.setZero();
    for (int i = 0; i < n; ++i)
      set.states.row(i).head<3>() = (truth * (0.9 + 0.001 * i)).transpose();
    ImageHypotheses l, r;
    l.view = View::Left;
    r.view = View::Right;
    state->project(frame.geometry, 0, set, l);
    state->project(frame.geometry, 0, set, r);
    Eigen::VectorXd ll(n), sim(n);
    double peak[2];
    for (int k = 0; k < 2; ++k)
    {
      (k == 0 ? flat : near_side)->evaluatePair(cache, l, r, ll, sim);
      Eigen::Index best;
      ll.maxCoeff(&best);
      peak[k] = 0.001 * static_cast<double>(best) - 0.1;  // relative depth error of the peak
    }
    EXPECT_LT(peak[0], -0.05) << "texture " << seed << ": the flat comparison peaks at the near side";
    EXPECT_GT(peak[1], peak[0] + 0.005) << "texture " << seed << ": surface_depth moves it towards the centre";
    EXPECT_LT(peak[1], 0.0) << "texture " << seed << ": but not beyond";
  }
}

TEST(StereoMatch, ParametersAndTarget)
{
  EXPECT_THROW(makeModel(with("rows", "0")), ParameterError);
  EXPECT_THROW(makeModel(with("sigma", "-1")), ParameterError);
  EXPECT_THROW(makeModel(with("column_step", "-1")), ParameterError);
  EXPECT_THROW(makeModel(with("samples", "3")), ParameterError);
  EXPECT_THROW(makeModel(with("edges", "maybe")), ParameterError);
  EXPECT_THROW(makeModel(with("surface_depth", "1.5")), ParameterError);
  auto m = makeModel();
  EXPECT_TRUE(m->comparesViews());
  EXPECT_TRUE(m->hasTarget());
  cv::Mat img(kHeight, kWidth, CV_8UC3, cv::Scalar(100, 100, 100));
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  EXPECT_TRUE(m->learnTarget(cache, View::Left, cv::Rect(10, 10, 20, 20), error)) << error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(1000, 10, 20, 20), error));
  EXPECT_NE(error.find("stereo"), std::string::npos) << error;
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

// With only_while_tracking (the default) the engine consults the stereo cue only in frames that follow a
// frame in the tracking state; without it (and not refining), in every frame. While tracking the local search
// also asks it, over a few dozen disparities, and the engine, before the cues adapt, at the best particle alone
// (EngineConfig::adapt_min_stereo): both counted apart from the particles' calls.
namespace
{
constexpr int kParticles = 300;

class CountingStereoMatch : public StereoMatch
{
public:
  int calls = 0;         ///< on the particle set
  int search_calls = 0;  ///< on the local search's disparities
  int check_calls = 0;   ///< on one pair: the best particle's, before the cues adapt
  void evaluatePair(FeatureCache& cache, const ImageHypotheses& left, const ImageHypotheses& right,
                    Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    ++(right.size() == kParticles ? calls : right.size() == 1 ? check_calls : search_calls);
    StereoMatch::evaluatePair(cache, left, right, log_likelihood, similarity);
  }
};

// Frames (k) after which the engine was tracking, and the stereo cue's call count after each frame.
void runEngine(bool only_while_tracking, std::vector<bool>& tracking_before, std::vector<int>& calls_after,
               std::vector<int>* search_calls_after = nullptr, std::vector<int>* check_calls_after = nullptr)
{
  SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml");
  scene.frames = 20;
  SceneRenderer renderer(scene);
  auto state = std::make_shared<Position3D>();
  state->initialize("state_model", Parameters());
  auto colour = std::make_shared<ColourHSI>();
  colour->initialize("colour", Parameters());
  auto stereo = std::make_shared<CountingStereoMatch>();
  Parameters p;
  p.set("only_while_tracking", only_while_tracking);
  p.set("refine", false);  // an ordinary cue here (a refining cue is consulted only while tracking anyway)
  stereo->initialize("stereo", p);
  EngineConfig config;
  config.acquire = false;  // the search path: the first frame is a search from the prior
  config.particles = kParticles;
  config.seed = 3;
  FilterEngine engine(state, { colour, stereo }, config);
  bool tracking = false;
  cv::Mat left, right;
  for (int k = 0; k < renderer.frames(); ++k)
  {
    const StereoFrame frame = renderer.renderFrame(k, left, right);
    if (k == 0)
    {
      std::string error;
      ASSERT_TRUE(engine.learnTarget(frame, renderer.targetRoi(0), error)) << error;
    }
    tracking_before.push_back(tracking);
    tracking = engine.step(frame).state == TrackState::Tracking;
    calls_after.push_back(stereo->calls);
    if (search_calls_after)
      search_calls_after->push_back(stereo->search_calls);
    if (check_calls_after)
      check_calls_after->push_back(stereo->check_calls);
  }
}
}  // namespace

TEST(StereoMatch, EngineUsesItOnlyWhileTracking)
{
  std::vector<bool> tracking_before;
  std::vector<int> calls, search_calls, check_calls;
  runEngine(true, tracking_before, calls, &search_calls, &check_calls);
  ASSERT_EQ(calls.size(), 20u);
  ASSERT_FALSE(tracking_before[0]);  // the first frame is always a search
  EXPECT_EQ(calls[0], 0);
  int expected = 0, tracked = 0;
  for (size_t k = 0; k < calls.size(); ++k)
  {
    expected += tracking_before[k] ? 1 : 0;  // one call per frame (one 3D set)
    tracked += tracking_before[k] ? 1 : 0;
    EXPECT_EQ(calls[k], expected) << "frame " << k;
    // The local search: at most once a frame, and only while tracking.
    const int searched = search_calls[k] - (k > 0 ? search_calls[k - 1] : 0);
    EXPECT_LE(searched, tracking_before[k] ? 1 : 0) << "frame " << k;
    // The views' agreement at the best particle: at most once a frame (one set), after a frame that tracks.
    EXPECT_LE(check_calls[k] - (k > 0 ? check_calls[k - 1] : 0), 1) << "frame " << k;
  }
  EXPECT_GT(tracked, 10);  // it did track, so the cue was used
  EXPECT_GT(search_calls.back(), 5) << "the local search's disparities were scored by the views' agreement";
  EXPECT_GT(check_calls.back(), 5) << "the views' agreement was not checked before the cues adapted";

  tracking_before.clear();
  calls.clear();
  runEngine(false, tracking_before, calls);
  for (size_t k = 0; k < calls.size(); ++k)
    EXPECT_EQ(calls[k], static_cast<int>(k) + 1) << "frame " << k;
}

// Before the cues adapt to the object's look, the engine asks the cues comparing the views how well the best
// particle's two views agree (EngineConfig::adapt_min_stereo): an occluder coming over the object is at another
// disparity, and a histogram adapting to it follows the occluder. Here the agreement at that one pair is scripted.
namespace
{
class ScriptedAgreement : public StereoMatch
{
public:
  double agreement = 1.0;  ///< the similarity of a single pair (the engine's check before adapting)
  void evaluatePair(FeatureCache& cache, const ImageHypotheses& left, const ImageHypotheses& right,
                    Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    StereoMatch::evaluatePair(cache, left, right, log_likelihood, similarity);
    if (right.size() == 1)
      similarity.setConstant(agreement);
  }
};

class AdaptCounting : public ColourHSI
{
public:
  int adapted = 0;
  void adapt(FeatureCache& cache, const ImageHypotheses& estimate) override
  {
    ++adapted;
    ColourHSI::adapt(cache, estimate);
  }
};

/// adapt() calls on the colour cue over 20 frames of the pendulum, tracked from its box, with the best particle's
/// views agreeing `agreement` and the engine adapting at `adapt_min_stereo`; `tracked`: frames tracked and seen.
int adaptCalls(double agreement, double adapt_min_stereo, int& tracked)
{
  SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml");
  scene.frames = 20;
  SceneRenderer renderer(scene);
  auto state = std::make_shared<Position3D>();
  state->initialize("state_model", Parameters());
  auto colour = std::make_shared<AdaptCounting>();
  colour->initialize("colour", Parameters());
  auto stereo = std::make_shared<ScriptedAgreement>();
  stereo->initialize("stereo", Parameters());
  stereo->agreement = agreement;
  EngineConfig config;
  config.adapt_min_stereo = adapt_min_stereo;
  FilterEngine engine(state, { colour, stereo }, config);
  cv::Mat left, right;
  tracked = 0;
  for (int k = 0; k < renderer.frames(); ++k)
  {
    const StereoFrame frame = renderer.renderFrame(k, left, right);
    if (k == 0)
    {
      std::string error;
      EXPECT_TRUE(engine.learnTarget(frame, renderer.targetRoi(0), error)) << error;
    }
    const FrameResult r = engine.step(frame);
    tracked += r.state == TrackState::Tracking && r.support == Support::Seen ? 1 : 0;
  }
  return colour->adapted;
}
}  // namespace

TEST(StereoMatch, TheCuesAdaptOnlyWhereTheBestParticlesViewsAgree)
{
  const double at = EngineConfig().adapt_min_stereo;
  ASSERT_GT(at, 0.0);
  int tracked = 0;
  // One set seen in two views: two adapt() calls per frame tracked and seen.
  const int agreeing = adaptCalls(std::min(1.0, at + 0.05), at, tracked);
  EXPECT_EQ(agreeing, 2 * tracked);
  EXPECT_GT(tracked, 15);
  const int disagreeing = adaptCalls(at - 0.05, at, tracked);
  EXPECT_EQ(disagreeing, 0) << "adapted where the views disagree";
  EXPECT_GT(tracked, 15);
  const int unchecked = adaptCalls(at - 0.05, 0.0, tracked);
  EXPECT_EQ(unchecked, 2 * tracked) << "adapt_min_stereo 0 must not check";
  EXPECT_GT(tracked, 15);
}
