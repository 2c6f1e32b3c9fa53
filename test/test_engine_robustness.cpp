// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The engine on a robot's bad days (issue 12): the state stays inside what the cameras can see, a target the
// background explains as well is never "tracking", a set that leaves the viewing volume is lost and redrawn,
// and learning or loading a target changes all the cues' targets or none.
#include <set>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <unistd.h>
#include <vector>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/map_proposals.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/core/viewing_volume.h"
#include "stereo_pf/plugins/colour_contour.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/stereo_match.h"
#include "stereo_pf/plugins/template_match.h"
#include "stereo_pf/plugins/velocity_3d.h"

using namespace stereo_pf;

namespace
{
const StereoGeometry kRig(525, 525, 319.5, 239.5, 0.09, 640, 480);

std::shared_ptr<Position3D> position3D()
{
  auto m = std::make_shared<Position3D>();
  m->initialize("state_model", Parameters());
  return m;
}

template <class Cue>
std::shared_ptr<Cue> cue(const std::string& name)
{
  auto m = std::make_shared<Cue>();
  m->initialize(name, Parameters());
  return m;
}

/// The default cues: the colour histogram and its outline.
std::vector<std::shared_ptr<ObservationModel>> defaultCues()
{
  return { cue<ColourHSI>("colour"), cue<ColourContour>("colour_contour") };
}

/// The search path (EngineConfig::acquire false): a learned box is not matched, the particles start from the
/// prior. The tests of the background check need it: with acquisition a box of wall is refused at once
/// (EngineBounds.AcquisitionRefusesABoxOfWall).
EngineConfig searchOnly()
{
  EngineConfig config;
  config.acquire = false;
  return config;
}

/// Frames of a shipped scene, rendered once per test.
class Scene
{
public:
  explicit Scene(const std::string& name) : renderer_(loadScene(std::string(SCENES_DIR) + "/" + name)) {}
  explicit Scene(const SceneDescription& description) : renderer_(description) {}
  StereoFrame frame(int k)
  {
    renderer_.render(k, left_, right_);
    StereoFrame f;
    f.geometry = renderer_.geometry();
    f.left = left_;
    f.right = right_;
    f.stamp = renderer_.stamp(k);
    return f;
  }
  SceneRenderer& renderer() { return renderer_; }

private:
  SceneRenderer renderer_;
  cv::Mat left_, right_;
};

/// Every model's target as text (to compare targets before and after a failed change).
std::string targets(const FilterEngine& engine)
{
  cv::FileStorage fs(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  for (const auto& m : engine.observationModels())
    if (m->hasTarget())
      m->saveTarget(fs);
  return fs.releaseAndGetString();
}
}  // namespace

TEST(ViewingVolume, FollowsTheCalibration)
{
  const ViewingVolume v(kRig, 0.5);
  // fx b = 47.25 px m: the far limit where the disparity is half a pixel, the near one where it is the width.
  EXPECT_NEAR(v.farDepth(), 47.25 / 0.5, 1e-9);
  EXPECT_NEAR(v.nearDepth(), 47.25 / 640.0, 1e-9);
  EXPECT_TRUE(v.containsDepth(1.0));
  EXPECT_FALSE(v.containsDepth(100.0));
  EXPECT_FALSE(v.containsDepth(0.05));
  EXPECT_FALSE(v.containsDepth(std::nan("")));
  EXPECT_FALSE(v.containsDisparity(0.2));
  EXPECT_FALSE(v.containsDisparity(700.0));
  // A longer baseline resolves farther.
  EXPECT_NEAR(ViewingVolume(StereoGeometry(525, 525, 319.5, 239.5, 0.18, 640, 480), 0.5).farDepth(), 189.0, 1e-9);
  // max_depth can only bring the far limit nearer.
  EXPECT_NEAR(ViewingVolume(kRig, 0.5, 5.0).farDepth(), 5.0, 1e-9);
  EXPECT_NEAR(ViewingVolume(kRig, 0.5, 1000.0).farDepth(), 94.5, 1e-9);
  // A disc overlaps the image when any of it is inside; a non-finite centre never does.
  EXPECT_TRUE(v.overlapsImage(-5.0, 100.0, 10.0));
  EXPECT_FALSE(v.overlapsImage(-5.0, 100.0, 2.0));
  EXPECT_TRUE(v.overlapsImage(639.4, 479.4, 0.0));
  EXPECT_FALSE(v.overlapsImage(660.0, 100.0, 10.0));
  EXPECT_FALSE(v.overlapsImage(std::nan(""), 100.0, 10.0));
}

// Issue 12's offline reproduction: the box of frame 12 learned on frame 13 holds mostly wall. Before the bound
// the estimate grew ~x1.2 per frame (|z| = 10^22 m by the end of the bag) while the track said "tracking".
TEST(EngineBounds, ATargetLearnedAFrameLateNeverDivergesAndIsNeverTrackedWrongly)
{
  Scene scene("pendulum_uncluttered.yaml");
  FilterEngine engine(position3D(), defaultCues(), searchOnly());
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(13), scene.renderer().targetRoi(12), error)) << error;
  double max_z = 0.0;
  int tracking = 0, like_background = 0;
  for (int k = 13; k < 100; ++k)
  {
    const FrameResult r = engine.step(scene.frame(k));
    const double far = engine.viewingVolume().farDepth();
    // Every particle and the estimate stay inside what the cameras can see.
    const ParticleSet& p = engine.sets().front();
    for (int i = 0; i < p.size(); ++i)
      ASSERT_LE(std::fabs(p.states(i, 2)), 2.0 * far) << "frame " << k << ": a particle at z = " << p.states(i, 2);
    if (r.estimate.valid)
    {
      ASSERT_LE(std::fabs(r.estimate.position.z()), far) << "frame " << k;
      max_z = std::max(max_z, std::fabs(r.estimate.position.z()));
    }
    // Lost or searching is honest; tracking must be right.
    if (r.state == TrackState::Tracking)
    {
      ++tracking;
      ASSERT_TRUE(r.estimate.valid);
      EXPECT_LT((r.estimate.position - scene.renderer().targetPosition(k)).norm(), 0.05) << "frame " << k;
    }
    like_background += r.support == Support::LikeBackground ? 1 : 0;
  }
  std::printf("a frame late: max |z| %.2f m (far limit %.1f m), %d frames tracking, %d like background\n", max_z,
              engine.viewingVolume().farDepth(), tracking, like_background);
  EXPECT_GT(like_background, 0) << "the background check never recognised the target as background";
}

// With acquisition (the default) a box of wall has no match in the right image: learning it is refused with an
// error naming the box, and the engine keeps no target.
TEST(EngineBounds, AcquisitionRefusesABoxOfWall)
{
  Scene scene("pendulum_uncluttered.yaml");
  FilterEngine engine(position3D(), defaultCues(), EngineConfig());
  std::string error;
  EXPECT_FALSE(engine.learnTarget(scene.frame(0), cv::Rect(20, 20, 40, 40), error));
  EXPECT_NE(error.find("box 20,20,40,40"), std::string::npos) << error;
  EXPECT_FALSE(engine.hasTarget());
  // The ball's own box is acquired: its 3D centre within 3 % of the truth and its radius within 3 %.
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  const Eigen::Vector3d truth = scene.renderer().targetPosition(0);
  EXPECT_LT((engine.acquisition().centre - truth).norm(), 0.03 * truth.norm());
  EXPECT_NEAR(engine.targetRadius(), 0.035, 0.03 * 0.035);
  const FrameResult r = engine.step(scene.frame(0));
  EXPECT_EQ(r.state, TrackState::Tracking);  // started where the box is
  EXPECT_LT((r.estimate.position - truth).norm(), 0.02);
}

// A target learned on a patch of the wall is everywhere: never tracked, never outside the volume.
TEST(EngineBounds, ATargetLearnedOnTheWallIsNeverTracked)
{
  Scene scene("pendulum_uncluttered.yaml");
  FilterEngine engine(position3D(), defaultCues(), searchOnly());
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), cv::Rect(20, 20, 40, 40), error)) << error;
  for (int k = 0; k < 40; ++k)
  {
    const FrameResult r = engine.step(scene.frame(k));
    EXPECT_NE(r.state, TrackState::Tracking) << "frame " << k << ": evidence " << r.evidence << ", background "
                                             << r.background;
    if (r.estimate.valid)
    {
      EXPECT_LE(r.estimate.position.z(), engine.viewingVolume().farDepth());
    }
  }
}

// The good case: the background check does not get in the way, and the background is far below the evidence.
TEST(EngineBounds, TheRightTargetIsTrackedAndStandsOutFromTheBackground)
{
  Scene scene("pendulum_uncluttered.yaml");
  FilterEngine engine(position3D(), defaultCues(), EngineConfig());
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  FrameResult r;
  int tracking = 0;
  for (int k = 0; k < 30; ++k)
  {
    r = engine.step(scene.frame(k));
    tracking += r.state == TrackState::Tracking ? 1 : 0;
    if (r.state == TrackState::Tracking)
    {
      EXPECT_EQ(r.state_frames, tracking) << "frames since acquisition";
    }
  }
  EXPECT_GE(tracking, 25);
  EXPECT_EQ(r.support, Support::Seen);
  EXPECT_GT(r.evidence - r.background, 0.5) << "evidence " << r.evidence << ", background " << r.background;
}

// A large object's background is measured too: beside a ball whose image is 0.3 of the image's height, the
// samples of the background (2.5 radii clear of it, their centres in the image) score the cluttered backdrop,
// which holds patches of the ball's colour. With samples 3 radii clear and their whole windows in the image, the
// rows held too few of them on 9 of these 20 frames, and the check did not run there.
TEST(EngineBounds, ALargeObjectIsJudgedAgainstTheBackgroundBesideIt)
{
  SceneDescription d = loadScene(std::string(SCENES_DIR) + "/pendulum_cluttered.yaml");
  d.objects[0].radius *= 5.0;
  d.background.target_patches = 30;
  Scene scene(d);
  FilterEngine engine(position3D(), defaultCues(), EngineConfig());
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  const cv::Rect roi = scene.renderer().targetRoi(0);
  ASSERT_GT(roi.height, scene.frame(0).left.rows / 4) << "the ball's image is not large";
  int measured = 0, seen = 0;
  for (int k = 0; k < 20; ++k)
  {
    const FrameResult r = engine.step(scene.frame(k));
    measured += r.background > 0.0 ? 1 : 0;
    seen += r.support == Support::Seen ? 1 : 0;
    EXPECT_LT(r.background, r.evidence) << "frame " << k;
  }
  EXPECT_GE(measured, 19) << "frames whose background was measured, of 20";
  EXPECT_GE(seen, 19) << "frames seen, of 20";
}

namespace
{
/// Position3D that, when asked, throws every particle far beyond what the cameras resolve.
class Escaping : public Position3D
{
public:
  bool escape = false;
  double escape_to = 0.0;  ///< > 0: every particle to this depth instead
  void predict(int set, double dt, ParticleSet& particles, Rng& rng) const override
  {
    Position3D::predict(set, dt, particles, rng);
    if (escape)
      particles.states.col(2).array() += 1e6;
    if (escape_to > 0.0)
      particles.states.col(2).setConstant(escape_to);
  }
};

/// Learned from the pendulum's first frame and tracking it with an Escaping state model, without the recovery
/// proposals and the local search, which would put a share of the set back at the object and so keep it from
/// leaving the volume whole.
struct EscapingRun
{
  explicit EscapingRun(unsigned long seed = 1) : config(escapingConfig(seed)) {}
  static EngineConfig escapingConfig(unsigned long seed)
  {
    EngineConfig c;
    c.tracking_respawn_fraction = 0.0;
    c.local_fraction = 0.0;
    c.seed = seed;
    return c;
  }
  Scene scene{ "pendulum_uncluttered.yaml" };
  std::shared_ptr<Escaping> state = [] {
    auto m = std::make_shared<Escaping>();
    m->initialize("state_model", Parameters());
    return m;
  }();
  EngineConfig config;
  FilterEngine engine{ state, defaultCues(), config };
  bool learned = [this] {
    std::string error;
    const bool ok = engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error);
    EXPECT_TRUE(ok) << error;
    return ok;
  }();
};
}  // namespace

