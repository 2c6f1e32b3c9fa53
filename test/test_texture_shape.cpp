// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The texture (TextureEdge) and shape (ShapeCircle) observation models constructed directly: edge
// histograms of synthetic stripes, checkerboards and flat patches, the texture likelihood around a
// checkered disc, the circle likelihood on rendered discs with and without clutter, robustness at the
// image border, the perspective silhouette of an off-axis ball, parameters, saved targets, cost per frame,
// the cues on frames of the shipped scenes checkered_cluttered and colour_distractor, and the engine
// (Position3D + all three cues) tracking past the colour distractor.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/eval/evaluation.h"
#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/histogram.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/shape_circle.h"
#include "stereo_pf/plugins/texture_edge.h"

using namespace stereo_pf;

namespace
{
// ---------------------------------------------------------------------------------------------------
// Synthetic images and helpers


StereoFrame makeFrame(const cv::Mat& left, const cv::Mat& right)
{
  StereoFrame f;
  f.left = left;
  f.right = right;
  f.geometry = StereoGeometry(500.0, 500.0, left.cols / 2.0, left.rows / 2.0, 0.1, left.cols, left.rows);
  return f;
}

void addNoise(cv::Mat& img, double sigma, unsigned seed)
{
  cv::Mat noise(img.size(), CV_16SC(img.channels()));
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(sigma));
  cv::add(img, noise, img, cv::noArray(), img.depth());
}

// Stripes `period` px apart (half dark, half bright) along x (vertical stripes) or y (horizontal stripes).
cv::Mat stripes(cv::Size size, int period, bool horizontal, int dark = 60, int bright = 190)
{
  cv::Mat img(size, CV_8UC3);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
    {
      const int c = horizontal ? y : x;
      const int level = (c / (period / 2)) % 2 ? bright : dark;
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(level, level, level);
    }
  return img;
}

cv::Mat checkerboard(cv::Size size, int square, int dark = 60, int bright = 190)
{
  cv::Mat img(size, CV_8UC3);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
    {
      const int level = ((x / square) + (y / square)) % 2 ? bright : dark;
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(level, level, level);
    }
  return img;
}

std::unique_ptr<TextureEdge> makeTexture(const Parameters& params = Parameters())
{
  auto m = std::make_unique<TextureEdge>();
  m->initialize("texture", params);
  return m;
}

std::unique_ptr<ShapeCircle> makeShape(const Parameters& params = Parameters())
{
  auto m = std::make_unique<ShapeCircle>();
  m->initialize("shape", params);
  return m;
}

Parameters orientationParams()
{
  Parameters p;
  p.set("mode", std::string("orientation"));
  return p;
}

// Target histogram of the whole `roi` of `img` (target_margin 0: every pixel of the region).
std::vector<double> textureHistogram(const cv::Mat& img, const cv::Rect& roi, Parameters params = Parameters())
{
  params.set("target_margin", 0.0);
  auto m = makeTexture(params);
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  EXPECT_TRUE(m->learnTarget(cache, View::Left, roi, error)) << error;
  return m->target().probabilities();
}

cv::Rect discBox(int cx, int cy, int radius)
{
  return cv::Rect(cx - radius, cy - radius, 2 * radius + 1, 2 * radius + 1);
}

// A disc filled with a checkerboard (squares of `square` px) on a plain grey background.
cv::Mat checkeredDisc(cv::Size size, int cx, int cy, int radius, int square, unsigned seed)
{
  cv::Mat img(size, CV_8UC3, cv::Scalar(128, 128, 128));
  const cv::Mat board = checkerboard(size, square, 40, 220);
  cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
  cv::circle(mask, cv::Point(cx, cy), radius, cv::Scalar(255), cv::FILLED, cv::LINE_8);
  board.copyTo(img, mask);
  addNoise(img, 2.0, seed);
  return img;
}

// A bright filled disc on a dark background (anti-aliased rim), with sensor noise.
cv::Mat disc(cv::Size size, cv::Point centre, int radius, unsigned seed)
{
  cv::Mat img(size, CV_8UC3, cv::Scalar(70, 70, 70));
  cv::circle(img, centre, radius, cv::Scalar(30, 140, 230), cv::FILLED, cv::LINE_AA);
  addNoise(img, 2.0, seed);
  return img;
}

// Random lines and rectangles (outlined and filled) of random grey levels.
void drawClutter(cv::Mat& img, int count, unsigned seed, const cv::Rect& area)
{
  cv::RNG rng(seed);
  for (int i = 0; i < count; ++i)
  {
    const cv::Scalar colour = cv::Scalar::all(rng.uniform(0, 256));
    const cv::Point a(rng.uniform(area.x, area.x + area.width), rng.uniform(area.y, area.y + area.height));
    const cv::Point b(a.x + rng.uniform(-60, 61), a.y + rng.uniform(-60, 61));
    switch (i % 3)
    {
      case 0:
        cv::line(img, a, b, colour, rng.uniform(1, 4), cv::LINE_AA);
        break;
      case 1:
        cv::rectangle(img, a, b, colour, rng.uniform(1, 3), cv::LINE_AA);
        break;
      default:
        cv::rectangle(img, a, b, colour, cv::FILLED, cv::LINE_AA);
        break;
    }
  }
}

struct Scored
{
  float u = 0, v = 0, r = 0;
  double ll = -std::numeric_limits<double>::infinity();
  double sim = 0;
};

// Scan (u, v, r) on a 1 px grid around a guess, all in one batch; returns every scored hypothesis.
std::vector<Scored> scanCircle(ShapeCircle& m, FeatureCache& cache, float cu, float cv, float cr, int range,
                               int radius_range)
{
  ImageHypotheses hyp;
  hyp.view = View::Left;
  for (int dr = -radius_range; dr <= radius_range; ++dr)
    for (int dy = -range; dy <= range; ++dy)
      for (int dx = -range; dx <= range; ++dx)
      {
        hyp.u.push_back(cu + dx);
        hyp.v.push_back(cv + dy);
        hyp.radius.push_back(cr + dr);
        hyp.valid.push_back(1);
      }
  Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
  m.evaluate(cache, hyp, ll, sim);
  std::vector<Scored> out(hyp.size());
  for (int i = 0; i < hyp.size(); ++i)
    out[i] = Scored{ hyp.u[i], hyp.v[i], hyp.radius[i], ll[i], sim[i] };
  return out;
}

Scored best(const std::vector<Scored>& s)
{
  return *std::max_element(s.begin(), s.end(), [](const Scored& a, const Scored& b) { return a.ll < b.ll; });
}

