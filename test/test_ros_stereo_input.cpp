// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Unit tests (no roscore) of the nodelet's building blocks: frame validation and rectification
// (StereoInput), the parameter-server conversion (mergeXmlRpc) and the output messages.
#include <cmath>

#include <gtest/gtest.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <thread>

#include "stereo_pf/ros/frame_slot.h"
#include "stereo_pf/ros/ros_parameters.h"
#include "stereo_pf/ros/stereo_input.h"
#include "stereo_pf/ros/tracker_outputs.h"

namespace
{
using namespace stereo_pf;

sensor_msgs::CameraInfoPtr info(bool right, double k1 = 0.0, int width = 64, int height = 48)
{
  auto c = boost::make_shared<sensor_msgs::CameraInfo>();
  c->header.stamp = ros::Time(10.0);
  c->header.frame_id = "cam";
  c->width = width;
  c->height = height;
  c->distortion_model = "plumb_bob";
  c->D = { k1, 0.0, 0.0, 0.0, 0.0 };
  const double f = 50.0, cx = (width - 1) / 2.0, cy = (height - 1) / 2.0;
  c->K = { f, 0, cx, 0, f, cy, 0, 0, 1 };
  c->R = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
  c->P = { f, 0, cx, right ? -f * 0.1 : 0.0, 0, f, cy, 0, 0, 0, 1, 0 };
  return c;
}

sensor_msgs::ImagePtr image(int width = 64, int height = 48, const std::string& encoding = "bgr8")
{
  auto m = boost::make_shared<sensor_msgs::Image>();
  m->header.stamp = ros::Time(10.0);
  m->header.frame_id = "cam";
  m->width = width;
  m->height = height;
  m->encoding = encoding;
  m->step = width * sensor_msgs::image_encodings::numChannels(encoding) *
            sensor_msgs::image_encodings::bitDepth(encoding) / 8;
  m->data.resize(static_cast<size_t>(m->step) * height);
  for (size_t i = 0; i < m->data.size(); ++i)
    m->data[i] = static_cast<uint8_t>((i * 7) % 251);  // a pattern, so remapping changes pixels
  return m;
}

struct Result
{
  bool ok;
  DropReason reason;
  std::string why;
  StereoFrame frame;
};

Result run(StereoInput& input, const sensor_msgs::ImageConstPtr& l, const sensor_msgs::ImageConstPtr& r,
           const sensor_msgs::CameraInfoConstPtr& li, const sensor_msgs::CameraInfoConstPtr& ri)
{
  Result res{ false, DropReason::Count, "", StereoFrame() };
  res.ok = input.assemble(l, r, li, ri, res.frame, res.reason, res.why);
  return res;
}
}  // namespace

TEST(StereoInput, AcceptsARectifiedPairWithoutCopying)
{
  StereoInput input;
  auto l = image(), r = image();
  const Result res = run(input, l, r, info(false), info(true));
  ASSERT_TRUE(res.ok) << res.why;
  EXPECT_EQ(res.frame.left.data, l->data.data()) << "bgr8 with an identity calibration must be shared, not copied";
  EXPECT_DOUBLE_EQ(res.frame.stamp, 10.0);
  EXPECT_NEAR(res.frame.geometry.baseline(), 0.1, 1e-9);
}

TEST(StereoInput, RectifiesRawImagesWithDistortion)
{
  StereoInput input;
  auto l = image(), r = image();
  const Result res = run(input, l, r, info(false, -0.3), info(true, -0.3));
  ASSERT_TRUE(res.ok) << res.why;
  EXPECT_NE(res.frame.left.data, l->data.data());
  EXPECT_EQ(res.frame.left.cols, 64);
  EXPECT_EQ(res.frame.left.rows, 48);
  const cv::Mat raw(48, 64, CV_8UC3, l->data.data());
  EXPECT_GT(cv::norm(raw, res.frame.left, cv::NORM_L1), 0.0) << "the distortion was not removed";

  // Already-rectified input (stereo_image_proc): never remapped, whatever camera_info says.
  StereoInput rectified(StereoInputOptions{ true, 0.0 });
  const Result same = run(rectified, l, r, info(false, -0.3), info(true, -0.3));
  ASSERT_TRUE(same.ok) << same.why;
  EXPECT_EQ(same.frame.left.data, l->data.data());
}

