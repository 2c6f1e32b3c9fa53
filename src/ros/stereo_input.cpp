// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/stereo_input.h"

#include <cmath>
#include <cstdio>

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
    case DropReason::Overload:
      return "overload";
    case DropReason::OutOfOrder:
      return "out of order";
    case DropReason::Count:
      break;
  }
  return "unknown";
}

StampOrder::Verdict StampOrder::check(double stamp, std::string& why)
{
  if (!last_valid_ || stamp > last_)
  {
    last_ = stamp;
    last_valid_ = true;
    stale_ = 0;
    return Verdict::Accept;
  }
  char text[300];
  const double back = last_ - stamp;
  // A run counts frames of one kind: a late frame among frames stamped alike (tracked, once their run was long
  // enough) starts a run of its own, rather than restarting the track at once.
  const bool alike = !(back > 0.0);
  if (stale_ > 0 && alike != stale_alike_)
    stale_ = 0;
  stale_alike_ = alike;
  if (++stale_ < stale_run_)
  {
    if (back > 0.0)
      std::snprintf(text, sizeof(text),
                    "stamped %.3f s before the last frame tracked (late; if the stamps went back, the track starts "
                    "afresh at the new time when %d frames in a row are stamped so)",
                    back, stale_run_);
    else
      std::snprintf(text, sizeof(text),
                    "stamped as the last frame tracked (repeated; when %d frames in a row are stamped alike, they are "
                    "tracked)",
                    stale_run_);
    why = text;
    return Verdict::Drop;
  }
  last_ = stamp;
  if (alike)
    return Verdict::Accept;  // every frame stamped alike: tracked (the engine takes the nominal period)
  stale_ = 0;
  std::snprintf(text, sizeof(text),
                "the stamps went back %.3f s and stayed there for %d frames (a bag played again?): the track starts "
                "afresh; the target is kept",
                back, stale_run_);
  why = text;
  return Verdict::Restart;
}

namespace
{
std::string size(uint32_t w, uint32_t h)
{
  return std::to_string(w) + "x" + std::to_string(h);
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
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "left and right stamps differ by %.3g ms (~max_stamp_difference %.3g ms): the images were not taken "
                  "together; raise ~max_stamp_difference only if the object moves little in that time",
                  skew * 1e3, options_.max_stamp_difference * 1e3);
    why = buf;
    return false;
  }

  // Calibration first: the image sizes are checked against it. Each camera_info on its own, then the pair; a
  // bad one drops this frame only (the calibration keeps no trace of it).
  for (const auto& [info, side] : { std::make_pair(left_info, "left"), std::make_pair(right_info, "right") })
  {
    const std::string bad = checkCameraInfo(*info, side, options_.images_rectified);
    if (!bad.empty())
    {
      reason = DropReason::BadCameraInfo;
      why = bad;
      return false;
    }
  }
  // The pair is checked by update() (checkCameraInfoPair), whenever the calibration changes.
  if (!calibration_.update(*left_info, *right_info, why))
  {
    reason = DropReason::BadCameraInfo;
    return false;
  }
  notes_ = cameraInfoNotes(*left_info, *right_info, options_.images_rectified);
  if (left->header.frame_id != left_info->header.frame_id)
    notes_.push_back("the left image's frame_id '" + left->header.frame_id + "' differs from its camera_info's '" +
                     left_info->header.frame_id + "': the estimate is published in the image's");

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
    why = "left image is " + size(left->width, left->height) + ", right image " + size(right->width, right->height) +
          ": both cameras must deliver the same size (check the driver's video mode)";
    return false;
  }
  if (left->width != left_info->width || left->height != left_info->height)
  {
    reason = DropReason::SizeMismatch;
    why = "images are " + size(left->width, left->height) + " but camera_info says " +
          size(left_info->width, left_info->height) +
          ": the calibration is for another resolution; run the camera at the calibrated one or recalibrate";
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
