// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/parameters.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace stereo_pf
{
namespace
{
std::string trim(const std::string& s)
{
  const auto b = s.find_first_not_of(" \t\n\r");
  if (b == std::string::npos)
    return "";
  const auto e = s.find_last_not_of(" \t\n\r");
  return s.substr(b, e - b + 1);
}

bool parseDouble(const std::string& text, double& out)
{
  const std::string t = trim(text);
  if (t.empty())
    return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(t.c_str(), &end);
  return errno == 0 && end == t.c_str() + t.size();
}

std::string formatDouble(double v)
{
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}
}  // namespace

Parameters::Parameters()
  : values_(std::make_shared<std::map<std::string, std::string>>()), asked_(std::make_shared<Asked>())
{
}

Parameters Parameters::copy() const
{
  Parameters p;
  *p.values_ = *values_;
  p.prefix_ = prefix_;
  return p;
}

void Parameters::declare(ParameterSpec spec) const
{
  spec.name = full(spec.name);
  std::lock_guard<std::mutex> lock(asked_->mutex);
  asked_->keys.insert(spec.name);
  for (ParameterSpec& s : asked_->declared)
    if (s.name == spec.name)
    {
      s = std::move(spec);  // the last read declares it (a component reads its parameters again when reconfigured)
      return;
    }
  asked_->declared.push_back(std::move(spec));
}

std::vector<ParameterSpec> Parameters::declared() const
{
  const std::string p = prefix_.empty() ? "" : prefix_ + "/";
  std::vector<ParameterSpec> out;
  std::lock_guard<std::mutex> lock(asked_->mutex);
  for (const ParameterSpec& s : asked_->declared)
    if (s.name.compare(0, p.size(), p) == 0)
    {
      out.push_back(s);
      out.back().name = s.name.substr(p.size());
    }
  return out;
}

void Parameters::forgetAsked()
{
  std::lock_guard<std::mutex> lock(asked_->mutex);
  asked_->keys.clear();
  asked_->declared.clear();
}

const char* toString(ParameterSpec::Type type)
{
  switch (type)
  {
    case ParameterSpec::Type::Bool:
      return "bool";
    case ParameterSpec::Type::Int:
      return "int";
    case ParameterSpec::Type::Double:
      return "double";
    case ParameterSpec::Type::String:
      return "str";
    case ParameterSpec::Type::List:
      return "list";
  }
  return "str";
}

std::string Parameters::check(const ParameterSpec& spec, const std::string& value) const
{
  // The getter itself on a tree of this one value, under this view's namespace (so the message names the key).
  Parameters trial;
  trial.prefix_ = prefix_;
  trial.set(spec.name, value);
  try
  {
    switch (spec.type)
    {
      case ParameterSpec::Type::Bool:
        trial.getBool(spec.name, false);
        break;
      case ParameterSpec::Type::Int:
        trial.getInt(spec.name, 0, static_cast<int>(spec.min), static_cast<int>(spec.max));
        break;
      case ParameterSpec::Type::Double:
        trial.getDouble(spec.name, 0.0, spec.min, spec.max);
        break;
      case ParameterSpec::Type::String:
        trial.getString(spec.name, "", spec.allowed);
        break;
      case ParameterSpec::Type::List:
        trial.getDoubles(spec.name, {});
        break;
    }
  }
  catch (const ParameterError& e)
  {
    return e.what();
  }
  return "";
}

std::vector<std::string> Parameters::askedKeys() const
{
  const std::string p = prefix_.empty() ? "" : prefix_ + "/";
  std::vector<std::string> out;
  std::lock_guard<std::mutex> lock(asked_->mutex);
  for (const auto& k : asked_->keys)
    if (k.compare(0, p.size(), p) == 0)
      out.push_back(k.substr(p.size()));
  return out;
}

std::vector<std::string> Parameters::unaskedKeys() const
{
  const std::string p = prefix_.empty() ? "" : prefix_ + "/";
  std::vector<std::string> out;
  std::lock_guard<std::mutex> lock(asked_->mutex);
  for (const auto& kv : *values_)
    if (kv.first.compare(0, p.size(), p) == 0 && !asked_->keys.count(kv.first))
      out.push_back(kv.first.substr(p.size()));
  return out;
}

std::string closestKey(const std::string& key, const std::vector<std::string>& candidates)
{
  // Two-row dynamic programme over the edit distance.
  auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j)
      prev[j] = j;
    for (size_t i = 1; i <= a.size(); ++i)
    {
      cur[0] = i;
      for (size_t j = 1; j <= b.size(); ++j)
        cur[j] = std::min({ prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1) });
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  const size_t limit = std::max<size_t>(2, key.size() / 3);
  std::string best;
  size_t best_distance = limit + 1;
  for (const auto& c : candidates)
  {
    const size_t d = distance(key, c);
    if (d < best_distance)
    {
      best_distance = d;
      best = c;
    }
  }
  return best;
}

