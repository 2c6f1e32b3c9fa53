// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Every plugin loads through pluginlib by its lookup name; configuration errors are explained.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <set>

#include "stereo_pf/ros/plugin_loader.h"
#include "stereo_pf/ros/yaml_parameters.h"

using namespace stereo_pf;

namespace
{
bool contains(const std::vector<std::string>& v, const std::string& s)
{
  return std::find(v.begin(), v.end(), s) != v.end();
}
}  // namespace

TEST(PluginLoading, EveryDeclaredStateModelLoads)
{
  Tracker tracker{ Parameters() };
  const auto declared = tracker.declaredStateModels();
  for (const char* name : { "stereo_pf/StereoConstraints", "stereo_pf/Position3D", "stereo_pf/Velocity3D" })
    EXPECT_TRUE(contains(declared, name)) << name;
  for (const std::string& type : declared)
  {
    auto m = tracker.createStateModel(type, "state_model", Parameters());
    ASSERT_TRUE(m) << type;
    EXPECT_GE(m->numSets(), 1) << type;
    EXPECT_FALSE(m->views(0).empty()) << type;
  }
  EXPECT_EQ(tracker.createStateModel("stereo_pf/StereoConstraints", "s", Parameters())->numSets(), 2);
  EXPECT_EQ(tracker.createStateModel("stereo_pf/Velocity3D", "s", Parameters())->dimension(0), 6);
}

TEST(PluginLoading, EveryDeclaredObservationModelLoads)
{
  Tracker tracker{ Parameters() };
  const auto declared = tracker.declaredObservationModels();
  EXPECT_TRUE(contains(declared, "stereo_pf/ColourHSI"));
  EXPECT_TRUE(contains(declared, "stereo_pf/ColourContour"));
  for (const std::string& type : declared)
  {
    auto m = tracker.createObservationModel(type, "cue", Parameters());
    ASSERT_TRUE(m) << type;
    EXPECT_EQ(m->name(), "cue");
    // Models that compare the two views with each other have no target to learn.
    EXPECT_EQ(m->hasTarget(), m->comparesViews()) << type;
  }
}

TEST(PluginLoading, UnknownTypeListsTheDeclaredClasses)
{
  Parameters p;
  p.set("state_model/type", std::string("stereo_pf/Position4D"));
  try
  {
    Tracker tracker(p);
    FAIL() << "an unknown state model type was accepted";
  }
  catch (const PluginError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find("stereo_pf/Position4D"), std::string::npos) << what;
    EXPECT_NE(what.find("stereo_pf/Position3D"), std::string::npos) << what;
    EXPECT_NE(what.find("stereo_pf/StereoConstraints"), std::string::npos) << what;
  }
  Parameters q;
  loadYamlString("observation_models: [{name: colour, type: stereo_pf/Colour}]", q);
  try
  {
    Tracker tracker(q);
    FAIL() << "an unknown observation model type was accepted";
  }
  catch (const PluginError& e)
  {
    EXPECT_NE(std::string(e.what()).find("stereo_pf/ColourHSI"), std::string::npos) << e.what();
  }
}

TEST(PluginLoading, ConfigurationBuildsTheListedModelsWithTheirParameters)
{
  Parameters p;
  loadYamlString("state_model: {type: stereo_pf/Velocity3D, z_max: 4.0}\n"
                 "engine: {particles: 123, seed: 9}\n"
                 "observation_models:\n"
                 "  - {name: hue, type: stereo_pf/ColourHSI}\n"
                 "  - {name: hue2, type: stereo_pf/ColourHSI}\n"
                 "hue2: {enabled: false, weight: 0.5}\n",
                 p);
  Tracker tracker(p);
  EXPECT_EQ(tracker.pluginTypes(),
            (std::vector<std::string>{ "stereo_pf/Velocity3D", "stereo_pf/ColourHSI", "stereo_pf/ColourHSI" }));
  EXPECT_EQ(tracker.engine().config().particles, 123);
  EXPECT_EQ(tracker.engine().config().seed, 9u);
  const auto& models = tracker.engine().observationModels();
  ASSERT_EQ(models.size(), 2u);
  EXPECT_EQ(models[0]->name(), "hue");
  EXPECT_TRUE(models[0]->enabled());
  EXPECT_FALSE(models[1]->enabled());
  EXPECT_DOUBLE_EQ(models[1]->weight(), 0.5);
}

