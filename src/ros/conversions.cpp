#include "stereo_pf/ros/conversions.h"

#include <cmath>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

namespace stereo_pf
{
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
  // image_geometry asserts that the two cameras share their frame and P's fx, fy and cy: in Debian's build
  // a failed assert aborts the whole nodelet manager. A rectified pair has equal ones; anything else is refused
  // here, and the right camera's frame (unused: results are in the left frame) is taken to be the left's.
  if (left.P[0] != right.P[0] || left.P[5] != right.P[5] || left.P[6] != right.P[6])
  {
    error = "left and right camera_info P differ in fx, fy or cy (left " + std::to_string(left.P[0]) + ", " +
            std::to_string(left.P[5]) + ", " + std::to_string(left.P[6]) + "; right " + std::to_string(right.P[0]) +
            ", " + std::to_string(right.P[5]) + ", " + std::to_string(right.P[6]) +
            "): not a rectified stereo pair, they must be equal";
    return false;
  }
  sensor_msgs::CameraInfo right_in_left_frame = right;
  right_in_left_frame.header.frame_id = left.header.frame_id;
  model_.fromCameraInfo(left, right_in_left_frame);  // returns whether it changed, not whether it is valid
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