TEST(StereoInput, ConvertsOtherEncodings)
{
  StereoInput input;
  const Result res = run(input, image(64, 48, "rgb8"), image(64, 48, "rgb8"), info(false), info(true));
  ASSERT_TRUE(res.ok) << res.why;
  EXPECT_EQ(res.frame.left.type(), CV_8UC3);
}

TEST(StereoInput, RejectsBadFramesWithAReason)
{
  StereoInput input;
  EXPECT_EQ(run(input, image(), image(32, 48), info(false), info(true)).reason, DropReason::SizeMismatch);
  EXPECT_EQ(run(input, image(32, 24), image(32, 24), info(false), info(true)).reason, DropReason::SizeMismatch);

  auto truncated = image();
  truncated->data.resize(100);
  EXPECT_EQ(run(input, truncated, image(), info(false), info(true)).reason, DropReason::BadImage);
  auto short_step = image();
  short_step->step = 10;
  EXPECT_EQ(run(input, short_step, image(), info(false), info(true)).reason, DropReason::BadImage);
  EXPECT_EQ(run(input, image(64, 48, "32FC1"), image(64, 48, "32FC1"), info(false), info(true)).reason,
            DropReason::BadImage);
  auto unknown = image();
  unknown->encoding = "no_such_encoding";
  const Result u = run(input, unknown, image(), info(false), info(true));
  EXPECT_EQ(u.reason, DropReason::BadImage);
  EXPECT_NE(u.why.find("no_such_encoding"), std::string::npos) << u.why;

  auto nan_info = info(true);
  nan_info->P[0] = std::nan("");
  EXPECT_EQ(run(input, image(), image(), info(false), nan_info).reason, DropReason::BadCameraInfo);
  auto nan_k = info(false);
  nan_k->K[2] = std::nan("");
  EXPECT_EQ(run(input, image(), image(), nan_k, info(true)).reason, DropReason::BadCameraInfo);
  auto uncalibrated = boost::make_shared<sensor_msgs::CameraInfo>();
  EXPECT_EQ(run(input, image(), image(), uncalibrated, info(true)).reason, DropReason::BadCameraInfo);
  auto no_baseline = info(true);
  no_baseline->P[3] = 0.0;
  EXPECT_EQ(run(input, image(), image(), info(false), no_baseline).reason, DropReason::BadCameraInfo);
  EXPECT_EQ(run(input, image(), image(), nullptr, info(true)).reason, DropReason::OutOfSync);

  auto late = image();
  late->header.stamp = ros::Time(10.02);
  EXPECT_EQ(run(input, image(), late, info(false), info(true)).reason, DropReason::OutOfSync);
  StereoInput tolerant(StereoInputOptions{ false, 0.05 });
  EXPECT_TRUE(run(tolerant, image(), late, info(false), info(true)).ok);

  // A good frame after all that still works.
  EXPECT_TRUE(run(input, image(), image(), info(false), info(true)).ok);
}

