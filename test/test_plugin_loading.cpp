// Every plugin loads through pluginlib by its lookup name; configuration errors are explained.
#include <gtest/gtest.h>

#include <algorithm>

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

// Without a list: the colour histogram, the grey-level template and the colour outline (a refining cue), each
// under its own namespace; the `refine` switch is a common parameter of every cue.
TEST(PluginLoading, DefaultCuesAreTheColourHistogramTheTemplateAndTheOutline)
{
  Parameters p;
  loadYamlString("colour_contour: {sigma: 0.08}\nstereo_cue: {refine: false}\n", p);
  Tracker tracker(p);
  EXPECT_EQ(tracker.pluginTypes(), (std::vector<std::string>{ "stereo_pf/Position3D", "stereo_pf/ColourHSI",
                                                               "stereo_pf/TemplateMatch", "stereo_pf/ColourContour" }));
  const auto& models = tracker.engine().observationModels();
  ASSERT_EQ(models.size(), 3u);
  EXPECT_EQ(models[0]->name(), "colour");
  EXPECT_FALSE(models[0]->refine());
  EXPECT_EQ(models[1]->name(), "template");
  EXPECT_FALSE(models[1]->refine());
  EXPECT_EQ(models[2]->name(), "colour_contour");
  EXPECT_TRUE(models[2]->refine());
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
                 "stereo: {sigma: 0.1}\n"
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
  EXPECT_TRUE(said("'stereo/sigma' (ignored): nothing loaded reads the namespace 'stereo'"));
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
