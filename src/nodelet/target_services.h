// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The services: ~set_target (queued for the frame thread, answered when a frame has learned it), ~save_target and
// ~load_target (between two steps, under the engine's lock), ~reset. They run on the multi-threaded queue.
#pragma once

#include <string>

#include <ros/ros.h>
#include <std_srvs/Empty.h>

#include "engine_host.h"
#include "frame_pipeline.h"
#include "nodelet_options.h"
#include "stereo_pf/SetTarget.h"
#include "stereo_pf/TargetFile.h"
#include "target_requests.h"
#include "tracker_status.h"

namespace stereo_pf
{
class TargetServices
{
public:
  TargetServices(const std::string& name, const NodeletOptions& options, EngineHost& host, TargetRequests& requests,
                 FramePipeline& pipeline, TrackerStatus& status)
    : name_(name), options_(options), host_(host), requests_(requests), pipeline_(pipeline), status_(status)
  {
  }
  /// Advertise the services under `mt_pnh`.
  void advertise(ros::NodeHandle& mt_pnh);

private:
  bool setTarget(SetTarget::Request& req, SetTarget::Response& res);
  bool saveTarget(TargetFile::Request& req, TargetFile::Response& res);
  bool loadTarget(TargetFile::Request& req, TargetFile::Response& res);
  bool reset(std_srvs::Empty::Request& req, std_srvs::Empty::Response& res);

  std::string name_;
  const NodeletOptions& options_;
  EngineHost& host_;
  TargetRequests& requests_;
  FramePipeline& pipeline_;
  TrackerStatus& status_;
  ros::ServiceServer set_target_srv_, save_target_srv_, load_target_srv_, reset_srv_;
};

}  // namespace stereo_pf