// Log-likelihood margin of the best hypothesis over the best one at least `far` px from the truth in
// centre or radius.
double margin(const std::vector<Scored>& s, float u, float v, float r, float far)
{
  double best_near = -std::numeric_limits<double>::infinity(), best_far = best_near;
  for (const Scored& h : s)
  {
    const bool is_far = std::hypot(h.u - u, h.v - v) >= far || std::abs(h.r - r) >= far;
    (is_far ? best_far : best_near) = std::max(is_far ? best_far : best_near, h.ll);
  }
  return best_near - best_far;
}

// ---------------------------------------------------------------------------------------------------
// Edge binning and texture histograms

TEST(EdgeBinning, BinsAndValidation)
{
  EdgeBinning b;
  EXPECT_EQ(b.bins(), 9);  // no-edge bin + 8 intensity bins
  b.mode = EdgeBinning::Mode::Orientation;
  EXPECT_EQ(b.bins(), 4);  // no-edge bin + horizontal, vertical, diagonal
  EXPECT_NO_THROW(b.validate());
  b.max_magnitude = b.tau;
  EXPECT_THROW(b.validate(), std::invalid_argument);
  b = EdgeBinning();
  b.intensity_bins = 0;
  EXPECT_THROW(b.validate(), std::invalid_argument);
  EXPECT_TRUE(EdgeBinning().sameAs(EdgeBinning()));
  EdgeBinning other;
  other.tau = 30.0;
  EXPECT_FALSE(EdgeBinning().sameAs(other));
  EXPECT_NE(EdgeBinning().describe(), other.describe());
}

TEST(EdgeBinner, PerPixelBins)
{
  EdgeBinning o;
  o.mode = EdgeBinning::Mode::Orientation;
  const EdgeBinner orient(o);
  EXPECT_EQ(orient.bin(0, 0), EdgeBinning::kNoEdge);
  EXPECT_EQ(orient.bin(10, 10), EdgeBinning::kNoEdge);  // |S| = 14 < tau = 24
  EXPECT_EQ(orient.bin(0, 200), EdgeBinning::kHorizontal);  // intensity changes along y
  EXPECT_EQ(orient.bin(-200, 30), EdgeBinning::kVertical);
  EXPECT_EQ(orient.bin(150, -140), EdgeBinning::kDiagonal);
  EXPECT_EQ(orient.bin(0, 24), EdgeBinning::kHorizontal);  // |S| = tau is an edge

  const EdgeBinner intensity{ EdgeBinning() };  // tau 24, 8 bins up to 400: 47 per bin
  EXPECT_EQ(intensity.bin(20, 0), 0);
  EXPECT_EQ(intensity.bin(30, 0), 1);
  EXPECT_EQ(intensity.bin(0, 24 + 47 * 3 + 20), 4);
  EXPECT_EQ(intensity.bin(-1000, 1000), 8);  // saturates in the top bin
}

TEST(EdgeBinner, ImageIsThePerPixelBinOfTheSobelDerivatives)
{
  // Odd sizes exercise the scalar tails and the reflected borders; tiny ones the degenerate borders.
  for (const cv::Size size : { cv::Size(161, 121), cv::Size(17, 2), cv::Size(1, 1), cv::Size(2, 3), cv::Size(33, 1) })
  {
    cv::Mat img = checkerboard(size, 9);
    cv::circle(img, cv::Point(size.width / 2, size.height / 2), 30, cv::Scalar(200, 100, 20), cv::FILLED,
               cv::LINE_AA);
    addNoise(img, 12.0, 3);
    FeatureCache cache;
    cache.reset(makeFrame(img, img));
    const cv::Mat& gray = cache.gray(View::Left);
    cv::Mat sx, sy;  // the reference: OpenCV's Sobel with its default border
    cv::Sobel(gray, sx, CV_16S, 1, 0, 3);
    cv::Sobel(gray, sy, CV_16S, 0, 1, 3);
    for (const auto mode : { EdgeBinning::Mode::Intensity, EdgeBinning::Mode::Orientation })
    {
      EdgeBinning b;
      b.mode = mode;
      const EdgeBinner binner(b);
      cv::Mat bins;
      binner.binImage(gray, bins);
      ASSERT_EQ(bins.type(), CV_8UC1);
      ASSERT_EQ(bins.size(), size);
      int mismatches = 0, edges = 0;
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x)
        {
          const int expected = binner.bin(sx.at<int16_t>(y, x), sy.at<int16_t>(y, x));
          mismatches += bins.at<uint8_t>(y, x) != expected ? 1 : 0;
          edges += expected != 0 ? 1 : 0;
        }
      EXPECT_EQ(mismatches, 0) << EdgeBinning::toString(mode) << " " << size;
      if (size.area() > 1000)
      {
        EXPECT_GT(edges, size.area() / 10) << EdgeBinning::toString(mode);
      }
    }
  }
  cv::Mat out;
  EXPECT_THROW(EdgeBinner().binImage(cv::Mat(4, 4, CV_8UC3), out), std::invalid_argument);
}

TEST(TextureHistogram, StripesCheckerboardAndFlatOrientation)
{
  const cv::Size size(120, 120);
  const cv::Rect roi(20, 20, 80, 80);
  const std::vector<double> h = textureHistogram(stripes(size, 16, true), roi, orientationParams());
  const std::vector<double> v = textureHistogram(stripes(size, 16, false), roi, orientationParams());
  const std::vector<double> c = textureHistogram(checkerboard(size, 8), roi, orientationParams());
  const std::vector<double> f = textureHistogram(cv::Mat(size, CV_8UC3, cv::Scalar(90, 120, 150)), roi,
                                                 orientationParams());
  ASSERT_EQ(h.size(), 4u);
  // Horizontal stripes: only horizontal edges (and flat pixels between them).
  EXPECT_GT(h[EdgeBinning::kHorizontal], 0.15);
  EXPECT_DOUBLE_EQ(h[EdgeBinning::kVertical], 0.0);
  EXPECT_DOUBLE_EQ(h[EdgeBinning::kDiagonal], 0.0);
  EXPECT_GT(h[EdgeBinning::kNoEdge], 0.5);
  // Vertical stripes: the mirror image.
  EXPECT_GT(v[EdgeBinning::kVertical], 0.15);
  EXPECT_DOUBLE_EQ(v[EdgeBinning::kHorizontal], 0.0);
  EXPECT_NEAR(v[EdgeBinning::kVertical], h[EdgeBinning::kHorizontal], 1e-12);
  // Checkerboard: both, and diagonal responses at the corners.
  EXPECT_GT(c[EdgeBinning::kHorizontal], 0.1);
  EXPECT_GT(c[EdgeBinning::kVertical], 0.1);
  EXPECT_GT(c[EdgeBinning::kDiagonal], 0.0);
  // A flat patch: everything in the no-edge bin.
  EXPECT_DOUBLE_EQ(f[EdgeBinning::kNoEdge], 1.0);

  // Horizontal and vertical stripes are told apart; each histogram matches itself.
  EXPECT_LT(bhattacharyya(h, v), 0.85);
  EXPECT_DOUBLE_EQ(bhattacharyya(h, h), 1.0);
  EXPECT_DOUBLE_EQ(bhattacharyya(c, c), 1.0);
  EXPECT_GT(bhattacharyya(c, h), bhattacharyya(v, h));  // the checkerboard shares the horizontal edges
}

