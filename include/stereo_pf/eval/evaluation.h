// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Accuracy summary of a tracked sequence against ground truth (what track_bag prints and tests assert).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace stereo_pf
{
/// One tracked frame with its ground truth.
struct FrameRecord
{
  bool has_truth = false;        ///< ground truth available
  bool target_visible = true;    ///< ground truth says the object can be seen (not occluded, in view)
  bool estimate_valid = false;   ///< the tracker produced a 3D estimate
  Eigen::Vector3d estimate = Eigen::Vector3d::Zero();
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();
  bool tracking = false;         ///< track state was "tracking"
  double ms = 0.0;               ///< processing time of the frame
  /// 3D error (infinite without a valid estimate).
  double error() const;
};

/// What the summary line reports.
struct TrackSummary
{
  int frames = 0;
  int frames_with_truth = 0;
  /// First frame index from which the error stays below the threshold for `hold` consecutive visible
  /// frames; -1 when it never converges.
  int convergence_frame = -1;
  double rms_after = 0.0;               ///< RMS 3D error over visible frames from convergence on, m
  Eigen::Vector3d rms_axis_after = Eigen::Vector3d::Zero();  ///< per-axis RMS, m
  double max_after = 0.0;               ///< largest 3D error over visible frames after convergence, m
  int frames_above_10cm_after = 0;      ///< visible frames after convergence with error > 0.10 m
  double mean_ms = 0.0;                 ///< mean processing time per frame
  /// Occlusions (runs of frames with target_visible == false after convergence):
  int occlusions = 0;
  int occlusions_declared_lost = 0;     ///< how many had a non-tracking state while the object was hidden
  int max_reacquire_frames = -1;        ///< worst frames from reappearance to tracking with error < threshold
                                        ///< (-1: no occlusion; a large number when never re-acquired)

  /// One line: frames, convergence, RMS, per-axis RMS, ms.
  std::string line() const;
};

/// Summarise records. `threshold` is the convergence error (m), `hold` the frames it must hold.
TrackSummary summarise(const std::vector<FrameRecord>& records, double threshold = 0.05, int hold = 10);

}  // namespace stereo_pf
