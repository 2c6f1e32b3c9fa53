// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The per-frame feature cache computes each product once per image per frame.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "stereo_pf/core/feature_cache.h"

using namespace stereo_pf;

namespace
{
StereoFrame frame(int value)
{
  StereoFrame f;
  f.geometry = StereoGeometry(100, 100, 32, 24, 0.1, 64, 48);
  f.left = cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(value));
  f.right = cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(255 - value));
  cv::rectangle(f.left, cv::Rect(20, 10, 10, 10), cv::Scalar(255, 255, 255), cv::FILLED);
  return f;
}
}  // namespace

TEST(FeatureCache, ComputesOncePerImagePerFrame)
{
  FeatureCache cache;
  cache.reset(frame(10));
  int calls = 0;
  auto compute = [&calls](const cv::Mat& image, cv::Mat& out) {
    ++calls;
    out = image.clone();
  };
  for (int k = 0; k < 5; ++k)
  {
    cache.get(View::Left, "copy", compute);
    cache.get(View::Right, "copy", compute);
  }
  EXPECT_EQ(calls, 2);
  cache.reset(frame(20));
  const cv::Mat& l = cache.get(View::Left, "copy", compute);
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(l.at<cv::Vec3b>(0, 0)[0], 20);  // recomputed from the new frame
}

TEST(FeatureCache, AProductAskedForWithAnotherTagIsComputedAgainInTheSameBuffer)
{
  // What a product depends on that changes while the tracker runs (a model's target) goes in its tag, not its key:
  // another tag computes it again, this frame too, and no buffer is added.
  FeatureCache cache;
  cache.reset(frame(10));
  int calls = 0;
  auto compute = [&calls](const cv::Mat& image, cv::Mat& out) {
    ++calls;
    image.convertTo(out, CV_8UC3, 1.0, calls);  // each computation leaves its own mark
  };
  const cv::Mat& a = cache.get(View::Left, "mapped", compute, 1);
  const uint8_t* buffer = a.data;
  cache.get(View::Left, "mapped", compute, 1);
  EXPECT_EQ(calls, 1);
  const cv::Mat& b = cache.get(View::Left, "mapped", compute, 2);
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(b.at<cv::Vec3b>(0, 0)[0], 12);
  EXPECT_EQ(b.data, buffer);
  EXPECT_EQ(cache.products(), 1u);
  // The same for a product computed by regions: another tag starts its valid region afresh.
  int regions = 0;
  auto region = [&regions](const cv::Mat& image, cv::Mat& out, const cv::Rect& r) {
    ++regions;
    out.create(image.size(), CV_8UC1);
    out(r).setTo(cv::Scalar(regions));
  };
  cache.getRegion(View::Left, "regional", cv::Rect(0, 0, 10, 10), region, 7);
  cache.getRegion(View::Left, "regional", cv::Rect(2, 2, 5, 5), region, 7);
  EXPECT_EQ(regions, 1);
  const cv::Mat& r = cache.getRegion(View::Left, "regional", cv::Rect(2, 2, 5, 5), region, 8);
  EXPECT_EQ(regions, 2);
  EXPECT_EQ(r.at<uint8_t>(3, 3), 2);
  EXPECT_EQ(cache.products(), 2u);
}

