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

Parameters::Parameters() : values_(std::make_shared<std::map<std::string, std::string>>())
{
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

double Parameters::getDouble(const std::string& key, double fallback, double min, double max) const
{
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

int Parameters::getInt(const std::string& key, int fallback, int min, int max) const
{
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

bool Parameters::getBool(const std::string& key, bool fallback) const
{
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
                                  const std::vector<std::string>& allowed) const
{
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

std::vector<double> Parameters::getDoubles(const std::string& key, const std::vector<double>& fallback) const
{
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