TEST(TextureHistogram, IntensityModeSeesContrastAndDensity)
{
  const cv::Size size(120, 120);
  const cv::Rect roi(20, 20, 80, 80);
  const std::vector<double> weak = textureHistogram(stripes(size, 16, true, 100, 130), roi);   // step 30
  const std::vector<double> strong = textureHistogram(stripes(size, 16, true, 40, 200), roi);  // step 160
  const std::vector<double> dense = textureHistogram(stripes(size, 6, true, 40, 200), roi);
  const std::vector<double> flat = textureHistogram(cv::Mat(size, CV_8UC3, cv::Scalar::all(100)), roi);
  ASSERT_EQ(weak.size(), 9u);
  EXPECT_DOUBLE_EQ(flat[0], 1.0);
  // Mean edge bin grows with contrast; edge fraction with stripe density.
  auto meanEdgeBin = [](const std::vector<double>& p) {
    double m = 0.0, w = 0.0;
    for (size_t b = 1; b < p.size(); ++b)
    {
      m += b * p[b];
      w += p[b];
    }
    return m / w;
  };
  EXPECT_LT(meanEdgeBin(weak), meanEdgeBin(strong) - 2.0);
  EXPECT_GT(1.0 - dense[0], 1.0 - strong[0] + 0.2);
  EXPECT_LT(bhattacharyya(weak, strong), 0.9);
  EXPECT_DOUBLE_EQ(bhattacharyya(strong, strong), 1.0);
}

// ---------------------------------------------------------------------------------------------------
// TextureEdge likelihood

TEST(TextureEdge, CheckeredDiscOnPlainBackgroundPeaksAtTheDisc)
{
  const cv::Size size(320, 240);
  const int cx = 200, cy = 110, radius = 30;
  const cv::Mat img = checkeredDisc(size, cx, cy, radius, 8, 5);
  auto m = makeTexture();
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, discBox(cx, cy, radius), error)) << error;

  // Every 4 px over the whole image, with the disc's radius (3D hypotheses) and as 2D hypotheses.
  for (const float r : { static_cast<float>(radius), 0.0f })
  {
    ImageHypotheses hyp;
    for (int v = 0; v < size.height; v += 4)
      for (int u = 0; u < size.width; u += 4)
      {
        hyp.u.push_back(static_cast<float>(u));
        hyp.v.push_back(static_cast<float>(v));
        hyp.radius.push_back(r);
        hyp.valid.push_back(1);
      }
    Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
    m->evaluate(cache, hyp, ll, sim);
    int arg = 0;
    ll.maxCoeff(&arg);
    // Texture is a regional cue: every window inside the disc looks alike, so the maximum lies somewhere
    // inside it (colour and shape do the fine localisation).
    EXPECT_LT(std::hypot(hyp.u[arg] - cx, hyp.v[arg] - cy), radius) << "radius " << r;
    EXPECT_GT(sim[arg], 0.9);
    // The plain background is far less like the texture (it still shares the target's no-edge pixels).
    double background = 0.0;
    for (int i = 0; i < hyp.size(); ++i)
      if (std::hypot(hyp.u[i] - cx, hyp.v[i] - cy) > 2.0 * radius)
        background = std::max(background, sim[i]);
    EXPECT_LT(background, sim[arg] - 0.15);
  }
}

TEST(TextureEdge, InvalidAndOutsideHypotheses)
{
  const cv::Mat img = checkeredDisc(cv::Size(160, 120), 80, 60, 25, 8, 6);
  auto m = makeTexture();
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  ImageHypotheses hyp;
  hyp.u = { 80.0f, 80.0f, -500.0f, std::nanf(""), 80.0f, 0.0f };
  hyp.v = { 60.0f, 60.0f, 60.0f, 60.0f, std::nanf(""), 0.0f };
  hyp.radius = { 25.0f, 25.0f, 25.0f, 25.0f, 25.0f, std::nanf("") };
  hyp.valid = { 1, 0, 1, 1, 1, 1 };
  Eigen::VectorXd ll(6), sim(6);
  // No target yet: everything is invalid, with a finite log-likelihood.
  m->evaluate(cache, hyp, ll, sim);
  EXPECT_TRUE(ll.allFinite());
  EXPECT_EQ(sim.maxCoeff(), 0.0);
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, discBox(80, 60, 25), error)) << error;
  m->evaluate(cache, hyp, ll, sim);
  EXPECT_TRUE(ll.allFinite());
  EXPECT_GT(sim[0], 0.9);
  for (int i = 1; i < 5; ++i)
  {
    EXPECT_EQ(sim[i], 0.0) << i;
    EXPECT_EQ(ll[i], ll.minCoeff()) << i;
  }
  EXPECT_GE(sim[5], 0.0);  // NaN radius: treated as a 2D hypothesis (fixed window) at the corner
  EXPECT_LE(sim[5], 1.0);
  // Mismatched sizes are a programming error.
  Eigen::VectorXd small(2);
  EXPECT_THROW(m->evaluate(cache, hyp, small, sim), std::invalid_argument);
}

TEST(TextureEdge, LearnTargetRejectsBadRegions)
{
  const cv::Mat img = checkeredDisc(cv::Size(160, 120), 80, 60, 25, 8, 7);
  auto m = makeTexture();
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(10, 10, 0, 5), error));
  EXPECT_NE(error.find("empty"), std::string::npos) << error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(500, 10, 20, 20), error));
  EXPECT_NE(error.find("outside"), std::string::npos) << error;
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(10, 10, 2, 5), error));  // < 3x3 after the margin
  EXPECT_FALSE(m->hasTarget());
}

