// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Statistics, drop warnings and diagnostics of the tracker nodelet.
#include "tracker_status.h"

#include <algorithm>

namespace stereo_pf
{
namespace
{
constexpr size_t kTimingWindow = 300;  // frames kept for the median processing time / latency

double median(std::deque<double> values)
{
  if (values.empty())
    return 0.0;
  const auto mid = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

void pushWindow(std::deque<double>& window, double value)
{
  window.push_back(value);
  if (window.size() > kTimingWindow)
    window.pop_front();
}
}  // namespace

TrackerStatus::TrackerStatus(ros::NodeHandle& nh, ros::NodeHandle& pnh, const std::string& name) : name_(name)
{
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, name);
  diagnostics_->setHardwareID("stereo_pf");
  diagnostics_->add("tracker", this, &TrackerStatus::diagnose);
  reported_time_ = last_frame_time_ = ros::WallTime::now();
}

TrackerStatus::~TrackerStatus()
{
  stop();
}

void TrackerStatus::start(ros::NodeHandle& mt_pnh, double period)
{
  timer_ = mt_pnh.createWallTimer(ros::WallDuration(std::max(period, 0.02)),
                                  [this](const ros::WallTimerEvent&) { diagnostics_->force_update(); });
}

void TrackerStatus::stop()
{
  timer_.stop();
}

double TrackerStatus::frameReceived(const ros::WallTime& arrival)
{
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_in_;
  last_frame_time_ = arrival;
  return processing_ms_.empty() ? 0.0 : processing_ms_.back();
}

bool TrackerStatus::unpaired()
{
  std::lock_guard<std::mutex> lock(mutex_);
  ++unpaired_;
  return frames_in_ > 0;
}

void TrackerStatus::drop(DropReason reason, const std::string& why, bool warn_now)
{
  // Throttled per reason, so one kind of bad frame cannot hide another.
  const ros::WallTime now = ros::WallTime::now();
  bool warn = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const size_t r = static_cast<size_t>(reason);
    ++drops_[r];
    last_drop_ = std::string(toString(reason)) + ": " + why;
    const double period = reason == DropReason::NoTarget ? 10.0 : 2.0;
    if (warn_now && (last_warning_[r].isZero() || (now - last_warning_[r]).toSec() >= period))
    {
      last_warning_[r] = now;
      warn = true;
    }
  }
  if (!warn)
    return;
  if (reason == DropReason::NoTarget)
    ROS_WARN_NAMED(name_, "frame skipped: %s", why.c_str());
  else
    ROS_WARN_NAMED(name_, "frame dropped (%s): %s", toString(reason), why.c_str());
}

void TrackerStatus::setHasTarget(bool has_target)
{
  std::lock_guard<std::mutex> lock(mutex_);
  has_target_ = has_target;
}

uint64_t TrackerStatus::droppedLocked() const
{
  uint64_t dropped = 0;
  for (size_t r = 0; r < drops_.size(); ++r)
    if (static_cast<DropReason>(r) != DropReason::NoTarget)
      dropped += drops_[r];
  return dropped;
}

void TrackerStatus::frameTracked(bool estimate_published, TrackStatus& status)
{
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_tracked_;
  estimates_published_ += estimate_published ? 1 : 0;
  status.frames_received = frames_in_;
  status.frames_dropped = droppedLocked();
  status.frames_dropped_overload = drops_[static_cast<size_t>(DropReason::Overload)];
}

void TrackerStatus::framePublished(double processing_ms, double latency_ms, double age_ms, int debug_images,
                                   const FrameResult& result, const std::string& message)
{
  std::lock_guard<std::mutex> lock(mutex_);
  debug_images_ += debug_images;
  pushWindow(processing_ms_, processing_ms);
  pushWindow(latency_ms_, latency_ms);
  if (std::isfinite(age_ms))
    pushWindow(age_ms_, age_ms);
  last_result_ = result;
  last_message_ = message;
  has_result_ = true;
}

void TrackerStatus::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status)
{
  if (!init_error_.empty())
  {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, init_error_);
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double period = std::max((now - reported_time_).toSec(), 1e-3);
  const double rate = static_cast<double>(frames_in_ - reported_frames_in_) / period;
  const double output_rate = static_cast<double>(frames_tracked_ - reported_frames_tracked_) / period;
  const uint64_t dropped = droppedLocked();
  const uint64_t overload = drops_[static_cast<size_t>(DropReason::Overload)];
  const bool new_drops = dropped > reported_drops_;
  const uint64_t new_overload = overload - reported_overload_;
  const uint64_t period_frames = frames_in_ - reported_frames_in_;
  reported_frames_in_ = frames_in_;
  reported_frames_tracked_ = frames_tracked_;
  reported_drops_ = dropped;
  reported_overload_ = overload;
  reported_time_ = now;

  status.add("input rate (Hz)", rate);
  status.add("output rate (Hz)", output_rate);
  status.add("frames received", frames_in_);
  status.add("frames tracked", frames_tracked_);
  status.add("estimates published", estimates_published_);
  status.add("dropped frames", dropped);
  for (size_t r = 0; r < drops_.size(); ++r)
    status.add(std::string("dropped: ") + toString(static_cast<DropReason>(r)), drops_[r]);
  status.add("unpaired stereo sets", unpaired_);
  status.add("last drop", last_drop_);
  const double processing = median(processing_ms_);
  status.add("processing time median (ms)", processing);
  status.add("processing time max (ms)",
             processing_ms_.empty() ? 0.0 : *std::max_element(processing_ms_.begin(), processing_ms_.end()));
  status.add("latency from arrival median (ms)", median(latency_ms_));
  status.add("age from image stamp median (ms)", median(age_ms_));
  status.add("debug images drawn", debug_images_);
  status.add("plugins", plugins_);
  status.add("unknown parameters", unknown_parameters_.empty() ? std::string("none") : unknown_parameters_);
  if (has_result_)
  {
    status.add("track state", toString(last_result_.state));
    status.add("support", toString(last_result_.support));
    status.add("frames in state", last_result_.state_frames);
    status.add("ESS", last_result_.ess);
    status.add("evidence", last_result_.evidence);
    status.add("background", last_result_.background);
    const auto& p = last_result_.estimate.position;
    status.addf("estimate (m)", "%.3f %.3f %.3f", p.x(), p.y(), p.z());
    status.add("status", last_message_);
  }
  else
    status.add("track state", "no frame tracked yet");

  if ((now - last_frame_time_).toSec() > 3.0)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no stereo frames received");
  else if (!has_target_)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no target: call ~set_target");
  else if (new_overload > 0)
    status.summaryf(diagnostic_msgs::DiagnosticStatus::WARN,
                    "overloaded: %llu of %llu frames dropped in the last %.1f s (the last frame took %.1f ms, input %.1f Hz): "
                    "use fewer particles (~engine/particles) or fewer or cheaper cues, or lower the camera rate",
                    static_cast<unsigned long long>(new_overload), static_cast<unsigned long long>(period_frames),
                    period, processing_ms_.empty() ? 0.0 : processing_ms_.back(), rate);
  else if (new_drops)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropping frames: " + last_drop_);
  else if (has_result_ && last_result_.state != TrackState::Tracking)
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_message_);
  else
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "tracking");
}

}  // namespace stereo_pf