// Without a list: Velocity3D and the colour histogram, the grey-level template, the colour outline and the stereo
// match (two refining cues) and the shape (no evidence that the target is seen, at a fifth of its thesis weight),
// each under its own namespace; the `refine` switch is a common parameter of every cue.
TEST(PluginLoading, DefaultCuesAreTheColourHistogramTheTemplateTheOutlineTheStereoMatchAndTheShape)
{
  Parameters p;
  loadYamlString("colour_contour: {sigma: 0.08}\nstereo: {sigma: 0.2}\nstereo_cue: {refine: false}\n", p);
  Tracker tracker(p);
  EXPECT_EQ(tracker.pluginTypes(),
            (std::vector<std::string>{ "stereo_pf/Velocity3D", "stereo_pf/ColourHSI", "stereo_pf/TemplateMatch",
                                       "stereo_pf/ColourContour", "stereo_pf/StereoMatch", "stereo_pf/ShapeCircle" }));
  const auto& models = tracker.engine().observationModels();
  ASSERT_EQ(models.size(), 5u);
  EXPECT_EQ(models[0]->name(), "colour");
  EXPECT_FALSE(models[0]->refine());
  EXPECT_EQ(models[1]->name(), "template");
  EXPECT_FALSE(models[1]->refine());
  EXPECT_EQ(models[2]->name(), "colour_contour");
  EXPECT_TRUE(models[2]->refine());
  EXPECT_EQ(models[3]->name(), "stereo");
  EXPECT_TRUE(models[3]->refine());
  EXPECT_TRUE(models[3]->comparesViews());
  EXPECT_EQ(models[4]->name(), "shape");
  EXPECT_FALSE(models[4]->refine());
  EXPECT_FALSE(models[4]->identifiesTarget());
  EXPECT_DOUBLE_EQ(models[4]->weight(), 0.2);
  for (size_t k = 0; k < 4; ++k)
  {
    EXPECT_TRUE(models[k]->identifiesTarget()) << models[k]->name();
    EXPECT_DOUBLE_EQ(models[k]->weight(), 1.0) << models[k]->name();
  }
  for (const std::string& m : unknownParameters(p, kRosRuntimeParameters))
    EXPECT_EQ(m.find("'stereo/"), std::string::npos) << "the default stereo cue reads its namespace: " << m;
  auto stereo = tracker.createObservationModel("stereo_pf/StereoMatch", "stereo_cue", p.sub("stereo_cue"));
  EXPECT_FALSE(stereo->refine());
  EXPECT_TRUE(tracker.createObservationModel("stereo_pf/StereoMatch", "s", Parameters())->refine());
  Parameters bad;
  loadYamlString("colour_contour: {refine: maybe}", bad);
  EXPECT_THROW(Tracker{ bad }, ParameterError);
}

TEST(PluginLoading, BadPluginParameterNamesIt)
{
  Parameters p;
  loadYamlString("colour: {sigma: -3}", p);
  try
  {
    Tracker tracker(p);
    FAIL();
  }
  catch (const ParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("colour/sigma"), std::string::npos) << e.what();
  }
  Parameters q;
  loadYamlString("observation_models: [{name: a, type: stereo_pf/ColourHSI}, {name: a, type: stereo_pf/ColourHSI}]", q);
  EXPECT_THROW(Tracker{ q }, PluginError);
}

