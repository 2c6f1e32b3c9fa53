// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// A dynamic_reconfigure server for any component, driven by its parameter table (ParameterSpec rows) instead of a
// generated .cfg type: the same protocol (~<ns>/set_parameters, latched parameter_descriptions and
// parameter_updates), so `dynparam` and dynamic_reconfigure's clients work with it, and a third party's cue is
// reconfigurable without a .cfg of its own. Values travel as text, as in the Parameters tree.
#pragma once

#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <dynamic_reconfigure/Config.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <ros/ros.h>

#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
class ParameterServer
{
public:
  /// Called with the values a client changed (name -> text, names relative to the server's namespace); returns
  /// false with `error` set to refuse them all (the server keeps and answers with the values in force).
  using Apply = std::function<bool(const std::map<std::string, std::string>& changes, std::string& error)>;

  /// Serve the bool, int, double and string rows of `table` under `nh`'s namespace; `values` holds those in force
  /// (a row without one shows its default).
  ParameterServer(const ros::NodeHandle& nh, const std::vector<ParameterSpec>& table,
                  const std::map<std::string, std::string>& values, Apply apply);

private:
  bool setParameters(dynamic_reconfigure::Reconfigure::Request& req, dynamic_reconfigure::Reconfigure::Response& res);
  /// The values in force as a message (mutex_ held).
  dynamic_reconfigure::Config current() const;
  /// One value per row as a message: `value(row)` gives its text.
  dynamic_reconfigure::Config message(const std::function<std::string(const ParameterSpec&)>& value) const;

  ros::NodeHandle nh_;
  std::vector<ParameterSpec> table_;
  Apply apply_;
  std::mutex mutex_;
  std::map<std::string, std::string> values_;  ///< in force, as text
  ros::Publisher descriptions_, updates_;
  ros::ServiceServer service_;
};

}  // namespace stereo_pf
