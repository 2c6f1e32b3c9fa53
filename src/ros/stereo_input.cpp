#include "stereo_pf/ros/stereo_input.h"

#include <cmath>

#include <sensor_msgs/image_encodings.h>

namespace stereo_pf
{
const char* toString(DropReason reason)
{
  switch (reason)
  {
    case DropReason::BadImage:
      return "bad image";
    case DropReason::SizeMismatch:
      return "size mismatch";
    case DropReason::BadCameraInfo:
      return "bad camera_info";
    case DropReason::OutOfSync:
      return "out of sync";
    case DropReason::NoTarget:
      return "no target";
    case DropReason::ProcessingError:
      return "processing error";
    case DropReason::Count:
      break;
  }
  return "unknown";
}

namespace
{
std::string size(uint32_t w, uint32_t h)
{
  return std::to_string(w) + "x" + std::to_string(h);
}

template <class Array>
bool allFinite(const Array& a)
{
  for (double v : a)
    if (!std::isfinite(v))
      return false;
  return true;
}

// image_geometry uses K, D and R to build the rectification maps: a NaN there gives NaN maps, not an error.
std::string checkInfo(const sensor_msgs::CameraInfo& info, const char* side)
{
  if (info.width == 0 || info.height == 0)
    return std::string(side) + " camera_info has no image size (uncalibrated camera?)";
  if (!allFinite(info.K) || !allFinite(info.D) || !allFinite(info.R) || !allFinite(info.P))
    return std::string(side) + " camera_info contains NaN or infinity";
  return "";
}
}  // namespace

std::string checkImageMessage(const sensor_msgs::Image& msg)
{
  namespace enc = sensor_msgs::image_encodings;
  if (msg.width == 0 || msg.height == 0)
    return "empty image (" + size(msg.width, msg.height) + ")";
  int bytes_per_pixel = 0;
  try
  {
    bytes_per_pixel = enc::numChannels(msg.encoding) * enc::bitDepth(msg.encoding) / 8;
  }
  catch (const std::exception&)
  {
    return "unknown image encoding '" + msg.encoding + "'";
  }
  if (static_cast<uint64_t>(msg.step) < static_cast<uint64_t>(msg.width) * bytes_per_pixel)
    return "row step " + std::to_string(msg.step) + " is shorter than width " + std::to_string(msg.width) + " x " +
           std::to_string(bytes_per_pixel) + " bytes";
  if (msg.data.size() < static_cast<uint64_t>(msg.step) * msg.height)
    return "image data has " + std::to_string(msg.data.size()) + " bytes, step x height needs " +
           std::to_string(static_cast<uint64_t>(msg.step) * msg.height);
  return "";
}

bool StereoInput::assemble(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                           const sensor_msgs::CameraInfoConstPtr& left_info,
                           const sensor_msgs::CameraInfoConstPtr& right_info, StereoFrame& frame, DropReason& reason,
                           std::string& why)
{
  if (!left || !right || !left_info || !right_info)
  {
    reason = DropReason::OutOfSync;
    why = "incomplete stereo set (a message is missing)";
    return false;
  }
  const double skew = std::fabs((left->header.stamp - right->header.stamp).toSec());
  if (skew > options_.max_stamp_difference)
  {
    reason = DropReason::OutOfSync;
    why = "left and right stamps differ by " + std::to_string(skew * 1e3) + " ms (max_stamp_difference " +
          std::to_string(options_.max_stamp_difference * 1e3) + " ms)";
    return false;
  }

  // Calibration first: the image sizes are checked against it.
  for (const auto& [info, side] : { std::make_pair(left_info, "left"), std::make_pair(right_info, "right") })
  {
    const std::string bad = checkInfo(*info, side);
    if (!bad.empty())
    {
      reason = DropReason::BadCameraInfo;
      why = bad;
      return false;
    }
  }
  if (!calibration_.update(*left_info, *right_info, why))
  {
    reason = DropReason::BadCameraInfo;
    return false;
  }

  const sensor_msgs::ImageConstPtr images[2] = { left, right };
  const char* sides[2] = { "left", "right" };
  for (int i = 0; i < 2; ++i)
  {
    const std::string bad = checkImageMessage(*images[i]);
    if (!bad.empty())
    {
      reason = DropReason::BadImage;
      why = std::string(sides[i]) + " image: " + bad;
      return false;
    }
  }
  if (left->width != right->width || left->height != right->height)
  {
    reason = DropReason::SizeMismatch;
    why = "left image is " + size(left->width, left->height) + ", right image " + size(right->width, right->height);
    return false;
  }
  if (left->width != left_info->width || left->height != left_info->height)
  {
    reason = DropReason::SizeMismatch;
    why = "images are " + size(left->width, left->height) + " but camera_info says " +
          size(left_info->width, left_info->height);
    return false;
  }

  for (int i = 0; i < 2; ++i)
  {
    if (!toEngineImage(images[i], converted_[i], keep_[i], why))
    {
      reason = DropReason::BadImage;
      why = std::string(sides[i]) + " image: " + why;
      return false;
    }
  }

  if (options_.images_rectified || calibration_.identity())
  {
    frame.left = converted_[0];  // zero copy: shares the message (or the converted buffer)
    frame.right = converted_[1];
  }
  else
  {
    calibration_.rectify(View::Left, converted_[0], rectified_[0]);
    calibration_.rectify(View::Right, converted_[1], rectified_[1]);
    frame.left = rectified_[0];
    frame.right = rectified_[1];
  }
  frame.stamp = left->header.stamp.toSec();
  frame.geometry = calibration_.geometry();
  const std::string invalid = frame.validate();
  if (!invalid.empty())
  {
    reason = DropReason::SizeMismatch;
    why = invalid;
    return false;
  }
  return true;
}

}  // namespace stereo_pf
