// dynamic_reconfigure -> the engine: one server per component (~engine, ~state_model, ~<cue>), each in the namespace
// of the parameters it changes. A value is checked at once on a copy of the configuration in force (a rejected one
// changes nothing, and the server is answered with the values in force), then queued; the frame thread applies
// what was queued before its next step (apply()). Server callbacks run on the multi-threaded queue.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>

#include "engine_host.h"
#include "stereo_pf/TrackerEngineConfig.h"
#include "stereo_pf/TrackerObservationConfig.h"
#include "stereo_pf/TrackerStateModelConfig.h"

namespace stereo_pf
{
class ReconfigureBridge
{
public:
  /// `host` must hold a tracker; its tree as it is now is the configuration in force.
  ReconfigureBridge(const std::string& name, EngineHost& host);

  /// Start the servers under `mt_pnh`.
  void start(const ros::NodeHandle& mt_pnh);
  /// The frame thread, host.mutex held: write the accepted values into the tree the plugins read and queue them
  /// for the engine, which applies them at the start of its next step.
  void apply();

private:
  using ObservationServer = dynamic_reconfigure::Server<TrackerObservationConfig>;

  void engineReconfigure(TrackerEngineConfig& config, uint32_t level);
  void stateReconfigure(TrackerStateModelConfig& config, uint32_t level);
  void observationReconfigure(const std::string& name, TrackerObservationConfig& config, uint32_t level);
  /// The reconfigure values in force (from `accepted_`, mutex_ held).
  TrackerEngineConfig engineInForce() const;
  TrackerStateModelConfig stateInForce() const;
  TrackerObservationConfig observationInForce(const std::string& name) const;
  /// Check `changes` (tree key -> value) of the server `server` ("engine", "state_model" or a cue's name) on
  /// a copy of the configuration in force: the engine config parsed, the changed plugin constructed. On success
  /// they become the configuration in force and are queued for the frame thread; otherwise nothing changes and
  /// `error` says why (mutex_ held).
  bool accept(const std::string& server, const std::map<std::string, std::string>& changes, std::string& error);

  std::string name_;
  EngineHost& host_;

  std::mutex mutex_;
  Parameters accepted_;                                 ///< the configuration in force plus accepted changes
  std::map<std::string, std::string> pending_changes_;  ///< accepted, not yet applied: key -> value
  std::optional<EngineConfig> pending_engine_config_;
  bool pending_plugins_ = false;                        ///< a plugin's parameters changed

  boost::recursive_mutex engine_server_mutex_, state_server_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<TrackerEngineConfig>> engine_server_;
  std::unique_ptr<dynamic_reconfigure::Server<TrackerStateModelConfig>> state_server_;
  std::vector<std::unique_ptr<boost::recursive_mutex>> observation_server_mutexes_;
  std::vector<std::unique_ptr<ObservationServer>> observation_servers_;
};

}  // namespace stereo_pf