// Issue 12: three frames with an all-zero K/P (or sizes that differ) and every later good frame was dropped
// ("image_geometry rejected the camera_info pair"): fromCameraInfo reports a change, not validity.
TEST(StereoInput, AGoodCalibrationWorksAgainRightAfterBadOnes)
{
  StereoInput input;
  ASSERT_TRUE(run(input, image(), image(), info(false), info(true)).ok);
  auto zero = info(true);
  std::fill(zero->K.begin(), zero->K.end(), 0.0);
  std::fill(zero->P.begin(), zero->P.end(), 0.0);
  for (int k = 0; k < 3; ++k)
  {
    const Result bad = run(input, image(), image(), info(false), zero);
    EXPECT_EQ(bad.reason, DropReason::BadCameraInfo);
    EXPECT_NE(bad.why.find("right camera_info has no calibration (P is all zero"), std::string::npos) << bad.why;
  }
  const Result good = run(input, image(), image(), info(false), info(true));
  EXPECT_TRUE(good.ok) << good.why;

  auto small = info(true, 0.0, 32, 24);
  for (int k = 0; k < 3; ++k)
  {
    const Result bad = run(input, image(), image(), info(false), small);
    EXPECT_EQ(bad.reason, DropReason::BadCameraInfo);
    EXPECT_NE(bad.why.find("sizes differ (64x48 vs 32x24)"), std::string::npos) << bad.why;
  }
  EXPECT_TRUE(run(input, image(), image(), info(false), info(true)).ok);
  // With distortion (the maps are rebuilt) as well.
  EXPECT_TRUE(run(input, image(), image(), info(false, -0.3), info(true, -0.3)).ok);
  for (int k = 0; k < 3; ++k)
    EXPECT_FALSE(run(input, image(), image(), info(false, -0.3), zero).ok);
  EXPECT_TRUE(run(input, image(), image(), info(false, -0.3), info(true, -0.3)).ok);

  // The calibration object on its own (StereoInput checks first, so it rarely sees a bad pair).
  StereoCalibration calibration;
  std::string error;
  ASSERT_TRUE(calibration.update(*info(false), *info(true), error)) << error;
  EXPECT_FALSE(calibration.update(*info(false), *small, error));
  EXPECT_TRUE(calibration.update(*info(false), *info(true), error)) << error;
  EXPECT_TRUE(calibration.valid());
}

TEST(StereoInput, EachCameraInfoIsValidatedAndTheMessageSaysWhatToDo)
{
  StereoInput input;
  auto expectDrop = [&](const sensor_msgs::CameraInfoConstPtr& l, const sensor_msgs::CameraInfoConstPtr& r,
                        const std::string& says) {
    const Result res = run(input, image(), image(), l, r);
    EXPECT_FALSE(res.ok) << says;
    EXPECT_EQ(res.reason, DropReason::BadCameraInfo) << res.why;
    EXPECT_NE(res.why.find(says), std::string::npos) << res.why;
  };
  // K = 0 with a valid P: raw images cannot be rectified.
  auto k_zero = info(false);
  std::fill(k_zero->K.begin(), k_zero->K.end(), 0.0);
  expectDrop(k_zero, info(true), "left camera_info has K all zero (P is set)");
  // ... but stereo_image_proc's rectified images need only P: accepted, with a note.
  StereoInput rectified(StereoInputOptions{ true, 0.0 });
  const Result ok = run(rectified, image(), image(), k_zero, info(true));
  EXPECT_TRUE(ok.ok) << ok.why;
  ASSERT_EQ(rectified.notes().size(), 1u);
  EXPECT_NE(rectified.notes()[0].find("K all zero"), std::string::npos);

  auto negative_f = info(false);
  negative_f->K[0] = -50.0;
  expectDrop(negative_f, info(true), "non-positive focal length in K");
  auto size_only = boost::make_shared<sensor_msgs::CameraInfo>();
  size_only->width = 64;
  size_only->height = 48;
  expectDrop(info(false), size_only, "right camera_info has no calibration");
  expectDrop(info(false), boost::make_shared<sensor_msgs::CameraInfo>(), "right camera_info has no image size");
  auto nan_d = info(false, 0.1);
  nan_d->D[1] = std::nan("");
  expectDrop(nan_d, info(true), "left camera_info contains D[1] = nan");
  auto skewed_r = info(false);
  skewed_r->R[1] = 0.5;
  expectDrop(skewed_r, info(true), "R that is not a rotation");
  auto other_f = info(true);
  other_f->P[0] = 60.0;
  expectDrop(info(false), other_f, "rectified focal lengths differ");
  auto other_row = info(true);
  other_row->P[6] += 3.0;
  expectDrop(info(false), other_row, "different rows");
  auto swapped = info(true);
  swapped->P[3] = +5.0;
  expectDrop(info(false), swapped, "left and right topics swapped");
  auto no_baseline = info(true);
  no_baseline->P[3] = 0.0;
  expectDrop(info(false), no_baseline, "no baseline");

  // Odd but usable: frame_ids that differ are said, not dropped.
  auto other_frame = info(true);
  other_frame->header.frame_id = "right_cam";
  EXPECT_TRUE(run(input, image(), image(), info(false), other_frame).ok);
  ASSERT_FALSE(input.notes().empty());
  EXPECT_NE(input.notes()[0].find("frame_ids differ ('cam' vs 'right_cam')"), std::string::npos);
  EXPECT_TRUE(run(input, image(), image(), info(false), info(true)).ok);
  EXPECT_TRUE(input.notes().empty());
}

