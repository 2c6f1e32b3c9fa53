// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The ROS-free parameter tree and its range checks.
#include <gtest/gtest.h>

#include <memory>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/plugins/colour_contour.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/shape_circle.h"
#include "stereo_pf/plugins/stereo_constraints.h"
#include "stereo_pf/plugins/stereo_match.h"
#include "stereo_pf/plugins/template_match.h"
#include "stereo_pf/plugins/texture_edge.h"
#include "stereo_pf/plugins/velocity_3d.h"

using stereo_pf::ParameterError;
using stereo_pf::Parameters;

namespace
{
std::string errorOf(const std::function<void()>& f)
{
  try
  {
    f();
  }
  catch (const ParameterError& e)
  {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Parameters, TypedGettersAndDefaults)
{
  Parameters p;
  p.set("a/x", 1.5);
  p.set("a/n", 7);
  p.set("a/flag", std::string("yes"));
  p.set("a/name", std::string(" colour "));
  p.set("a/list", std::string("[1, 2.5, -3]"));
  const Parameters a = p.sub("a");
  EXPECT_DOUBLE_EQ(a.getDouble("x", 0, -10, 10), 1.5);
  EXPECT_EQ(a.getInt("n", 0, 0, 10), 7);
  EXPECT_TRUE(a.getBool("flag", false));
  EXPECT_EQ(a.getString("name", ""), "colour");
  EXPECT_EQ(a.getDoubles("list", {}), (std::vector<double>{ 1, 2.5, -3 }));
  EXPECT_DOUBLE_EQ(a.getDouble("missing", 4.0, 0, 10), 4.0);
  EXPECT_EQ(a.prefix(), "a");
}

TEST(Parameters, ViewsShareValues)
{
  Parameters p;
  const Parameters a = p.sub("colour");
  p.set("colour/sigma", 0.3);
  EXPECT_DOUBLE_EQ(a.getDouble("sigma", 0.1, 0, 1), 0.3);
}

TEST(Parameters, RecordsTheKeysAskedForAndCopiesDeeply)
{
  Parameters p;
  p.set("colour/sigma", 0.3);
  p.set("colour/sigmaa", 0.3);
  const Parameters colour = p.sub("colour");
  colour.getDouble("sigma", 0.1, 0, 1);
  colour.getInt("window", 11, 3, 101);  // absent, still a known key
  EXPECT_EQ(p.unaskedKeys(), std::vector<std::string>{ "colour/sigmaa" });
  EXPECT_EQ(colour.askedKeys(), (std::vector<std::string>{ "sigma", "window" }));
  // A copy has its own values and its own record.
  Parameters c = p.copy();
  c.set("colour/sigma", 0.5);
  EXPECT_DOUBLE_EQ(colour.getDouble("sigma", 0.1, 0, 1), 0.3);
  EXPECT_EQ(c.unaskedKeys().size(), 2u);
  EXPECT_EQ(stereo_pf::closestKey("colour/sigmaa", { "colour/sigma", "colour/window", "engine/seed" }), "colour/sigma");
  EXPECT_EQ(stereo_pf::closestKey("engine/particle", { "engine/particles", "engine/seed" }), "engine/particles");
  EXPECT_EQ(stereo_pf::closestKey("something_else", { "colour/sigma" }), "");
}

TEST(Parameters, ErrorsNameTheParameterValueAndRange)
{
  Parameters p;
  p.set("colour/sigma", -1.0);
  p.set("colour/bins", std::string("many"));
  p.set("colour/n", 2.5);
  p.set("colour/on", std::string("maybe"));
  const Parameters c = p.sub("colour");
  const std::string range = errorOf([&] { c.getDouble("sigma", 0.1, 0.001, 10); });
  EXPECT_NE(range.find("colour/sigma"), std::string::npos);
  EXPECT_NE(range.find("-1"), std::string::npos);
  EXPECT_NE(range.find("[0.001, 10]"), std::string::npos);
  EXPECT_NE(errorOf([&] { c.getDouble("bins", 1, 0, 9); }).find("must be a number"), std::string::npos);
  EXPECT_NE(errorOf([&] { c.getInt("n", 1, 0, 9); }).find("integer"), std::string::npos);
  EXPECT_NE(errorOf([&] { c.getBool("on", true); }).find("true or false"), std::string::npos);
  EXPECT_NE(errorOf([&] { c.getString("missing", "x", { "a", "b" }); }).find("a, b"), std::string::npos);
}

TEST(Parameters, NanIsRejected)
{
  Parameters p;
  p.set("x", std::string("nan"));
  EXPECT_THROW(p.getDouble("x", 0, -1e9, 1e9), ParameterError);
}

TEST(EngineConfig, ReadsAndValidates)
{
  Parameters p;
  p.set("engine/particles", 250);
  p.set("engine/estimator", std::string("density"));
  p.set("engine/seed", 42);
  const auto c = stereo_pf::EngineConfig::fromParameters(p.sub("engine"));
  EXPECT_EQ(c.particles, 250);
  EXPECT_EQ(c.estimator, stereo_pf::Estimator::Density);
  EXPECT_EQ(c.seed, 42u);
  p.set("engine/estimator", std::string("median"));
  EXPECT_NE(errorOf([&] { stereo_pf::EngineConfig::fromParameters(p.sub("engine")); }).find("engine/estimator"),
            std::string::npos);
  p.set("engine/estimator", std::string("mean"));
  p.set("engine/particles", 0);
  EXPECT_NE(errorOf([&] { stereo_pf::EngineConfig::fromParameters(p.sub("engine")); }).find("engine/particles"),
            std::string::npos);
  p.set("engine/particles", 10);
  p.set("engine/lost_similarity", 0.9);
  EXPECT_NE(errorOf([&] { stereo_pf::EngineConfig::fromParameters(p.sub("engine")); }).find("lost_similarity"),
            std::string::npos);
}

// Each engine parameter is declared once, in EngineConfig::table(): fromParameters reads exactly its rows (with
// their ranges and defaults, as the getters declare them), and the particle count has one range.
TEST(EngineConfig, TheTableIsWhatFromParametersReads)
{
  Parameters p;
  stereo_pf::EngineConfig::fromParameters(p.sub("engine"));
  const std::vector<stereo_pf::ParameterSpec> read = p.sub("engine").declared();
  const std::vector<stereo_pf::ParameterSpec>& table = stereo_pf::EngineConfig::table();
  ASSERT_EQ(read.size(), table.size());
  for (size_t i = 0; i < table.size(); ++i)
  {
    EXPECT_EQ(read[i].name, table[i].name);
    EXPECT_EQ(read[i].type, table[i].type) << table[i].name;
    EXPECT_EQ(read[i].default_value, table[i].default_value) << table[i].name;
    EXPECT_EQ(read[i].min, table[i].min) << table[i].name;
    EXPECT_EQ(read[i].max, table[i].max) << table[i].name;
    EXPECT_FALSE(table[i].description.empty()) << table[i].name;
  }
  EXPECT_EQ(table.front().name, "particles");
  EXPECT_EQ(table.front().min, 1.0);
  EXPECT_EQ(table.front().max, 1000000.0);
  EXPECT_TRUE(table.front().reconfigurable);
  // check() says what the getter would.
  EXPECT_EQ(p.sub("engine").check(table.front(), "1000000"), "");
  EXPECT_NE(p.sub("engine").check(table.front(), "0").find("engine/particles"), std::string::npos);
}

namespace
{
/// A table row the reconfigure servers and the YAML template can show: it says what it means, its range is a range,
/// and its default is a value the getter itself would accept (check() applies the row's range, allowed values,
/// boolean and list syntax).
void expectWellFormed(const Parameters& view, const stereo_pf::ParameterSpec& spec)
{
  SCOPED_TRACE(view.prefix() + "/" + spec.name);
  EXPECT_FALSE(spec.description.empty()) << "no description";
  EXPECT_LE(spec.min, spec.max) << "empty range";
  EXPECT_EQ(view.check(spec, spec.default_value), "") << "the default " << spec.default_value;
}

/// The table a plugin declares when it is initialised with no values set (all defaults), as the ROS layer's
/// Tracker::pluginTable builds it, constructed directly here (no pluginlib).
template <typename Model>
std::vector<stereo_pf::ParameterSpec> tableOf(const std::string& name, Parameters& view)
{
  Parameters tree;
  view = tree.sub(name);
  Model model;
  model.initialize(name, view);
  return view.declared();
}
}  // namespace

// Every built-in plugin's parameters (state and observation models) and the engine's are documented: each row has a
// description and a default within its own range. A parameter read without a description shows up blank in the
// reconfigure GUIs and in the tables the docs are checked against.
TEST(ParameterTables, EveryBuiltInParameterIsDescribedAndItsDefaultAllowed)
{
  struct Case
  {
    std::string type;
    std::function<std::vector<stereo_pf::ParameterSpec>(Parameters&)> table;
  };
  const std::vector<Case> cases = {
    { "ColourHSI", [](Parameters& v) { return tableOf<stereo_pf::ColourHSI>("colour", v); } },
    { "ColourContour", [](Parameters& v) { return tableOf<stereo_pf::ColourContour>("colour_contour", v); } },
    { "TextureEdge", [](Parameters& v) { return tableOf<stereo_pf::TextureEdge>("texture", v); } },
    { "ShapeCircle", [](Parameters& v) { return tableOf<stereo_pf::ShapeCircle>("shape", v); } },
    { "StereoMatch", [](Parameters& v) { return tableOf<stereo_pf::StereoMatch>("stereo", v); } },
    { "TemplateMatch", [](Parameters& v) { return tableOf<stereo_pf::TemplateMatch>("template", v); } },
    { "StereoConstraints", [](Parameters& v) { return tableOf<stereo_pf::StereoConstraints>("state_model", v); } },
    { "Position3D", [](Parameters& v) { return tableOf<stereo_pf::Position3D>("state_model", v); } },
    { "Velocity3D", [](Parameters& v) { return tableOf<stereo_pf::Velocity3D>("state_model", v); } },
  };
  for (const Case& c : cases)
  {
    SCOPED_TRACE(c.type);
    Parameters view;
    const std::vector<stereo_pf::ParameterSpec> table = c.table(view);
    EXPECT_FALSE(table.empty());
    for (const stereo_pf::ParameterSpec& spec : table)
      expectWellFormed(view, spec);
  }
  Parameters engine;
  for (const stereo_pf::ParameterSpec& spec : stereo_pf::EngineConfig::table())
    expectWellFormed(engine.sub("engine"), spec);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
