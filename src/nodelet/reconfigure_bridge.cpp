// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The reconfigure bridge (see the header).
#include "reconfigure_bridge.h"


namespace stereo_pf
{
void ReconfigureBridge::serve(const ros::NodeHandle& mt_pnh, const std::string& component,
                              const std::vector<ParameterSpec>& table)
{
  std::vector<ParameterSpec> served;
  std::map<std::string, std::string> values;
  const Parameters view = host_.params.sub(component);
  for (const ParameterSpec& spec : table)
    if (spec.reconfigurable)
    {
      served.push_back(spec);
      if (view.has(spec.name))
        values[spec.name] = view.raw(spec.name);
    }
  servers_.push_back(std::make_unique<ParameterServer>(
      ros::NodeHandle(mt_pnh, component), served, values,
      [this, component](const std::map<std::string, std::string>& changes, std::string& error) {
        return accept(component, changes, error);
      }));
}

void ReconfigureBridge::start(const ros::NodeHandle& mt_pnh)
{
  Tracker& tracker = *host_.tracker;
  const std::vector<std::string>& types = tracker.pluginTypes();  // state model first, then the cues in order
  serve(mt_pnh, "engine", EngineConfig::table());
  serve(mt_pnh, "state_model", tracker.pluginTable(types.at(0), "state_model", host_.params));
  const auto& models = tracker.engine().observationModels();
  for (size_t i = 0; i < models.size(); ++i)
    serve(mt_pnh, models[i]->name(), tracker.pluginTable(types.at(i + 1), models[i]->name(), host_.params));
}

bool ReconfigureBridge::accept(const std::string& component, const std::map<std::string, std::string>& changes,
                               std::string& error)
{
  // Between two steps: the frame thread holds the lock for a whole step, and only then do the engine and the
  // plugins read the tree.
  std::lock_guard<std::mutex> lock(host_.mutex);
  Tracker& tracker = *host_.tracker;
  Parameters trial = host_.params.copy();
  for (const auto& [key, value] : changes)
    trial.set(component + "/" + key, value);
  EngineConfig engine_config;
  try
  {
    engine_config = EngineConfig::fromParameters(trial.sub("engine"));
    const std::vector<std::string>& types = tracker.pluginTypes();
    if (component == "state_model")
      tracker.createStateModel(types.at(0), component, trial.sub(component));
    const auto& models = tracker.engine().observationModels();  // the list itself never changes
    for (size_t i = 0; i < models.size(); ++i)
      if (models[i]->name() == component)
        tracker.createObservationModel(types.at(i + 1), component, trial.sub(component));
  }
  catch (const std::exception& e)
  {
    error = e.what();
    ROS_ERROR_NAMED(name_, "reconfigure ~%s rejected, nothing changed (the server keeps the values in force): %s",
                    component.c_str(), error.c_str());
    return false;
  }
  for (const auto& [key, value] : changes)
  {
    const std::string full = component + "/" + key;
    ROS_INFO_NAMED(name_, "reconfigure accepted (applied at the next frame): %s = %s (was %s)", full.c_str(),
                   value.c_str(), host_.params.has(full) ? host_.params.raw(full).c_str() : "the default");
    host_.params.set(full, value);
  }
  if (component == "engine")
    host_.engine().setConfig(engine_config);
  else
    host_.engine().requestPluginReconfigure();
  return true;
}

}  // namespace stereo_pf
