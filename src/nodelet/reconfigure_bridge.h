// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// dynamic_reconfigure -> the engine: one server per component (~engine, ~state_model, ~<cue>), in the namespace of
// the parameters it changes, serving the component's parameter table: the engine's reconfigurable rows
// (EngineConfig::table()), and for a plugin every parameter its reconfigure() reads again (learned from the plugin
// itself, so a third party's cue is served like ours). A change is checked at once on a copy of the tree (the
// engine's configuration parsed, the changed plugin constructed); accepted, it is written into the tree between two
// steps (under EngineHost::mutex) and the engine is told through its one queue (setConfig /
// requestPluginReconfigure), applied at the start of its next step; refused, nothing changes and the server
// answers with the values in force. Server callbacks run on the multi-threaded queue.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <ros/ros.h>

#include "engine_host.h"
#include "parameter_server.h"

namespace stereo_pf
{
class ReconfigureBridge
{
public:
  /// `host` must hold a tracker.
  ReconfigureBridge(const std::string& name, EngineHost& host) : name_(name), host_(host) {}

  /// Start the servers under `mt_pnh`.
  void start(const ros::NodeHandle& mt_pnh);

private:
  /// Check and apply `changes` (names relative to `component`: "engine", "state_model" or a cue's name).
  bool accept(const std::string& component, const std::map<std::string, std::string>& changes, std::string& error);
  /// Serve `table` (its reconfigurable rows) for `component`.
  void serve(const ros::NodeHandle& mt_pnh, const std::string& component, const std::vector<ParameterSpec>& table);

  std::string name_;
  EngineHost& host_;
  std::vector<std::unique_ptr<ParameterServer>> servers_;
};

}  // namespace stereo_pf
