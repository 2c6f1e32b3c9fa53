// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The engine the nodelet runs, its plugins and the parameter tree they read, and the lock that keeps other threads
// out of it mid-step. Built once at start-up from the private namespace.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include <ros/node_handle.h>

#include "stereo_pf/ros/plugin_loader.h"

namespace stereo_pf
{
struct EngineHost
{
  /// The whole private tree; written under `mutex` only (reconfigure), read by the engine and plugins in a step.
  Parameters params;
  /// The engine and its plugins (the ClassLoaders inside outlive the plugins).
  std::unique_ptr<Tracker> tracker;
  /// Held by the frame thread for a whole step (from applying the queued requests to the end of publishing), and
  /// by what touches the engine or the tree from other threads (save/load target, reconfigure): they run between
  /// two steps, never during one.
  std::mutex mutex;

  FilterEngine& engine() { return tracker->engine(); }

  /// Build the Tracker from the private parameters under `pnh`. Returns "" or why it could not be built;
  /// `unknown` gets one message per parameter nothing reads (each also warned about under the logger `name`).
  std::string create(const ros::NodeHandle& pnh, const std::string& name, std::string& unknown);
};

}  // namespace stereo_pf
