// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/conversions.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Core>
#include <Eigen/LU>
#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

namespace stereo_pf
{
namespace
{
template <class T>
bool allFinite(const T& values, std::string& which, const char* name)
{
  for (size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
    {
      which = std::string(name) + "[" + std::to_string(i) + "] = " + std::to_string(values[i]);
      return false;
    }
  return true;
}

template <class T>
bool allZero(const T& values)
{
  return std::all_of(values.begin(), values.end(), [](double v) { return v == 0.0; });
}

std::string number(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

const char* const kCalibrate = "calibrate the camera (camera_calibration) and give the driver the file "
                               "(camera_info_url)";
}  // namespace

std::string checkCameraInfo(const sensor_msgs::CameraInfo& c, const std::string& side, bool rectified)
{
  const std::string who = side + " camera_info";
  if (c.width == 0 || c.height == 0)
    return who + " has no image size (" + std::to_string(c.width) + "x" + std::to_string(c.height) +
           "): the camera is not calibrated or its driver publishes no calibration; " + kCalibrate;
  std::string which;
  if (!allFinite(c.K, which, "K") || !allFinite(c.D, which, "D") || !allFinite(c.R, which, "R") ||
      !allFinite(c.P, which, "P"))
    return who + " contains " + which + ": the calibration is corrupt; " + kCalibrate;
  if (allZero(c.P))
    return who + " has no calibration (P is all zero, only the size is set: a driver whose calibration file does "
                 "not match the camera publishes this); " + kCalibrate;
  if (!(c.P[0] > 0.0) || !(c.P[5] > 0.0))
    return who + " has a non-positive rectified focal length (P[0] = " + number(c.P[0]) + ", P[5] = " +
           number(c.P[5]) + "); " + kCalibrate;
  if (!rectified)
  {
    // The rectification maps are built from K: without it raw images cannot be rectified.
    if (allZero(c.K))
      return who + " has K all zero (P is set): raw images cannot be rectified without K; publish the full "
                   "calibration, or set ~images_rectified: true if these images are already rectified";
    if (!(c.K[0] > 0.0) || !(c.K[4] > 0.0))
      return who + " has a non-positive focal length in K (K[0] = " + number(c.K[0]) + ", K[4] = " +
             number(c.K[4]) + "); " + kCalibrate;
  }
  if (!allZero(c.R))
  {
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> r(c.R.data());
    const double off = (r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (off > 1e-3 || r.determinant() < 0.0)
      return who + " has an R that is not a rotation (|R R^T - I| up to " + number(off) + ", det " +
             number(r.determinant()) + "); " + kCalibrate;
  }
  return "";
}

std::string checkCameraInfoPair(const sensor_msgs::CameraInfo& l, const sensor_msgs::CameraInfo& r)
{
  if (l.width != r.width || l.height != r.height)
    return "left and right camera_info sizes differ (" + std::to_string(l.width) + "x" + std::to_string(l.height) +
           " vs " + std::to_string(r.width) + "x" + std::to_string(r.height) +
           "): both cameras must run at the same resolution (check the driver's video mode)";
  auto differs = [](double a, double b, double tolerance) { return std::fabs(a - b) > tolerance; };
  if (differs(l.P[0], r.P[0], 1e-3 * l.P[0]) || differs(l.P[5], r.P[5], 1e-3 * l.P[5]))
    return "the rectified focal lengths differ (left P[0], P[5] = " + number(l.P[0]) + ", " + number(l.P[5]) +
           "; right " + number(r.P[0]) + ", " + number(r.P[5]) +
           "): not a rectified stereo pair; calibrate the two cameras together (camera_calibration with both)";
  if (differs(l.P[6], r.P[6], 0.5))
    return "the rectified principal points are on different rows (left P[6] = " + number(l.P[6]) + ", right " +
           number(r.P[6]) + "): not a rectified stereo pair; calibrate the two cameras together";
  // Right P[3] = -fx * baseline: negative for a right camera at +x of the left one.
  const double tx = r.P[3] - l.P[3];
  if (tx == 0.0)
    return "the right camera_info has no baseline (P[3] = " + number(r.P[3]) +
           "; it must be -fx * baseline): calibrate the two cameras together, or check that the right topic "
           "carries the right camera's calibration";
  if (tx > 0.0)
    return "the right camera_info's P[3] = " + number(r.P[3]) +
           " is positive: the right camera is to the left of the left one; are the left and right topics swapped? "
           "remap them";
  return "";
}

std::vector<std::string> cameraInfoNotes(const sensor_msgs::CameraInfo& l, const sensor_msgs::CameraInfo& r,
                                         bool rectified)
{
  std::vector<std::string> notes;
  if (l.header.frame_id != r.header.frame_id)
    notes.push_back("the left and right camera_info frame_ids differ ('" + l.header.frame_id + "' vs '" +
                    r.header.frame_id + "'): the estimate is published in the left images' frame");
  if (rectified && (allZero(l.K) || allZero(r.K)))
    notes.push_back("a camera_info has K all zero: ignored, since ~images_rectified is set and P gives the geometry");
  if (std::fabs(l.P[2] - r.P[2]) > 0.5)
    notes.push_back("the rectified principal points are in different columns (left P[2] = " + number(l.P[2]) +
                    ", right " + number(r.P[2]) + "): the tracker assumes they are equal, so depths are biased; "
                    "calibrate with zero disparity (camera_calibration's default)");
  return notes;
}

namespace
{
bool sameCalibration(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b)
{
  return a.width == b.width && a.height == b.height && a.K == b.K && a.D == b.D && a.R == b.R && a.P == b.P &&
         a.distortion_model == b.distortion_model;
}

bool isIdentityRectification(const sensor_msgs::CameraInfo& c)
{
  for (double d : c.D)
    if (d != 0.0)
      return false;
  // R identity, or all zero (unset, which image_geometry also treats as no rotation).
  const double identity[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
  bool is_identity = true, is_zero = true;
  for (int i = 0; i < 9; ++i)
  {
    is_identity = is_identity && c.R[i] == identity[i];
    is_zero = is_zero && c.R[i] == 0.0;
  }
  if (!is_identity && !is_zero)
    return false;
  // K must equal the left 3x3 of P for the raw image to already be the rectified one.
  return c.K[0] == c.P[0] && c.K[2] == c.P[2] && c.K[4] == c.P[5] && c.K[5] == c.P[6];
}
}  // namespace

bool StereoCalibration::update(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right,
                               std::string& error)
{
  if (valid_ && sameCalibration(left, last_left_) && sameCalibration(right, last_right_))
    return true;
  valid_ = false;
  if (left.width != right.width || left.height != right.height)
  {
    error = "left and right camera_info sizes differ (" + std::to_string(left.width) + "x" +
            std::to_string(left.height) + " vs " + std::to_string(right.width) + "x" + std::to_string(right.height) + ")";
    return false;
  }
  for (double v : left.P)
    if (!std::isfinite(v))
      return error = "left camera_info P contains NaN or infinity", false;
  for (double v : right.P)
    if (!std::isfinite(v))
      return error = "right camera_info P contains NaN or infinity", false;
  if (left.P[0] == 0.0 || right.P[0] == 0.0)
  {
    error = "camera_info has a zero focal length in P (uncalibrated camera?)";
    return false;
  }
  // Sizes, finiteness and focal length are checked above; the pair's consistency here, since bag reading calls
  // this directly. image_geometry asserts (in Debian's build a failed assert aborts the whole nodelet manager)
  // that both cameras share their frame_id and P's fx, fy and cy exactly: the right camera's frame (unused:
  // results are in the left frame) is taken to be the left's, and the differences the pair check tolerates
  // (rounding in a calibration file) are removed. fromCameraInfo returns whether the model changed, not whether
  // it is valid: validity is checked here and by StereoGeometry::validate() below.
  const std::string pair = checkCameraInfoPair(left, right);
  if (!pair.empty())
  {
    error = pair;
    return false;
  }
  sensor_msgs::CameraInfo right_in_left_frame = right;
  right_in_left_frame.header.frame_id = left.header.frame_id;
  right_in_left_frame.P[0] = left.P[0];
  right_in_left_frame.P[5] = left.P[5];
  right_in_left_frame.P[6] = left.P[6];
  model_.fromCameraInfo(left, right_in_left_frame);
  const auto& l = model_.left();
  geometry_ = StereoGeometry(l.fx(), l.fy(), l.cx(), l.cy(), model_.baseline(), static_cast<int>(left.width),
                             static_cast<int>(left.height));
  const std::string invalid = geometry_.validate();
  if (!invalid.empty())
  {
    error = "invalid stereo calibration: " + invalid;
    return false;
  }
  identity_ = isIdentityRectification(left) && isIdentityRectification(right);
  last_left_ = left;
  last_right_ = right;
  valid_ = true;
  return true;
}

void StereoCalibration::rectify(View view, const cv::Mat& raw, cv::Mat& out) const
{
  if (identity_)
  {
    out = raw;
    return;
  }
  (view == View::Left ? model_.left() : model_.right()).rectifyImage(raw, out);
}

bool toEngineImage(const sensor_msgs::ImageConstPtr& msg, cv::Mat& out, std::shared_ptr<const void>& keep_alive,
                   std::string& error)
{
  namespace enc = sensor_msgs::image_encodings;
  const std::string& e = msg->encoding;
  // cv_bridge trusts width/height/step; a truncated message would be read past its end.
  if (msg->width == 0 || msg->height == 0 || msg->data.size() < static_cast<size_t>(msg->step) * msg->height)
  {
    error = "image data is truncated or empty (" + std::to_string(msg->data.size()) + " bytes for " +
            std::to_string(msg->width) + "x" + std::to_string(msg->height) + " with step " + std::to_string(msg->step) +
            ")";
    return false;
  }
  try
  {
    cv_bridge::CvImageConstPtr cv;
    if (e == enc::BGR8 || e == enc::MONO8)
      cv = cv_bridge::toCvShare(msg);  // zero copy
    else if (e == enc::RGB8 || e == enc::BGRA8 || e == enc::RGBA8 || enc::isBayer(e))
      cv = cv_bridge::toCvCopy(msg, enc::BGR8);
    else if (e == enc::MONO16)
      cv = cv_bridge::toCvCopy(msg, enc::MONO8);
    else
    {
      error = "unsupported image encoding '" + e + "' (supported: mono8, bgr8, rgb8, bgra8, rgba8, bayer_*, mono16)";
      return false;
    }
    out = cv->image;
    keep_alive = std::shared_ptr<const void>(cv->image.data, [cv](const void*) {});  // boost -> std ownership
    return true;
  }
  catch (const cv_bridge::Exception& ex)
  {
    error = "cannot convert image (encoding '" + e + "', " + std::to_string(msg->width) + "x" +
            std::to_string(msg->height) + ", step " + std::to_string(msg->step) + "): " + ex.what();
    return false;
  }
}

}  // namespace stereo_pf
