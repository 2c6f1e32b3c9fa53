// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// End to end through the command-line tools: make_scene writes a bag, track_bag tracks it, and the
// summary line is checked against the accuracy bounds of issues 2 and 3 (fewer seeds and frames than the
// 10-seed acceptance runs reported in docs/).
#include <gtest/gtest.h>

#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/PoseArray.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <vector>
#include <sys/stat.h>

#include "run_command.h"

namespace
{
using stereo_pf_test::run;

// "summary: frames=150 converged_at=3 rms_cm=2.40 ..." -> key/value map.
std::map<std::string, std::string> summary(const std::string& output)
{
  std::map<std::string, std::string> kv;
  const auto at = output.rfind("summary:");
  if (at == std::string::npos)
    return kv;
  std::istringstream line(output.substr(at + 8, output.find('\n', at) - at - 8));
  std::string item;
  while (line >> item)
  {
    const auto eq = item.find('=');
    if (eq != std::string::npos)
      kv[item.substr(0, eq)] = item.substr(eq + 1);
  }
  return kv;
}

std::string bag(const std::string& scene, int frames)
{
  mkdir(TEST_OUT_DIR, 0755);
  const std::string path = std::string(TEST_OUT_DIR) + "/" + scene + "_" + std::to_string(frames) + ".bag";
  struct stat st;
  if (stat(path.c_str(), &st) != 0)
  {
    int status = 0;
    const std::string out = run(std::string(MAKE_SCENE_BIN) + " " + SCENES_DIR + "/" + scene + ".yaml " + path +
                                    ".part --quiet --frames " + std::to_string(frames) + " && mv " + path + ".part " + path,
                                status);
    EXPECT_EQ(status, 0) << out;
  }
  return path;
}

std::map<std::string, std::string> track(const std::string& bag_path, const std::string& args)
{
  int status = 0;
  const std::string out = run(std::string(TRACK_BAG_BIN) + " " + bag_path + " --quiet " + args, status);
  EXPECT_EQ(status, 0) << out;
  auto kv = summary(out);
  EXPECT_FALSE(kv.empty()) << out;
  return kv;
}

double num(const std::map<std::string, std::string>& kv, const std::string& key)
{
  const auto it = kv.find(key);
  return it == kv.end() ? 1e9 : std::atof(it->second.c_str());
}
}  // namespace

// Issue 2's bounds with the default cues (colour histogram + its outline): 1.5 cm, converged within 30 frames.
TEST(EndToEnd, UnclutteredPendulumPosition3D)
{
  const std::string b = bag("pendulum_uncluttered", 150);
  for (int seed : { 1, 2, 3 })
  {
    const auto s = track(b, "--state Position3D --particles 1000 --seed " + std::to_string(seed));
    EXPECT_GE(num(s, "converged_at"), 0) << "seed " << seed;
    EXPECT_LE(num(s, "converged_at"), 30) << "seed " << seed;
    EXPECT_LE(num(s, "rms_cm"), 1.5) << "seed " << seed;
    EXPECT_EQ(num(s, "frames_over_10cm"), 0) << "seed " << seed;
  }
}

// The thesis's colour model alone (config/thesis_colour.yaml) is measurably less precise in depth, and the
// stereo cue on top of the default (config/colour_stereo.yaml) keeps the default's precision.
TEST(EndToEnd, OutlineAndStereoCuesSharpenTheThesisColourModel)
{
  const std::string b = bag("pendulum_uncluttered", 150);
  const auto thesis = track(b, "--config config/thesis_colour.yaml --seed 1");
  const auto outline = track(b, "--seed 1");
  const auto stereo = track(b, "--config config/colour_stereo.yaml --seed 1");
  EXPECT_LE(num(thesis, "rms_cm"), 3.0);
  EXPECT_LT(num(outline, "rms_cm"), 0.6 * num(thesis, "rms_cm"));
  EXPECT_LE(num(stereo, "rms_cm"), 1.5);
}

