// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Filling the ROS-free Parameters tree from the ROS parameter server (the nodelet's private namespace).
#pragma once

#include <functional>
#include <string>

#include <ros/node_handle.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
/// Merge one XmlRpc value into `params` under `key` with the same layout as the YAML loader: structs become
/// namespaces ("a/b"), arrays of structs "a/<index>/b", arrays of scalars "[x, y, z]", booleans true/false,
/// doubles with full precision. An empty `key` is only allowed for a struct (the root). Entries for which
/// `skip(key, value)` returns true are left out.
using SkipParameter = std::function<bool(const std::string& key, const XmlRpc::XmlRpcValue& value)>;
void mergeXmlRpc(const XmlRpc::XmlRpcValue& value, const std::string& key, Parameters& params,
                 const SkipParameter& skip = SkipParameter());

/// Every parameter under `nh`'s namespace (normally the private one) as a Parameters tree rooted there.
/// An empty or absent namespace gives an empty tree.
Parameters loadRosParameters(const ros::NodeHandle& nh);

}  // namespace stereo_pf
