// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "target_requests.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

namespace stereo_pf
{
namespace
{
std::string formatNumber(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.15g", v);  // reads back as the same number
  return buf;
}
}  // namespace

void TargetRequests::queue(const cv::Rect& roi)
{
  std::lock_guard<std::mutex> lock(mutex_);
  pending_ = RoiRequest{ next_id_++, roi, std::nullopt };
}

void TargetRequests::ask(const cv::Rect& roi, double timeout, bool& success, std::string& message)
{
  std::unique_lock<std::mutex> lock(mutex_);
  const uint64_t id = next_id_++;
  pending_ = RoiRequest{ id, roi, std::nullopt };
  const bool answered = done_.wait_for(lock, std::chrono::duration<double>(std::max(timeout, 0.0)),
                                       [this, id] { return done_id_ >= id; });
  if (!answered)
  {
    success = true;
    message = "queued: no frame arrived within " + formatNumber(timeout) +
              " s; the target will be learned from the next frame";
  }
  else if (done_id_ > id)
  {
    success = false;
    message = "superseded by a later set_target request";
  }
  else
  {
    success = done_ok_;
    message = done_message_;
  }
}

void TargetRequests::topicRoi(const cv::Rect& roi, const ros::WallTime& arrival)
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (topic_done_ || pending_ || topic_roi_ || roi.width == 0 || roi.height == 0)
    return;
  topic_roi_ = TopicRoi{ roi, arrival, last_set_ };
}

void TargetRequests::frameArrived(const FrameMessages& set)
{
  // Learning a topic's region on a later frame taught the tracker a box of wall: it belongs to the set that
  // arrived nearest to it in time.
  std::lock_guard<std::mutex> lock(mutex_);
  if (topic_roi_ && !pending_)
  {
    const bool before = topic_roi_->before &&
                        (topic_roi_->arrival - topic_roi_->before->arrival) < (set.arrival - topic_roi_->arrival);
    pending_ = RoiRequest{ next_id_++, topic_roi_->roi, before ? topic_roi_->before : set };
    topic_roi_.reset();
  }
  last_set_ = set;
}

std::optional<RoiRequest> TargetRequests::take()
{
  std::optional<RoiRequest> request;
  std::lock_guard<std::mutex> lock(mutex_);
  request.swap(pending_);
  return request;
}

void TargetRequests::answer(uint64_t id, bool ok, const std::string& message)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    topic_done_ = topic_done_ || ok;
    done_id_ = std::max(done_id_, id);
    done_ok_ = ok;
    done_message_ = message;
  }
  done_.notify_all();
}

void TargetRequests::cancelAll(const std::string& message)
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    done_id_ = next_id_;
    done_message_ = message;
  }
  done_.notify_all();
}

}  // namespace stereo_pf