TEST(TextureEdge, BadParametersNameThemselves)
{
  auto expectError = [](const std::string& key, const std::string& value, const std::string& needle) {
    Parameters root;
    root.set("texture/" + key, value);
    TextureEdge m;
    try
    {
      m.initialize("texture", root.sub("texture"));
      ADD_FAILURE() << key << " = " << value << " was accepted";
    }
    catch (const ParameterError& e)
    {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expectError("mode", "gabor", "texture/mode");
  expectError("bins", "0", "texture/bins");
  expectError("tau", "-1", "texture/tau");
  expectError("max_magnitude", "10", "texture/max_magnitude");  // below tau = 24
  expectError("sigma", "0", "texture/sigma");
  expectError("window", "10", "texture/window");
  expectError("samples", "2", "texture/samples");
}

TEST(TextureEdge, ReconfigureKeepsOldValuesOnError)
{
  Parameters root;
  auto m = std::make_unique<TextureEdge>();
  m->initialize("texture", root.sub("texture"));
  root.set("texture/window", 9);
  root.set("texture/sigma", -1.0);
  EXPECT_THROW(m->reconfigure(), ParameterError);
  root.set("texture/sigma", 0.2);
  root.set("texture/weight", 0.5);
  EXPECT_NO_THROW(m->reconfigure());
  EXPECT_DOUBLE_EQ(m->weight(), 0.5);
}

TEST(TextureEdge, SaveLoadRoundTrip)
{
  const cv::Mat img = checkeredDisc(cv::Size(160, 120), 80, 60, 25, 8, 8);
  auto m = makeTexture(orientationParams());
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, discBox(80, 60, 25), error)) << error;
  cv::FileStorage out(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  m->saveTarget(out);
  const std::string text = out.releaseAndGetString();
  cv::FileStorage in(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);

  auto same = makeTexture(orientationParams());
  ASSERT_TRUE(same->loadTarget(in.root(), error)) << error;
  EXPECT_EQ(same->target().probabilities(), m->target().probabilities());
  auto direct = makeTexture(orientationParams());
  ASSERT_TRUE(direct->loadTarget(in["texture"], error)) << error;

  auto different = makeTexture();  // intensity mode: the bins mean something else
  EXPECT_FALSE(different->loadTarget(in.root(), error));
  EXPECT_NE(error.find("orientation"), std::string::npos) << error;
  EXPECT_FALSE(different->hasTarget());
}

// ---------------------------------------------------------------------------------------------------
// ShapeCircle likelihood

TEST(ShapeCircle, RenderedCirclePeaksAtTrueCentreAndRadius)
{
  const cv::Size size(320, 240);
  const cv::Point centre(150, 110);
  const int radius = 24;
  const cv::Mat img = disc(size, centre, radius, 11);
  auto m = makeShape();
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  const std::vector<Scored> s = scanCircle(*m, cache, centre.x + 3.0f, centre.y - 2.0f, radius + 2.0f, 8, 8);
  const Scored b = best(s);
  std::printf("[ shape    ] clean disc at (%d, %d) r %d: best (%.0f, %.0f) r %.0f\n", centre.x, centre.y, radius, b.u, b.v,
              b.r);
  EXPECT_LE(std::hypot(b.u - centre.x, b.v - centre.y), 2.0) << b.u << ", " << b.v;
  EXPECT_LE(std::abs(b.r - radius), 2.0) << b.r;
  EXPECT_GT(b.sim, 0.9);
  EXPECT_GT(margin(s, centre.x, centre.y, radius, 4.0f), 10.0);
  for (const Scored& h : s)
  {
    ASSERT_TRUE(std::isfinite(h.ll));
    ASSERT_GE(h.ll, 0.0);
    ASSERT_GE(h.sim, 0.0);
    ASSERT_LE(h.sim, 1.0);
  }
}

TEST(ShapeCircle, DegradesGracefullyWithClutter)
{
  const cv::Size size(320, 240);
  const cv::Point centre(160, 120);
  const int radius = 22;
  cv::Mat clean = disc(size, centre, radius, 12);
  auto m = makeShape();
  FeatureCache cache;
  cache.reset(makeFrame(clean, clean));
  const std::vector<Scored> s_clean = scanCircle(*m, cache, centre.x, centre.y, radius, 8, 8);
  const double clean_margin = margin(s_clean, centre.x, centre.y, radius, 4.0f);

  // Clutter everywhere behind the disc (edges right next to its rim too), then two thin lines across it.
  cv::Mat cluttered(size, CV_8UC3, cv::Scalar(70, 70, 70));
  drawClutter(cluttered, 60, 13, cv::Rect(0, 0, size.width, size.height));
  cv::circle(cluttered, centre, radius, cv::Scalar(30, 140, 230), cv::FILLED, cv::LINE_AA);
  cv::line(cluttered, centre + cv::Point(-radius - 10, -8), centre + cv::Point(radius + 10, 5), cv::Scalar::all(20), 1,
           cv::LINE_AA);
  cv::line(cluttered, centre + cv::Point(6, -radius - 10), centre + cv::Point(-4, radius + 10), cv::Scalar::all(230), 2,
           cv::LINE_AA);
  addNoise(cluttered, 2.0, 15);
  cache.reset(makeFrame(cluttered, cluttered));
  const std::vector<Scored> s_clutter = scanCircle(*m, cache, centre.x, centre.y, radius, 8, 8);
  const Scored b = best(s_clutter);
  std::printf("[ shape    ] cluttered disc at (%d, %d) r %d: best (%.0f, %.0f) r %.0f\n", centre.x, centre.y, radius, b.u,
              b.v, b.r);
  EXPECT_LE(std::hypot(b.u - centre.x, b.v - centre.y), 2.0) << b.u << ", " << b.v;
  EXPECT_LE(std::abs(b.r - radius), 2.0) << b.r;
  const double clutter_margin = margin(s_clutter, centre.x, centre.y, radius, 4.0f);
  EXPECT_GT(clutter_margin, 0.0);
  EXPECT_LT(clutter_margin, clean_margin);
  std::printf("[ shape    ] margin over hypotheses >= 4 px off: clean %.1f, cluttered %.1f (log-likelihood)\n",
              clean_margin, clutter_margin);
}

TEST(ShapeCircle, TwoDimensionalHypothesesUseLearnedOrConfiguredRadius)
{
  const cv::Size size(320, 240);
  const cv::Point centre(120, 100);
  const int radius = 20;
  const cv::Mat img = disc(size, centre, radius, 16);
  auto m = makeShape();
  EXPECT_FALSE(m->hasTarget());  // no radius for 2D hypotheses yet
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, discBox(centre.x, centre.y, radius), error)) << error;
  EXPECT_TRUE(m->hasTarget());
  EXPECT_NEAR(m->learnedRadius(), radius + 0.5, 1e-9);
  const std::vector<Scored> s = scanCircle(*m, cache, centre.x, centre.y, 0.0f, 6, 0);
  const Scored b = best(s);
  EXPECT_LE(std::hypot(b.u - centre.x, b.v - centre.y), 1.5);

  // A configured radius wins over the learned one (and needs no target).
  Parameters p;
  p.set("radius", 35.0);
  auto fixed = makeShape(p);
  EXPECT_TRUE(fixed->hasTarget());
  EXPECT_DOUBLE_EQ(fixed->radius2D(), 35.0);
}