TEST(PluginLoading, MisspeltKeysAreNamedWithTheNearestKnownOne)
{
  Parameters p;
  loadYamlString("colour: {sigmaa: 0.2}\n"
                 "engine: {particle: 500}\n"
                 "texture: {sigma: 0.1}\n"
                 "state_model: {type: stereo_pf/Position3D, z_mx: 4.0}\n"
                 "queue_size: 3\n"
                 "publish_tff: true\n"
                 "entirely_unknown_setting: 1\n",
                 p);
  Tracker tracker(p);
  const std::vector<std::string> m = unknownParameters(p, kRosRuntimeParameters);
  auto said = [&m](const std::string& what) {
    return std::any_of(m.begin(), m.end(), [&](const std::string& s) { return s.find(what) != std::string::npos; });
  };
  EXPECT_TRUE(said("'colour/sigmaa' (ignored): did you mean 'colour/sigma'?"));
  EXPECT_TRUE(said("'engine/particle' (ignored): did you mean 'engine/particles'?"));
  EXPECT_TRUE(said("'state_model/z_mx' (ignored): did you mean 'state_model/z_max'?"));
  EXPECT_TRUE(said("'publish_tff' (ignored): did you mean 'publish_tf'?"));
  EXPECT_TRUE(said("'texture/sigma' (ignored): nothing loaded reads the namespace 'texture'"));
  EXPECT_TRUE(said("'entirely_unknown_setting' (ignored): not a parameter"));
  EXPECT_FALSE(said("queue_size")) << "a ROS runtime key reported";
  EXPECT_EQ(m.size(), 6u);
}