TEST(EngineBounds, ASetOutsideTheViewingVolumeIsLostAndRedrawnFromThePrior)
{
  // The path for a set that leaves the volume whole, over several seeds: where the redrawn set is found again
  // is a draw, and one seed's draw says little.
  std::vector<double> errors;
  for (unsigned long seed = 1; seed <= 20; ++seed)
  {
    EscapingRun run(seed);
    ASSERT_TRUE(run.learned);
    Scene& scene = run.scene;
    FilterEngine& engine = run.engine;
    auto& state = run.state;
    FrameResult r;
    for (int k = 0; k < 10; ++k)
      r = engine.step(scene.frame(k));
    ASSERT_EQ(r.state, TrackState::Tracking) << "seed " << seed;

    state->escape = true;
    r = engine.step(scene.frame(10));
    state->escape = false;
    EXPECT_EQ(r.support, Support::OutsideView) << "seed " << seed;
    EXPECT_EQ(r.state, TrackState::Lost) << "seed " << seed;
    EXPECT_FALSE(r.estimate.valid) << "an estimate from outside the viewing volume, seed " << seed;
    EXPECT_TRUE(r.reinitialised) << "seed " << seed;

    // Redrawn from the prior (z_min..z_max) at the next frame, and found again. The proposals that join the
    // redrawn set come from stereo pairs the cues found, which can be anywhere in the viewing volume (a pair of
    // small disparity is far): the set's bulk is within the prior's range and all of it inside the volume.
    r = engine.step(scene.frame(11));
    const ParticleSet& p = engine.sets().front();
    std::vector<double> depths(p.states.col(2).data(), p.states.col(2).data() + p.size());
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    EXPECT_LE(depths[depths.size() / 2], 3.0 + 1.0) << "seed " << seed;
    EXPECT_LE(p.states.col(2).maxCoeff(), engine.viewingVolume().farDepth() + 1e-6) << "seed " << seed;
    int k = 12;
    for (; k < 40 && r.state != TrackState::Tracking; ++k)
      r = engine.step(scene.frame(k));
    EXPECT_EQ(r.state, TrackState::Tracking) << "not re-acquired after the re-initialisation, seed " << seed;
    errors.push_back((r.estimate.position - scene.renderer().targetPosition(k - 1)).norm());
    std::printf("seed %lu: re-acquired at frame %d, %.4f m off\n", seed, k - 1, errors.back());
  }
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.05);
  EXPECT_LT(errors.back(), 0.15);
}

TEST(EngineBounds, ANearerMaxDepthBoundsTheParticles)
{
  Scene scene("pendulum_uncluttered.yaml");
  EngineConfig config;
  config.max_depth = 2.0;
  FilterEngine engine(position3D(), defaultCues(), config);
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  const FrameResult r = engine.step(scene.frame(0));  // the prior reaches 3 m
  const ParticleSet& p = engine.sets().front();
  double beyond = 0.0;
  for (int i = 0; i < p.size(); ++i)
    if (p.states(i, 2) > 2.0 + 1e-6)
      beyond += 1.0;  // resampled away: none of them can be drawn
  EXPECT_EQ(beyond, 0.0);
  EXPECT_NEAR(engine.viewingVolume().farDepth(), 2.0, 1e-9);
  (void)r;
}