TEST(ShapeCircle, LinesLeavingTheImageStayFiniteAndNeutral)
{
  const cv::Size size(200, 150);
  const cv::Mat img = disc(size, cv::Point(40, 30), 30, 17);  // its top is cut by the border
  auto m = makeShape();
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  ImageHypotheses hyp;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  auto add = [&hyp](float u, float v, float r, unsigned char valid) {
    hyp.u.push_back(u);
    hyp.v.push_back(v);
    hyp.radius.push_back(r);
    hyp.valid.push_back(valid);
  };
  add(40, 30, 30, 1);        // 0: the disc: the lines through its top leave the image
  add(0, 0, 10, 1);          // 1: at the corner: 3/4 of the lines out -> invalid
  add(-100, 50, 10, 1);      // 2: completely outside
  add(100, 75, 5000, 1);     // 3: a circle far larger than the image
  add(nan, 75, 10, 1);       // 4
  add(100, nan, 10, 1);      // 5
  add(100, 75, nan, 1);      // 6: NaN radius and no learned radius
  add(100, 75, inf, 1);      // 7
  add(100, 75, 10, 0);       // 8: marked invalid
  add(199, 75, 10, 1);       // 9: centre on the right border: about half the lines out
  add(100, 75, 0.01f, 1);    // 10: tiny radius, clamped to min_radius
  Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
  m->evaluate(cache, hyp, ll, sim);
  ASSERT_TRUE(ll.allFinite());
  ASSERT_TRUE(sim.allFinite());
  EXPECT_GE(ll.minCoeff(), 0.0);
  EXPECT_GE(sim.minCoeff(), 0.0);
  EXPECT_LE(sim.maxCoeff(), 1.0);
  for (int i : { 1, 2, 3, 4, 5, 6, 7, 8 })
  {
    EXPECT_EQ(ll[i], 0.0) << i;
    EXPECT_EQ(sim[i], 0.0) << i;
  }
  EXPECT_GT(ll[0], 5.0);  // the visible half of the contour still counts
  EXPECT_GT(sim[0], 0.6);
}

TEST(ShapeCircle, BadParametersNameThemselves)
{
  for (const auto& kv : std::vector<std::pair<std::string, std::string>>{
           { "lines", "2" }, { "line_half_length", "0" }, { "sigma", "0" }, { "q0", "1" }, { "q0", "0" },
           { "edge_threshold", "-3" }, { "radius", "-1" }, { "min_radius", "abc" }, { "weight", "-1" } })
  {
    Parameters root;
    root.set("shape/" + kv.first, kv.second);
    ShapeCircle m;
    try
    {
      m.initialize("shape", root.sub("shape"));
      ADD_FAILURE() << kv.first << " = " << kv.second << " was accepted";
    }
    catch (const ParameterError& e)
    {
      EXPECT_NE(std::string(e.what()).find("shape/" + kv.first), std::string::npos) << e.what();
    }
  }
}

TEST(ShapeCircle, ReconfigureAndSaveLoad)
{
  Parameters root;
  auto m = std::make_unique<ShapeCircle>();
  m->initialize("shape", root.sub("shape"));
  EXPECT_EQ(m->lines(), 8);
  EXPECT_DOUBLE_EQ(m->weight(), 0.2);
  root.set("shape/lines", 24);
  root.set("shape/q0", 2.0);
  EXPECT_THROW(m->reconfigure(), ParameterError);
  EXPECT_EQ(m->lines(), 8);  // unchanged after the error
  root.set("shape/q0", 0.2);
  m->reconfigure();
  EXPECT_EQ(m->lines(), 24);

  const cv::Mat img = disc(cv::Size(160, 120), cv::Point(80, 60), 20, 18);
  FeatureCache cache;
  cache.reset(makeFrame(img, img));
  std::string error;
  ASSERT_TRUE(m->learnTarget(cache, View::Left, cv::Rect(60, 45, 41, 31), error)) << error;
  EXPECT_DOUBLE_EQ(m->learnedRadius(), 15.5);
  EXPECT_FALSE(m->learnTarget(cache, View::Left, cv::Rect(500, 500, 10, 10), error));
  cv::FileStorage out(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  m->saveTarget(out);
  cv::FileStorage in(out.releaseAndGetString(), cv::FileStorage::READ | cv::FileStorage::MEMORY);
  auto loaded = makeShape();
  ASSERT_TRUE(loaded->loadTarget(in.root(), error)) << error;
  EXPECT_DOUBLE_EQ(loaded->learnedRadius(), 15.5);

  cv::FileStorage empty("%YAML:1.0\nother: 1\n", cv::FileStorage::READ | cv::FileStorage::MEMORY);
  auto none = makeShape();
  EXPECT_FALSE(none->loadTarget(empty.root(), error));
  EXPECT_NE(error.find("shape"), std::string::npos) << error;
  Parameters p;
  p.set("radius", 12.0);
  auto configured = makeShape(p);
  EXPECT_TRUE(configured->loadTarget(empty.root(), error)) << error;
}

TEST(ShapeCircle, OffAxisSphereIsMatchedWithItsPerspectiveSilhouette)
{
  // A ball 0.37 m right of the axis at 1 m (20 deg off it): its image is an ellipse about 6 % wider
  // radially than the apparent radius f R / z the 3D state models give their hypotheses.
  SceneDescription d;
  d.frames = 1;
  d.noise_sigma = 0.0;
  stereo_pf::SceneSphere ball;
  ball.radius = 0.035;
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.37, 0.05, 1.0));
  d.objects.push_back(ball);
  SceneRenderer renderer(d);
  cv::Mat left, right;
  const StereoFrame frame = renderer.renderFrame(0, left, right);
  FeatureCache cache;
  cache.reset(frame);
  const Pixel centre = frame.geometry.projectSphere(ball.trajectory.position, ball.radius, View::Left);
  const float radius = static_cast<float>(frame.geometry.fx() * ball.radius / ball.trajectory.position.z());

  // Scan the radius (0.1 px steps) at the true centre: the radius the cue prefers.
  auto preferredRadius = [&](bool perspective) {
    Parameters p;
    p.set("perspective", perspective);
    auto m = makeShape(p);
    ImageHypotheses hyp;
    for (int k = -20; k <= 20; ++k)
    {
      hyp.u.push_back(static_cast<float>(centre.u));
      hyp.v.push_back(static_cast<float>(centre.v));
      hyp.radius.push_back(radius + 0.1f * k);
      hyp.valid.push_back(1);
    }
    Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
    m->evaluate(cache, hyp, ll, sim);
    int arg = 0;
    ll.maxCoeff(&arg);
    return hyp.radius[arg];
  };
  const float with = preferredRadius(true);
  const float without = preferredRadius(false);
  std::printf("[ shape    ] f R / z = %.2f px; preferred radius with the perspective silhouette %.2f, with a circle %.2f\n",
              radius, with, without);
  EXPECT_NEAR(with, radius, 0.15);
  EXPECT_GT(without - radius, 0.3);  // a circle fits the ellipse with a larger radius: a depth bias
}

