// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "engine_host.h"

#include "stereo_pf/ros/ros_parameters.h"

namespace stereo_pf
{
std::string EngineHost::create(const ros::NodeHandle& pnh, const std::string& name, std::string& unknown)
{
  try
  {
    XmlRpc::XmlRpcValue tree;
    if (pnh.getParam(pnh.getNamespace(), tree))
      mergeXmlRpc(tree, "", params);
    tracker = std::make_unique<Tracker>(params);
  }
  catch (const std::exception& e)  // PluginError, ParameterError, pluginlib
  {
    return std::string("cannot create the tracker: ") + e.what();
  }
  // A misspelt key is ignored by every component: say so, with the key meant.
  for (const std::string& m : unknownParameters(params, kRosRuntimeParameters))
  {
    ROS_WARN_NAMED(name, "%s", m.c_str());
    unknown += (unknown.empty() ? "" : "; ") + m;
  }
  return "";
}

}  // namespace stereo_pf