TEST(EngineBounds, BeyondWhereTheLearnedObjectIsResolvedIsOutsideTheView)
{
  // The far limit is also where the learned object's image radius falls to min_apparent_radius (fx R / 1 px: 18 m
  // for the pendulum's 3.5 cm ball on its 525 px rig, nearer than fx b / 0.5 px = 94 m). A cloud thrown to 40 m,
  // within the disparity's limit, is lost there rather than tracked as a speck.
  EscapingRun run;
  ASSERT_TRUE(run.learned);
  Scene& scene = run.scene;
  FilterEngine& engine = run.engine;
  EngineConfig config = run.config;
  FrameResult r = engine.step(scene.frame(0));
  const double fx = scene.renderer().geometry().fx();
  EXPECT_NEAR(engine.viewingVolume().farDepth(), fx * engine.targetRadius() / config.min_apparent_radius, 1e-6);
  EXPECT_LT(engine.viewingVolume().farDepth(), 25.0);
  run.state->escape_to = 40.0;
  r = engine.step(scene.frame(1));
  EXPECT_EQ(r.support, Support::OutsideView);
  EXPECT_FALSE(r.estimate.valid);
  EXPECT_EQ(r.state, TrackState::Lost);

  // Without the limit, 40 m is inside the volume (the disparity's limit alone).
  config.min_apparent_radius = 0.0;
  FilterEngine unlimited(position3D(), defaultCues(), config);
  std::string error;
  ASSERT_TRUE(unlimited.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  unlimited.step(scene.frame(0));
  EXPECT_GT(unlimited.viewingVolume().farDepth(), 40.0);
}

// Transactions: a target change applies to every cue or to none.
namespace
{
/// ColourHSI that can be told to refuse the next region.
class Refusing : public ColourHSI
{
public:
  bool refuse = false;
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override
  {
    if (refuse)
    {
      error = "refused for the test";
      return false;
    }
    return ColourHSI::learnTarget(cache, view, roi, error);
  }
};
}  // namespace

namespace
{
/// Mean evidence over frames 5..19 of a grey pendulum tracked with its images times these gains from frame 1 on
/// (the target learned at gain 1 from frame 0); `adapt` false: the colour histogram held as learned.
double evidenceUnderGains(bool compensate, double left_gain, double right_gain, bool adapt = true)
{
  // The pendulum with a grey ball before a darker grey backdrop: only intensity tells them apart.
  SceneDescription grey = loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml");
  grey.objects[0].colour = cv::Vec3d(190, 190, 190);
  grey.background.colour = cv::Vec3d(90, 90, 90);
  Scene scene(grey);
  EngineConfig config;
  config.gain_compensation = compensate;
  std::vector<std::shared_ptr<ObservationModel>> cues = defaultCues();
  if (!adapt)
  {
    Parameters held;
    held.set("adapt_rate", 0.0);
    auto colour = std::make_shared<ColourHSI>();
    colour->initialize("colour", held);
    cues[0] = colour;
  }
  FilterEngine engine(position3D(), cues, config);
  std::string error;
  EXPECT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  double sum = 0.0;
  int n = 0;
  for (int k = 1; k < 20; ++k)
  {
    StereoFrame f = scene.frame(k);
    cv::Mat left, right;
    f.left.convertTo(left, -1, left_gain);
    f.right.convertTo(right, -1, right_gain);
    f.left = left;
    f.right = right;
    const FrameResult r = engine.step(f);
    if (k >= 5)
    {
      sum += r.evidence;
      ++n;
    }
  }
  return sum / n;
}
}  // namespace

TEST(EngineGain, ACameraGainChangeIsTakenOutOfTheColourCues)
{
  // After the target is learned the left camera's gain falls by 40 % and the right one's by 25 % (auto gain, or
  // two cameras that differ). Each view's pixels are scaled back by its brightness against the learning frame's,
  // so the ball scores as it does at the learning gain; without that its colours move into other intensity bins
  // and its evidence drops. (Lower gains: what a higher one clips, no gain brings back.) The histogram's adaptation
  // (on by default) follows the ball's new colours too, over the frames it is still seen in (0.91 here without
  // compensation), so what compensation does is measured with the histogram held as learned; the defaults are
  // held to the evidence as learned.
  const double as_learned = evidenceUnderGains(true, 1.0, 1.0);
  const double compensated = evidenceUnderGains(true, 0.6, 0.75);
  EXPECT_GT(compensated, as_learned - 0.05);
  const double held_as_learned = evidenceUnderGains(true, 1.0, 1.0, false);
  const double held_compensated = evidenceUnderGains(true, 0.6, 0.75, false);
  const double held_raw = evidenceUnderGains(false, 0.6, 0.75, false);
  std::printf("evidence: %.3f as learned, %.3f compensated; histogram held: %.3f as learned, %.3f compensated, %.3f "
              "as they are\n",
              as_learned, compensated, held_as_learned, held_compensated, held_raw);
  EXPECT_GT(held_compensated, held_as_learned - 0.05) << "raw " << held_raw;
  EXPECT_LT(held_raw, held_compensated - 0.1) << "as learned " << held_as_learned;
}

TEST(EngineGain, TheLearningBrightnessTravelsWithTheTargetFile)
{
  // A target loaded from a file is compared at the brightness it was learned at, not at the first frame's after
  // loading: learned at gain 1, loaded and tracked at gain 0.75, each view is brought back by 1 / 0.75.
  Scene scene("pendulum_uncluttered.yaml");
  const std::string path = "/tmp/stereo_pf_test_gain_" + std::to_string(getpid()) + ".yml";
  std::string error;
  {
    FilterEngine learner(position3D(), defaultCues(), EngineConfig());
    ASSERT_TRUE(learner.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
    ASSERT_TRUE(learner.saveTarget(path, error)) << error;
  }
  cv::FileStorage fs(path, cv::FileStorage::READ);
  ASSERT_TRUE(fs["photometry"]["brightness"].isReal());
  const double stored = static_cast<double>(fs["photometry"]["brightness"]);
  fs.release();
  FeatureCache cache;
  cache.reset(scene.frame(0));
  EXPECT_DOUBLE_EQ(stored, cache.brightness(View::Left));

  FilterEngine engine(position3D(), defaultCues(), searchOnly());
  ASSERT_TRUE(engine.loadTarget(path, error)) << error;
  std::remove(path.c_str());
  EXPECT_DOUBLE_EQ(engine.targetBrightness(), stored);
  StereoFrame f = scene.frame(0);
  cv::Mat left, right;
  f.left.convertTo(left, -1, 0.75);
  f.right.convertTo(right, -1, 0.75);
  f.left = left;
  f.right = right;
  engine.step(f);
  // The gains the step used: the file's brightness over this frame's.
  FeatureCache scaled;
  scaled.reset(f);
  EXPECT_NEAR(engine.featureCache().gain(View::Left), stored / scaled.brightness(View::Left), 1e-12);
  EXPECT_NEAR(engine.featureCache().gain(View::Left), 1.0 / 0.75, 0.03);
}

TEST(EngineTransactions, AFailedLearnKeepsEveryCuesTarget)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto refusing = std::make_shared<Refusing>();
  refusing->initialize("texture_like", Parameters());
  FilterEngine engine(position3D(), { cue<ColourHSI>("colour"), cue<ColourContour>("colour_contour"), refusing },
                      searchOnly());  // the cues' transaction, on a box of wall (which acquisition would refuse first)
  const StereoFrame f = scene.frame(0);
  std::string error;
  ASSERT_TRUE(engine.learnTarget(f, scene.renderer().targetRoi(0), error)) << error;
  const std::string before = targets(engine);
  refusing->refuse = true;
  EXPECT_FALSE(engine.learnTarget(f, cv::Rect(20, 20, 40, 40), error));
  EXPECT_NE(error.find("texture_like"), std::string::npos) << error;
  EXPECT_EQ(targets(engine), before) << "the cues before the refusing one kept the new region";
}

TEST(EngineTransactions, ATargetFileMissingACueChangesNothing)
{
  Scene scene("pendulum_uncluttered.yaml");
  const StereoFrame f = scene.frame(0);
  const std::string path = "/tmp/stereo_pf_test_target_" + std::to_string(getpid()) + ".yml";
  std::string error;
  {
    // Saved with the colour histogram only (another configuration), from a region of wall.
    FilterEngine colour_only(position3D(), { cue<ColourHSI>("colour") }, searchOnly());
    ASSERT_TRUE(colour_only.learnTarget(f, cv::Rect(20, 20, 40, 40), error)) << error;
    ASSERT_TRUE(colour_only.saveTarget(path, error)) << error;
  }
  FilterEngine engine(position3D(), defaultCues(), EngineConfig());
  ASSERT_TRUE(engine.learnTarget(f, scene.renderer().targetRoi(0), error)) << error;
  const std::string before = targets(engine);
  EXPECT_FALSE(engine.loadTarget(path, error));
  EXPECT_NE(error.find("colour_contour"), std::string::npos) << error;
  EXPECT_NE(error.find("No target was changed"), std::string::npos) << error;
  EXPECT_EQ(targets(engine), before) << "the colour target was replaced by a failed load";

  // A malformed entry for the second cue: the first one's target is restored.
  {
    std::ifstream in(path);
    std::ofstream out(path + ".2.yml");
    out << in.rdbuf() << "colour_contour:\n   type: \"stereo_pf/ColourContour\"\n   histogram: oops\n";
  }
  EXPECT_FALSE(engine.loadTarget(path + ".2.yml", error));
  EXPECT_EQ(targets(engine), before) << "a failed load changed a target";
  std::remove(path.c_str());
  std::remove((path + ".2.yml").c_str());
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

namespace
{
/// An engine with `state`, the colour histogram and its outline, and `config`, that learned the pendulum's ball from
/// its box in frame 0 and tracked frames 0-9; `last` is frame 9's result.
std::unique_ptr<FilterEngine> trackingTheFirstTenFrames(Scene& scene, const std::shared_ptr<StateModel>& state,
                                                        const EngineConfig& config, FrameResult& last)
{
  auto engine = std::make_unique<FilterEngine>(state, defaultCues(), config);
  std::string error;
  EXPECT_TRUE(engine->learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  for (int k = 0; k < 10; ++k)
    last = engine->step(scene.frame(k));
  return engine;
}

/// Position3D that, when asked, puts every particle at one wrong place: a lock planted on the background.
class Planting : public Position3D
{
public:
  bool plant = false;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();
  void predict(int set, double dt, ParticleSet& particles, Rng& rng) const override
  {
    Position3D::predict(set, dt, particles, rng);
    if (plant)
      for (int i = 0; i < particles.size(); ++i)
        particles.states.row(i).head<3>() = at.transpose();
  }
};

/// Frames after a lock planted 25 cm beside the pendulum's ball until the estimate is back within 3 cm of it
/// (-1: not within 15 frames), and whether the track was declared lost meanwhile; `searches`: with the recovery
/// proposals and the local search as configured by default, else with neither.
int framesToLeaveAPlantedLock(bool searches, bool& lost)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto state = std::make_shared<Planting>();
  state->initialize("state_model", Parameters());
  EngineConfig config;
  if (!searches)
  {
    config.tracking_respawn_fraction = 0.0;
    config.local_fraction = 0.0;
  }
  FrameResult r;
  std::unique_ptr<FilterEngine> tracking = trackingTheFirstTenFrames(scene, state, config, r);
  FilterEngine& engine = *tracking;
  EXPECT_EQ(r.state, TrackState::Tracking);
  state->plant = true;
  state->at = scene.renderer().targetPosition(10) + Eigen::Vector3d(0.25, 0.0, 0.0);
  r = engine.step(scene.frame(10));
  state->plant = false;
  lost = false;
  for (int k = 11; k <= 25; ++k)
  {
    r = engine.step(scene.frame(k));
    lost = lost || r.state != TrackState::Tracking;
    if (r.estimate.valid && r.state == TrackState::Tracking &&
        (r.estimate.position - scene.renderer().targetPosition(k)).norm() < 0.03)
      return k - 10;
  }
  return -1;
}
}  // namespace

TEST(EngineRecovery, APlantedWrongLockIsLeftForTheObjectWithoutLosingTheTrack)
{
  // The recovery proposals (tracking_respawn_fraction) and the local search (local_fraction) keep a share of the
  // set where the cues see the target: the planted cloud sees only background, those particles take the weight,
  // and the track goes on.
  bool lost = true;
  const int with = framesToLeaveAPlantedLock(true, lost);
  EXPECT_GE(with, 1);
  EXPECT_LE(with, 3) << "frames to leave the planted lock";
  EXPECT_FALSE(lost) << "the track was declared lost although the object stayed in view";
  // Without them the filter has to lose the track first and search again.
  const int without = framesToLeaveAPlantedLock(false, lost);
  std::printf("planted lock left after %d frame(s) with the recovery and local search, %d without (-1: not in 15)\n",
              with, without);
  EXPECT_TRUE(without == -1 || without > with) << without;
  EXPECT_TRUE(without == -1 || lost);
}

namespace
{
/// The colour histogram that notes the frames on which its target map is asked for: while tracking, only the
/// recovery search draws from the maps.
class MapCounting : public ColourHSI
{
public:
  int frame = 0;
  std::set<int> frames;
  bool targetMap(FeatureCache& cache, View view, cv::Mat& map) override
  {
    frames.insert(frame);
    return ColourHSI::targetMap(cache, view, map);
  }
};

/// The frames (after acquisition at frame 0, tracking) on which the recovery search ran, of the pendulum's first 13.
std::set<int> recoveryFrames(int period)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto colour = cue<MapCounting>("colour");
  EngineConfig config;
  config.recovery_period = period;
  FilterEngine engine(position3D(), { colour, cue<ColourContour>("colour_contour") }, config);
  std::string error;
  EXPECT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  for (int k = 0; k <= 12; ++k)
  {
    colour->frame = k;
    EXPECT_EQ(engine.step(scene.frame(k)).state, TrackState::Tracking) << "frame " << k;
  }
  return colour->frames;
}
}  // namespace

TEST(EngineRecovery, TheRecoverySearchRunsOnEveryPeriodthFrameOfATrack)
{
  // Frame 0 starts the track from the box (no search); frame k is the track's k-th after it.
  EXPECT_EQ(recoveryFrames(1), (std::set<int>{ 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12 }));
  EXPECT_EQ(recoveryFrames(4), (std::set<int>{ 4, 8, 12 }));
}

namespace
{
/// Velocity3D that notes where from and over what time each jumped particle is said to have arrived, and the speed
/// that implies.
class ArrivalNoting : public Velocity3D
{
public:
  mutable std::vector<std::pair<Eigen::Vector3d, double>> arrivals;
  mutable std::vector<double> speeds;
  void setArrival(const StateEstimate& from, double dt, int set, ParticleSet& particles, int row) const override
  {
    arrivals.emplace_back(from.position, dt);
    speeds.push_back((particles.states.row(row).head<3>().transpose() - from.position).norm() / dt);
    Velocity3D::setArrival(from, dt, set, particles, row);
  }
};

/// The speeds the recovery search's jumps imply when the pendulum's ball, tracked for 10 frames, is shown next where
/// it is farthest from there (the recovery search on every frame, no local search); `max_jump_speed` as given.
std::vector<double> jumpSpeedsAfterATeleport(double max_jump_speed)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto state = std::make_shared<ArrivalNoting>();
  state->initialize("state_model", Parameters());
  EngineConfig config;
  config.recovery_period = 1;
  config.local_fraction = 0.0;
  config.max_jump_speed = max_jump_speed;
  FrameResult r;
  std::unique_ptr<FilterEngine> engine = trackingTheFirstTenFrames(scene, state, config, r);
  EXPECT_EQ(r.support, Support::Seen);
  int far = 10;
  for (int k = 10; k < 90; ++k)
    if ((scene.renderer().targetPosition(k) - r.estimate.position).norm() >
        (scene.renderer().targetPosition(far) - r.estimate.position).norm())
      far = k;
  StereoFrame teleport = scene.frame(far);
  teleport.stamp = scene.renderer().stamp(10);
  state->speeds.clear();
  engine->step(teleport);
  return state->speeds;
}
}  // namespace

namespace
{
/// The grey template that counts the hypotheses it scores: those the screening left valid.
class ScoreCounting : public TemplateMatch
{
public:
  long scored = 0;
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    scored += std::count(hyp.valid.begin(), hyp.valid.end(), 1);
    TemplateMatch::evaluate(cache, hyp, log_likelihood, similarity);
  }
};

/// The colour histogram that counts the hypotheses it scores in full (evaluate()) and in preview.
class ColourCounting : public ColourHSI
{
public:
  long scored = 0, previewed = 0;
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    scored += std::count(hyp.valid.begin(), hyp.valid.end(), 1);
    ColourHSI::evaluate(cache, hyp, log_likelihood, similarity);
  }
  bool preview(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood) override
  {
    const bool has = ColourHSI::preview(cache, hyp, log_likelihood);
    previewed += has ? std::count(hyp.valid.begin(), hyp.valid.end(), 1) : 0;
    return has;
  }
};

struct ScreenedRun
{
  double rms = 0.0;        ///< m, over the tracked frames
  long scored = 0;         ///< hypotheses the template scored
  long colour_scored = 0;  ///< hypotheses the colour histogram scored in full
  long previewed = 0;      ///< hypotheses it previewed
  long screened = 0;       ///< FrameResult::screened, summed
};

/// The pendulum's first 40 frames tracked by the colour histogram, the template, the outline and the stereo match
/// (two stages while tracking) with the given screen_mass and the colour histogram's preview_samples.
ScreenedRun trackScreened(double screen_mass, int preview_samples = 5)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto grey = cue<ScoreCounting>("template");
  auto colour = std::make_shared<ColourCounting>();
  Parameters colour_parameters;
  colour_parameters.set("preview_samples", preview_samples);
  colour->initialize("colour", colour_parameters);
  EngineConfig config;
  config.screen_mass = screen_mass;
  FilterEngine engine(position3D(), { colour, grey, cue<ColourContour>("colour_contour"), cue<StereoMatch>("stereo") },
                      config);
  std::string error;
  EXPECT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  ScreenedRun run;
  double sum2 = 0.0;
  const int frames = 40;
  for (int k = 0; k < frames; ++k)
  {
    const FrameResult r = engine.step(scene.frame(k));
    EXPECT_EQ(r.state, TrackState::Tracking) << "frame " << k;
    sum2 += (r.estimate.position - scene.renderer().targetPosition(k)).squaredNorm();
    run.screened += r.screened;
  }
  run.rms = std::sqrt(sum2 / frames);
  run.scored = grey->scored;
  run.colour_scored = colour->scored;
  run.previewed = colour->previewed;
  return run;
}
}  // namespace

