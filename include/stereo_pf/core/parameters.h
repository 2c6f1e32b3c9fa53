// ROS-free parameter tree: a flat map of "ns/key" -> text, filled from YAML (CLI) or the ROS parameter
// server (nodelet). Typed getters validate ranges and throw ParameterError naming the parameter.
#pragma once

#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace stereo_pf
{
/// Thrown for a missing, malformed or out-of-range parameter; what() says which, what was given and
/// what is allowed.
class ParameterError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// A view into a shared parameter map under a namespace prefix. Copies share the same map, so values
/// set later (reconfigure) are seen by every view.
class Parameters
{
public:
  /// An empty tree.
  Parameters();

  /// A view of the sub-namespace `ns` (keys are joined with '/').
  Parameters sub(const std::string& ns) const;
  /// The namespace this view reads, e.g. "colour" (empty at the root); used in error messages.
  const std::string& prefix() const { return prefix_; }

  /// Store a value (text form; numbers as written, booleans as true/false, lists as "[a, b, c]").
  void set(const std::string& key, const std::string& value);
  void set(const std::string& key, double value);
  void set(const std::string& key, int value);
  void set(const std::string& key, bool value);
  /// True when key exists in this view.
  bool has(const std::string& key) const;
  /// The raw text, or `fallback` when absent.
  std::string raw(const std::string& key, const std::string& fallback = "") const;
  /// Every key (relative to this view) that starts with this view's prefix.
  std::vector<std::string> keys() const;

  /// A number in [min, max]; `fallback` when absent. Throws ParameterError when malformed or out of range.
  double getDouble(const std::string& key, double fallback, double min, double max) const;
  /// An integer in [min, max]; `fallback` when absent.
  int getInt(const std::string& key, int fallback, int min, int max) const;
  /// A boolean (true/false/1/0/yes/no); `fallback` when absent.
  bool getBool(const std::string& key, bool fallback) const;
  /// A string; when `allowed` is not empty the value must be one of them.
  std::string getString(const std::string& key, const std::string& fallback,
                        const std::vector<std::string>& allowed = {}) const;
  /// A list of numbers written "[a, b, c]" (or a single number); `fallback` when absent.
  std::vector<double> getDoubles(const std::string& key, const std::vector<double>& fallback) const;

private:
  std::string full(const std::string& key) const;
  std::shared_ptr<std::map<std::string, std::string>> values_;
  std::string prefix_;
};

}  // namespace stereo_pf
