// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/plugin_loader.h"

#include <algorithm>
#include <set>

namespace stereo_pf
{
namespace
{
std::string join(const std::vector<std::string>& items)
{
  std::string s;
  for (const auto& i : items)
    s += (s.empty() ? "" : ", ") + i;
  return s.empty() ? "(none: is this package on ROS_PACKAGE_PATH?)" : s;
}

template <class Base>
std::shared_ptr<Base> create(pluginlib::ClassLoader<Base>& loader, const std::string& kind, const std::string& type,
                             const std::string& name)
{
  const std::vector<std::string> declared = loader.getDeclaredClasses();
  if (std::find(declared.begin(), declared.end(), type) == declared.end())
    throw PluginError(kind + " '" + name + "': unknown type '" + type + "'; declared " + kind + " types: " +
                      join(declared) +
                      ". A plugin of another package is declared only when that package's package.xml depends on "
                      "stereo_pf and exports its plugin XML (<export><stereo_pf plugin=\"${prefix}/<file>.xml\"/>"
                      "</export>) naming the class, and the package is on ROS_PACKAGE_PATH (source its workspace's "
                      "setup.bash; a package that uses it lists it as a run dependency). See docs/writing_a_cue.md");
  try
  {
    return std::shared_ptr<Base>(loader.createUnmanagedInstance(type));
  }
  catch (const pluginlib::PluginlibException& e)
  {
    throw PluginError(kind + " '" + name + "' of type '" + type + "' could not be created: " + e.what());
  }
}
}  // namespace

const std::vector<std::string> kRosRuntimeParameters = {
  "approximate_sync", "queue_size", "images_rectified", "max_stamp_difference", "image_transport", "camera_frame",
  "object_frame", "publish_tf", "camera_parent_frame", "target_file", "target_roi", "target_roi_topic",
  "set_target_timeout", "marker_radius", "marker_sigma_scale", "trajectory_length", "diagnostic_period",
  "publish_when_lost"
};

std::vector<std::string> unknownParameters(const Parameters& params, const std::vector<std::string>& also_known)
{
  std::vector<std::string> known = params.askedKeys();
  known.insert(known.end(), also_known.begin(), also_known.end());
  std::set<std::string> namespaces;
  for (const auto& k : known)
    if (k.find('/') != std::string::npos)
      namespaces.insert(k.substr(0, k.find('/')));
  std::vector<std::string> messages;
  for (const auto& key : params.unaskedKeys())
  {
    if (std::find(also_known.begin(), also_known.end(), key) != also_known.end())
      continue;
    std::string m = "unknown parameter '" + key + "' (ignored)";
    const auto slash = key.find('/');
    const std::string ns = slash == std::string::npos ? "" : key.substr(0, slash);
    if (!ns.empty() && !namespaces.count(ns))
    {
      // A whole namespace nobody reads: a cue that is not loaded, or a misspelt cue name.
      std::string loaded;
      for (const auto& n : namespaces)
        loaded += (loaded.empty() ? "" : ", ") + n;
      const std::string near_ns = closestKey(ns, std::vector<std::string>(namespaces.begin(), namespaces.end()));
      m += ": nothing loaded reads the namespace '" + ns + "'" +
           (near_ns.empty() ? std::string(" (an observation model not in observation_models?)") :
                              " (did you mean '" + near_ns + "'?)") +
           "; the namespaces read are: " + loaded;
    }
    else
    {
      const std::string near = closestKey(key, known);
      if (!near.empty())
        m += ": did you mean '" + near + "'?";
      else
        m += ": not a parameter of the tracker, the engine, the state model or a loaded cue (config/tracker.yaml "
             "lists them all)";
    }
    messages.push_back(m);
  }
  return messages;
}

Tracker::Tracker(const Parameters& params)
  : state_loader_(std::make_unique<pluginlib::ClassLoader<StateModel>>("stereo_pf", "stereo_pf::StateModel"))
  , observation_loader_(
        std::make_unique<pluginlib::ClassLoader<ObservationModel>>("stereo_pf", "stereo_pf::ObservationModel"))
{
  const Parameters state_params = params.sub("state_model");
  const std::string state_type = state_params.getString("type", "stereo_pf/Velocity3D");
  std::shared_ptr<StateModel> state = createStateModel(state_type, "state_model", state_params);
  types_.push_back(state_type);

  std::vector<std::shared_ptr<ObservationModel>> observations;
  const Parameters list = params.sub("observation_models");
  if (!list.has("0/type"))
  {
    if (!list.keys().empty())
      throw PluginError("observation_models must be a list of {name, type} entries");
    // The default: the colour histogram finds the object, its colour outline pins it to a fraction of a pixel.
    for (const auto& [type, name] : kDefaultObservationModels)
    {
      observations.push_back(createObservationModel(type, name, params.sub(name)));
      types_.push_back(type);
    }
  }
  for (int i = 0; list.has(std::to_string(i) + "/type"); ++i)
  {
    const Parameters entry = list.sub(std::to_string(i));
    const std::string type = entry.getString("type", "");
    const std::string name = entry.getString("name", "");
    if (name.empty())
      throw PluginError("observation_models[" + std::to_string(i) + "] (type '" + type + "') needs a name");
    for (const auto& m : observations)
      if (m->name() == name)
        throw PluginError("observation_models: the name '" + name + "' is used twice");
    observations.push_back(createObservationModel(type, name, params.sub(name)));
    types_.push_back(type);
  }
  engine_ = std::make_unique<FilterEngine>(state, observations, EngineConfig::fromParameters(params.sub("engine")));
}

Tracker::~Tracker()
{
  engine_.reset();  // drop the plugins before their loaders go
}

std::vector<std::string> Tracker::declaredStateModels() const
{
  return state_loader_->getDeclaredClasses();
}

std::vector<std::string> Tracker::declaredObservationModels() const
{
  return observation_loader_->getDeclaredClasses();
}

std::shared_ptr<StateModel> Tracker::createStateModel(const std::string& type, const std::string& name,
                                                      const Parameters& params)
{
  auto model = create(*state_loader_, "state model", type, name);
  model->initialize(name, params);
  return model;
}

std::shared_ptr<ObservationModel> Tracker::createObservationModel(const std::string& type, const std::string& name,
                                                                  const Parameters& params)
{
  auto model = create(*observation_loader_, "observation model", type, name);
  model->initialize(name, params);
  return model;
}

std::vector<ParameterSpec> Tracker::pluginTable(const std::string& type, const std::string& component,
                                                const Parameters& params)
{
  Parameters trial = params.copy();  // its own record of what was asked
  const Parameters view = trial.sub(component);
  std::vector<ParameterSpec> table;
  auto mark = [&](const auto& model) {
    table = view.declared();
    trial.forgetAsked();
    model->reconfigure();
    const std::vector<std::string> again = view.askedKeys();
    for (ParameterSpec& spec : table)
      spec.reconfigurable = std::find(again.begin(), again.end(), spec.name) != again.end();
  };
  if (component == "state_model")
    mark(createStateModel(type, component, view));
  else
    mark(createObservationModel(type, component, view));
  return table;
}

}  // namespace stereo_pf