TEST(EngineScreening, TheCuesAfterTheFirstWeighOnlyTheParticlesItFindsWorthIt)
{
  // screen_mass 1 weighs every particle with every cue; the default leaves out those that carry the last 0.1 % of
  // the colour histogram's (tempered) weight, in the first stage, and of the outline's in the refining one (here
  // the histogram's own evaluation, its preview off; the next test has it on).
  const ScreenedRun every = trackScreened(1.0);
  const ScreenedRun screened = trackScreened(EngineConfig().screen_mass, 0);
  std::printf("template scored %ld hypotheses screened, %ld not; %ld particles screened out; RMS %.2f / %.2f cm\n",
              screened.scored, every.scored, screened.screened, 100.0 * screened.rms, 100.0 * every.rms);
  EXPECT_EQ(every.screened, 0);
  EXPECT_GT(screened.screened, 0);
  EXPECT_LT(screened.scored, every.scored * 3 / 4);  // at least a quarter of its work saved
  EXPECT_LT(screened.rms, 0.01);
  EXPECT_LT(screened.rms, every.rms + 0.002);
}

TEST(EngineScreening, TheColourPreviewChoosesTheParticlesTheHistogramWeighsInFull)
{
  // With its preview (the default), the colour histogram scores in full only the particles its coarser window and
  // ring find worth it; without (preview_samples 0), every one, and the cues after it the ones it chose.
  const ScreenedRun full = trackScreened(EngineConfig().screen_mass, 0);
  const ScreenedRun previewed = trackScreened(EngineConfig().screen_mass);
  std::printf("colour scored %ld hypotheses in full after %ld previews, %ld without; template %ld / %ld; RMS %.2f / "
              "%.2f cm\n",
              previewed.colour_scored, previewed.previewed, full.colour_scored, previewed.scored, full.scored,
              100.0 * previewed.rms, 100.0 * full.rms);
  EXPECT_EQ(full.previewed, 0);
  EXPECT_GT(previewed.previewed, 0);
  EXPECT_LT(previewed.colour_scored, full.colour_scored / 2);  // half of the full scoring saved at least
  EXPECT_LT(previewed.rms, 0.01);
  EXPECT_LT(previewed.rms, full.rms + 0.002);
}

TEST(EngineRecovery, NoJumpIsFasterThanMaxJumpSpeed)
{
  // Without the bound the recovery search jumps to the ball wherever it went; with it, only as far as the speed
  // allows in one frame (a look-alike on the wall behind a ball is out of reach).
  const std::vector<double> free = jumpSpeedsAfterATeleport(0.0);
  ASSERT_FALSE(free.empty());
  const double fastest = *std::max_element(free.begin(), free.end());
  std::printf("fastest jump to the teleported ball without the bound: %.1f m/s\n", fastest);
  ASSERT_GT(fastest, 4.0);
  for (const double speed : jumpSpeedsAfterATeleport(2.0))
    EXPECT_LE(speed, 2.0 + 1e-6);
  EXPECT_EQ(EngineConfig().max_jump_speed, 40.0);
}

namespace
{
/// Frame k of `scene` with both views a uniform grey: nothing of the object is seen.
StereoFrame blankFrame(Scene& scene, int k, double grey = 128)
{
  StereoFrame blank = scene.frame(k);
  blank.left = cv::Mat(blank.left.size(), blank.left.type(), cv::Scalar::all(grey));
  blank.right = cv::Mat(blank.right.size(), blank.right.type(), cv::Scalar::all(grey));
  return blank;
}
}  // namespace

TEST(EngineRecovery, AJumpAfterUnseenFramesArrivesFromWhereTheObjectWasLastSeen)
{
  // The pendulum tracked for 10 frames; then two blank frames (the track is kept, unseen: lost_frames is more) over
  // which the estimate drifts with the particles' velocities; then the ball again, found by the searches. The
  // jumped particles' velocity is the way from the last estimate that saw the object over the time since, not
  // from the drifted estimate over one frame: with that, a ball the nodelet test showed again after its last
  // frame (a jump across the swing) was re-found with 15 m/s, and lost again two frames later outside the view.
  Scene scene("pendulum_uncluttered.yaml");
  auto state = std::make_shared<ArrivalNoting>();
  state->initialize("state_model", Parameters());
  const EngineConfig config;
  ASSERT_GT(config.lost_frames, 2);
  FrameResult seen;
  std::unique_ptr<FilterEngine> tracking = trackingTheFirstTenFrames(scene, state, config, seen);
  FilterEngine& engine = *tracking;
  ASSERT_EQ(seen.state, TrackState::Tracking);
  ASSERT_EQ(seen.support, Support::Seen);
  ASSERT_TRUE(seen.estimate.valid);
  for (int k = 10; k < 12; ++k)
  {
    const FrameResult r = engine.step(blankFrame(scene, k));
    ASSERT_EQ(r.state, TrackState::Tracking) << "frame " << k;
    ASSERT_EQ(r.support, Support::LowEvidence) << "frame " << k;
  }
  state->arrivals.clear();
  const FrameResult back = engine.step(scene.frame(12));
  EXPECT_EQ(back.support, Support::Seen);
  ASSERT_FALSE(state->arrivals.empty()) << "no particle jumped to the ball";
  const double since = scene.renderer().stamp(12) - scene.renderer().stamp(9);
  for (const auto& [from, dt] : state->arrivals)
  {
    EXPECT_NEAR(dt, since, 1e-9);
    EXPECT_LT((from - seen.estimate.position).norm(), 1e-9);
  }
}

namespace
{
/// The pendulum tracked for 10 frames, then held still (frame 9 for 12 more frames: 0.4 s, longer than the sightings
/// the track's speed is fitted to, FilterEngine::recordSighting), then blank frames until the track
/// is lost, then `shown` (a frame of the scene) again and again, the stamps going on at the scene's frame period:
/// the frames until the ball is tracked again (-1: not within 20); `distance` gets how far it is from where the track
/// last saw it, `error` how far the first estimate back is from the ball (-1: not found). `replayed`: the stamps start
/// again from the scene's first when the ball is shown (a bag played again). `jitter` (a frame of the scene): the
/// "still" frames alternate between frame 9 and it, the track's estimate jumping to and fro every frame.
int framesToFindTheBallAgain(const EngineConfig& config, int shown, double& distance, double& error,
                             bool replayed = false, int jitter = -1)
{
  Scene scene("pendulum_uncluttered.yaml");
  FrameResult r;
  std::unique_ptr<FilterEngine> tracking = trackingTheFirstTenFrames(scene, position3D(), config, r);
  FilterEngine& engine = *tracking;
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  double stamp = scene.renderer().stamp(9);
  for (int k = 0; k < 12; ++k)
  {
    StereoFrame still = scene.frame(jitter >= 0 && k % 2 == 0 ? jitter : 9);
    still.stamp = stamp += period;
    r = engine.step(still);
  }
  EXPECT_EQ(r.support, Support::Seen);
  distance = (scene.renderer().targetPosition(shown) - r.estimate.position).norm();
  for (int k = 0; k < 10 && r.state == TrackState::Tracking; ++k)
  {
    StereoFrame blank = blankFrame(scene, 10);
    blank.stamp = stamp += period;
    r = engine.step(blank);
  }
  EXPECT_EQ(r.state, TrackState::Lost);
  error = -1.0;
  if (replayed)
    stamp = scene.renderer().stamp(0) - period;
  for (int k = 1; k <= 20; ++k)
  {
    StereoFrame back = scene.frame(shown);
    back.stamp = stamp += period;
    r = engine.step(back);
    if (r.state == TrackState::Tracking)
    {
      error = (r.estimate.position - scene.renderer().targetPosition(shown)).norm();
      return k;
    }
  }
  return -1;
}

/// The frame among the pendulum's frames 10-89 whose ball lies farthest from where it is in frame 9.
int farthestFromFrameNine(Scene& scene)
{
  int far = 10;
  for (int k = 10; k < 90; ++k)
    if ((scene.renderer().targetPosition(k) - scene.renderer().targetPosition(9)).norm() >
        (scene.renderer().targetPosition(far) - scene.renderer().targetPosition(9)).norm())
      far = k;
  return far;
}
}  // namespace

TEST(EngineRecovery, ALostTrackIsFoundAgainOnlyWithinReachOfWhereItWasLastSeen)
{
  // The ball, still, then hidden, shows again where the swing is farthest from where the track last saw it: a
  // look-alike for all the engine can tell. With a floor of 0.2 m/s (and twice the still ball's speed, about 0) that
  // place stays out of reach for the 20 frames; without the bound the ball is found there; where the track last saw
  // it, it is found with the bound too. The first estimate back is one frame's draw from particles just come to the
  // ball (over engine seeds 1-8 it lay 0.4-4.1 cm off with the colour histogram held as learned, 0.5-6.7 cm with it
  // adapting), so each case runs at seven engine seeds, and their median must be on the ball: within its radius
  // (3.5 cm) of its centre.
  Scene scene("pendulum_uncluttered.yaml");
  const int far = farthestFromFrameNine(scene);
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  std::vector<double> free_errors, near_errors, replayed_errors;
  for (unsigned long seed = 1; seed <= 7; ++seed)
  {
    SCOPED_TRACE("engine seed " + std::to_string(seed));
    EngineConfig config;
    config.seed = seed;
    config.reacquire_min_speed = 0.2;
    double distance = 0.0, error = 0.0;
    const int bounded = framesToFindTheBallAgain(config, far, distance, error);
    ASSERT_GT(distance, 2.0 * config.reacquire_min_speed * 35 * period) << "the far place must stay out of reach";
    EXPECT_EQ(bounded, -1) << "found " << distance << " m away within " << bounded << " frames";
    config.reacquire_min_speed = 0.0;
    const int free = framesToFindTheBallAgain(config, far, distance, error);
    free_errors.push_back(error);
    std::printf("seed %lu: ball %.2f m from where it was last seen: found again after %d frames without the bound "
                "(%.1f cm off), %d with\n",
                seed, distance, free, 100.0 * error, bounded);
    EXPECT_GE(free, 1);
    EXPECT_LE(free, 10);
    config.reacquire_min_speed = 0.2;
    const int near = framesToFindTheBallAgain(config, 9, distance, error);
    near_errors.push_back(error);
    EXPECT_LT(distance, 0.02);
    EXPECT_GE(near, 1);
    EXPECT_LE(near, 10);
    // Stamps that start again (a bag played again) before the ball is back: the time since would be negative, the
    // reach none for as long as the replay lasts; the last place is not held against it then.
    const int replayed = framesToFindTheBallAgain(config, far, distance, error, true);
    replayed_errors.push_back(error);
    EXPECT_GE(replayed, 1);
    EXPECT_LE(replayed, 10);
    std::printf("seed %lu: where it was last seen: after %d frames (%.1f cm off); stamps replayed: after %d (%.1f cm)\n",
                seed, near, 100.0 * near_errors.back(), replayed, 100.0 * error);
  }
  for (std::vector<double>* errors : { &free_errors, &near_errors, &replayed_errors })
  {
    std::sort(errors->begin(), errors->end());
    EXPECT_GE(errors->front(), 0.0) << "not found at some seed";
    EXPECT_LT((*errors)[errors->size() / 2], 0.035) << "the median first estimate back is off the ball";
  }
}

