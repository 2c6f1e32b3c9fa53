#include "engine_host.h"

#include "stereo_pf/ros/ros_parameters.h"

namespace stereo_pf
{
namespace
{
// The -1 "unchanged" values of the reconfigure servers are written back to the parameter server by
// dynamic_reconfigure; they must not reach the plugins (which would reject them) when the tree is re-read,
// e.g. when the nodelet is reloaded into a running manager.
bool isReconfigureSentinel(const std::string& key, const XmlRpc::XmlRpcValue& value)
{
  const auto slash = key.rfind('/');
  const std::string leaf = slash == std::string::npos ? key : key.substr(slash + 1);
  if (leaf != "sigma" && leaf != "noise" && leaf != "acceleration_noise")
    return false;
  XmlRpc::XmlRpcValue& v = const_cast<XmlRpc::XmlRpcValue&>(value);
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    return static_cast<double>(v) == -1.0;
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt)
    return static_cast<int>(v) == -1;
  return false;
}
}  // namespace

std::string EngineHost::create(const ros::NodeHandle& pnh, const std::string& name, std::string& unknown)
{
  try
  {
    XmlRpc::XmlRpcValue tree;
    if (pnh.getParam(pnh.getNamespace(), tree))
      mergeXmlRpc(tree, "", params, isReconfigureSentinel);
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
