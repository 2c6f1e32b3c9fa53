// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
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

/// One row of a component's parameter table: what a parameter is, its default, what is allowed and what it means.
/// The engine writes its table out (EngineConfig::table()); a plugin's table is what its typed getters declare when
/// they read it (Parameters::declared()). The validation, the reconfigure servers and the YAML template's check are
/// driven by these rows.
struct ParameterSpec
{
  enum class Type
  {
    Bool,
    Int,
    Double,
    String,
    List  ///< a list of numbers, "[a, b, c]"
  };
  std::string name;                  ///< key relative to the component's namespace, e.g. "particles"
  Type type = Type::Double;
  std::string default_value;         ///< as text (what the getter falls back to)
  double min = 0.0, max = 0.0;       ///< Int and Double: the allowed range
  std::vector<std::string> allowed;  ///< String: the allowed values (empty: any)
  std::string description;           ///< what it means (empty when the getter gave none; stereo_pf's own all have one)
  /// Can be changed while running (a reconfigure server offers it). Set by the component's table; for a plugin,
  /// the parameters its reconfigure() reads again.
  bool reconfigurable = false;
};
/// "bool", "int", "double", "str" or "list" (dynamic_reconfigure's names for the first four).
const char* toString(ParameterSpec::Type type);

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
  /// What the typed getters declared about the keys they were asked for under this view (names relative to it),
  /// in the order first asked: the table of the component that reads this view. `reconfigurable` is false and
  /// `description` empty unless a getter gave one.
  std::vector<ParameterSpec> declared() const;
  /// Forget which keys were asked for and what was declared (the whole tree's record, not only this view's).
  void forgetAsked();

  /// A number in [min, max]; `fallback` when absent. Throws ParameterError when malformed or out of range.
  /// Each getter also declares the parameter (declared()): its type, the fallback as its default, its range and
  /// `description`.
  double getDouble(const std::string& key, double fallback, double min, double max,
                   const std::string& description = "") const;
  /// An integer in [min, max]; `fallback` when absent.
  int getInt(const std::string& key, int fallback, int min, int max, const std::string& description = "") const;
  /// A boolean (true/false/1/0/yes/no); `fallback` when absent.
  bool getBool(const std::string& key, bool fallback, const std::string& description = "") const;
  /// A string; when `allowed` is not empty the value must be one of them.
  std::string getString(const std::string& key, const std::string& fallback,
                        const std::vector<std::string>& allowed = {}, const std::string& description = "") const;
  /// A list of numbers written "[a, b, c]" (or a single number); `fallback` when absent.
  std::vector<double> getDoubles(const std::string& key, const std::vector<double>& fallback,
                                 const std::string& description = "") const;
  /// Check `value` (text) against `spec` as the typed getter would: "" when it is allowed, else why not (naming
  /// the parameter under this view).
  std::string check(const ParameterSpec& spec, const std::string& value) const;

private:
  /// Which keys the typed getters were asked for (shared by the views of one tree; getters may run on
  /// several threads, hence the mutex).
  struct Asked
  {
    std::mutex mutex;
    std::set<std::string> keys;
    std::vector<ParameterSpec> declared;  ///< full key names, in the order first asked
  };
  std::string full(const std::string& key) const;
  /// Record `spec` (its name relative to this view) as asked for and declared.
  void declare(ParameterSpec spec) const;
  std::shared_ptr<std::map<std::string, std::string>> values_;
  std::shared_ptr<Asked> asked_;
  std::string prefix_;
};

/// The candidate nearest to `key` by edit distance (Levenshtein: insertions, deletions, substitutions), or
/// "" when none is within max(2, |key| / 3) edits. For "did you mean" messages.
std::string closestKey(const std::string& key, const std::vector<std::string>& candidates);

}  // namespace stereo_pf