TEST(PluginLoading, TheShippedConfigurationsHaveNoUnknownKeys)
{
  for (const char* name : { "tracker.yaml", "colour_stereo.yaml", "multi_cue.yaml", "thesis_colour.yaml" })
  {
    Parameters p;
    loadYamlFile(std::string(CONFIG_DIR) + "/" + name, p);
    Tracker tracker(p);
    const std::vector<std::string> m = unknownParameters(p, kRosRuntimeParameters);
    EXPECT_TRUE(m.empty()) << name << ": " << (m.empty() ? "" : m.front());
  }
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

// config/tracker.yaml is the template that documents every parameter: checked here against the parameter tables
// (the engine's EngineConfig::table(), each shipped plugin's as its getters declare it), so the two cannot disagree:
// every parameter is documented in its section with its default, a documented key exists, and "(*)" marks exactly
// the parameters a reconfigure server offers (the cues' common enabled/weight/refine are documented once for all).
namespace
{
struct Documented
{
  std::string value;
  bool starred = false;
};
/// section ("engine", "colour", "state_model/StereoConstraints", ...) -> key -> what the template says.
std::map<std::string, std::map<std::string, Documented>> readTemplate(const std::string& path)
{
  std::ifstream in(path);
  std::map<std::string, std::map<std::string, Documented>> out;
  std::string section, line;
  const std::regex top(R"(^(?:#\s*)?(\w+):\s*$)");
  const std::regex sub(R"(^\s+#\s*--\s*(.*):\s*$)");
  const std::regex entry(R"(^\s+(?:#\s*)?(\w+):\s*(\S+)\s*(#.*)?$)");
  std::string base;
  std::smatch m;
  while (std::getline(in, line))
  {
    if (std::regex_match(line, m, top))
      section = base = m[1];
    else if (base == "state_model" && std::regex_match(line, m, sub))
      section = "state_model/" + std::string(m[1]);
    else if (!section.empty() && std::regex_match(line, m, entry) && m[1] != "type")
      out[section][m[1]] = { m[2], m[3].str().find("(*)") != std::string::npos };
  }
  return out;
}

bool sameValue(const std::string& documented, const std::string& declared)
{
  char* end = nullptr;
  const double a = std::strtod(documented.c_str(), &end);
  if (end != documented.c_str() && *end == '\0')
  {
    const double b = std::strtod(declared.c_str(), nullptr);
    return std::fabs(a - b) <= 1e-6 * std::max(1.0, std::fabs(b));
  }
  return documented == declared;
}
}  // namespace

TEST(ParameterTables, TheYamlTemplateDocumentsEveryParameterWithItsDefault)
{
  const auto doc = readTemplate(std::string(CONFIG_DIR) + "/tracker.yaml");
  ASSERT_TRUE(doc.count("engine"));
  const auto& engine = doc.at("engine");
  for (const ParameterSpec& spec : EngineConfig::table())
  {
    ASSERT_TRUE(engine.count(spec.name)) << "engine/" << spec.name << " is not in config/tracker.yaml";
    EXPECT_TRUE(sameValue(engine.at(spec.name).value, spec.default_value))
        << "engine/" << spec.name << ": the template says " << engine.at(spec.name).value << ", the table "
        << spec.default_value;
    EXPECT_EQ(engine.at(spec.name).starred, spec.reconfigurable) << "engine/" << spec.name << ": (*) mark";
  }
  EXPECT_EQ(engine.size(), EngineConfig::table().size()) << "the template documents an engine key the table lacks";

  Tracker tracker{ Parameters() };
  const std::set<std::string> common = { "enabled", "weight", "refine" };
  // (type, section) pairs; a state model's keys may be documented in a shared section (`own` false: no default check).
  struct Case
  {
    std::string type, name, section;
    bool state, own;
  };
  const std::vector<Case> cases = {
    { "stereo_pf/ColourHSI", "colour", "colour", false, true },
    { "stereo_pf/TemplateMatch", "template", "template", false, true },
    { "stereo_pf/ColourContour", "colour_contour", "colour_contour", false, true },
    { "stereo_pf/StereoMatch", "stereo", "stereo", false, true },
    { "stereo_pf/TextureEdge", "texture", "texture", false, true },
    { "stereo_pf/ShapeCircle", "shape", "shape", false, true },
    { "stereo_pf/Position3D", "state_model", "state_model/Position3D and Velocity3D", true, true },
    { "stereo_pf/StereoConstraints", "state_model", "state_model/StereoConstraints", true, true },
  };
  for (const Case& c : cases)
  {
    SCOPED_TRACE(c.type);
    ASSERT_TRUE(doc.count(c.section)) << c.section;
    const auto& section = doc.at(c.section);
    const std::vector<ParameterSpec> table = tracker.pluginTable(c.type, c.name, Parameters());
    std::set<std::string> declared;
    for (const ParameterSpec& spec : table)
    {
      declared.insert(spec.name);
      if (!section.count(spec.name))
      {
        EXPECT_TRUE(common.count(spec.name)) << c.section << "/" << spec.name << " is not in config/tracker.yaml";
        continue;
      }
      EXPECT_TRUE(sameValue(section.at(spec.name).value, spec.default_value))
          << c.section << "/" << spec.name << ": the template says " << section.at(spec.name).value
          << ", the plugin " << spec.default_value;
      if (!common.count(spec.name))
      {
        EXPECT_EQ(section.at(spec.name).starred, spec.reconfigurable) << c.section << "/" << spec.name << ": (*) mark";
      }
    }
    if (c.type == "stereo_pf/Position3D")
      continue;  // its section is shared with Velocity3D: checked below
    for (const auto& [key, d] : section)
    {
      EXPECT_TRUE(declared.count(key)) << c.section << "/" << key << " is documented but " << c.type
                                       << " reads no such key";
    }
  }
  // Velocity3D: its own keys in "Velocity3D only", the rest shared with Position3D.
  const std::vector<ParameterSpec> velocity = tracker.pluginTable("stereo_pf/Velocity3D", "state_model", Parameters());
  const std::vector<ParameterSpec> position = tracker.pluginTable("stereo_pf/Position3D", "state_model", Parameters());
  const auto& shared = doc.at("state_model/Position3D and Velocity3D");
  const auto& only = doc.at("state_model/Velocity3D only");
  std::set<std::string> both;
  for (const auto* t : { &velocity, &position })
    for (const ParameterSpec& spec : *t)
      both.insert(spec.name);
  for (const ParameterSpec& spec : velocity)
  {
    if (only.count(spec.name))
    {
      EXPECT_TRUE(sameValue(only.at(spec.name).value, spec.default_value)) << "Velocity3D/" << spec.name;
      EXPECT_EQ(only.at(spec.name).starred, spec.reconfigurable) << "Velocity3D/" << spec.name << ": (*) mark";
    }
    else
      EXPECT_TRUE(shared.count(spec.name)) << "Velocity3D/" << spec.name << " is not in config/tracker.yaml";
  }
  for (const auto* section : { &shared, &only })
    for (const auto& [key, d] : *section)
      EXPECT_TRUE(both.count(key)) << "state_model/" << key << " is documented but no 3D state model reads it";
}
