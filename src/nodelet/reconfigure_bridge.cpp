// The reconfigure bridge (see the header).
#include "reconfigure_bridge.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <boost/bind/bind.hpp>

namespace stereo_pf
{
using namespace boost::placeholders;

namespace
{
std::string formatNumber(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.15g", v);  // reads back as the same number
  return buf;
}

std::string joinChanges(const std::map<std::string, std::string>& changes)
{
  std::string s;
  for (const auto& [key, value] : changes)
    s += (s.empty() ? "" : ", ") + key + " = " + value;
  return s;
}
}  // namespace

ReconfigureBridge::ReconfigureBridge(const std::string& name, EngineHost& host)
  : name_(name), host_(host), accepted_(host.params.copy())
{
}

void ReconfigureBridge::start(const ros::NodeHandle& mt_pnh)
{
  // Each server lives in the namespace of the parameters it changes (~engine, ~state_model, ~<cue>), so its
  // initial values are the configured ones. The engine's effective values are published first, so a
  // server never starts from its own defaults where the engine has different ones.
  const EngineConfig& c = host_.tracker->engine().config();
  ros::NodeHandle engine_nh(mt_pnh, "engine");
  auto seed = [&engine_nh](const std::string& key, const auto& value) {
    if (!engine_nh.hasParam(key))
      engine_nh.setParam(key, value);
  };
  seed("particles", c.particles);
  seed("resample_threshold", c.resample_threshold);
  seed("estimator", toString(c.estimator));
  seed("density_radius", c.density_radius);
  seed("found_similarity", c.found_similarity);
  seed("lost_similarity", c.lost_similarity);
  seed("respawn_fraction", c.respawn_fraction);
  seed("refine_jitter", c.refine_jitter);
  seed("refine_search_weight", c.refine_search_weight);
  seed("max_depth", c.max_depth);
  seed("background_margin", c.background_margin);

  engine_server_ = std::make_unique<dynamic_reconfigure::Server<TrackerEngineConfig>>(engine_server_mutex_, engine_nh);
  engine_server_->setCallback(boost::bind(&ReconfigureBridge::engineReconfigure, this, _1, _2));
  state_server_ = std::make_unique<dynamic_reconfigure::Server<TrackerStateModelConfig>>(
      state_server_mutex_, ros::NodeHandle(mt_pnh, "state_model"));
  state_server_->setCallback(boost::bind(&ReconfigureBridge::stateReconfigure, this, _1, _2));
  for (const auto& model : host_.tracker->engine().observationModels())
  {
    const std::string name = model->name();
    observation_server_mutexes_.push_back(std::make_unique<boost::recursive_mutex>());
    observation_servers_.push_back(
        std::make_unique<ObservationServer>(*observation_server_mutexes_.back(), ros::NodeHandle(mt_pnh, name)));
    observation_servers_.back()->setCallback(
        [this, name](TrackerObservationConfig& config, uint32_t level) { observationReconfigure(name, config, level); });
  }
}

void ReconfigureBridge::apply()
{
  std::map<std::string, std::string> changes;
  std::optional<EngineConfig> engine_config;
  bool plugins = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    changes.swap(pending_changes_);
    engine_config.swap(pending_engine_config_);
    std::swap(plugins, pending_plugins_);
  }
  // Reconfigure values were checked when they were accepted: here they are written into the tree the plugins
  // read, and the engine applies them at the start of its next step.
  for (const auto& [key, value] : changes)
  {
    ROS_INFO_NAMED(name_, "reconfigure applied: %s = %s (was %s)", key.c_str(), value.c_str(),
                   host_.params.has(key) ? host_.params.raw(key).c_str() : "the default");
    host_.params.set(key, value);
  }
  FilterEngine& engine = host_.engine();
  if (engine_config)
    engine.setConfig(*engine_config);
  if (plugins)
    engine.requestPluginReconfigure();
}

// Reconfigure transactions. A server's callback answers with the configuration it is given back, and the
// server keeps it: so a value a component rejects is replaced by the one in force, and nothing changes.
namespace
{
bool sameNumber(double a, double b)
{
  return std::fabs(a - b) <= 1e-12 * std::max(1.0, std::fabs(a));
}
}  // namespace

TrackerEngineConfig ReconfigureBridge::engineInForce() const
{
  const EngineConfig e = EngineConfig::fromParameters(accepted_.sub("engine"));  // accepted values parse
  TrackerEngineConfig c;
  c.particles = e.particles;
  c.resample_threshold = e.resample_threshold;
  c.estimator = toString(e.estimator);
  c.density_radius = e.density_radius;
  c.found_similarity = e.found_similarity;
  c.lost_similarity = e.lost_similarity;
  c.respawn_fraction = e.respawn_fraction;
  c.refine_jitter = e.refine_jitter;
  c.refine_search_weight = e.refine_search_weight;
  c.max_depth = e.max_depth;
  c.background_margin = e.background_margin;
  return c;
}

TrackerStateModelConfig ReconfigureBridge::stateInForce() const
{
  // -1: the model's own default (nothing configured).
  TrackerStateModelConfig c;
  const Parameters p = accepted_.sub("state_model");
  c.noise = p.has("noise") ? p.getDouble("noise", -1.0, -1e300, 1e300) : -1.0;
  c.acceleration_noise = p.has("acceleration_noise") ? p.getDouble("acceleration_noise", -1.0, -1e300, 1e300) : -1.0;
  return c;
}

TrackerObservationConfig ReconfigureBridge::observationInForce(const std::string& name) const
{
  TrackerObservationConfig c;
  const Parameters p = accepted_.sub(name);
  c.enabled = p.getBool("enabled", true);
  c.weight = p.getDouble("weight", 1.0, -1e300, 1e300);
  c.sigma = p.has("sigma") ? p.getDouble("sigma", -1.0, -1e300, 1e300) : -1.0;
  return c;
}

