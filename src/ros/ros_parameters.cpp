// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/ros_parameters.h"

#include <sstream>

namespace stereo_pf
{
namespace
{
std::string join(const std::string& a, const std::string& b)
{
  return a.empty() ? b : a + "/" + b;
}

bool isScalar(const XmlRpc::XmlRpcValue& v)
{
  switch (v.getType())
  {
    case XmlRpc::XmlRpcValue::TypeBoolean:
    case XmlRpc::XmlRpcValue::TypeInt:
    case XmlRpc::XmlRpcValue::TypeDouble:
    case XmlRpc::XmlRpcValue::TypeString:
      return true;
    default:
      return false;
  }
}

std::string scalarText(const XmlRpc::XmlRpcValue& v)
{
  XmlRpc::XmlRpcValue& m = const_cast<XmlRpc::XmlRpcValue&>(v);  // XmlRpc's conversions are not const
  switch (v.getType())
  {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return static_cast<bool>(m) ? "true" : "false";
    case XmlRpc::XmlRpcValue::TypeInt:
      return std::to_string(static_cast<int>(m));
    case XmlRpc::XmlRpcValue::TypeDouble:
    {
      std::ostringstream s;
      s.precision(17);  // round-trips: the tree holds text, the plugins parse it back
      s << static_cast<double>(m);
      return s.str();
    }
    case XmlRpc::XmlRpcValue::TypeString:
      return static_cast<std::string>(m);
    default:
      return "";
  }
}

// Text of a list of scalars (nested lists of scalars are written inline too).
std::string listText(const XmlRpc::XmlRpcValue& v)
{
  XmlRpc::XmlRpcValue& m = const_cast<XmlRpc::XmlRpcValue&>(v);
  std::string s = "[";
  for (int i = 0; i < m.size(); ++i)
  {
    if (i > 0)
      s += ", ";
    s += m[i].getType() == XmlRpc::XmlRpcValue::TypeArray ? listText(m[i]) : scalarText(m[i]);
  }
  return s + "]";
}
}  // namespace

void mergeXmlRpc(const XmlRpc::XmlRpcValue& value, const std::string& key, Parameters& params,
                 const SkipParameter& skip)
{
  if (skip && !key.empty() && skip(key, value))
    return;
  XmlRpc::XmlRpcValue& v = const_cast<XmlRpc::XmlRpcValue&>(value);
  switch (v.getType())
  {
    case XmlRpc::XmlRpcValue::TypeStruct:
      for (auto it = v.begin(); it != v.end(); ++it)
        mergeXmlRpc(it->second, join(key, it->first), params, skip);
      return;
    case XmlRpc::XmlRpcValue::TypeArray:
    {
      bool has_struct = false;
      for (int i = 0; i < v.size(); ++i)
        has_struct = has_struct || v[i].getType() == XmlRpc::XmlRpcValue::TypeStruct;
      if (!has_struct)
      {
        params.set(key, listText(v));
        return;
      }
      // A list of maps (observation_models): one namespace per entry, like the YAML loader.
      for (int i = 0; i < v.size(); ++i)
      {
        const std::string entry = join(key, std::to_string(i));
        if (v[i].getType() == XmlRpc::XmlRpcValue::TypeStruct)
          mergeXmlRpc(v[i], entry, params, skip);
        else
          params.set(entry, v[i].getType() == XmlRpc::XmlRpcValue::TypeArray ? listText(v[i]) : scalarText(v[i]));
      }
      return;
    }
    default:
      if (isScalar(v) && !key.empty())
        params.set(key, scalarText(v));
      return;  // base64, date-time and invalid values have no text form the plugins could read
  }
}

Parameters loadRosParameters(const ros::NodeHandle& nh)
{
  Parameters params;
  XmlRpc::XmlRpcValue tree;
  if (nh.getParam(nh.getNamespace(), tree))
    mergeXmlRpc(tree, "", params);
  return params;
}

}  // namespace stereo_pf
