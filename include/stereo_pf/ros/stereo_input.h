// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Turning four synchronised messages (left/right image + camera_info) into a validated, rectified
// StereoFrame, or into a drop reason. ROS messages in, engine types out; no node handle, so it is
// unit-testable and shared by the nodelet and tests.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/ros/conversions.h"

namespace stereo_pf
{
/// Why a frame was dropped; each reason has its own counter in the diagnostics.
enum class DropReason : int
{
  BadImage = 0,     ///< unsupported encoding, truncated data, inconsistent step
  SizeMismatch,     ///< left/right sizes differ, or differ from camera_info
  BadCameraInfo,    ///< missing/zero/NaN calibration, image_geometry rejects it
  OutOfSync,        ///< left/right stamps further apart than allowed, or a message left unpaired
  NoTarget,         ///< nothing to track yet (no target learned or loaded)
  ProcessingError,  ///< the engine threw
  Overload,         ///< replaced by a newer frame before the tracker was free to take it
  OutOfOrder,       ///< stamped at or before the last frame tracked (StampOrder)
  Count
};
/// Short label of a reason, e.g. "bad image" (the diagnostics key).
const char* toString(DropReason reason);

/// Options read once at start-up.
struct StereoInputOptions
{
  /// Images are already rectified (stereo_image_proc's image_rect_color): use camera_info for the
  /// geometry only, never remap the pixels.
  bool images_rectified = false;
  /// Largest |left stamp - right stamp| accepted, seconds (0: stamps must be identical).
  double max_stamp_difference = 0.0;
};

class StereoInput
{
public:
  explicit StereoInput(const StereoInputOptions& options = StereoInputOptions()) : options_(options) {}

  /// Validate and convert one synchronised set. On success `frame` holds the rectified pair (sharing
  /// the messages' data when no conversion or rectification is needed; otherwise this object's
  /// buffers, valid until the next call) and true is returned. Otherwise `reason` and `why` say what is wrong.
  bool assemble(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::ImageConstPtr& right,
                const sensor_msgs::CameraInfoConstPtr& left_info, const sensor_msgs::CameraInfoConstPtr& right_info,
                StereoFrame& frame, DropReason& reason, std::string& why);

  /// What was odd about the last assembled frame's calibration without stopping it (cameraInfoNotes(), image
  /// and camera_info frame_ids that differ): one sentence each, for a warning the caller gives once.
  const std::vector<std::string>& notes() const { return notes_; }
  /// The calibration of the last good frame.
  const StereoCalibration& calibration() const { return calibration_; }
  /// The options.
  const StereoInputOptions& options() const { return options_; }

private:
  StereoInputOptions options_;
  StereoCalibration calibration_;
  std::vector<std::string> notes_;
  std::shared_ptr<const void> keep_[2];  ///< what the converted (unrectified) images point into
  cv::Mat converted_[2];                 ///< BGR/mono view of each message
  cv::Mat rectified_[2];                 ///< rectification output buffers, reused across frames
};

/// Frames are tracked in the order of their stamps. One stamped at or before the last frame tracked is late (held
/// up on the way) or repeated (published twice) and is dropped: tracked, it would move the object back in time and
/// carry the track off. Time that stays behind (a bag played again, a simulated clock restarted) is taken at the
/// `stale_run`-th such frame in a row: the track then starts afresh, as it does for a new target. A camera that
/// stamps every frame alike (a driver without a clock) loses stale_run - 1 frames, then every frame is tracked:
/// never a stall.
class StampOrder
{
public:
  enum class Verdict
  {
    Accept,   ///< newer than the last frame tracked (or, from the stale_run-th stale frame in a row, at its stamp)
    Drop,     ///< at or before the last frame tracked: late or repeated; `why` says so
    Restart,  ///< the time went back and stayed there: track it, afresh
  };
  explicit StampOrder(int stale_run = 3) : stale_run_(stale_run) {}
  /// The verdict on a frame stamped `stamp` (seconds); a frame accepted or restarted is the new last one. On Drop
  /// and Restart `why` says what was seen.
  Verdict check(double stamp, std::string& why);

private:
  int stale_run_;
  double last_ = 0.0;
  bool last_valid_ = false;
  int stale_ = 0;             ///< stale frames of one kind in a row
  bool stale_alike_ = false;  ///< ... stamped as the last frame tracked (else before it)
};

/// Empty when `msg` is internally consistent (non-empty, step >= width * pixel size, data.size() >=
/// step * height), otherwise what is wrong. cv_bridge trusts these fields, so a corrupt message would
/// otherwise read past its buffer.
std::string checkImageMessage(const sensor_msgs::Image& msg);

}  // namespace stereo_pf
