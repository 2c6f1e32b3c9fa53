// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// dynamic_reconfigure's protocol, served from a parameter table.
#include "parameter_server.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <dynamic_reconfigure/ConfigDescription.h>

namespace stereo_pf
{
namespace
{
using Type = ParameterSpec::Type;

std::string formatNumber(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.15g", v);  // reads back as the same number
  return buf;
}

bool parseBool(const std::string& text)
{
  return text == "true" || text == "1" || text == "yes" || text == "on" || text == "True";
}

double parseNumber(const std::string& text)
{
  return std::strtod(text.c_str(), nullptr);
}

/// The same value (a number written another way is the same number).
bool same(const ParameterSpec& spec, const std::string& a, const std::string& b)
{
  switch (spec.type)
  {
    case Type::Bool:
      return parseBool(a) == parseBool(b);
    case Type::Int:
    case Type::Double:
    {
      const double x = parseNumber(a), y = parseNumber(b);
      return std::fabs(x - y) <= 1e-12 * std::max(1.0, std::fabs(x));
    }
    default:
      return a == b;
  }
}
}  // namespace

ParameterServer::ParameterServer(const ros::NodeHandle& nh, const std::vector<ParameterSpec>& table,
                                 const std::map<std::string, std::string>& values, Apply apply)
  : nh_(nh), apply_(std::move(apply))
{
  for (const ParameterSpec& spec : table)
    if (spec.type != Type::List)
    {
      table_.push_back(spec);
      const auto it = values.find(spec.name);
      values_[spec.name] = it == values.end() ? spec.default_value : it->second;
    }

  dynamic_reconfigure::ConfigDescription description;
  dynamic_reconfigure::Group group;
  group.name = "Default";
  group.id = 0;
  group.parent = 0;
  for (const ParameterSpec& spec : table_)
  {
    dynamic_reconfigure::ParamDescription p;
    p.name = spec.name;
    p.type = toString(spec.type);
    p.level = 0;
    p.description = spec.description;
    if (spec.type == Type::String && !spec.allowed.empty())
    {
      p.description += p.description.empty() ? "one of: " : " (one of: ";
      for (size_t i = 0; i < spec.allowed.size(); ++i)
        p.description += (i ? ", " : "") + spec.allowed[i];
      p.description += spec.description.empty() ? "" : ")";
    }
    group.parameters.push_back(p);
  }
  description.groups.push_back(group);
  description.dflt = message([](const ParameterSpec& s) { return s.default_value; });
  description.min = message([](const ParameterSpec& s) {
    return s.type == Type::Bool ? std::string("false") : s.type == Type::String ? std::string() : formatNumber(s.min);
  });
  description.max = message([](const ParameterSpec& s) {
    return s.type == Type::Bool ? std::string("true") : s.type == Type::String ? std::string() : formatNumber(s.max);
  });

  descriptions_ = nh_.advertise<dynamic_reconfigure::ConfigDescription>("parameter_descriptions", 1, true);
  updates_ = nh_.advertise<dynamic_reconfigure::Config>("parameter_updates", 1, true);
  descriptions_.publish(description);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    updates_.publish(current());
  }
  service_ = nh_.advertiseService("set_parameters", &ParameterServer::setParameters, this);
}

dynamic_reconfigure::Config ParameterServer::message(const std::function<std::string(const ParameterSpec&)>& value) const
{
  dynamic_reconfigure::Config config;
  for (const ParameterSpec& spec : table_)
  {
    const std::string text = value(spec);
    switch (spec.type)
    {
      case Type::Bool:
      {
        dynamic_reconfigure::BoolParameter p;
        p.name = spec.name;
        p.value = parseBool(text);
        config.bools.push_back(p);
        break;
      }
      case Type::Int:
      {
        dynamic_reconfigure::IntParameter p;
        p.name = spec.name;
        p.value = static_cast<int>(std::lround(parseNumber(text)));
        config.ints.push_back(p);
        break;
      }
      case Type::Double:
      {
        dynamic_reconfigure::DoubleParameter p;
        p.name = spec.name;
        p.value = parseNumber(text);
        config.doubles.push_back(p);
        break;
      }
      default:
      {
        dynamic_reconfigure::StrParameter p;
        p.name = spec.name;
        p.value = text;
        config.strs.push_back(p);
        break;
      }
    }
  }
  dynamic_reconfigure::GroupState group;
  group.name = "Default";
  group.state = true;
  group.id = 0;
  group.parent = 0;
  config.groups.push_back(group);
  return config;
}

dynamic_reconfigure::Config ParameterServer::current() const
{
  return message([this](const ParameterSpec& s) { return values_.at(s.name); });
}

bool ParameterServer::setParameters(dynamic_reconfigure::Reconfigure::Request& req,
                                    dynamic_reconfigure::Reconfigure::Response& res)
{
  std::lock_guard<std::mutex> lock(mutex_);
  // What the client sent, as text; names the table does not have are ignored (as dynamic_reconfigure does).
  std::map<std::string, std::string> sent;
  for (const auto& p : req.config.bools)
    sent[p.name] = p.value ? "true" : "false";
  for (const auto& p : req.config.ints)
    sent[p.name] = std::to_string(p.value);
  for (const auto& p : req.config.doubles)
    sent[p.name] = formatNumber(p.value);
  for (const auto& p : req.config.strs)
    sent[p.name] = p.value;
  std::map<std::string, std::string> changes;
  for (const ParameterSpec& spec : table_)
  {
    const auto it = sent.find(spec.name);
    if (it != sent.end() && !same(spec, it->second, values_.at(spec.name)))
      changes[spec.name] = it->second;
  }
  std::string error;
  if (!changes.empty() && apply_(changes, error))
  {
    for (const ParameterSpec& spec : table_)
    {
      const auto it = changes.find(spec.name);
      if (it == changes.end())
        continue;
      values_[spec.name] = it->second;
      // As dynamic_reconfigure does: the parameter server shows what is in force, typed.
      if (spec.type == Type::Bool)
        nh_.setParam(spec.name, parseBool(it->second));
      else if (spec.type == Type::Int)
        nh_.setParam(spec.name, static_cast<int>(std::lround(parseNumber(it->second))));
      else if (spec.type == Type::Double)
        nh_.setParam(spec.name, parseNumber(it->second));
      else
        nh_.setParam(spec.name, it->second);
    }
    updates_.publish(current());
  }
  res.config = current();
  return true;
}

}  // namespace stereo_pf
