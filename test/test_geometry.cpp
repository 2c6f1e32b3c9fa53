// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Stereo geometry: projection, triangulation, validity (thesis eq. 6.1-6.3).
#include <gtest/gtest.h>

#include <cmath>

#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/core/stereo_geometry.h"

using stereo_pf::Pixel;
using stereo_pf::StereoGeometry;

namespace
{
StereoGeometry rig()
{
  return StereoGeometry(525.0, 525.0, 319.5, 239.5, 0.09, 640, 480);
}
}  // namespace

TEST(Geometry, ProjectsKnownPoint)
{
  const StereoGeometry g = rig();
  const Eigen::Vector3d p(0.1, -0.05, 1.0);
  const Pixel l = g.projectLeft(p), r = g.projectRight(p);
  EXPECT_NEAR(l.u, 319.5 + 52.5, 1e-9);
  EXPECT_NEAR(l.v, 239.5 - 26.25, 1e-9);
  EXPECT_NEAR(l.u - r.u, 525.0 * 0.09 / 1.0, 1e-9);  // disparity = f b / z
  EXPECT_DOUBLE_EQ(l.v, r.v);                        // rectified: same row
  EXPECT_NEAR(g.apparentRadius(0.035, 1.0), 18.375, 1e-9);
}

TEST(Geometry, TriangulationRoundTrip)
{
  const StereoGeometry g = rig();
  for (double z : { 0.3, 0.8, 1.7, 4.0 })
    for (double x : { -0.4, 0.0, 0.25 })
      for (double y : { -0.2, 0.1 })
      {
        const Eigen::Vector3d p(x * z, y * z, z);
        Eigen::Vector3d q;
        ASSERT_TRUE(g.triangulate(g.projectLeft(p), g.projectRight(p).u, q));
        EXPECT_LT((p - q).norm(), 1e-9 * z);
      }
}

TEST(Geometry, TriangulationRejectsNonPositiveDisparity)
{
  const StereoGeometry g = rig();
  Eigen::Vector3d q(1, 2, 3);
  EXPECT_FALSE(g.triangulate({ 100, 100 }, 100, q));
  EXPECT_FALSE(g.triangulate({ 100, 100 }, 120, q));
  EXPECT_EQ(q, Eigen::Vector3d(1, 2, 3));
}

TEST(Geometry, Visibility)
{
  const StereoGeometry g = rig();
  EXPECT_TRUE(g.visible({ 0.0, 0.0, 1.0 }));
  EXPECT_FALSE(g.visible({ 0.0, 0.0, -1.0 }));  // behind
  // Seen by the left camera at its right edge, but the right camera (shifted +b) sees it further left,
  // while a point at the left edge of the left image falls outside the right image.
  const Eigen::Vector3d left_edge = g.backProject({ 2.0, 240.0 }, 1.0);
  EXPECT_TRUE(g.inImage(g.projectLeft(left_edge)));
  EXPECT_FALSE(g.visible(left_edge));
}

TEST(Geometry, RangeResolutionGrowsWithSquareOfDepth)
{
  // dr = r^2 / (b f) * dd (thesis 6.1): one pixel of disparity matters 4x more at twice the depth.
  const StereoGeometry g = rig();
  auto dr = [&](double z) { return g.depth(g.disparity(z) - 1.0) - z; };
  EXPECT_NEAR(dr(2.0) / dr(1.0), 4.0, 0.15);
}

TEST(Geometry, ValidateExplains)
{
  EXPECT_TRUE(rig().valid());
  EXPECT_NE(StereoGeometry(0, 525, 320, 240, 0.09, 640, 480).validate().find("focal"), std::string::npos);
  EXPECT_NE(StereoGeometry(525, 525, 320, 240, 0.0, 640, 480).validate().find("baseline"), std::string::npos);
  EXPECT_NE(StereoGeometry(525, 525, NAN, 240, 0.09, 640, 480).validate().find("principal"), std::string::npos);
  EXPECT_NE(StereoGeometry(525, 525, 320, 240, 0.09, 0, 480).validate().find("size"), std::string::npos);
}

TEST(StereoFrame, ValidateCatchesBadFrames)
{
  stereo_pf::StereoFrame f;
  f.geometry = rig();
  f.left = cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0));
  f.right = cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0));
  EXPECT_EQ(f.validate(), "");
  f.right = cv::Mat(240, 320, CV_8UC3);
  EXPECT_NE(f.validate().find("differ"), std::string::npos);
  f.right = cv::Mat(480, 640, CV_16UC1);
  EXPECT_FALSE(f.validate().empty());
  f.left = cv::Mat(240, 320, CV_8UC3);
  f.right = cv::Mat(240, 320, CV_8UC3);
  EXPECT_NE(f.validate().find("calibration"), std::string::npos);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
