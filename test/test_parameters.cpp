// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The ROS-free parameter tree and its range checks.
#include <gtest/gtest.h>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/parameters.h"

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

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