// ---------------------------------------------------------------------------------------------------
// The new scenes at the level of the cues, and the engine on the colour distractor

// Sum over both views of each cue's log-likelihood and mean similarity for a ball hypothesis at P.
struct CueScores
{
  double ll[3] = { 0, 0, 0 };
  double sim[3] = { 0, 0, 0 };
};

CueScores scoreAt(std::initializer_list<ObservationModel*> models, FeatureCache& cache, const Eigen::Vector3d& p,
                  double ball_radius)
{
  CueScores out;
  const StereoGeometry& g = cache.geometry();
  for (const View view : { View::Left, View::Right })
  {
    ImageHypotheses h;
    h.view = view;
    h.resize(1);
    const Pixel px = g.projectSphere(p, ball_radius, view);
    h.u[0] = static_cast<float>(px.u);
    h.v[0] = static_cast<float>(px.v);
    h.radius[0] = static_cast<float>(g.fx() * ball_radius / p.z());
    h.valid[0] = 1;
    Eigen::VectorXd ll(1), sim(1);
    int q = 0;
    for (ObservationModel* m : models)
    {
      m->evaluate(cache, h, ll, sim);
      out.ll[q] += ll[0];
      out.sim[q] += 0.5 * sim[0];
      ++q;
    }
  }
  return out;
}

TEST(NewScenes, ColourDistractorIsToldApartByTextureAndShape)
{
  const SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/colour_distractor.yaml");
  ASSERT_EQ(scene.objects.size(), 2u);
  SceneRenderer renderer(scene);
  cv::Mat left, right;
  StereoFrame frame = renderer.renderFrame(scene.target_roi_frame, left, right);
  FeatureCache cache;
  cache.reset(frame);
  ColourHSI colour;
  colour.initialize("colour", Parameters());
  TextureEdge texture;
  texture.initialize("texture", Parameters());
  ShapeCircle shape;
  shape.initialize("shape", Parameters());
  std::string error;
  for (ObservationModel* m : { static_cast<ObservationModel*>(&colour), static_cast<ObservationModel*>(&texture),
                               static_cast<ObservationModel*>(&shape) })
    ASSERT_TRUE(m->learnTarget(cache, View::Left, renderer.targetRoi(scene.target_roi_frame), error)) << error;

  // Every third frame in which both objects are fully in view: a ball hypothesis at the ball and one at the
  // square (same depth), scored by each cue.
  double colour_margin = 1e9, texture_margin = 1e9, shape_margin = 1e9;
  int frames = 0;
  for (int k = 0; k < renderer.frames(); k += 3)
  {
    if (renderer.visibleFraction(0, k, View::Left) < 0.99 || renderer.visibleFraction(0, k, View::Right) < 0.99 ||
        renderer.visibleFraction(1, k, View::Left) < 0.99 || renderer.visibleFraction(1, k, View::Right) < 0.99)
      continue;
    renderer.render(k, left, right);
    frame.left = left;
    frame.right = right;
    cache.reset(frame);
    const CueScores ball = scoreAt({ &colour, &texture, &shape }, cache, renderer.objectPosition(0, k), 0.035);
    const CueScores square = scoreAt({ &colour, &texture, &shape }, cache, renderer.objectPosition(1, k), 0.035);
    colour_margin = std::min(colour_margin, ball.ll[0] - square.ll[0]);
    texture_margin = std::min(texture_margin, ball.ll[1] - square.ll[1]);
    shape_margin = std::min(shape_margin, ball.ll[2] - square.ll[2]);
    // The square's own similarities: colour-like, but neither textured nor shaped like the target.
    EXPECT_GT(square.sim[0], 0.8) << "frame " << k;
    EXPECT_LT(square.sim[1], ball.sim[1] - 0.2) << "frame " << k;
    EXPECT_LT(square.sim[2], ball.sim[2] - 0.2) << "frame " << k;
    ++frames;
  }
  ASSERT_GT(frames, 20);
  std::printf("[ scenes   ] colour_distractor, %d frames: smallest log-likelihood margin ball - square: colour %.1f, "
              "texture %.1f, shape %.1f\n",
              frames, colour_margin, texture_margin, shape_margin);
  // Colour alone barely separates them (the square is the ball's orange); texture and shape do, by far.
  EXPECT_LT(colour_margin, 5.0);
  EXPECT_GT(texture_margin, 2.0 * colour_margin);
  EXPECT_GT(shape_margin, 2.0 * colour_margin);
}

TEST(NewScenes, CheckeredBallTextureStandsOutOfTheClutter)
{
  const SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/checkered_cluttered.yaml");
  SceneRenderer renderer(scene);
  cv::Mat left, right;
  StereoFrame frame = renderer.renderFrame(scene.target_roi_frame, left, right);
  FeatureCache cache;
  cache.reset(frame);
  TextureEdge texture;
  texture.initialize("texture", Parameters());
  std::string error;
  ASSERT_TRUE(texture.learnTarget(cache, View::Left, renderer.targetRoi(scene.target_roi_frame), error)) << error;

  // Over the sequence (the pattern turns), the ball's window against windows of the same size all over the
  // cluttered wall (away from the ball).
  cv::RNG rng(9);
  double target_sum = 0.0, background_sum = 0.0;
  int targets = 0, backgrounds = 0, background_above = 0;
  for (int k = 0; k < renderer.frames(); k += 10)
  {
    renderer.render(k, left, right);
    frame.left = left;
    frame.right = right;
    cache.reset(frame);
    const Pixel px = frame.geometry.projectLeft(renderer.targetPosition(k));
    const float radius = static_cast<float>(frame.geometry.fx() * 0.035 / renderer.targetPosition(k).z());
    ImageHypotheses hyp;
    hyp.u.push_back(static_cast<float>(px.u));
    hyp.v.push_back(static_cast<float>(px.v));
    hyp.radius.push_back(radius);
    hyp.valid.push_back(1);
    while (hyp.size() < 60)
    {
      const float u = rng.uniform(20.0f, 620.0f), v = rng.uniform(20.0f, 460.0f);
      if (std::hypot(u - px.u, v - px.v) < 3.0 * radius)
        continue;
      hyp.u.push_back(u);
      hyp.v.push_back(v);
      hyp.radius.push_back(radius);
      hyp.valid.push_back(1);
    }
    Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
    texture.evaluate(cache, hyp, ll, sim);
    target_sum += sim[0];
    ++targets;
    for (int i = 1; i < hyp.size(); ++i)
    {
      background_sum += sim[i];
      ++backgrounds;
      background_above += sim[i] >= sim[0] ? 1 : 0;
    }
  }
  const double target_mean = target_sum / targets, background_mean = background_sum / backgrounds;
  std::printf("[ scenes   ] checkered_cluttered texture similarity: ball %.2f, wall %.2f (mean); wall windows at "
              "least as similar as the ball: %d of %d\n",
              target_mean, background_mean, background_above, backgrounds);
  EXPECT_GT(target_mean, 0.9);
  EXPECT_LT(background_mean, target_mean - 0.2);
  EXPECT_LE(background_above, backgrounds / 50);
}