TEST(EngineRecovery, TheReachFollowsTheSpeedOverTheLastSightingsNotTheLastFrame)
{
  // The reach grows with the object's speed where it was last seen. The still ball's estimate is made to jump to and
  // fro between frame 9's place and frame 10's (one frame's swing) on every frame before it is hidden: read off the
  // last frame, the speed would be that jump over a frame period, and the far place of the swing would come within
  // reach. Fitted to the last sightings, the speed stays near zero and the far place out of reach, as for the still
  // ball (ALostTrackIsFoundAgainOnlyWithinReachOfWhereItWasLastSeen).
  Scene scene("pendulum_uncluttered.yaml");
  const int far = farthestFromFrameNine(scene);
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  const double jump = (scene.renderer().targetPosition(10) - scene.renderer().targetPosition(9)).norm();
  for (unsigned long seed = 1; seed <= 3; ++seed)
  {
    SCOPED_TRACE("engine seed " + std::to_string(seed));
    EngineConfig config;
    config.seed = seed;
    config.reacquire_min_speed = 0.2;
    double distance = 0.0, error = 0.0;
    const int found = framesToFindTheBallAgain(config, far, distance, error, false, 10);
    // Out of reach at the floor; within it at the speed of one frame's jump (the way the last frame would have it).
    ASSERT_GT(distance, 2.0 * config.reacquire_min_speed * 35 * period) << "the far place must stay out of reach";
    ASSERT_LT(distance, (2.0 * jump / period + config.reacquire_min_speed) * 15 * period)
        << "a speed read off the last frame would not reach the far place: the test shows nothing";
    std::printf("seed %lu: estimate jumping %.1f cm a frame (%.2f m/s), ball %.2f m away: found after %d frames\n",
                seed, 100.0 * jump, jump / period, distance, found);
    EXPECT_EQ(found, -1) << "found " << distance << " m away within " << found << " frames";
  }
}

namespace
{
/// A ball (2 cm at 2 m: 5 px in radius) standing still among `lookalikes` balls of its colour and size spread over
/// the view, each at least 0.6 m from it (scenes/occlusion.yaml's camera, light and backdrop, without its board).
SceneDescription ballAmongLookalikes(int lookalikes)
{
  SceneDescription d = loadScene(std::string(SCENES_DIR) + "/occlusion.yaml");
  d.frames = 1;
  d.occluders.clear();
  SceneSphere ball = d.objects[0];
  ball.draw_string = false;
  ball.radius = 0.02;
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.1, 0.05, 2.0));
  d.objects = { ball };
  cv::RNG rng(7);
  while (static_cast<int>(d.objects.size()) <= lookalikes)
  {
    const double z = rng.uniform(1.8, 3.0);
    const Eigen::Vector3d p(rng.uniform(-0.45, 0.45) * z * 640 / 525, rng.uniform(-0.4, 0.4) * z * 480 / 525, z);
    if ((p - ball.trajectory.position).norm() < 0.6)
      continue;
    SceneSphere other = ball;
    other.name = "lookalike" + std::to_string(d.objects.size());
    other.trajectory = Trajectory::fixed(p);
    d.objects.push_back(other);
  }
  return d;
}
}  // namespace

namespace
{
/// The occlusion scene's ball (3.5 cm, orange), standing still 1.2 m away, and a look-alike 0.47 m from it; without
/// the ball when `with_ball` is false (hidden).
SceneDescription ballAndALookalike(bool with_ball)
{
  SceneDescription d = loadScene(std::string(SCENES_DIR) + "/occlusion.yaml");
  d.occluders.clear();
  SceneSphere ball = d.objects[0];
  ball.draw_string = false;
  ball.trajectory = Trajectory::fixed(Eigen::Vector3d(0.1, 0.05, 1.2));
  SceneSphere other = ball;
  other.name = "lookalike";
  other.trajectory = Trajectory::fixed(Eigen::Vector3d(-0.25, -0.05, 1.5));
  d.objects = { ball, other };
  if (!with_ball)
    d.objects[0].trajectory = Trajectory::fixed(Eigen::Vector3d(3.0, 0.05, 1.2));  // out of the view
  return d;
}

/// The default engine on ballAndALookalike(): the ball tracked for `tracked` frames, hidden for at most 80 frames,
/// until the track is lost and then taken by the look-alike (`taken`: the track's estimate was within 2 cm of it), then
/// shown again: the frames until the estimate is back within 2 cm of the ball (-1: not within 20).
int framesToComeBackToTheBall(const EngineConfig& config, bool& taken, int tracked = 10)
{
  Scene both(ballAndALookalike(true)), hidden(ballAndALookalike(false));
  const Eigen::Vector3d ball = both.renderer().targetPosition(0);
  const Eigen::Vector3d lookalike(-0.25, -0.05, 1.5);
  auto state = std::make_shared<Velocity3D>();
  state->initialize("state_model", Parameters());
  FilterEngine engine(state,
                      { cue<ColourHSI>("colour"), cue<TemplateMatch>("template"), cue<ColourContour>("colour_contour"),
                        cue<StereoMatch>("stereo") },
                      config);
  std::string error;
  EXPECT_TRUE(engine.learnTarget(both.frame(0), both.renderer().targetRoi(0), error)) << error;
  const double period = both.renderer().stamp(1) - both.renderer().stamp(0);
  double stamp = 0.0;
  auto step = [&](Scene& scene, int k) {
    StereoFrame f = scene.frame(k);
    f.stamp = stamp += period;
    return engine.step(f);
  };
  FrameResult r;
  for (int k = 0; k < tracked; ++k)
    r = step(both, k);
  EXPECT_EQ(r.state, TrackState::Tracking);
  EXPECT_LT((r.estimate.position - ball).norm(), 0.02);
  taken = false;
  bool lost = false;
  for (int k = tracked; k < tracked + 80 && !taken; ++k)
  {
    r = step(hidden, k);
    lost = lost || r.state != TrackState::Tracking;
    taken = lost && r.state == TrackState::Tracking && (r.estimate.position - lookalike).norm() < 0.02;
  }
  for (int k = 1; k <= 20; ++k)
  {
    r = step(both, tracked + 80 + k);
    if (r.state == TrackState::Tracking && (r.estimate.position - ball).norm() < 0.02)
      return k;
  }
  return -1;
}
}  // namespace

TEST(EngineRecovery, ALookalikeTakenWhileTheObjectWasHiddenIsLeftWhenItComesBack)
{
  // The ball is hidden long enough for the look-alike 0.47 m away to come within the re-acquisition's reach: the
  // lost track takes it (nothing else in view tells them apart). The return watch looks where the ball was lost;
  // when it shows there again, the track goes back to it. Without the watch it stays on the look-alike.
  // The look-alike memory is off: as for a look-alike that came into view after the track was lost (with it, the one
  // seen beside the track is not taken at all: the next test).
  EngineConfig config;
  config.lookalike_memory = 0.0;
  bool taken = false;
  const int with = framesToComeBackToTheBall(config, taken);
  ASSERT_TRUE(taken) << "the look-alike was not taken while the ball was hidden";
  EXPECT_GE(with, 1);
  EXPECT_LE(with, 5) << "frames to come back to the ball";
  config.return_watch = 0.0;
  const int without = framesToComeBackToTheBall(config, taken);
  ASSERT_TRUE(taken);
  std::printf("back on the ball %d frames after it showed again with the return watch, %d without (-1: not in 20)\n",
              with, without);
  EXPECT_EQ(without, -1);
}

TEST(EngineRecovery, ALookalikeSeenBesideTheTrackIsNotTakenWhileTheObjectIsHidden)
{
  // The same ball and look-alike, the ball tracked for 20 frames: the recovery search sees the look-alike beside the
  // track on its frames, and the engine remembers it. While the ball is hidden the lost track is not found again on
  // it; when the ball shows again, the track is on the ball within a few frames. Without the memory (and the return
  // watch) the look-alike is taken and kept.
  EngineConfig config;
  bool taken = true;
  const int with = framesToComeBackToTheBall(config, taken, 20);
  EXPECT_FALSE(taken) << "the look-alike seen beside the track was taken while the ball was hidden";
  EXPECT_GE(with, 1);
  EXPECT_LE(with, 5) << "frames to find the ball again";
  config.lookalike_memory = 0.0;
  config.return_watch = 0.0;
  const int without = framesToComeBackToTheBall(config, taken, 20);
  EXPECT_TRUE(taken) << "without the memory the scene does not test it: the look-alike is not taken";
  std::printf("on the ball %d frames after it showed again with the look-alike memory, %d without (-1: not in 20)\n",
              with, without);
  EXPECT_EQ(without, -1);
}

TEST(MapProposals, ASearchForALostObjectDrawsOnlyWithinReachOfWhereItWasLastSeen)
{
  // The colour histogram learned from the ball sees it and its 12 look-alikes alike. Over the whole view few of the
  // pairs land on the ball; searching for the object a track lost, every pair lies where the object can be by now
  // (its left pixel on the image of the reach, its disparity among those of the reach's depths, both to a 4 px
  // cell), and most of them on the ball.
  Scene scene(ballAmongLookalikes(12));
  const StereoFrame frame = scene.frame(0);
  const StereoGeometry& g = frame.geometry;
  FeatureCache cache;
  cache.reset(frame);
  auto colour = cue<ColourHSI>("colour");
  std::string error;
  ASSERT_TRUE(colour->learnTarget(cache, View::Left, scene.renderer().targetRoi(0), error)) << error;
  const std::vector<std::shared_ptr<ObservationModel>> models{ colour };
  const Eigen::Vector3d ball = scene.renderer().targetPosition(0);
  const double reach = 0.3;
  // On the ball: the left pixel on its image, the disparity its own, both to a cell.
  const Pixel image = g.projectLeft(ball);
  const double radius = g.fx() * 0.02 / ball.z(), disparity = g.disparity(ball.z());
  auto onBall = [&](const std::vector<std::pair<Pixel, Pixel>>& pairs) {
    int on = 0;
    for (const auto& pair : pairs)
      on += std::hypot(pair.first.u - image.u, pair.first.v - image.v) < radius + 4.0 &&
            std::abs(pair.first.u - pair.second.u - disparity) < 4.0;
    return on;
  };
  MapProposals proposals;
  MapProposals::Bounds bounds;
  Rng rng(1);
  std::vector<std::pair<Pixel, Pixel>> everywhere, within;
  proposals.draw(cache, models, { 1.0 }, g, 400, bounds, rng, everywhere);
  bounds.last_seen = &ball;
  bounds.reach_radius = reach;
  proposals.draw(cache, models, { 1.0 }, g, 400, bounds, rng, within);
  ASSERT_GT(everywhere.size(), 300u);
  ASSERT_GT(within.size(), 300u);
  std::printf("pairs on the ball: %d of %zu over the whole view, %d of %zu within reach\n", onBall(everywhere),
              everywhere.size(), onBall(within), within.size());
  EXPECT_LT(onBall(everywhere), 0.5 * everywhere.size());
  EXPECT_GT(onBall(within), 0.7 * within.size());
  // The image of the reach: the sphere's extreme rays and depths.
  const double z_near = ball.z() - reach, z_far = ball.z() + reach;
  const double u_min = g.fx() * (ball.x() - reach) / z_near + g.cx();
  const double u_max = g.fx() * (ball.x() + reach) / z_near + g.cx();
  const double v_min = g.fy() * (ball.y() - reach) / z_near + g.cy();
  const double v_max = g.fy() * (ball.y() + reach) / z_near + g.cy();
  for (const auto& pair : within)
  {
    EXPECT_GT(pair.first.u, u_min - 4.0);
    EXPECT_LT(pair.first.u, u_max + 4.0);
    EXPECT_GT(pair.first.v, v_min - 4.0);
    EXPECT_LT(pair.first.v, v_max + 4.0);
    const double d = pair.first.u - pair.second.u;
    EXPECT_GT(d, g.disparity(z_far) - 4.0);
    EXPECT_LT(d, g.disparity(z_near) + 4.0);
  }
}

