// ROS-free parameter tree: a flat map of "ns/key" -> text, filled from YAML (CLI) or the ROS parameter
// server (nodelet). Typed getters validate ranges and throw ParameterError naming the parameter.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <set>
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
/// set later (reconfigure) are seen by every view. The typed getters also record which keys were asked for
/// (present or not), so the keys nobody reads (misspelt or misplaced) can be reported (unaskedKeys()).
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
  /// A deep copy of the whole tree (same prefix): its own values and its own record of asked keys.
  Parameters copy() const;
  /// Every key (relative to this view) a typed getter was asked for, present or not: the known parameters.
  std::vector<std::string> askedKeys() const;
  /// The keys present (relative to this view) that no typed getter asked for: misspelt or misplaced ones.
  std::vector<std::string> unaskedKeys() const;

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
  /// Which keys the typed getters were asked for (shared by the views of one tree; getters may run on
  /// several threads, hence the mutex).
  struct Asked
  {
    std::mutex mutex;
    std::set<std::string> keys;
  };
  std::string full(const std::string& key) const;
  void noteAsked(const std::string& key) const;
  std::shared_ptr<std::map<std::string, std::string>> values_;
  std::shared_ptr<Asked> asked_;
  std::string prefix_;
};

/// The candidate nearest to `key` by edit distance (Levenshtein: insertions, deletions, substitutions), or
/// "" when none is within max(2, |key| / 3) edits. For "did you mean" messages.
std::string closestKey(const std::string& key, const std::vector<std::string>& candidates);

}  // namespace stereo_pf