// Issue 3: colour, texture and shape keep the target while a textured square of its colour crosses it
// (config/multi_cue.yaml without the stereo cue), and so do all cues.
TEST(EndToEnd, ColourTextureShapeKeepTheTargetPastTheColourDistractor)
{
  const std::string b = bag("colour_distractor", 150);
  for (const std::string extra : { " --set stereo/enabled=false", "" })
    for (int seed : { 1, 2 })
    {
      const auto s = track(b, "--config config/multi_cue.yaml --particles 1000 --seed " + std::to_string(seed) + extra);
      EXPECT_GE(num(s, "converged_at"), 0) << "seed " << seed << extra;
      EXPECT_LE(num(s, "rms_cm"), 3.0) << "seed " << seed << extra;
      EXPECT_EQ(num(s, "frames_over_10cm"), 0) << "seed " << seed << extra;
    }
}

TEST(EndToEnd, UnclutteredPendulumStereoConstraints)
{
  const std::string b = bag("pendulum_uncluttered", 150);
  for (int seed : { 1, 2, 3 })
  {
    const auto s = track(b, "--state StereoConstraints --particles 1000 --seed " + std::to_string(seed));
    EXPECT_LE(num(s, "converged_at"), 30) << "seed " << seed;
    EXPECT_LE(num(s, "rms_cm"), 3.0) << "seed " << seed;
  }
}

TEST(EndToEnd, ClutteredPendulumPosition3D)
{
  const std::string b = bag("pendulum_cluttered", 150);
  for (int seed : { 1, 2 })
  {
    const auto s = track(b, "--state Position3D --seed " + std::to_string(seed));
    EXPECT_LE(num(s, "converged_at"), 30) << "seed " << seed;
    EXPECT_LE(num(s, "rms_cm"), 3.0) << "seed " << seed;
  }
}

TEST(EndToEnd, OcclusionIsDeclaredLostAndReacquired)
{
  const std::string b = bag("occlusion", 150);
  for (int seed : { 1, 2 })
  {
    const auto s = track(b, "--seed " + std::to_string(seed));
    EXPECT_EQ(num(s, "occlusions"), 1) << "seed " << seed;
    EXPECT_EQ(num(s, "declared_lost"), 1) << "seed " << seed;
    EXPECT_LE(num(s, "reacquire_frames"), 15) << "seed " << seed;
  }
}

// make_scene records where the other objects are (ground_truth/others), so a run can be checked for
// locking onto the wrong object. multi_object's blue ball exists from t = 3 s (frame 90) on.
TEST(EndToEnd, MultiObjectBagRecordsTheOtherObjects)
{
  rosbag::Bag b(bag("multi_object", 120), rosbag::bagmode::Read);
  std::map<int, geometry_msgs::PoseArray> others;
  std::map<int, geometry_msgs::PointStamped> target;
  const std::vector<std::string> topics{ "ground_truth/others", "ground_truth/target" };
  for (const rosbag::MessageInstance& m : rosbag::View(b, rosbag::TopicQuery(topics)))
  {
    if (auto a = m.instantiate<geometry_msgs::PoseArray>())
      others[static_cast<int>(a->header.seq)] = *a;
    else if (auto p = m.instantiate<geometry_msgs::PointStamped>())
      target[static_cast<int>(p->header.seq)] = *p;
  }
  ASSERT_EQ(others.size(), 120u);
  ASSERT_EQ(target.size(), 120u);
  EXPECT_TRUE(others[0].poses.empty());
  EXPECT_TRUE(others[89].poses.empty());
  ASSERT_EQ(others[90].poses.size(), 1u);
  ASSERT_EQ(others[119].poses.size(), 1u);
  // The scene's linear trajectory from (-0.9, 0.32, 0.9) at t = 3 s to (1.0, 0.32, 1.3) at t = 8 s.
  const auto& p90 = others[90].poses[0].position;
  EXPECT_NEAR(p90.x, -0.9, 1e-6);
  EXPECT_NEAR(p90.y, 0.32, 1e-6);
  EXPECT_NEAR(p90.z, 0.9, 1e-6);
  const auto& p119 = others[119].poses[0].position;
  EXPECT_NEAR(p119.x, -0.9 + 1.9 * (29.0 / 30.0) / 5.0, 1e-6);
  EXPECT_NEAR(p119.z, 0.9 + 0.4 * (29.0 / 30.0) / 5.0, 1e-6);
  EXPECT_GT(std::abs(p119.x - target[119].point.x) + std::abs(p119.y - target[119].point.y), 0.1);
}