Parameters Parameters::sub(const std::string& ns) const
{
  Parameters p(*this);
  p.prefix_ = full(ns);
  return p;
}

std::string Parameters::full(const std::string& key) const
{
  return prefix_.empty() ? key : prefix_ + "/" + key;
}

void Parameters::set(const std::string& key, const std::string& value)
{
  (*values_)[full(key)] = value;
}
void Parameters::set(const std::string& key, double value)
{
  set(key, formatDouble(value));
}
void Parameters::set(const std::string& key, int value)
{
  set(key, std::to_string(value));
}
void Parameters::set(const std::string& key, bool value)
{
  set(key, std::string(value ? "true" : "false"));
}

bool Parameters::has(const std::string& key) const
{
  return values_->count(full(key)) > 0;
}

std::string Parameters::raw(const std::string& key, const std::string& fallback) const
{
  const auto it = values_->find(full(key));
  return it == values_->end() ? fallback : it->second;
}

std::vector<std::string> Parameters::keys() const
{
  std::vector<std::string> out;
  const std::string p = prefix_.empty() ? "" : prefix_ + "/";
  for (const auto& kv : *values_)
    if (kv.first.compare(0, p.size(), p) == 0)
      out.push_back(kv.first.substr(p.size()));
  return out;
}

double Parameters::getDouble(const std::string& key, double fallback, double min, double max,
                             const std::string& description) const
{
  declare({ key, ParameterSpec::Type::Double, formatDouble(fallback), min, max, {}, description, false });
  if (!has(key))
    return fallback;
  double v = 0.0;
  const std::string text = raw(key);
  if (!parseDouble(text, v) || std::isnan(v))
    throw ParameterError("parameter '" + full(key) + "' must be a number, got '" + text + "'");
  if (v < min || v > max)
    throw ParameterError("parameter '" + full(key) + "' = " + trim(text) + " is out of range [" + formatDouble(min) +
                         ", " + formatDouble(max) + "]");
  return v;
}

int Parameters::getInt(const std::string& key, int fallback, int min, int max, const std::string& description) const
{
  declare({ key, ParameterSpec::Type::Int, std::to_string(fallback), static_cast<double>(min), static_cast<double>(max),
            {}, description, false });
  if (!has(key))
    return fallback;
  double v = 0.0;
  const std::string text = raw(key);
  if (!parseDouble(text, v) || v != std::floor(v))
    throw ParameterError("parameter '" + full(key) + "' must be an integer, got '" + text + "'");
  if (v < min || v > max)
    throw ParameterError("parameter '" + full(key) + "' = " + trim(text) + " is out of range [" +
                         std::to_string(min) + ", " + std::to_string(max) + "]");
  return static_cast<int>(v);
}

bool Parameters::getBool(const std::string& key, bool fallback, const std::string& description) const
{
  declare({ key, ParameterSpec::Type::Bool, fallback ? "true" : "false", 0.0, 1.0, {}, description, false });
  if (!has(key))
    return fallback;
  std::string t = trim(raw(key));
  std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
  if (t == "true" || t == "1" || t == "yes" || t == "on")
    return true;
  if (t == "false" || t == "0" || t == "no" || t == "off")
    return false;
  throw ParameterError("parameter '" + full(key) + "' must be true or false, got '" + raw(key) + "'");
}

std::string Parameters::getString(const std::string& key, const std::string& fallback,
                                  const std::vector<std::string>& allowed, const std::string& description) const
{
  declare({ key, ParameterSpec::Type::String, fallback, 0.0, 0.0, allowed, description, false });
  const std::string v = has(key) ? trim(raw(key)) : fallback;
  if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), v) == allowed.end())
  {
    std::string list;
    for (const auto& a : allowed)
      list += (list.empty() ? "" : ", ") + a;
    throw ParameterError("parameter '" + full(key) + "' = '" + v + "' is not one of: " + list);
  }
  return v;
}

std::vector<double> Parameters::getDoubles(const std::string& key, const std::vector<double>& fallback,
                                           const std::string& description) const
{
  std::string text = "[";
  for (double v : fallback)
    text += (text.size() > 1 ? ", " : "") + formatDouble(v);
  declare({ key, ParameterSpec::Type::List, text + "]", 0.0, 0.0, {}, description, false });
  if (!has(key))
    return fallback;
  std::string t = trim(raw(key));
  if (!t.empty() && t.front() == '[')
  {
    if (t.back() != ']')
      throw ParameterError("parameter '" + full(key) + "' must be a list like [1, 2, 3], got '" + t + "'");
    t = t.substr(1, t.size() - 2);
  }
  std::vector<double> out;
  std::stringstream ss(t);
  std::string item;
  while (std::getline(ss, item, ','))
  {
    if (trim(item).empty())
      continue;
    double v = 0.0;
    if (!parseDouble(item, v))
      throw ParameterError("parameter '" + full(key) + "' has a non-numeric element '" + trim(item) + "'");
    out.push_back(v);
  }
  return out;
}

}  // namespace stereo_pf