// The drop policy under overload: the receiver never waits, the worker gets the newest frame, every frame
// replaced before the worker took it is counted, and nothing else is lost.
TEST(LatestSlot, KeepsTheNewestAndCountsWhatItReplaced)
{
  LatestSlot<int> slot;
  EXPECT_FALSE(slot.put(1));
  EXPECT_TRUE(slot.put(2));  // 1 was never taken
  EXPECT_TRUE(slot.put(3));
  int item = 0;
  ASSERT_TRUE(slot.take(item));
  EXPECT_EQ(item, 3);
  EXPECT_FALSE(slot.put(4));
  ASSERT_TRUE(slot.take(item));
  EXPECT_EQ(item, 4);
  EXPECT_EQ(slot.putCount(), 4u);
  EXPECT_EQ(slot.replacedCount(), 2u);

  // A slow worker and a fast producer: taken + replaced = put, and the last one is always taken.
  LatestSlot<int> busy;
  std::vector<int> taken;
  std::thread worker([&] {
    int x = 0;
    while (busy.take(x))
    {
      taken.push_back(x);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  for (int k = 1; k <= 200; ++k)
  {
    busy.put(k);
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  while (busy.putCount() != taken.size() + busy.replacedCount())
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  busy.close();
  worker.join();
  EXPECT_GT(busy.replacedCount(), 0u);
  EXPECT_EQ(taken.size() + busy.replacedCount(), 200u);
  EXPECT_EQ(taken.back(), 200);
  EXPECT_TRUE(std::is_sorted(taken.begin(), taken.end()));
  EXPECT_FALSE(busy.take(item)) << "take() after close()";
}

TEST(TrackerOutputs, TheStatusMessageSaysWhatToDo)
{
  const ViewingVolume volume(StereoGeometry(525, 525, 319.5, 239.5, 0.09, 640, 480), 0.5);
  FrameResult r;
  r.state = TrackState::Searching;
  r.support = Support::LikeBackground;
  r.evidence = 0.95;
  r.background = 0.93;
  const std::string background = describeTrack(r, EngineConfig(), volume);
  EXPECT_NE(background.find("learn it again with ~set_target"), std::string::npos) << background;
  r.state = TrackState::Lost;
  r.support = Support::OutsideView;
  const std::string outside = describeTrack(r, EngineConfig(), volume);
  EXPECT_NE(outside.find("left what the cameras can see (near 0.0738 m, far 94.5 m, disparity 640 .. 0.5 px)"), std::string::npos) << outside;
  r.state = TrackState::Tracking;
  r.support = Support::Seen;
  r.state_frames = 12;
  EXPECT_NE(describeTrack(r, EngineConfig(), volume).find("tracking for 12 frames"), std::string::npos);
  // A frame of the track that does not see the object says that it gives no estimate (FrameResult::published()).
  r.estimate.valid = true;
  ASSERT_TRUE(r.published());
  r.support = Support::LowEvidence;
  r.evidence = 0.2;
  ASSERT_FALSE(r.published());
  const std::string unseen = describeTrack(r, EngineConfig(), volume);
  EXPECT_NE(unseen.find("tracking: the target is not seen"), std::string::npos) << unseen;
  EXPECT_NE(unseen.find("no estimate this frame"), std::string::npos) << unseen;
  // ... unless it still sees the object faintly (engine/estimate_similarity): then the estimate is given.
  r.evidence = 0.35;
  r.faint = true;
  ASSERT_TRUE(r.published());
  const std::string faint = describeTrack(r, EngineConfig(), volume);
  EXPECT_NE(faint.find("seen faintly"), std::string::npos) << faint;
  EXPECT_EQ(faint.find("no estimate this frame"), std::string::npos) << faint;
}

TEST(RosParameters, FlattensLikeTheYamlLoader)
{
  XmlRpc::XmlRpcValue root;
  root["engine"]["particles"] = 500;
  root["engine"]["resample_threshold"] = 0.5;
  root["colour"]["enabled"] = false;
  root["state_model"]["type"] = std::string("stereo_pf/Position3D");
  XmlRpc::XmlRpcValue models;
  models[0]["name"] = std::string("colour");
  models[0]["type"] = std::string("stereo_pf/ColourHSI");
  models[1]["name"] = std::string("shape");
  models[1]["type"] = std::string("stereo_pf/ShapeCircle");
  root["observation_models"] = models;
  root["target_roi"][0] = 1;
  root["target_roi"][1] = 2.5;
  root["colour"]["sigma"] = -1.0;  // a reconfigure "unchanged" value: skipped below

  Parameters p;
  mergeXmlRpc(root, "", p, [](const std::string& key, const XmlRpc::XmlRpcValue&) { return key == "colour/sigma"; });
  EXPECT_EQ(p.getInt("engine/particles", 0, 0, 10000), 500);
  EXPECT_DOUBLE_EQ(p.getDouble("engine/resample_threshold", 0, 0, 1), 0.5);
  EXPECT_FALSE(p.getBool("colour/enabled", true));
  EXPECT_EQ(p.raw("state_model/type"), "stereo_pf/Position3D");
  EXPECT_EQ(p.raw("observation_models/1/type"), "stereo_pf/ShapeCircle");
  EXPECT_EQ(p.raw("observation_models/0/name"), "colour");
  EXPECT_EQ(p.getDoubles("target_roi", {}), (std::vector<double>{ 1.0, 2.5 }));
  EXPECT_FALSE(p.has("colour/sigma"));
}

TEST(TrackerOutputs, CloudMergesResampledCopiesAndSumsTheirWeights)
{
  Eigen::MatrixX3d points(4, 3);
  points << 0, 0, 1, 0, 0, 1, 0.1, 0, 1, std::nan(""), 0, 1;
  Eigen::VectorXd weights(4);
  weights << 0.25, 0.25, 0.25, 0.25;
  std::vector<Eigen::Vector3f> merged;
  std::vector<float> merged_w;
  mergeDuplicates(points, weights, merged, merged_w);
  ASSERT_EQ(merged.size(), 2u);
  EXPECT_FLOAT_EQ(merged_w[0], 0.5f);
  EXPECT_FLOAT_EQ(merged_w[1], 0.25f);

  std_msgs::Header h;
  h.frame_id = "cam";
  sensor_msgs::PointCloud2 cloud;
  toCloud(h, merged, merged_w, cloud);
  EXPECT_EQ(cloud.width, 2u);
  ASSERT_EQ(cloud.fields.size(), 4u);
  EXPECT_EQ(cloud.fields[3].name, "weight");
  sensor_msgs::PointCloud2ConstIterator<float> w(cloud, "weight");
  EXPECT_FLOAT_EQ(*w, 0.5f);
}

TEST(TrackerOutputs, CovarianceEllipsoidFollowsTheEigenvectors)
{
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov(0, 0) = 0.01;  // sigma 0.1 along x
  cov(1, 1) = 0.0001;
  cov(2, 2) = 0.0004;
  Eigen::Vector3d scale;
  Eigen::Vector4d q;
  covarianceEllipsoid(cov, 2.0, scale, q);
  std::vector<double> s = { scale.x(), scale.y(), scale.z() };
  std::sort(s.begin(), s.end());
  EXPECT_NEAR(s[2], 0.4, 1e-9);  // 2 sigma on each side of the centre
  EXPECT_NEAR(s[0], 0.04, 1e-9);
  EXPECT_NEAR(q.norm(), 1.0, 1e-9);

  covarianceEllipsoid(Eigen::Matrix3d::Constant(std::nan("")), 2.0, scale, q);
  EXPECT_TRUE(scale.allFinite());
  EXPECT_TRUE(q.allFinite());
}

TEST(TrackerOutputs, MarkersDeleteTheEstimateWhenInvalid)
{
  std_msgs::Header h;
  h.frame_id = "cam";
  FrameResult r;
  r.estimate.valid = false;
  EstimateTrail trail(3);
  for (int i = 0; i < 5; ++i)
    trail.add(Eigen::Vector3d(i, 0, 1));
  EXPECT_EQ(trail.points().size(), 3u);
  const visualization_msgs::MarkerArray m = toMarkers(h, r, trail, MarkerOptions());
  int deletes = 0, lines = 0;
  for (const auto& marker : m.markers)
  {
    deletes += marker.action == visualization_msgs::Marker::DELETE;
    lines += marker.ns == "trajectory" && marker.points.size() == 3;
  }
  EXPECT_EQ(deletes, 3);
  EXPECT_EQ(lines, 1);
}

// image_geometry asserts that both cameras share their frame and P's fx, fy and cy; with asserts compiled in
// (Debian) a camera_info pair that differs there used to abort the whole nodelet manager.
TEST(StereoInput, CameraInfoThatImageGeometryAssertsOnIsHandled)
{
  StereoInput input;
  for (const int index : { 0, 5, 6 })  // fx, fy, cy of P
  {
    auto right = info(true);
    right->P[index] *= 2.0;
    const Result res = run(input, image(), image(), info(false), right);
    EXPECT_FALSE(res.ok);
    EXPECT_EQ(res.reason, DropReason::BadCameraInfo);
    EXPECT_NE(res.why.find("not a rectified stereo pair"), std::string::npos) << res.why;
  }
  // Separate frames per camera, as some drivers publish: results are in the left frame, so that is fine.
  auto right_frame = info(true);
  right_frame->header.frame_id = "right_cam";
  const Result other_frame = run(input, image(), image(), info(false), right_frame);
  EXPECT_TRUE(other_frame.ok) << other_frame.why;
  // A calibration refused after image_geometry took it in, then sent again, is refused for the same reason.
  auto no_baseline = info(true);
  no_baseline->P[3] = 0.0;
  const Result first = run(input, image(), image(), info(false), no_baseline);
  const Result again = run(input, image(), image(), info(false), no_baseline);
  EXPECT_EQ(first.reason, DropReason::BadCameraInfo);
  EXPECT_EQ(again.why, first.why);
  EXPECT_TRUE(run(input, image(), image(), info(false), info(true)).ok);
}

TEST(TrackerOutputs, MarkersCarryTheParticlesColouredByWeight)
{
  std_msgs::Header h;
  h.frame_id = "cam";
  FrameResult r;
  r.estimate.valid = true;
  r.estimate.position = Eigen::Vector3d(0, 0, 1);
  r.estimate.covariance = Eigen::Matrix3d::Identity() * 1e-4;
  const std::vector<Eigen::Vector3f> points = { { 0, 0, 1 }, { 0.1f, 0, 1 }, { 0, 0.1f, 1 } };
  const std::vector<float> weights = { 0.02f, 0.9f, 0.08f };
  const visualization_msgs::MarkerArray none = toMarkers(h, r, EstimateTrail(), MarkerOptions());
  for (const auto& m : none.markers)
    EXPECT_NE(m.ns, "particles");
  const visualization_msgs::MarkerArray m = toMarkers(h, r, EstimateTrail(), MarkerOptions(), &points, &weights);
  const visualization_msgs::Marker* cloud = nullptr;
  for (const auto& marker : m.markers)
    if (marker.ns == "particles")
      cloud = &marker;
  ASSERT_NE(cloud, nullptr);
  EXPECT_EQ(cloud->type, visualization_msgs::Marker::POINTS);
  ASSERT_EQ(cloud->points.size(), 3u);
  ASSERT_EQ(cloud->colors.size(), 3u);
  EXPECT_FLOAT_EQ(cloud->points[1].x, 0.1f);
  EXPECT_FLOAT_EQ(cloud->colors[1].r, 1.0f);  // the heaviest: red
  EXPECT_FLOAT_EQ(cloud->colors[1].b, 0.0f);
  EXPECT_GT(cloud->colors[0].b, 0.9f);        // light: blue
  EXPECT_LT(cloud->colors[0].r, 0.1f);
  EXPECT_EQ(cloud->header.frame_id, "cam");
}

TEST(StereoInput, StampOrderDropsLateAndRepeatedFramesAndRestartsWhenTimeStaysBack)
{
  using V = StampOrder::Verdict;
  StampOrder order(3);
  std::string why;
  EXPECT_EQ(order.check(10.0, why), V::Accept);  // the first frame, whatever its stamp
  EXPECT_EQ(order.check(10.1, why), V::Accept);
  EXPECT_EQ(order.check(9.6, why), V::Drop);  // late
  EXPECT_NE(why.find("0.500 s before the last frame tracked"), std::string::npos) << why;
  EXPECT_EQ(order.check(10.1, why), V::Drop);  // repeated
  EXPECT_NE(why.find("repeated"), std::string::npos) << why;
  EXPECT_EQ(order.check(10.2, why), V::Accept);  // a newer frame: the run of stale ones is over
  EXPECT_EQ(order.check(9.0, why), V::Drop);
  EXPECT_EQ(order.check(10.2, why), V::Drop);
  EXPECT_EQ(order.check(10.3, why), V::Accept);
  // A bag played again: its first frames are dropped, the third is taken and restarts the track.
  EXPECT_EQ(order.check(1.0, why), V::Drop);
  EXPECT_EQ(order.check(1.1, why), V::Drop);
  EXPECT_EQ(order.check(1.2, why), V::Restart);
  EXPECT_NE(why.find("went back 9.100 s"), std::string::npos) << why;
  EXPECT_EQ(order.check(1.3, why), V::Accept);  // and then runs on from there
  EXPECT_EQ(order.check(1.2, why), V::Drop);
  // A camera stamping every frame alike loses two frames, then every frame is tracked: never a stall.
  StampOrder still(3);
  EXPECT_EQ(still.check(0.0, why), V::Accept);
  EXPECT_EQ(still.check(0.0, why), V::Drop);
  EXPECT_EQ(still.check(0.0, why), V::Drop);
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(still.check(0.0, why), V::Accept) << i;
  // ... and a late frame among them is dropped as late, not taken for time gone back.
  EXPECT_EQ(still.check(-0.1, why), V::Drop);
  EXPECT_NE(why.find("late"), std::string::npos) << why;
  EXPECT_EQ(still.check(0.0, why), V::Drop);  // the run of frames stamped alike starts again
}

TEST(TrackerOutputs, TrailStartsAfreshOnTimeJumpsGapsAndLoss)
{
  EstimateTrail trail(90, 1.0);
  double t = 100.0;
  for (int i = 0; i < 5; ++i, t += 0.033)
    trail.update(t, Eigen::Vector3d(i, 0, 1), true);
  EXPECT_EQ(trail.points().size(), 5u);
  trail.update(50.0, Eigen::Vector3d(0, 0, 1), true);  // time went back: a bag played again
  EXPECT_EQ(trail.points().size(), 1u);
  trail.update(50.033, Eigen::Vector3d(0, 0, 1), true);
  trail.update(50.033, Eigen::Vector3d(0, 0, 1), true);  // the same stamp again
  EXPECT_EQ(trail.points().size(), 1u);
  trail.update(50.066, Eigen::Vector3d(0, 0, 1), true);
  EXPECT_EQ(trail.points().size(), 2u);
  trail.update(52.0, Eigen::Vector3d(0, 0, 1), true);  // no estimate for more than max_gap
  EXPECT_EQ(trail.points().size(), 1u);
  trail.update(52.033, Eigen::Vector3d(0, 0, 1), true);
  trail.update(52.066, Eigen::Vector3d(3, 0, 1), false);  // not tracked: the search is not drawn
  EXPECT_TRUE(trail.points().empty());
  trail.update(52.1, Eigen::Vector3d(3, 0, 1), true);
  EXPECT_EQ(trail.points().size(), 1u);
  EstimateTrail short_trail(3);
  for (int i = 0; i < 5; ++i)
    short_trail.update(i * 0.033, Eigen::Vector3d(i, 0, 1), true);
  ASSERT_EQ(short_trail.points().size(), 3u);
  EXPECT_EQ(short_trail.points().front().x(), 2.0);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::Time::init();
  return RUN_ALL_TESTS();
}