// An OpenCV baseline through the same tool and summary (issue 5): the row must be comparable, so it has to
// parse and be finite. Measured on this bag: converged_at=0 rms_cm=2.42 max_cm=5.85 (csrt is about
// 45 ms per stereo frame, so this takes several seconds).
TEST(EndToEnd, UnclutteredPendulumCsrtBaseline)
{
  const std::string b = bag("pendulum_uncluttered", 150);
  const auto s = track(b, "--baseline csrt");
  EXPECT_EQ(num(s, "frames"), 150);
  EXPECT_GE(num(s, "converged_at"), 0);
  EXPECT_LE(num(s, "converged_at"), 5);
  EXPECT_TRUE(std::isfinite(num(s, "rms_cm")));
  EXPECT_LE(num(s, "rms_cm"), 3.5);
  EXPECT_EQ(num(s, "frames_over_10cm"), 0);
  EXPECT_GT(num(s, "ms_per_frame"), 0.0);
}

// --target-frame K is the first frame tracked, with a loaded target too: a target saved from a clip's first frame
// is looked for from frame K on (until session 28 a loaded target silently started at frame 0).
TEST(EndToEnd, ALoadedTargetIsLookedForFromTheTargetFrame)
{
  const std::string b = bag("pendulum_uncluttered", 150);
  const std::string target = std::string(TEST_OUT_DIR) + "/saved_target.yml";
  const std::string csv = std::string(TEST_OUT_DIR) + "/from_frame_60.csv";
  track(b, "--seed 1 --save-target " + target);
  const auto s = track(b, "--seed 1 --target-model " + target + " --target-frame 60 --output " + csv);
  EXPECT_EQ(num(s, "frames"), 90);
  EXPECT_LE(num(s, "converged_at"), 10);
  EXPECT_LE(num(s, "rms_cm"), 1.5);
  FILE* f = std::fopen(csv.c_str(), "r");
  ASSERT_NE(f, nullptr) << csv;
  char line[4096];
  ASSERT_NE(std::fgets(line, sizeof line, f), nullptr);  // header
  ASSERT_NE(std::fgets(line, sizeof line, f), nullptr);
  std::fclose(f);
  EXPECT_EQ(std::atoi(line), 60) << "first row: " << line;
  int status = 0;
  const std::string out = run(std::string(TRACK_BAG_BIN) + " " + b + " --quiet --target-model " + target +
                                  " --target-frame 500",
                              status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("no usable frame at or after --target-frame 500"), std::string::npos) << out;
}

TEST(EndToEnd, ClearErrorsForBadInvocations)
{
  int status = 0;
  std::string out = run(std::string(TRACK_BAG_BIN) + " /nonexistent.bag", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("cannot open bag"), std::string::npos) << out;
  const std::string b = bag("pendulum_uncluttered", 150);
  out = run(std::string(TRACK_BAG_BIN) + " " + b + " --left-image /nope/image_raw", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("has no topic '/nope/image_raw'"), std::string::npos) << out;
  out = run(std::string(TRACK_BAG_BIN) + " " + b + " --state Position4D", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("stereo_pf/Position3D"), std::string::npos) << out;
  out = run(std::string(TRACK_BAG_BIN) + " " + b + " --set engine/particles=-5", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("engine/particles"), std::string::npos) << out;
  out = run(std::string(TRACK_BAG_BIN) + " " + b + " --baseline mil", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("unknown baseline 'mil' (allowed: csrt, kcf, camshift)"), std::string::npos) << out;
  out = run(std::string(TRACK_BAG_BIN) + " " + b + " --baseline kcf --target-model ball.yml", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("--target-model configures the particle filter"), std::string::npos) << out;
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
