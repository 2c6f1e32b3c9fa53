// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The nodelet's statistics and how they are reported: frame counters, drops (counted and warned about, throttled
// per reason), timing windows, the last result; the diagnostics (diagnostic_updater on a wall timer) and the
// counters of each ~status message. Every method is thread-safe (one mutex): the receiving queue, the frame thread
// and the diagnostics timer all report here.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

#include "stereo_pf/TrackStatus.h"
#include "stereo_pf/core/engine.h"
#include "stereo_pf/ros/stereo_input.h"

namespace stereo_pf
{
class TrackerStatus
{
public:
  /// The diagnostics are published under `nh` as `name` (the nodelet's name, also the logger's).
  TrackerStatus(ros::NodeHandle& nh, ros::NodeHandle& pnh, const std::string& name);
  ~TrackerStatus();

  /// Set once before start(): why the tracker could not be built (the diagnostics then say only that), the
  /// parameters nothing reads, the plugins loaded.
  void setInitError(const std::string& error) { init_error_ = error; }
  void setUnknownParameters(const std::string& text) { unknown_parameters_ = text; }
  void setPlugins(const std::string& text) { plugins_ = text; }

  /// Publish the diagnostics now (the reason a tracker could not be built is not left waiting for the timer).
  void publishNow() { diagnostics_->force_update(); }
  /// Publish the diagnostics every `period` seconds of wall time (a bag's simulated clock may stop).
  void start(ros::NodeHandle& mt_pnh, double period);
  /// Stop the timer (before what the diagnostics read goes away).
  void stop();

  /// A complete set arrived at `arrival`: counted. Returns the last frame's processing time, ms (the load now).
  double frameReceived(const ros::WallTime& arrival);
  /// A set the synchroniser gave up on: counted. Returns whether a set was ever complete before.
  bool unpaired();
  /// Count a dropped frame and say why (throttled per reason); `warn` false counts it silently.
  void drop(DropReason reason, const std::string& why, bool warn = true);
  /// Whether the engine has a target (as of the last frame or load).
  void setHasTarget(bool has_target);
  /// A frame tracked, just before its ~status goes out: counted (so a client that saw the status finds it
  /// counted), and the frame counters copied into `status`.
  void frameTracked(bool estimate_published, TrackStatus& status);
  /// A frame published: its timings (ms; `age_ms` may be non-finite), debug images drawn, result and message.
  void framePublished(double processing_ms, double latency_ms, double age_ms, int debug_images,
                      const FrameResult& result, const std::string& message);

private:
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  uint64_t droppedLocked() const;  ///< every drop but NoTarget (stats_mutex_ held)

  std::string name_;
  std::string init_error_, unknown_parameters_, plugins_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::WallTimer timer_;

  std::mutex mutex_;
  uint64_t frames_in_ = 0, frames_tracked_ = 0, estimates_published_ = 0, unpaired_ = 0, debug_images_ = 0;
  std::array<uint64_t, static_cast<size_t>(DropReason::Count)> drops_{};
  std::array<ros::WallTime, static_cast<size_t>(DropReason::Count)> last_warning_{};  ///< per-reason throttle
  uint64_t reported_frames_in_ = 0, reported_frames_tracked_ = 0, reported_drops_ = 0, reported_overload_ = 0;
  ros::WallTime reported_time_, last_frame_time_;
  /// Recent processing times (worker start -> published), latencies (arrival -> published, waiting included)
  /// and ages (image stamp -> published, on the ROS clock), ms.
  std::deque<double> processing_ms_, latency_ms_, age_ms_;
  FrameResult last_result_;
  std::string last_message_;  ///< the last ~status message text
  bool has_result_ = false;
  bool has_target_ = false;
  std::string last_drop_;
};

}  // namespace stereo_pf
