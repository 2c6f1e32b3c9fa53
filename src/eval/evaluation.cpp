// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/eval/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace stereo_pf
{
double FrameRecord::error() const
{
  if (!estimate_valid || !has_truth)
    return std::numeric_limits<double>::infinity();
  return (estimate - truth).norm();
}

TrackSummary summarise(const std::vector<FrameRecord>& r, double threshold, int hold)
{
  TrackSummary s;
  s.frames = static_cast<int>(r.size());
  double ms = 0.0;
  for (const auto& f : r)
  {
    ms += f.ms;
    s.frames_with_truth += f.has_truth ? 1 : 0;
  }
  s.mean_ms = s.frames > 0 ? ms / s.frames : 0.0;

  // Convergence: the first visible frame that starts `hold` consecutive visible frames under threshold.
  for (int k = 0; k < s.frames && s.convergence_frame < 0; ++k)
  {
    if (!r[k].has_truth || !r[k].target_visible || r[k].error() >= threshold)
      continue;
    int good = 0;
    bool broken = false;
    for (int j = k; j < s.frames && good < hold; ++j)
    {
      if (!r[j].has_truth || !r[j].target_visible)
        continue;
      if (r[j].error() >= threshold)
      {
        broken = true;
        break;
      }
      ++good;
    }
    if (!broken && good >= hold)
      s.convergence_frame = k;
  }
  if (s.convergence_frame < 0)
    return s;

  double sum2 = 0.0;
  Eigen::Vector3d axis2 = Eigen::Vector3d::Zero();
  int n = 0;
  const int big = 1000000;
  for (int k = s.convergence_frame; k < s.frames; ++k)
  {
    const FrameRecord& f = r[k];
    if (!f.has_truth)
      continue;
    if (!f.target_visible)
    {
      // An occlusion: find its end, check the state while hidden and the re-acquisition afterwards.
      int end = k;
      bool declared_lost = false;
      for (; end < s.frames && r[end].has_truth && !r[end].target_visible; ++end)
        declared_lost = declared_lost || !r[end].tracking;
      ++s.occlusions;
      s.occlusions_declared_lost += declared_lost ? 1 : 0;
      int reacquire = big;
      for (int j = end; j < s.frames; ++j)
        if (r[j].tracking && r[j].error() < threshold)
        {
          reacquire = j - end;
          break;
        }
      s.max_reacquire_frames = std::max(s.max_reacquire_frames, reacquire);
      k = end - 1;
      continue;
    }
    const double e = f.error();
    const Eigen::Vector3d d = f.estimate_valid ? Eigen::Vector3d(f.estimate - f.truth) :
                                                 Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    sum2 += e * e;
    axis2 += d.cwiseProduct(d);
    s.max_after = std::max(s.max_after, e);
    s.frames_above_10cm_after += e > 0.10 ? 1 : 0;
    ++n;
  }
  if (n > 0)
  {
    s.rms_after = std::sqrt(sum2 / n);
    s.rms_axis_after = (axis2 / n).cwiseSqrt();
  }
  return s;
}

std::string TrackSummary::line() const
{
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(2);
  o << "summary: frames=" << frames << " converged_at=" << convergence_frame;
  if (convergence_frame >= 0)
  {
    o << " rms_cm=" << rms_after * 100 << " rms_xyz_cm=" << rms_axis_after.x() * 100 << ","
      << rms_axis_after.y() * 100 << "," << rms_axis_after.z() * 100 << " max_cm=" << max_after * 100
      << " frames_over_10cm=" << frames_above_10cm_after;
    if (occlusions > 0)
      o << " occlusions=" << occlusions << " declared_lost=" << occlusions_declared_lost
        << " reacquire_frames=" << max_reacquire_frames;
  }
  else if (frames_with_truth == 0)
    o << " (no ground truth)";
  o.precision(3);
  o << " ms_per_frame=" << mean_ms;
  return o.str();
}

}  // namespace stereo_pf
