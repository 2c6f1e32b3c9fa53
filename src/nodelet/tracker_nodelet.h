// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The tracker nodelet: camera1394stereo-style stereo topics in, 3D estimate, track status, particles, markers,
// debug images, TF and diagnostics out. See docs/ros_runtime.md for topics, parameters and services. Private: the
// class is reached through pluginlib (stereo_pf/TrackerNodelet) only, and this header is not installed.
//
// It only puts together pieces that each do one job:
//  - NodeletOptions: the nodelet's own parameters, read once;
//  - EngineHost: the engine, its plugins and their parameter tree, and the lock that keeps other threads out mid-step;
//  - FrameInput: the synchronised stereo topics and ~target_roi_topic;
//  - FramePipeline: the frame thread (track, publish);
//  - TargetRequests: target regions waiting for the frame thread, and their answers;
//  - ReconfigureBridge: a ParameterServer (dynamic_reconfigure) per component, driven by its parameter table -> the engine;
//  - TargetServices: ~set_target, ~save_target, ~load_target, ~reset;
//  - TrackerStatus: counters, drop warnings, diagnostics.
//
// Threading model:
//  - The synchronised image/camera_info sets and the ~target_roi_topic arrive on the nodelet's single-threaded
//    queue (FrameInput). That callback only stamps the set's arrival and puts it into a one-place slot
//    (LatestSlot): it never waits, so the subscriber queues do not overflow under load. A set still waiting in the
//    slot when the next one comes is replaced and counted as dropped (overload): the tracker always works on the
//    newest frame, and the latency it reports (arrival -> publish) includes the wait.
//  - One worker thread (FramePipeline, the frame thread) takes sets from the slot, runs the engine's step() and
//    publishes, holding EngineHost::mutex for the whole of it. Only it runs the engine.
//  - Services, dynamic_reconfigure and the diagnostics timer run on the multi-threaded queue. They never
//    touch the engine mid-step: a reconfigure change is checked at once on a copy of the tree (a rejected one
//    changes nothing and the server is answered with the values in force); accepted, it is written into the tree
//    under EngineHost::mutex (between two steps) and queued in the engine (setConfig, requestPluginReconfigure),
//    which applies it at the start of its next step. set_target regions are queued in TargetRequests and learned
//    by the frame thread before its next step; save/load target take EngineHost::mutex; reset uses the engine's
//    own thread-safe reset().
//  - Statistics for the diagnostics and ~status are guarded by TrackerStatus's own mutex.
#pragma once

#include <memory>

#include <nodelet/nodelet.h>

#include "engine_host.h"
#include "frame_input.h"
#include "frame_pipeline.h"
#include "nodelet_options.h"
#include "reconfigure_bridge.h"
#include "target_requests.h"
#include "target_services.h"
#include "tracker_status.h"

namespace stereo_pf
{
class TrackerNodelet : public nodelet::Nodelet
{
public:
  TrackerNodelet() = default;
  ~TrackerNodelet() override;

private:
  void onInit() override;
  /// The start-up target: a file, else a region of the first frame, else ~set_target / ~target_roi_topic later.
  void startupTarget();

  // Declared in the order they are needed; destroyed in reverse, the engine (and its plugin loaders) last.
  NodeletOptions options_;
  EngineHost host_;
  std::unique_ptr<TrackerStatus> status_;
  TargetRequests requests_;
  std::unique_ptr<ReconfigureBridge> reconfigure_;
  std::unique_ptr<FrameInput> input_;
  std::unique_ptr<FramePipeline> pipeline_;
  std::unique_ptr<TargetServices> services_;
};

}  // namespace stereo_pf
