// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The target requests waiting for the frame thread, and their answers: ~set_target (which waits for its answer),
// the start-up ~target_roi, and a region from ~target_roi_topic (paired with the frame it belongs to). Only the
// newest request waits; one that is replaced is answered "superseded". Thread-safe.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "frame_messages.h"

namespace stereo_pf
{
/// One queued target request (answered by the frame thread).
struct RoiRequest
{
  uint64_t id = 0;
  cv::Rect roi;
  /// The frame to learn from (a ROI topic's own frame); empty: the next frame tracked (set_target).
  std::optional<FrameMessages> source;
};

class TargetRequests
{
public:
  /// Queue `roi` for the next frame tracked (start-up ~target_roi).
  void queue(const cv::Rect& roi);
  /// Queue `roi` for the next frame tracked and wait up to `timeout` seconds for its answer (~set_target).
  void ask(const cv::Rect& roi, double timeout, bool& success, std::string& message);
  /// A region from ~target_roi_topic: ignored once a target was learned, while a request waits, or when empty.
  /// Which frame it belongs to is decided when the next set arrives (frameArrived()).
  void topicRoi(const cv::Rect& roi, const ros::WallTime& arrival);
  /// A complete set arrived: a region from the topic becomes a request for this set or the one before it,
  /// whichever arrived nearer to it in time (RegionOfInterest has no stamp).
  void frameArrived(const FrameMessages& set);
  /// The frame thread: the waiting request, if any.
  std::optional<RoiRequest> take();
  /// The frame thread: the answer to request `id` (a learned target also ends ~target_roi_topic).
  void answer(uint64_t id, bool ok, const std::string& message);
  /// Release every waiter with `message` (shutdown).
  void cancelAll(const std::string& message);

private:
  /// A ROI from ~target_roi_topic waiting for the set after it, to decide which frame it belongs to.
  struct TopicRoi
  {
    cv::Rect roi;
    ros::WallTime arrival;
    std::optional<FrameMessages> before;  ///< the set that arrived last before it
  };
  std::mutex mutex_;
  std::condition_variable done_;
  std::optional<RoiRequest> pending_;
  uint64_t next_id_ = 1;
  uint64_t done_id_ = 0;
  bool done_ok_ = false;
  std::string done_message_;
  bool topic_done_ = false;
  std::optional<TopicRoi> topic_roi_;
  std::optional<FrameMessages> last_set_;  ///< the last set received (for topic_roi_)
};

}  // namespace stereo_pf