namespace
{
/// The default state model (Velocity3D), cues and configuration, seeded with `seed`, the scene's target learned from
/// its box in frame 0 (null when it was not).
std::unique_ptr<FilterEngine> defaultEngineOn(Scene& scene, unsigned long seed)
{
  EngineConfig config;
  config.seed = seed;
  auto state = std::make_shared<Velocity3D>();
  state->initialize("state_model", Parameters());
  auto engine = std::make_unique<FilterEngine>(
      state,
      std::vector<std::shared_ptr<ObservationModel>>{ cue<ColourHSI>("colour"), cue<TemplateMatch>("template"),
                                                      cue<ColourContour>("colour_contour"), cue<StereoMatch>("stereo") },
      config);
  std::string error;
  if (!engine->learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error))
  {
    ADD_FAILURE() << error;
    return nullptr;
  }
  return engine;
}

/// defaultEngineOn(scene, seed) after frames [0, frames) of the scene, `last` the last one's result; null (a failure)
/// when it is not tracking by then.
std::unique_ptr<FilterEngine> trackedThrough(Scene& scene, unsigned long seed, int frames, FrameResult& last)
{
  std::unique_ptr<FilterEngine> engine = defaultEngineOn(scene, seed);
  for (int k = 0; engine && k < frames; ++k)
    last = engine->step(scene.frame(k));
  if (engine && last.state != TrackState::Tracking)
  {
    ADD_FAILURE() << "not tracking after " << frames << " frames";
    return nullptr;
  }
  return engine;
}
}  // namespace

TEST(EngineRecovery, ATrackIsNotPredictedAcrossAGapOfDroppedFrames)
{
  // The pendulum tracked by the default model and cues, one frame in which the ball is not seen, then 0.7 s in which
  // no frame comes (dropped as bad: the soak test's burst), then the ball where the swing goes on. Predicted across
  // the whole gap, the cloud spread over metres: at none of these 8 seeds was the first frame after the gap within
  // 5 cm (at one the ball was tracked again only 8 frames later), and the estimates published meanwhile were 7 cm to
  // 14 m off (over 1 m at 3 seeds: a small hypothesis far behind the ball, its windows inside the ball's image in
  // both views, held the track). The prediction stops at 3.5 frame periods: the ball is tracked on
  // the first frame after the gap, never more than 5 cm off.
  Scene scene("pendulum_uncluttered.yaml");
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  for (unsigned long seed = 1; seed <= 8; ++seed)
  {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const int gap_at = 20 + static_cast<int>(7 * seed) % 50;  // other places of the swing
    FrameResult r;
    std::unique_ptr<FilterEngine> learned = trackedThrough(scene, seed, gap_at, r);
    ASSERT_TRUE(learned);
    FilterEngine& engine = *learned;
    StereoFrame blank = blankFrame(scene, gap_at);
    blank.stamp = scene.renderer().stamp(gap_at - 1) + period;
    r = engine.step(blank);
    EXPECT_EQ(r.support, Support::LowEvidence);
    double worst = 0.0;
    int first = -1;
    for (int j = 0; j < 10; ++j)
    {
      StereoFrame f = scene.frame(gap_at + j);
      f.stamp = blank.stamp + (22 + j) * period;
      r = engine.step(f);
      if (j == 0)
      {
        EXPECT_NEAR(r.dt, 22 * period, 1e-9);
      }
      const double e = (r.estimate.position - scene.renderer().targetPosition(gap_at + j)).norm();
      if (r.published())
        worst = std::max(worst, e);
      if (first < 0 && r.published() && e < 0.05)
        first = j;
    }
    EXPECT_EQ(first, 0) << "the ball was not tracked on the first frame after the gap";
    EXPECT_LT(worst, 0.05) << "an estimate published " << worst << " m off after the gap";
  }
}