bool ReconfigureBridge::accept(const std::string& server, const std::map<std::string, std::string>& changes,
                                       std::string& error)
{
  Parameters trial = accepted_.copy();
  for (const auto& [key, value] : changes)
    trial.set(key, value);
  EngineConfig engine_config;
  try
  {
    engine_config = EngineConfig::fromParameters(trial.sub("engine"));
    const std::vector<std::string>& types = host_.tracker->pluginTypes();  // state model first, then the cues in order
    if (server == "state_model")
      host_.tracker->createStateModel(types.at(0), "state_model", trial.sub("state_model"));
    const auto& models = host_.tracker->engine().observationModels();  // the list itself never changes
    for (size_t i = 0; i < models.size(); ++i)
      if (models[i]->name() == server)
        host_.tracker->createObservationModel(types.at(i + 1), server, trial.sub(server));
  }
  catch (const std::exception& e)
  {
    error = e.what();
    return false;
  }
  accepted_ = trial;
  for (const auto& [key, value] : changes)
    pending_changes_[key] = value;
  if (server == "engine")
    pending_engine_config_ = engine_config;
  else
    pending_plugins_ = true;
  return true;
}

void ReconfigureBridge::engineReconfigure(TrackerEngineConfig& config, uint32_t)
{
  if (config.lost_similarity > config.found_similarity)
  {
    ROS_WARN_NAMED(name_, "lost_similarity %.3f > found_similarity %.3f: lowered to %.3f", config.lost_similarity,
                 config.found_similarity, config.found_similarity);
    config.lost_similarity = config.found_similarity;  // sanitised values are echoed back to the client
  }
  std::lock_guard<std::mutex> lock(mutex_);
  const TrackerEngineConfig now = engineInForce();
  std::map<std::string, std::string> changes;
  auto number = [&](const char* key, double value, double in_force) {
    if (!sameNumber(value, in_force))
      changes[std::string("engine/") + key] = formatNumber(value);
  };
  if (config.particles != now.particles)
    changes["engine/particles"] = std::to_string(config.particles);
  if (config.estimator != now.estimator)
    changes["engine/estimator"] = config.estimator;
  number("resample_threshold", config.resample_threshold, now.resample_threshold);
  number("density_radius", config.density_radius, now.density_radius);
  number("found_similarity", config.found_similarity, now.found_similarity);
  number("lost_similarity", config.lost_similarity, now.lost_similarity);
  number("respawn_fraction", config.respawn_fraction, now.respawn_fraction);
  number("refine_jitter", config.refine_jitter, now.refine_jitter);
  number("refine_search_weight", config.refine_search_weight, now.refine_search_weight);
  number("max_depth", config.max_depth, now.max_depth);
  number("background_margin", config.background_margin, now.background_margin);
  if (changes.empty())
    return;
  std::string error;
  if (accept("engine", changes, error))
    ROS_INFO_NAMED(name_, "reconfigure ~engine accepted (applied at the next frame): %s", joinChanges(changes).c_str());
  else
  {
    ROS_ERROR_NAMED(name_, "reconfigure ~engine rejected, nothing changed (the server keeps the values in force): %s",
                  error.c_str());
    config = now;
  }
}

void ReconfigureBridge::stateReconfigure(TrackerStateModelConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(mutex_);
  const TrackerStateModelConfig now = stateInForce();
  std::map<std::string, std::string> changes;
  // -1 means "leave it": the server then shows the value in force.
  if (config.noise >= 0.0 && !sameNumber(config.noise, now.noise))
    changes["state_model/noise"] = formatNumber(config.noise);
  if (config.acceleration_noise >= 0.0 && !sameNumber(config.acceleration_noise, now.acceleration_noise))
    changes["state_model/acceleration_noise"] = formatNumber(config.acceleration_noise);
  std::string error;
  if (changes.empty())
    config = now;
  else if (accept("state_model", changes, error))
    ROS_INFO_NAMED(name_, "reconfigure ~state_model accepted (applied at the next frame): %s", joinChanges(changes).c_str());
  else
  {
    ROS_ERROR_NAMED(name_, "reconfigure ~state_model rejected, nothing changed (the server keeps the values in force): %s",
                  error.c_str());
    config = now;
  }
}

void ReconfigureBridge::observationReconfigure(const std::string& name, TrackerObservationConfig& config, uint32_t)
{
  std::lock_guard<std::mutex> lock(mutex_);
  const TrackerObservationConfig now = observationInForce(name);
  std::map<std::string, std::string> changes;
  if (config.enabled != now.enabled)
    changes[name + "/enabled"] = config.enabled ? "true" : "false";
  if (!sameNumber(config.weight, now.weight))
    changes[name + "/weight"] = formatNumber(config.weight);
  if (config.sigma >= 0.0 && !sameNumber(config.sigma, now.sigma))
    changes[name + "/sigma"] = formatNumber(config.sigma);
  std::string error;
  if (changes.empty())
  {
    if (config.sigma < 0.0)
      config.sigma = now.sigma;
  }
  else if (accept(name, changes, error))
  {
    ROS_INFO_NAMED(name_, "reconfigure ~%s accepted (applied at the next frame): %s", name.c_str(), joinChanges(changes).c_str());
    if (config.sigma < 0.0)
      config.sigma = now.sigma;
  }
  else
  {
    ROS_ERROR_NAMED(name_, "reconfigure ~%s rejected, nothing changed (the server keeps the values in force): %s",
                  name.c_str(), error.c_str());
    config = now;
  }
}

}  // namespace stereo_pf
