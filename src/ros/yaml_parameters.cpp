// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/yaml_parameters.h"

#include <yaml-cpp/yaml.h>

namespace stereo_pf
{
namespace
{
void flatten(const YAML::Node& node, const std::string& key, Parameters& params)
{
  switch (node.Type())
  {
    case YAML::NodeType::Map:
      for (const auto& kv : node)
      {
        const std::string k = kv.first.as<std::string>();
        flatten(kv.second, key.empty() ? k : key + "/" + k, params);
      }
      break;
    case YAML::NodeType::Sequence:
    {
      bool scalars = true;
      for (const auto& item : node)
        scalars = scalars && item.IsScalar();
      if (scalars)
      {
        std::string text = "[";
        for (size_t i = 0; i < node.size(); ++i)
          text += (i ? ", " : "") + node[i].as<std::string>();
        params.set(key, text + "]");
      }
      else
        for (size_t i = 0; i < node.size(); ++i)
          flatten(node[i], key + "/" + std::to_string(i), params);
      break;
    }
    case YAML::NodeType::Scalar:
      params.set(key, node.as<std::string>());
      break;
    default:
      break;  // null: leave the default in place
  }
}
}  // namespace

void loadYamlFile(const std::string& path, Parameters& params)
{
  try
  {
    flatten(YAML::LoadFile(path), "", params);
  }
  catch (const YAML::Exception& e)
  {
    throw ParameterError("cannot read parameters from '" + path + "': " + e.what());
  }
}

void loadYamlString(const std::string& text, Parameters& params)
{
  try
  {
    flatten(YAML::Load(text), "", params);
  }
  catch (const YAML::Exception& e)
  {
    throw ParameterError(std::string("cannot parse parameters: ") + e.what());
  }
}

void applyOverride(const std::string& assignment, Parameters& params)
{
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ParameterError("override '" + assignment + "' must look like ns/key=value");
  const std::string key = assignment.substr(0, eq);
  try
  {
    flatten(YAML::Load(assignment.substr(eq + 1)), key, params);
  }
  catch (const YAML::Exception& e)
  {
    throw ParameterError("override '" + assignment + "': " + e.what());
  }
}

}  // namespace stereo_pf