TEST(EngineUncertainty, ThePublishedCovarianceHoldsWhereInTheObjectItsCentreLies)
{
  // The particle cloud knows where the hypotheses fit the images, not where in the object its centre lies: the
  // published covariance adds (centre_sigma x the learned radius)^2 on each axis, and nothing with centre_sigma 0.
  Scene scene("pendulum_uncluttered.yaml");
  FrameResult r;
  std::unique_ptr<FilterEngine> engine = trackedThrough(scene, 1, 10, r);
  ASSERT_TRUE(engine);
  ASSERT_TRUE(r.estimate.valid);
  const double floor = std::pow(EngineConfig().centre_sigma * engine->targetRadius(), 2);
  ASSERT_GT(floor, 0.0);
  for (int i = 0; i < 3; ++i)
    EXPECT_GE(r.estimate.covariance(i, i), floor) << "axis " << i;
  // The same frames with centre_sigma 0 (an engine seeded alike gives the same cloud): smaller by exactly that.
  std::unique_ptr<FilterEngine> bare = defaultEngineOn(scene, 1);
  ASSERT_TRUE(bare);
  EngineConfig config;
  config.centre_sigma = 0.0;
  bare->setConfig(config);
  FrameResult b;
  for (int k = 0; k < 10; ++k)
    b = bare->step(scene.frame(k));
  ASSERT_TRUE(b.estimate.valid);
  EXPECT_LT((b.estimate.position - r.estimate.position).norm(), 1e-12);
  EXPECT_LT((r.estimate.covariance - b.estimate.covariance - floor * Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

TEST(EngineRecovery, FramesThatShowNothingLeaveTheTrackWhereItWas)
{
  // The soak test's burst of bad input, as the engine gets it: the pendulum tracked by the default model and cues,
  // then a blank frame 5 periods later and another 22 periods after that (the frames between dropped as bad), then
  // the ball again 5 periods on, where it was (the soak's feed pauses while it sends bad frames), and on.
  // On a blank frame the other cues see nothing at all (nothing better than the background), and the refining
  // outline cue has no region to refine: given one, it scored the blank image's uniform map and collapsed the set
  // onto a few hypotheses (ESS 10-363 of 1000); in the soak the estimate went 1.3 m deeper, was held metres off after
  // the burst and only found again once lost. And the local search looked for the ball where the drifted estimate
  // was, not where it was last seen.
  // Before: on grey frames the track was metres off for 1-4 frames at 3 of 8 seeds, and lost at one. Now, at every
  // seed and for black and grey frames: ESS 227-972 on the blank frames, the first two frames after them within
  // 11 cm, every later one within 5 cm.
  Scene scene("pendulum_uncluttered.yaml");
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  for (const double grey : { 0.0, 128.0 })
    for (unsigned long seed = 1; seed <= 8; ++seed)
    {
      SCOPED_TRACE("grey " + std::to_string(static_cast<int>(grey)) + ", seed " + std::to_string(seed));
      const int gap_at = 20 + static_cast<int>(11 * seed) % 50;  // other places of the swing
      FrameResult r;
      std::unique_ptr<FilterEngine> learned = trackedThrough(scene, seed, gap_at, r);
      ASSERT_TRUE(learned);
      FilterEngine& engine = *learned;
      const Eigen::Vector3d seen = r.estimate.position;
      double stamp = scene.renderer().stamp(gap_at - 1);
      for (const int periods : { 5, 22 })
      {
        StereoFrame blank = blankFrame(scene, gap_at, grey);
        stamp += periods * period;
        blank.stamp = stamp;
        r = engine.step(blank);
        EXPECT_EQ(r.support, Support::LowEvidence);
        EXPECT_GT(r.ess, 0.2 * engine.config().particles) << "a frame showing nothing picked particles";
        // Not given (a frame of low evidence: published() false), but kept where it was.
        EXPECT_FALSE(r.published()) << "an estimate given on a frame showing nothing";
        if (r.estimate.valid)
        {
          EXPECT_LT((r.estimate.position - seen).norm(), 0.5) << "the estimate moved on a frame showing nothing";
        }
      }
      for (int j = 0; j < 10; ++j)
      {
        StereoFrame f = scene.frame(gap_at + j);
        f.stamp = stamp + (5 + j) * period;
        r = engine.step(f);
        ASSERT_TRUE(r.published()) << "frame " << j << " after the blank ones";
        EXPECT_LT((r.estimate.position - scene.renderer().targetPosition(gap_at + j)).norm(), j < 2 ? 0.11 : 0.05)
            << "frame " << j << " after the blank ones";
      }
    }
}

TEST(EngineRecovery, ATrackLeftBehindIsLostNotKeptByTheJumpsItRefuses)
{
  // The pendulum tracked by the default model and cues to frame 80, then shown from frame 10 on (half a metre away:
  // a bag played again, as the nodelet test does). The recovery search's jumps see the ball there, but coarsely,
  // below the bar a jump must pass (reacquire_margin below the object's own evidence). Their evidence kept each
  // recovery frame "seen", so the track stayed "tracking" while it ran off on its velocity: 5-8 of these 20 frames
  // were published more than 10 cm off at 4 of the 6 seeds (track_bag on the test bag played so: at seed 1 every
  // frame, up to 1.9 m off). A refused jump is no evidence now: the track is followed to the ball or lost within
  // lost_frames.
  Scene scene("pendulum_uncluttered.yaml");
  const double period = scene.renderer().stamp(1) - scene.renderer().stamp(0);
  for (unsigned long seed = 1; seed <= 6; ++seed)
  {
    SCOPED_TRACE("seed " + std::to_string(seed));
    FrameResult r;
    std::unique_ptr<FilterEngine> learned = trackedThrough(scene, seed, 81, r);
    ASSERT_TRUE(learned);
    FilterEngine& engine = *learned;
    ASSERT_GT((scene.renderer().targetPosition(10) - r.estimate.position).norm(), 0.3);
    int off = 0;  // frames published more than 10 cm from the ball
    for (int j = 0; j < 20; ++j)
    {
      StereoFrame f = scene.frame(10 + j);
      f.stamp = scene.renderer().stamp(80) + (j + 1) * period;
      r = engine.step(f);
      if (r.published() && (r.estimate.position - scene.renderer().targetPosition(10 + j)).norm() > 0.1)
        ++off;
    }
    EXPECT_LE(off, EngineConfig().lost_frames) << "frames published more than 10 cm off the ball";
  }
}

namespace
{
/// The colour histogram whose similarity, once `script` is set, is script[k] at every particle of frame k (the
/// background places beside the best particle score `background` of their view), so the engine's evidence follows
/// the script.
class Scripted : public ColourHSI
{
public:
  std::vector<double> script;
  /// When set: the right view's similarity instead of script's (script is then the left view's).
  std::vector<double> right_script;
  double background[2] = { 0.0, 0.0 };  ///< left, right
  int frame = 0;
  int particles = 0;
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    ColourHSI::evaluate(cache, hyp, log_likelihood, similarity);
    const bool right = hyp.view == View::Right;
    const std::vector<double>& s = right && !right_script.empty() ? right_script : script;
    if (frame >= 0 && frame < static_cast<int>(s.size()))
      similarity.setConstant(hyp.size() == particles ? s[frame] : background[right ? 1 : 0]);
  }
};

/// Every frame's result on the pendulum whose evidence follows `script` from frame 10 on (in the left view only
/// when `right_script` is given: the right view's follows that).
std::vector<FrameResult> resultsUnder(const std::vector<double>& script, EngineConfig config = EngineConfig(),
                                      const std::vector<double>& right_script = {}, double left_background = 0.0,
                                      double right_background = 0.0)
{
  Scene scene("pendulum_uncluttered.yaml");
  auto colour = cue<Scripted>("colour");
  config.local_fraction = 0.0;  // the local search scores batches of its own size
  colour->particles = config.particles;
  colour->background[0] = left_background;
  colour->background[1] = right_background;
  FilterEngine engine(position3D(), { colour }, config);
  std::string error;
  EXPECT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  std::vector<FrameResult> results;
  for (int k = 0; k < 10 + static_cast<int>(script.size()); ++k)
  {
    colour->frame = k - 10;
    colour->script = k >= 10 ? script : std::vector<double>{};
    colour->right_script = k >= 10 ? right_script : std::vector<double>{};
    results.push_back(engine.step(scene.frame(k)));
  }
  return results;
}

/// The track state after each frame of the pendulum whose evidence follows `script` from frame 10 on.
std::vector<TrackState> statesUnder(const std::vector<double>& script)
{
  std::vector<TrackState> states;
  for (const FrameResult& r : resultsUnder(script))
    states.push_back(r.state);
  return states;
}
}  // namespace

TEST(EngineTrackState, UnsureFramesNeitherCountNorBreakARunOfUnseenOnes)
{
  // Evidence flickering between low (0.3 < lost_similarity) and unsure (0.55, between the thresholds): lost at the
  // lost_frames-th low frame, although no two low frames are adjacent (a track stayed "tracking" metres off a real
  // pitch's ball that way).
  const EngineConfig defaults;
  const int lost = defaults.lost_frames;
  ASSERT_GE(lost, 2);
  ASSERT_LT(0.3, defaults.lost_similarity);
  ASSERT_TRUE(0.55 >= defaults.lost_similarity && 0.55 < defaults.found_similarity);
  ASSERT_GE(0.9, defaults.found_similarity);
  std::vector<double> script;
  for (int k = 0; k < lost; ++k)
    script.insert(script.end(), { 0.3, 0.55 });
  const std::vector<TrackState> flicker = statesUnder(script);
  ASSERT_EQ(flicker[9], TrackState::Tracking);
  EXPECT_EQ(flicker[10 + 2 * (lost - 2) + 1], TrackState::Tracking) << lost - 1 << " low frames";
  EXPECT_EQ(flicker[10 + 2 * (lost - 1)], TrackState::Lost) << "low frame " << lost;
  // A seen frame (0.9) between them does break the run: the track goes on.
  std::vector<double> interrupted_script;
  for (int k = 0; k < lost - 1; ++k)
    interrupted_script.insert(interrupted_script.end(), { 0.3, 0.55 });
  interrupted_script.push_back(0.9);
  for (int k = 0; k < lost - 1; ++k)
    interrupted_script.insert(interrupted_script.end(), { 0.3, 0.55 });
  const std::vector<TrackState> interrupted = statesUnder(interrupted_script);
  for (size_t k = 9; k < interrupted.size(); ++k)
    EXPECT_EQ(interrupted[k], TrackState::Tracking) << "frame " << k;
}

TEST(EngineTrackState, AFrameThatDoesNotSeeTheObjectKeepsTheTrackButGivesNoEstimate)
{
  // Seen (0.9), then lost_frames - 2 frames of low evidence (0.2), one that still sees the object faintly (0.35, at
  // least estimate_similarity), one unsure (0.55), and seen again. The track is kept over the low frames (one bad frame
  // must not lose it), but what it holds on the first ones is the prediction, not a sighting: no estimate is given
  // (published() false), though the engine still has one. The faint frame, the unsure frame and the seen ones are
  // given. With estimate_similarity 0 every one of them is.
  const EngineConfig defaults;
  const int low = defaults.lost_frames - 2;
  ASSERT_GE(low, 1);
  ASSERT_LT(0.2, defaults.estimate_similarity);
  ASSERT_TRUE(0.35 >= defaults.estimate_similarity && 0.35 < defaults.lost_similarity);
  ASSERT_TRUE(0.55 >= defaults.lost_similarity && 0.55 < defaults.found_similarity);
  std::vector<double> script(3, 0.9);
  script.insert(script.end(), low, 0.2);
  script.push_back(0.35);
  script.push_back(0.55);
  script.insert(script.end(), 3, 0.9);
  const std::vector<FrameResult> r = resultsUnder(script);
  for (int k = 10; k < 13; ++k)
  {
    ASSERT_EQ(r[k].support, Support::Seen) << "frame " << k;
    EXPECT_TRUE(r[k].published()) << "frame " << k;
  }
  for (int k = 13; k < 13 + low; ++k)
  {
    EXPECT_EQ(r[k].state, TrackState::Tracking) << "frame " << k;
    EXPECT_EQ(r[k].support, Support::LowEvidence) << "frame " << k;
    EXPECT_TRUE(r[k].estimate.valid) << "frame " << k;
    EXPECT_FALSE(r[k].faint) << "frame " << k;
    EXPECT_FALSE(r[k].published()) << "frame " << k << ": an estimate given on a frame that did not see the object";
  }
  const FrameResult& faint = r[13 + low];
  EXPECT_EQ(faint.state, TrackState::Tracking);
  EXPECT_EQ(faint.support, Support::LowEvidence);
  EXPECT_TRUE(faint.faint);
  EXPECT_TRUE(faint.published()) << "the frame that sees the object faintly";
  EXPECT_EQ(r[14 + low].support, Support::Unsure);
  EXPECT_TRUE(r[14 + low].published()) << "the unsure frame";
  for (int k = 15 + low; k < static_cast<int>(r.size()); ++k)
  {
    EXPECT_EQ(r[k].state, TrackState::Tracking) << "frame " << k;
    EXPECT_TRUE(r[k].published()) << "frame " << k;
  }
  EngineConfig every;
  every.estimate_similarity = 0.0;
  const std::vector<FrameResult> all = resultsUnder(script, every);
  for (int k = 13; k < 14 + low; ++k)
    EXPECT_TRUE(all[k].published()) << "frame " << k << " with estimate_similarity 0";
}

TEST(EngineTrackState, AnObjectOneCameraStillSeesIsUnsureNotUnseen)
{
  // From frame 10 the right view's cues score 0.05 (the object before something that hides it from them, as a
  // real pitch's ball before a bright panel seen by the right camera only) while the left view's score 0.8: their
  // mean is below lost_similarity, but the left camera sees the object. Unsure, so the track is kept until
  // unsure_frames of them; with one_view_unsure off, lost at the lost_frames-th such frame.
  const EngineConfig defaults;
  ASSERT_TRUE(defaults.one_view_unsure);
  ASSERT_LT(0.5 * (0.8 + 0.05), defaults.lost_similarity);
  ASSERT_GE(0.8, defaults.found_similarity);
  const std::vector<double> left(12, 0.8), right(12, 0.05);
  const std::vector<FrameResult> kept = resultsUnder(left, defaults, right);
  EXPECT_LT(kept[10].evidence, defaults.lost_similarity) << "the reported evidence is still the mean";
  EXPECT_EQ(kept[10].support, Support::Unsure);
  EXPECT_EQ(kept[18].state, TrackState::Tracking) << "nine unsure frames";
  EXPECT_EQ(kept[19].state, TrackState::Lost) << "the tenth unsure frame in a row";
  EngineConfig off;
  off.one_view_unsure = false;
  const std::vector<FrameResult> lost = resultsUnder(left, off, right);
  EXPECT_EQ(lost[10].support, Support::LowEvidence);
  EXPECT_EQ(lost[10 + off.lost_frames - 1].state, TrackState::Lost) << "low frame " << off.lost_frames;
  // A view between the thresholds but at least midway (0.6) still sees it: unsure. Neither view seeing it (0.5
  // and 0.05: each below midway between lost_similarity and found_similarity) is unseen, as before.
  const double midway = 0.5 * (defaults.lost_similarity + defaults.found_similarity);
  ASSERT_TRUE(0.6 >= midway && 0.6 < defaults.found_similarity && 0.5 < midway);
  const std::vector<FrameResult> weak = resultsUnder(std::vector<double>(12, 0.6), defaults, right);
  EXPECT_EQ(weak[10].support, Support::Unsure);
  EXPECT_EQ(weak[12].state, TrackState::Tracking);
  const std::vector<FrameResult> neither = resultsUnder(std::vector<double>(12, 0.5), defaults, right);
  EXPECT_EQ(neither[10].support, Support::LowEvidence);
  EXPECT_EQ(neither[10 + defaults.lost_frames - 1].state, TrackState::Lost) << "low frame " << defaults.lost_frames;
}

TEST(EngineTrackState, AnObjectOneCameraStillSeesIsJudgedAgainstThatCamerasBackground)
{
  // As above, the left view's cues score 0.8 and the right view's 0.05; the places beside the object score 0.3 in
  // both views. The two views' mean (0.425) is within background_margin of theirs (0.3), but the view that sees
  // the object tells it from its background by 0.5: unsure, not like the background (the end of the real
  // catch_test1). When the background of the seeing view scores as well as the object there (0.7), it is like the
  // background.
  const EngineConfig defaults;
  ASSERT_LT(0.5 * (0.8 + 0.05) - 0.3, defaults.background_margin);
  ASSERT_GT(0.8 - 0.3, defaults.background_margin);
  const std::vector<double> left(12, 0.8), right(12, 0.05);
  const std::vector<FrameResult> apart = resultsUnder(left, defaults, right, 0.3, 0.3);
  EXPECT_EQ(apart[10].support, Support::Unsure);
  EXPECT_TRUE(apart[10].published());
  EXPECT_EQ(apart[15].state, TrackState::Tracking);
  const std::vector<FrameResult> alike = resultsUnder(left, defaults, right, 0.7, 0.3);
  EXPECT_EQ(alike[10].support, Support::LikeBackground);
  EXPECT_FALSE(alike[10].published());
}

TEST(EngineTrackState, ATrackThatStaysUnsureIsLostAfterUnsureFrames)
{
  // Evidence stuck at 0.55, between the thresholds: no frame is seen or unseen, but after unsure_frames of them in
  // a row the track is lost (a stress scene's cylinder stayed "tracking" while its estimate drifted 8 m onto the
  // background). A seen frame before that restarts the count.
  const EngineConfig defaults;
  ASSERT_EQ(defaults.unsure_frames, 10);
  ASSERT_TRUE(0.55 >= defaults.lost_similarity && 0.55 < defaults.found_similarity);
  const std::vector<TrackState> stuck = statesUnder(std::vector<double>(12, 0.55));
  EXPECT_EQ(stuck[18], TrackState::Tracking) << "nine unsure frames";
  EXPECT_EQ(stuck[19], TrackState::Lost) << "the tenth unsure frame in a row";
  std::vector<double> broken(12, 0.55);
  broken[5] = 0.9;
  const std::vector<TrackState> restarted = statesUnder(broken);
  for (size_t k = 9; k < restarted.size(); ++k)
    EXPECT_EQ(restarted[k], TrackState::Tracking) << "frame " << k;
}

TEST(EngineTrackState, ATrackScoringFarBelowTheObjectIsLostAfterUnsureFrames)
{
  // Evidence at 0.68 from frame 10 on: above found_similarity, but more than hold_margin below what the object
  // scored when its track began, as after a ball has left the view and the track sits on a patch of its colour
  // (a real pitch's ball: 0.67-0.69 for 16 frames after it had gone, against its 0.94). Unsure, so lost after
  // unsure_frames of them; at 0.85, within the margin, it is kept; with the margin at 1 so is the first.
  const EngineConfig defaults;
  ASSERT_TRUE(0.68 >= defaults.found_similarity && defaults.hold_margin < 1.0);
  const std::vector<double> far(12, 0.68);
  const std::vector<FrameResult> r = resultsUnder(far);
  const double reference = r[0].evidence;
  ASSERT_GT(reference - defaults.hold_margin, 0.68) << "the pendulum's ball scores " << reference;
  ASSERT_LT(reference - defaults.hold_margin, 0.85);
  EXPECT_EQ(r[10].support, Support::Unsure);
  EXPECT_EQ(r[18].state, TrackState::Tracking) << "nine unsure frames";
  EXPECT_EQ(r[19].state, TrackState::Lost) << "the tenth unsure frame in a row";
  for (const FrameResult& kept : resultsUnder(std::vector<double>(12, 0.85)))
    EXPECT_EQ(kept.state, TrackState::Tracking);
  EngineConfig off;
  off.hold_margin = 1.0;
  for (const FrameResult& kept : resultsUnder(far, off))
    EXPECT_EQ(kept.state, TrackState::Tracking);
}

TEST(EngineTrackState, ALookThatChangesSlowlyIsKeptBelowTheHoldMargin)
{
  // Evidence falling from 0.9 to 0.66 by 0.005 a frame (a box turning a face of another colour to the camera,
  // which the adapting cues follow only part of the way: they stay anchored to the box). It ends well over
  // hold_margin below what the object scored when its track began, but the measure the margin applies to follows
  // the seen frames (hold_follow), so the track is kept; with hold_follow 0 the same decline loses it. A sudden
  // drop is still lost (ATrackScoringFarBelowTheObjectIsLostAfterUnsureFrames).
  const EngineConfig defaults;
  ASSERT_GT(defaults.hold_follow, 0.0);
  ASSERT_LE(defaults.found_similarity, 0.66);
  std::vector<double> decline;
  for (double e = 0.9; e >= 0.66 - 1e-9; e -= 0.005)
    decline.push_back(e);
  decline.resize(decline.size() + 10, decline.back());
  const std::vector<FrameResult> r = resultsUnder(decline);
  const double reference = r[0].evidence;
  ASSERT_GT(reference - defaults.hold_margin, 0.66) << "the pendulum's ball scores " << reference;
  for (size_t k = 0; k < r.size(); ++k)
    EXPECT_EQ(r[k].state, TrackState::Tracking) << "frame " << k << ", evidence " << r[k].evidence;
  EngineConfig fixed;
  fixed.hold_follow = 0.0;
  const std::vector<FrameResult> f = resultsUnder(decline, fixed);
  EXPECT_EQ(f.back().state, TrackState::Lost) << "held to the first track's evidence, the decline is lost";
}

TEST(EngineTrackState, ALookAlikeScoringBelowTheObjectIsNotTakenForItOnceLost)
{
  // Lost (lost_frames frames at 0.1), then something scoring 0.8 (well above found_similarity, but more than
  // reacquire_margin below what the object scored when its track began) for ten frames, then the object itself.
  const EngineConfig defaults;
  ASSERT_LT(defaults.reacquire_margin, 0.5);
  const int lost = defaults.lost_frames;
  std::vector<double> script(lost, 0.1);
  script.resize(lost + 10, 0.8);
  script.resize(lost + 12, 1.0);
  const std::vector<FrameResult> r = resultsUnder(script);
  const double reference = r[0].evidence;  // the first frame of the track, from the box
  ASSERT_EQ(r[0].state, TrackState::Tracking);
  ASSERT_GT(reference - defaults.reacquire_margin, 0.8) << "the pendulum's ball scores " << reference;
  EXPECT_EQ(r[10 + lost - 1].state, TrackState::Lost);
  for (int k = 10 + lost; k < 10 + lost + 10; ++k)
  {
    EXPECT_EQ(r[k].state, TrackState::Lost) << "frame " << k << ": the look-alike was taken for the object";
    EXPECT_EQ(r[k].support, Support::Unsure) << "frame " << k;
  }
  EXPECT_EQ(r[10 + lost + 11].state, TrackState::Tracking) << "the object itself, two frames";
  // With the margin at 1 only found_similarity holds: the look-alike is found in found_frames.
  EngineConfig loose;
  loose.reacquire_margin = 1.0;
  const std::vector<FrameResult> taken = resultsUnder(script, loose);
  EXPECT_EQ(taken[10 + lost - 1].state, TrackState::Lost);
  EXPECT_EQ(taken[10 + lost - 1 + loose.found_frames].state, TrackState::Tracking);
  // A look-alike that scores as the object did on every other frame only (0.8 between) is not found either: an
  // unsure frame breaks the run of seen ones while the track is being found again.
  std::vector<double> flicker(lost, 0.1);
  for (int k = 0; k < 10; ++k)
    flicker.push_back(k % 2 ? 0.8 : 1.0);
  const std::vector<FrameResult> f = resultsUnder(flicker);
  for (int k = 10 + lost; k < 10 + lost + 10; ++k)
    EXPECT_EQ(f[k].state, TrackState::Lost) << "frame " << k;
}

TEST(EngineTrackState, AnObjectScoringLessThanOnItsFirstFrameIsFoundAgainAfterAnOcclusion)
{
  // Tracked at 0.9 for 40 frames (below what it scored on the first frame after the box, where it was learned),
  // hidden (lost_frames frames at 0.1), then back at 0.87 (another side of it turned to the camera): found again within
  // found_frames of its return, as re-acquisition is held to what the object scored in its last track's seen
  // frames. Held to the first frame's evidence it was never found again (a drawn scene: a textured ball scoring
  // 0.94-0.95 before an occluder and 0.85-0.88 after it stayed lost for the 25 frames it was in view). Something
  // scoring 0.8 after the same track is still not taken for it.
  const EngineConfig defaults;
  const int lost = defaults.lost_frames;
  std::vector<double> script(40, 0.9);
  script.resize(40 + lost, 0.1);
  std::vector<double> lookalike = script;
  script.resize(50 + lost, 0.87);
  lookalike.resize(50 + lost, 0.8);
  const std::vector<FrameResult> r = resultsUnder(script);
  const double reference = r[0].evidence;
  ASSERT_GT(reference - defaults.reacquire_margin, 0.87) << "the pendulum's ball scores " << reference;
  EXPECT_EQ(r[10 + 40 + lost - 1].state, TrackState::Lost);
  EXPECT_EQ(r[10 + 40 + lost - 1 + defaults.found_frames].state, TrackState::Tracking) << "found again";
  const std::vector<FrameResult> l = resultsUnder(lookalike);
  for (int k = 10 + 40 + lost - 1; k < 10 + 50 + lost; ++k)
    EXPECT_EQ(l[k].state, TrackState::Lost) << "frame " << k << ": the look-alike was taken for the object";
}

namespace
{
/// scenes/turning_box.yaml (a 10 cm box, one turn in 8 s about the vertical, each side face another colour)
/// tracked by the default state model and cues (Velocity3D; colour histogram, template, outline, stereo match), the
/// histogram adapting at `colour_adapt_rate`. A frame is on the box when it is tracked with the estimate within the box's edge (10 cm)
/// of its centre (the cues see its faces, up to half an edge in front of the centre). `kept`: the last frame on
/// the box before the first two frames in a row that are not; `slips`: the single frames off it up to there (the
/// estimate's depth can swing by a few pixels of disparity for a frame while the track holds); `refound`: the
/// first frame after frame 150 on the box once that first track has ended (-1: none).
void trackTurningBox(double colour_adapt_rate, unsigned long seed, int& kept, int& refound, int& slips)
{
  Scene scene("turning_box.yaml");
  Parameters colour_params;
  colour_params.set("colour/adapt_rate", colour_adapt_rate);
  auto colour = std::make_shared<ColourHSI>();
  colour->initialize("colour", colour_params.sub("colour"));
  auto state = std::make_shared<Velocity3D>();
  state->initialize("state_model", Parameters());
  FilterEngine engine(state,
                      { colour, cue<TemplateMatch>("template"), cue<ColourContour>("colour_contour"),
                        cue<StereoMatch>("stereo") },
                      [seed] {
                        EngineConfig c;
                        c.seed = seed;
                        return c;
                      }());
  std::string error;
  ASSERT_TRUE(engine.learnTarget(scene.frame(0), scene.renderer().targetRoi(0), error)) << error;
  kept = -1;
  refound = -1;
  slips = 0;
  bool first = true, previous_on = true;
  for (int k = 0; k < 240; ++k)
  {
    const FrameResult r = engine.step(scene.frame(k));
    const bool on = r.state == TrackState::Tracking && r.estimate.valid &&
                    (r.estimate.position - scene.renderer().targetPosition(k)).norm() < 0.1;
    if (first && !on && !previous_on)
    {
      first = false;
      --slips;  // the previous frame began the end of the track
    }
    if (first && on)
      kept = k;
    if (first && !on)
      ++slips;
    previous_on = on;
    if (!first && k > 150 && on && refound < 0)
      refound = k;
  }
}
}  // namespace

TEST(EngineAdaptation, ATurningBoxIsKeptPastItsNextFaceAndFoundAgainByItsFirst)
{
  // The front face turns away from frame 0 (45 deg/s at 30 fps); a side face of another colour faces the camera
  // at frame 60, the back face at 120, the other side at 180, and the front face is half turned back at frame
  // 210. Without adaptation the histogram of the front face loses the box as the side face turns in; adapting,
  // it is kept past that face. Lost, it is searched for by the front face again (forgetAdaptation) and found
  // within 15 frames of frame 210. Over several seeds: how far a turning face is followed is a draw (frame 60 to
  // 239), and one seed's draw says little.
  std::vector<int> kepts, refounds;
  for (unsigned long seed = 1; seed <= 7; ++seed)
  {
    int kept = 0, refound = 0, slips = 0, kept_fixed = 0, refound_fixed = 0, slips_fixed = 0;
    trackTurningBox(0.1, seed, kept, refound, slips);
    trackTurningBox(0.0, seed, kept_fixed, refound_fixed, slips_fixed);
    std::printf("seed %lu, turning box: adapting, kept to frame %d (%d single frames off), found again at %d; fixed "
                "histogram, kept to %d, found again at %d\n",
                seed, kept, slips, refound, kept_fixed, refound_fixed);
    EXPECT_LE(slips, 3) << "kept, but not on the box in " << slips << " of its frames, seed " << seed;
    EXPECT_LT(kept_fixed, kept) << "seed " << seed;
    // Past the side face, which faces the camera at frame 60, at every seed: the template once adapted only where the
    // window at the estimate matched it, and on 6 of 21 seeds never adapted and lost the box by frame 60 (now it
    // adapts where the object matches near the estimate: kept to frame 100 or later at seeds 1-21).
    EXPECT_GT(kept, 90) << "seed " << seed << ": lost before the side face had turned in";
    kepts.push_back(kept);
    // Adapting, the box may be kept through every face (to frame 239); lost, it must be found again by its first
    // face. The fixed histogram always loses it.
    if (refound >= 0 || kept < 239)
    {
      EXPECT_GE(refound, 200) << "seed " << seed;
      refounds.push_back(refound);
    }
    EXPECT_GE(refound_fixed, 200) << "seed " << seed;
    refounds.push_back(refound_fixed);
  }
  std::sort(kepts.begin(), kepts.end());
  EXPECT_GE(kepts[kepts.size() / 2], 90) << "the side face's colour was not followed";
  std::sort(refounds.begin(), refounds.end());
  EXPECT_LE(refounds[refounds.size() / 2], 225) << "not found again by its first face within 15 frames";
  EXPECT_LE(refounds.back(), 235) << "not found again by its first face within 25 frames";
}