// One run of the engine (Position3D, 1000 particles, seed 1) over the first `frames` frames of a scene,
// rendered in process, with the cues of config/multi_cue.yaml; colour only when `all_cues` is false.
TrackSummary trackScene(const std::string& scene_file, int frames, bool all_cues)
{
  SceneDescription scene = loadScene(scene_file);
  scene.frames = std::min(scene.frames, frames);
  SceneRenderer renderer(scene);
  auto state = std::make_shared<Position3D>();
  Parameters state_params;
  state_params.set("size_band", 0.0);  // the thesis's cues: each particle's own apparent size, as the thesis
  state->initialize("state_model", state_params);
  std::vector<std::shared_ptr<ObservationModel>> cues;
  auto colour = std::make_shared<ColourHSI>();
  colour->initialize("colour", Parameters());
  cues.push_back(colour);
  if (all_cues)
  {
    Parameters texture_params, shape_params;
    texture_params.set("weight", 0.5);
    shape_params.set("weight", 0.2);
    auto texture = std::make_shared<TextureEdge>();
    texture->initialize("texture", texture_params);
    auto shape = std::make_shared<ShapeCircle>();
    shape->initialize("shape", shape_params);
    cues.push_back(texture);
    cues.push_back(shape);
  }
  EngineConfig config;
  config.particles = 1000;
  config.seed = 1;
  FilterEngine engine(state, cues, config);
  std::vector<FrameRecord> records;
  cv::Mat left, right;
  for (int k = 0; k < renderer.frames(); ++k)
  {
    const StereoFrame frame = renderer.renderFrame(k, left, right);
    if (k == scene.target_roi_frame)
    {
      std::string error;
      EXPECT_TRUE(engine.learnTarget(frame, renderer.targetRoi(k), error)) << error;
    }
    const FrameResult r = engine.step(frame);
    FrameRecord rec;
    rec.has_truth = true;
    rec.truth = renderer.targetPosition(k);
    rec.target_visible = renderer.targetVisible(k);
    rec.estimate_valid = r.estimate.valid;
    rec.estimate = r.estimate.position;
    rec.tracking = r.state == TrackState::Tracking;
    records.push_back(rec);
  }
  return summarise(records);
}

TEST(NewScenes, EngineKeepsTheTargetPastTheColourDistractor)
{
  // Five crossings (the first 150 frames); the 10-seed comparison over the whole sequence is made with
  // track_bag (see config/multi_cue.yaml).
  const std::string file = std::string(SCENES_DIR) + "/colour_distractor.yaml";
  const TrackSummary all = trackScene(file, 150, true);
  const TrackSummary colour = trackScene(file, 150, false);
  std::printf("[ scenes   ] colour_distractor, 150 frames, seed 1:\n[ scenes   ]   all cues:    %s\n"
              "[ scenes   ]   colour only: %s\n",
              all.line().c_str(), colour.line().c_str());
  ASSERT_GE(all.convergence_frame, 0);
  EXPECT_LE(all.convergence_frame, 40);
  EXPECT_LT(all.rms_after, 0.035);
  EXPECT_LE(all.frames_above_10cm_after, 2);
}

// ---------------------------------------------------------------------------------------------------
// Cost of the cues in one engine step (what the 4 ms budget is about)

