// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "target_services.h"

namespace stereo_pf
{
void TargetServices::advertise(ros::NodeHandle& mt_pnh)
{
  set_target_srv_ = mt_pnh.advertiseService("set_target", &TargetServices::setTarget, this);
  save_target_srv_ = mt_pnh.advertiseService("save_target", &TargetServices::saveTarget, this);
  load_target_srv_ = mt_pnh.advertiseService("load_target", &TargetServices::loadTarget, this);
  reset_srv_ = mt_pnh.advertiseService("reset", &TargetServices::reset, this);
}

bool TargetServices::setTarget(SetTarget::Request& req, SetTarget::Response& res)
{
  if (req.roi.width == 0 || req.roi.height == 0)
  {
    res.success = false;
    res.message = "the region is empty (width and height must be positive)";
    return true;
  }
  bool success = false;
  requests_.ask(cv::Rect(static_cast<int>(req.roi.x_offset), static_cast<int>(req.roi.y_offset),
                         static_cast<int>(req.roi.width), static_cast<int>(req.roi.height)),
                options_.set_target_timeout, success, res.message);
  res.success = success;
  return true;
}

bool TargetServices::saveTarget(TargetFile::Request& req, TargetFile::Response& res)
{
  const std::string path = req.path.empty() ? options_.target_file : req.path;
  if (path.empty())
  {
    res.success = false;
    res.message = "no path given and ~target_file is not set";
    return true;
  }
  std::lock_guard<std::mutex> lock(host_.mutex);
  std::string error;
  if (!host_.engine().hasTarget())
  {
    res.success = false;
    res.message = "no target learned yet";
    return true;
  }
  res.success = host_.engine().saveTarget(path, error);
  res.message = res.success ? "target saved to '" + path + "'" : error;
  return true;
}

bool TargetServices::loadTarget(TargetFile::Request& req, TargetFile::Response& res)
{
  const std::string path = req.path.empty() ? options_.target_file : req.path;
  if (path.empty())
  {
    res.success = false;
    res.message = "no path given and ~target_file is not set";
    return true;
  }
  std::lock_guard<std::mutex> lock(host_.mutex);  // between two steps, never during one
  std::string error;
  res.success = host_.engine().loadTarget(path, error);
  res.message = res.success ? "target loaded from '" + path + "'" : error;
  if (res.success)
  {
    status_.setHasTarget(host_.engine().hasTarget());
    host_.engine().reset();
    pipeline_.clearTrail();
  }
  return true;
}

bool TargetServices::reset(std_srvs::Empty::Request&, std_srvs::Empty::Response&)
{
  host_.engine().reset();  // thread-safe: applied at the start of the next step
  pipeline_.clearTrail();
  ROS_INFO_NAMED(name_, "reset: the particles are re-drawn from the prior at the next frame");
  return true;
}

}  // namespace stereo_pf