TEST(FeatureCache, GradientMatchesSobel)
{
  FeatureCache cache;
  const StereoFrame f = frame(0);
  cache.reset(f);
  const cv::Mat& mag = cache.gradientMagnitude(View::Left);
  cv::Mat gray, gx, gy, expected;
  cv::cvtColor(f.left, gray, cv::COLOR_BGR2GRAY);
  cv::Sobel(gray, gx, CV_32F, 1, 0, 3);
  cv::Sobel(gray, gy, CV_32F, 0, 1, 3);
  cv::magnitude(gx, gy, expected);
  EXPECT_EQ(cv::norm(mag, expected, cv::NORM_INF), 0.0);
  EXPECT_GT(mag.at<float>(15, 20), 100.0f);  // on the square's edge
  EXPECT_EQ(mag.at<float>(40, 5), 0.0f);     // flat background
  const long count = cache.computeCount();
  cache.gradientMagnitude(View::Left);
  EXPECT_EQ(cache.computeCount(), count);  // shared, not recomputed
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

// Row-wise products: only the rows asked for are computed, rows already there are kept, and the result in
// those rows equals the whole-image computation.
TEST(FeatureCache, RowProductsComputeOnlyTheMissingRows)
{
  FeatureCache cache;
  cache.reset(frame(10));
  std::vector<std::pair<int, int>> calls;
  auto compute = [&calls](const cv::Mat& image, cv::Mat& out, int y0, int y1) {
    calls.emplace_back(y0, y1);
    out.create(image.size(), CV_8UC1);
    if (y0 < y1)
      cv::cvtColor(image.rowRange(y0, y1), out.rowRange(y0, y1), cv::COLOR_BGR2GRAY);
  };
  cache.getRows(View::Left, "g", 10, 20, compute);
  cache.getRows(View::Left, "g", 12, 18, compute);  // inside: nothing to do
  cache.getRows(View::Left, "g", 5, 25, compute);   // both ends
  cache.getRows(View::Left, "g", -7, 1000, compute);  // clipped to the image's 48 rows
  const std::vector<std::pair<int, int>> expected{ { 10, 20 }, { 5, 10 }, { 20, 25 }, { 0, 5 }, { 25, 48 } };
  EXPECT_EQ(calls, expected);
  cv::Mat full;
  cv::cvtColor(cache.image(View::Left), full, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(cache.getRows(View::Left, "g", 0, 48, compute), full, cv::NORM_INF), 0.0);
  EXPECT_EQ(calls.size(), expected.size());

  // A new frame starts again from the rows asked for; an empty request only allocates.
  calls.clear();
  cache.reset(frame(20));
  const cv::Mat& empty = cache.getRows(View::Right, "g", 30, 30, compute);
  EXPECT_EQ(empty.size(), cv::Size(64, 48));
  cache.getRows(View::Right, "g", 40, 44, compute);
  const std::vector<std::pair<int, int>> expected2{ { 30, 30 }, { 40, 44 } };
  EXPECT_EQ(calls, expected2);

  // The grey image by rows equals the whole grey image in those rows.
  const cv::Mat band = cache.gray(View::Left, 8, 22).rowRange(8, 22).clone();
  cv::cvtColor(cache.image(View::Left), full, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(band, full.rowRange(8, 22), cv::NORM_INF), 0.0);
}

// Region products: a request outside the valid rectangle grows it to the bounding box, computing only the strips
// the box adds; the pixels asked for equal the whole-image computation; rows and regions share a key.
TEST(FeatureCache, RegionProductsComputeOnlyTheStripsTheBoundingBoxAdds)
{
  FeatureCache cache;
  cache.reset(frame(10));
  std::vector<cv::Rect> calls;
  auto compute = [&calls](const cv::Mat& image, cv::Mat& out, const cv::Rect& r) {
    calls.push_back(r);
    out.create(image.size(), CV_8UC1);
    if (!r.empty())
    {
      cv::Mat part = out(r);
      cv::cvtColor(image(r), part, cv::COLOR_BGR2GRAY);
    }
  };
  cache.getRegion(View::Left, "g", cv::Rect(10, 10, 20, 10), compute);
  cache.getRegion(View::Left, "g", cv::Rect(12, 12, 5, 5), compute);  // inside: nothing to do
  cache.getRegion(View::Left, "g", cv::Rect(5, 15, 10, 20), compute);  // left and below: bounding box (5, 10)-(30, 35)
  cache.getRegion(View::Left, "g", cv::Rect(-3, -3, 2, 2), compute);  // clipped to nothing: nothing to do
  const std::vector<cv::Rect> expected{ cv::Rect(10, 10, 20, 10), cv::Rect(5, 20, 25, 15), cv::Rect(5, 10, 5, 10) };
  EXPECT_EQ(calls, expected);
  cv::Mat full;
  cv::cvtColor(cache.image(View::Left), full, cv::COLOR_BGR2GRAY);
  const cv::Rect box(5, 10, 25, 25);
  EXPECT_EQ(cv::norm(cache.getRegion(View::Left, "g", box, compute)(box), full(box), cv::NORM_INF), 0.0);
  EXPECT_EQ(calls.size(), expected.size());

  // Whole rows of the same key: the rows above over the full width, then the box's rows again whole (a RowCompute
  // cannot fill less), once.
  calls.clear();
  cache.getRows(View::Left, "g", 8, 30, [&](const cv::Mat& image, cv::Mat& out, int y0, int y1) {
    compute(image, out, cv::Rect(0, y0, image.cols, y1 - y0));
  });
  const std::vector<cv::Rect> rows{ cv::Rect(0, 8, 64, 2), cv::Rect(0, 10, 64, 25) };
  EXPECT_EQ(calls, rows);
  EXPECT_EQ(cv::norm(cache.getRows(View::Left, "g", 8, 35, nullptr).rowRange(8, 35), full.rowRange(8, 35),
                     cv::NORM_INF),
            0.0);
}

TEST(FeatureCache, BrightnessIsTheMeanGreyLevelAndAGainMakesTheProductsStale)
{
  cv::Mat left(48, 64, CV_8UC3, cv::Scalar(10, 20, 30)), right(48, 64, CV_8UC1, cv::Scalar(200));
  StereoFrame f;
  f.left = left;
  f.right = right;
  FeatureCache cache;
  cache.reset(f);
  EXPECT_DOUBLE_EQ(cache.brightness(View::Left), 20.0) << "all channels alike";
  EXPECT_DOUBLE_EQ(cache.brightness(View::Right), 200.0);
  // The grid's pixels only, whatever the resolution: a quarter of the image brighter moves the mean by about a
  // quarter of the difference.
  right(cv::Rect(0, 0, 32, 24)).setTo(cv::Scalar(100));
  EXPECT_NEAR(cache.brightness(View::Right), 175.0, 1e-9);
  cv::Mat wide(48, 64, CV_16UC1, cv::Scalar(1000));
  f.right = wide;
  cache.reset(f);
  EXPECT_TRUE(std::isnan(cache.brightness(View::Right))) << "not 8-bit";

  f.right = right;
  cache.reset(f);
  EXPECT_EQ(cache.gain(View::Left), 1.0);
  long computed = 0;
  auto count = [&computed](const cv::Mat& image, cv::Mat& out) {
    ++computed;
    out = image.clone();
  };
  cache.get(View::Left, "copy", count);
  cache.get(View::Left, "copy", count);
  EXPECT_EQ(computed, 1);
  cache.setGain(View::Left, 1.25);
  EXPECT_EQ(cache.gain(View::Left), 1.25);
  cache.get(View::Left, "copy", count);
  EXPECT_EQ(computed, 2) << "a product computed before the gain was set is stale";
  cache.reset(f);
  EXPECT_EQ(cache.gain(View::Left), 1.0) << "each frame starts at gain 1";
}