TEST(Cues, TimingReport)
{
  // One core, as the budget is stated (OpenCV would otherwise split the Sobel filters over threads).
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  // A frame of the cluttered pendulum scene: 640x480 BGR, busy background (worst case for edges).
  const SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/pendulum_cluttered.yaml");
  SceneRenderer renderer(scene);
  cv::Mat left, right;
  renderer.render(0, left, right);
  const StereoGeometry g = renderer.geometry();
  StereoFrame frame;
  frame.left = left;
  frame.right = right;
  frame.geometry = g;

  ColourHSI colour;
  colour.initialize("colour", Parameters());
  TextureEdge texture;
  texture.initialize("texture", Parameters());
  ShapeCircle shape;
  shape.initialize("shape", Parameters());
  FeatureCache cache;
  cache.reset(frame);
  std::string error;
  const cv::Rect roi = renderer.targetRoi(0);
  ASSERT_TRUE(colour.learnTarget(cache, View::Left, roi, error)) << error;
  ASSERT_TRUE(texture.learnTarget(cache, View::Left, roi, error)) << error;
  ASSERT_TRUE(shape.learnTarget(cache, View::Left, roi, error)) << error;

  // 1000 3D particles around the target (10 cm spread), projected as Position3D does.
  const int n = 1000;
  const Eigen::Vector3d truth = renderer.targetPosition(0);
  std::mt19937 rng(21);
  std::normal_distribution<double> spread(0.0, 0.1);
  ImageHypotheses views[2];
  views[1].view = View::Right;
  for (ImageHypotheses& h : views)
    h.resize(n);
  for (int i = 0; i < n; ++i)
  {
    Eigen::Vector3d p = truth + Eigen::Vector3d(spread(rng), spread(rng), spread(rng));
    p.z() = std::max(p.z(), 0.3);
    for (int k = 0; k < 2; ++k)
    {
      const Pixel px = g.projectSphere(p, 0.035, views[k].view);
      views[k].u[i] = static_cast<float>(px.u);
      views[k].v[i] = static_cast<float>(px.v);
      views[k].radius[i] = static_cast<float>(g.fx() * 0.035 / p.z());
      views[k].valid[i] = g.inImage(px) ? 1 : 0;
    }
  }
  Eigen::VectorXd ll(n), sim(n);

  using Clock = std::chrono::steady_clock;
  // Best of `reps`: the minimum is what the code costs; the rest is other processes on the machine.
  auto bestMs = [](int reps, const std::function<void()>& f) {
    double b = std::numeric_limits<double>::infinity();
    for (int k = 0; k < reps; ++k)
    {
      const auto t = Clock::now();
      f();
      b = std::min(b, std::chrono::duration<double, std::milli>(Clock::now() - t).count());
    }
    return b;
  };
  auto step = [&](std::initializer_list<ObservationModel*> models) {
    return [&, models] {
      cache.reset(frame);
      for (ObservationModel* m : models)
        for (const ImageHypotheses& h : views)
          m->evaluate(cache, h, ll, sim);
    };
  };
  const int reps = 60;
  const double gray_ms = bestMs(reps, [&] {
    cache.reset(frame);
    for (const View v : { View::Left, View::Right })
      cache.gray(v);
  });
  const double bins_ms = bestMs(reps, [&] {
    cache.reset(frame);
    for (const View v : { View::Left, View::Right })
      texture.binImage(cache, v);
  });
  const double colour_ms = bestMs(reps, step({ &colour }));
  const double texture_ms = bestMs(reps, step({ &texture }));
  const double shape_ms = bestMs(reps, step({ &shape }));
  const double texture_shape_ms = bestMs(reps, step({ &texture, &shape }));
  const double all_ms = bestMs(reps, step({ &colour, &texture, &shape }));
  // Hypotheses only (per-image products already cached).
  cache.reset(frame);
  for (ObservationModel* m : { static_cast<ObservationModel*>(&colour), static_cast<ObservationModel*>(&texture),
                               static_cast<ObservationModel*>(&shape) })
    for (const ImageHypotheses& h : views)
      m->evaluate(cache, h, ll, sim);
  auto hypothesesOnly = [&](ObservationModel& m) {
    return bestMs(reps, [&] {
      for (const ImageHypotheses& h : views)
        m.evaluate(cache, h, ll, sim);
    });
  };
  const double colour_hyp_ms = hypothesesOnly(colour);
  const double texture_hyp_ms = hypothesesOnly(texture);
  const double shape_hyp_ms = hypothesesOnly(shape);
  std::printf("[ timing   ] per stereo frame, 640x480, 1000 particles x 2 views, per-image work included:\n");
  std::printf("[ timing   ]   grey images (shared by texture and shape): %.3f ms; with the edge-bin images: %.3f ms\n",
              gray_ms, bins_ms);
  std::printf("[ timing   ]   colour alone %.3f ms, texture alone %.3f ms, shape alone %.3f ms\n", colour_ms, texture_ms,
              shape_ms);
  std::printf("[ timing   ]   texture + shape %.3f ms, all three %.3f ms\n", texture_shape_ms, all_ms);
  std::printf("[ timing   ]   2000 hypotheses only (per-image products cached): colour %.3f ms, texture %.3f ms, "
              "shape %.3f ms\n",
              colour_hyp_ms, texture_hyp_ms, shape_hyp_ms);
  RecordProperty("all_cues_ms", std::to_string(all_ms));
  cv::setNumThreads(threads);
  // Loose bound (a shared, loaded machine must not fail the build); the budget is measured with track_bag.
  EXPECT_LT(all_ms, 20.0);
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

// The cues ask the cache only for the rows their windows, rings and lines reach. Scores must be exactly those
// of whole-image products: the buffers are first filled with another frame, so a row missing from a cue's
// band would be read stale and change its score.
TEST(Cues, RowLimitedProductsScoreLikeWholeImages)
{
  const SceneDescription scene = loadScene(std::string(SCENES_DIR) + "/checkered_cluttered.yaml");
  SceneRenderer renderer(scene);
  cv::Mat l0, r0, l1, r1;
  renderer.render(0, l0, r0);
  renderer.render(40, l1, r1);
  const StereoFrame stale = makeFrame(l0, r0);
  const StereoFrame current = makeFrame(l1, r1);
  FeatureCache learn;
  learn.reset(stale);
  ColourHSI colour;
  colour.initialize("colour", Parameters());
  TextureEdge texture;
  texture.initialize("texture", Parameters());
  ShapeCircle shape;
  shape.initialize("shape", Parameters());
  std::string error;
  std::vector<ObservationModel*> models{ &colour, &texture, &shape };
  for (ObservationModel* m : models)
    ASSERT_TRUE(m->learnTarget(learn, View::Left, renderer.targetRoi(0), error)) << error;

  // Two batches per view: 3D hypotheses around the ball, and 2D ones (radius 0) spread over the image,
  // some of them near or past its edges.
  std::mt19937 rng(7);
  const StereoGeometry g = renderer.geometry();
  auto batch = [&](View view, bool around_ball) {
    ImageHypotheses h;
    h.view = view;
    h.resize(300);
    const Pixel c = g.project(renderer.targetPosition(40), view);
    std::normal_distribution<float> near(0.0f, 20.0f);
    std::uniform_real_distribution<float> u(-30.0f, 670.0f), v(-30.0f, 510.0f), r(8.0f, 40.0f);
    for (int i = 0; i < h.size(); ++i)
    {
      h.u[i] = around_ball ? static_cast<float>(c.u) + near(rng) : u(rng);
      h.v[i] = around_ball ? static_cast<float>(c.v) + near(rng) : v(rng);
      h.radius[i] = around_ball ? r(rng) : 0.0f;
      h.valid[i] = i % 17 != 0;
    }
    return h;
  };
  std::vector<ImageHypotheses> batches;
  for (const View view : { View::Left, View::Right })
  {
    batches.push_back(batch(view, true));
    batches.push_back(batch(view, false));
  }

  auto scoreAll = [&](bool whole_first) {
    FeatureCache cache;
    cache.reset(stale);  // fill every buffer with another frame
    for (const View view : { View::Left, View::Right })
    {
      colour.binImage(cache, view);
      texture.binImage(cache, view);
      cache.gray(view);
    }
    cache.reset(current);
    if (whole_first)
      for (const View view : { View::Left, View::Right })
      {
        colour.binImage(cache, view);
        texture.binImage(cache, view);
        cache.gray(view);
      }
    std::vector<Eigen::VectorXd> out;
    for (const ImageHypotheses& h : batches)
      for (ObservationModel* m : models)
      {
        Eigen::VectorXd ll(h.size()), sim(h.size());
        m->evaluate(cache, h, ll, sim);
        out.push_back(ll);
        out.push_back(sim);
      }
    return out;
  };
  const std::vector<Eigen::VectorXd> rows = scoreAll(false), whole = scoreAll(true);
  ASSERT_EQ(rows.size(), whole.size());
  for (size_t k = 0; k < rows.size(); ++k)
    EXPECT_EQ(rows[k], whole[k]) << "batch " << k / (2 * models.size()) << ", model " << (k / 2) % models.size();
}
