// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The tracker nodelet: set-up and teardown of its pieces (see the header).
#include "tracker_nodelet.h"

#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
namespace
{
std::string joinNames(const std::vector<std::string>& names)
{
  std::string s;
  for (const auto& n : names)
    s += (s.empty() ? "" : ", ") + n;
  return s;
}
}  // namespace

TrackerNodelet::~TrackerNodelet()
{
  // Stop the callbacks before the engine they use goes away.
  if (status_)
    status_->stop();
  if (input_)
    input_->shutdown();
  if (pipeline_)
    pipeline_->stop();  // the worker finishes its frame and stops
  requests_.cancelAll("the tracker is shutting down");  // release any set_target waiter
}

void TrackerNodelet::onInit()
{
  // Frames on the single-threaded queue; services, reconfigure and diagnostics on the multi-threaded one.
  ros::NodeHandle &nh = getNodeHandle(), &pnh = getPrivateNodeHandle(), &mt_pnh = getMTPrivateNodeHandle();
  options_ = NodeletOptions::read(pnh);
  status_ = std::make_unique<TrackerStatus>(nh, pnh, getName());
  std::string unknown;
  const std::string error = host_.create(pnh, getName(), unknown);
  if (!error.empty())  // a bad configuration leaves the nodelet inert but explained (never a crash)
  {
    NODELET_FATAL("%s", error.c_str());
    status_->setInitError(error);
    status_->publishNow();
    return status_->start(mt_pnh, options_.diagnostic_period);
  }
  status_->setUnknownParameters(unknown);
  status_->setPlugins(joinNames(host_.tracker->pluginTypes()));
  reconfigure_ = std::make_unique<ReconfigureBridge>(getName(), host_);
  startupTarget();
  status_->setHasTarget(host_.engine().hasTarget());

  input_ = std::make_unique<FrameInput>(getName(), requests_, *status_);
  pipeline_ = std::make_unique<FramePipeline>(getName(), options_, host_, *status_, requests_, *input_);
  services_ = std::make_unique<TargetServices>(getName(), options_, host_, requests_, *pipeline_, *status_);
  input_->connect(options_, pipeline_->slot());  // the synchroniser on unsubscribed filters
  reconfigure_->start(mt_pnh);
  services_->advertise(mt_pnh);
  pipeline_->advertise(pnh);  // advertise last, then subscribe: no frame arrives before its publishers exist
  pipeline_->start();
  input_->subscribe(nh, pnh, options_, host_.engine().hasTarget() ? std::string() : options_.roi_topic);
  status_->start(mt_pnh, options_.diagnostic_period);

  NODELET_INFO("tracking '%s' and '%s' (%s sync%s) with %s; publishing %s", input_->leftTopic().c_str(),
               input_->rightTopic().c_str(), options_.approximate_sync ? "approximate" : "exact",
               options_.input.images_rectified ? ", images already rectified" : "",
               joinNames(host_.tracker->pluginTypes()).c_str(), pipeline_->targetTopic().c_str());
}

void TrackerNodelet::startupTarget()
{
  if (!options_.target_file.empty())
  {
    std::string error;
    if (host_.engine().loadTarget(options_.target_file, error))
      NODELET_INFO("target loaded from '%s'", options_.target_file.c_str());
    else
      NODELET_ERROR("~target_file: %s; waiting for ~set_target", error.c_str());
  }
  const std::vector<int>& roi = options_.target_roi;
  if (host_.engine().hasTarget() || roi.empty())
    return;
  if (roi.size() != 4 || roi[2] <= 0 || roi[3] <= 0)
    NODELET_ERROR("~target_roi must be [x, y, width, height] with positive width and height (got %zu values); "
                  "waiting for ~set_target",
                  roi.size());
  else
    requests_.queue(cv::Rect(roi[0], roi[1], roi[2], roi[3]));
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::TrackerNodelet, nodelet::Nodelet)
