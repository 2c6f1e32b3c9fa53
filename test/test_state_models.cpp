// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The 3D state models and the engine on rendered stereo frames (no ROS, no bag).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/colour_contour.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/stereo_constraints.h"
#include "stereo_pf/plugins/velocity_3d.h"

using namespace stereo_pf;

namespace
{
const StereoGeometry kRig(525, 525, 319.5, 239.5, 0.09, 640, 480);

template <class Model>
std::shared_ptr<Model> make(const Parameters& p = Parameters())
{
  auto m = std::make_shared<Model>();
  m->initialize("state_model", p);
  return m;
}

Eigen::VectorXd columnStd(const Eigen::MatrixXd& m)
{
  const Eigen::RowVectorXd mean = m.colwise().mean();
  return ((m.rowwise() - mean).array().square().colwise().sum() / (m.rows() - 1)).sqrt().transpose();
}

// Track the first `frames` frames of a shipped scene with Position3D (or `state`) + colour.
struct TrackRun
{
  std::vector<double> errors;
  std::vector<Eigen::Vector3d> estimates;
  std::vector<TrackState> states;
};

TrackRun track(const std::string& scene, int frames, unsigned long seed, std::shared_ptr<StateModel> state = nullptr)
{
  SceneRenderer renderer(loadScene(std::string(SCENES_DIR) + "/" + scene));
  if (!state)
    state = make<Position3D>();
  auto colour = std::make_shared<ColourHSI>();
  colour->initialize("colour", Parameters());
  EngineConfig config;
  config.seed = seed;
  FilterEngine engine(state, { colour }, config);
  TrackRun run;
  StereoFrame f;
  f.geometry = renderer.geometry();
  cv::Mat left, right;
  for (int k = 0; k < frames; ++k)
  {
    renderer.render(k, left, right);
    f.left = left;
    f.right = right;
    f.stamp = renderer.stamp(k);
    std::string error;
    if (k == 0)
    {
      EXPECT_TRUE(engine.learnTarget(f, renderer.targetRoi(0), error)) << error;
    }
    const FrameResult r = engine.step(f);
    run.errors.push_back(r.estimate.valid ? (r.estimate.position - renderer.targetPosition(k)).norm() : 1e9);
    run.estimates.push_back(r.estimate.position);
    run.states.push_back(r.state);
  }
  return run;
}
}  // namespace

TEST(Position3D, PriorIsInsideBothImagesAndDepthRange)
{
  Parameters p;
  p.set("z_min", 0.5);
  p.set("z_max", 2.0);
  for (const char* mode : { "volume", "depth", "disparity" })
  {
    p.set("init_depth", std::string(mode));
    auto m = make<Position3D>(p);
    ParticleSet s;
    s.resize(2000, 3);
    Rng rng(1);
    m->samplePrior(kRig, 0, s, 0, 2000, rng);
    int far = 0;
    for (int i = 0; i < 2000; ++i)
    {
      const Eigen::Vector3d x = s.states.row(i).transpose();
      ASSERT_GE(x.z(), 0.5 - 1e-9);
      ASSERT_LE(x.z(), 2.0 + 1e-9);
      ASSERT_TRUE(kRig.visible(x)) << mode << " " << x.transpose();
      far += x.z() > 1.25 ? 1 : 0;
    }
    // Volume-uniform puts most particles in the far half; uniform disparity puts most near.
    if (std::string(mode) == "volume")
    {
      EXPECT_GT(far, 1400);
    }
    if (std::string(mode) == "disparity")
    {
      EXPECT_LT(far, 800);
    }
  }
}

TEST(Position3D, RandomWalkHasTheConfiguredSpreadOnEveryAxis)
{
  Parameters p;
  p.set("noise", 0.02);
  auto m = make<Position3D>(p);
  ParticleSet s;
  s.resize(20000, 3);
  s.states.col(2).setConstant(1.0);
  Rng rng(2);
  m->predict(0, 1.0 / 30, s, rng);
  const Eigen::VectorXd sd = columnStd(s.states);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(sd[k], 0.02, 0.001);
}

TEST(Position3D, ProjectsSphereCentreAndApparentRadius)
{
  auto m = make<Position3D>();
  ParticleSet s;
  s.resize(3, 3);
  s.states << 0.09, 0.0, 1.0, 0.0, 0.0, -1.0, 5.0, 0.0, 1.0;  // the first on the right camera's axis
  ImageHypotheses h;
  h.view = View::Right;
  m->project(kRig, 0, s, h);
  EXPECT_NEAR(h.u[0], kRig.projectRight({ 0.09, 0, 1 }).u, 1e-3);
  EXPECT_NEAR(h.radius[0], 525 * 0.035, 1e-3);
  EXPECT_EQ(h.valid[0], 1);
  EXPECT_EQ(h.valid[1], 0);  // behind the camera
  EXPECT_EQ(h.valid[2], 0);  // outside the image
}

// Off the axis a near sphere's image is centred beyond the projection of its centre, by different amounts in
// the two views; the hypotheses are the middles of the images the cues see (as box acquisition assumes).
TEST(Position3D, HypothesesAreTheMiddlesOfTheSpheresImages)
{
  Parameters p;
  p.set("object_radius", 0.06);
  auto m = make<Position3D>(p);
  const Eigen::Vector3d c(0.3, -0.2, 0.7);
  ParticleSet s;
  s.resize(1, 3);
  s.states.row(0) = c.transpose();
  for (View view : { View::Left, View::Right })
  {
    // The image's extent by brute force: project points all over the sphere.
    double u0 = HUGE_VAL, u1 = -HUGE_VAL, v0 = HUGE_VAL, v1 = -HUGE_VAL;
    for (int i = 0; i <= 2000; ++i)
      for (int j = 0; j < 2000; ++j)
      {
        const double theta = M_PI * i / 2000, phi = 2 * M_PI * j / 2000;
        const Eigen::Vector3d q = c + 0.06 * Eigen::Vector3d(std::sin(theta) * std::cos(phi),
                                                             std::sin(theta) * std::sin(phi), std::cos(theta));
        const Pixel px = view == View::Left ? kRig.projectLeft(q) : kRig.projectRight(q);
        u0 = std::min(u0, px.u);
        u1 = std::max(u1, px.u);
        v0 = std::min(v0, px.v);
        v1 = std::max(v1, px.v);
      }
    ImageHypotheses h;
    h.view = view;
    m->project(kRig, 0, s, h);
    const Pixel centre = view == View::Left ? kRig.projectLeft(c) : kRig.projectRight(c);
    EXPECT_NEAR(h.u[0], 0.5 * (u0 + u1), 0.02);
    EXPECT_NEAR(h.v[0], 0.5 * (v0 + v1), 0.02);
    EXPECT_GT(std::abs(h.u[0] - centre.u), 1.0);  // what the centre's projection would have missed
  }
}

TEST(Position3D, SeedFromStereoTriangulatesWithinDepthRange)
{
  auto m = make<Position3D>();
  ParticleSet s;
  s.resize(1, 3);
  const Eigen::Vector3d p(0.1, -0.05, 1.2);
  ASSERT_TRUE(m->seedFromStereo(kRig, 0, s, 0, kRig.projectLeft(p), kRig.projectRight(p)));
  EXPECT_LT((s.states.row(0).transpose() - p).norm(), 1e-9);
  const Eigen::Vector3d too_far(0.0, 0.0, 50.0);
  EXPECT_FALSE(m->seedFromStereo(kRig, 0, s, 0, kRig.projectLeft(too_far), kRig.projectRight(too_far)));
}

TEST(Velocity3D, ConstantVelocityMovesTheCloud)
{
  Parameters p;
  p.set("noise", 0.0);
  p.set("jitter_radii", 0.0);
  p.set("acceleration_noise", 0.0);
  p.set("smooth_acceleration_noise", 0.0);
  auto m = make<Velocity3D>(p);
  ParticleSet s;
  s.resize(10, 6);
  s.states.col(2).setConstant(1.0);
  s.states.col(3).setConstant(0.3);   // vx
  s.states.col(5).setConstant(-0.6);  // vz
  Rng rng(3);
  m->predict(0, 0.5, s, rng);
  EXPECT_NEAR(s.states(4, 0), 0.15, 1e-12);
  EXPECT_NEAR(s.states(4, 2), 0.7, 1e-12);
  const StateEstimate e = m->estimate(kRig, { s }, Estimator::Mean, 0.03);
  EXPECT_NEAR(e.velocity.x(), 0.3, 1e-12);
}

TEST(Velocity3D, AccelerationNoiseScalesWithDt)
{
  Parameters p;
  p.set("noise", 0.0);
  p.set("acceleration_noise", 2.0);
  p.set("smooth_fraction", 0.0);
  auto m = make<Velocity3D>(p);
  ParticleSet s;
  s.resize(20000, 6);
  Rng rng(4);
  m->predict(0, 0.1, s, rng);
  EXPECT_NEAR(columnStd(s.states)[3], 0.2, 0.01);  // sigma_v = a * dt
}

TEST(Velocity3D, MostParticlesMoveSmoothlyAndSomeWidely)
{
  // By default 80 % of the particles get the smooth motion's acceleration noise (2 m/s^2) and half the jitter,
  // the rest 20 m/s^2 and the whole jitter (0.25 radii), drawn per particle and frame.
  Parameters p;
  p.set("object_radius", 0.04);
  auto m = make<Velocity3D>(p);
  ParticleSet s;
  const int n = 40000;
  s.resize(n, 6);
  Rng rng(5);
  const double dt = 0.1;
  m->predict(0, dt, s, rng);
  int smooth_v = 0;
  for (int i = 0; i < n; ++i)
    smooth_v += std::abs(s.states(i, 3)) < 3.0 * 2.0 * dt ? 1 : 0;
  // Within 3 sigma of the smooth part: 0.8 * 0.9973 of the smooth particles plus 0.2 * P(|N(0, 2)| < 0.6).
  EXPECT_NEAR(static_cast<double>(smooth_v) / n, 0.8 * 0.9973 + 0.2 * 0.2358, 0.01);
  // sigma_v of the mixture: sqrt(0.8 (2 dt)^2 + 0.2 (20 dt)^2).
  EXPECT_NEAR(columnStd(s.states)[3], std::sqrt(0.8 * 0.04 + 0.2 * 4.0), 0.02);
  // Each particle draws one mode for all three axes: its x and y velocities are both small or both wide.
  int both_small = 0;
  for (int i = 0; i < n; ++i)
    both_small += std::abs(s.states(i, 3)) < 0.6 && std::abs(s.states(i, 4)) < 0.6 ? 1 : 0;
  EXPECT_NEAR(static_cast<double>(both_small) / n, 0.8 * 0.9973 * 0.9973 + 0.2 * 0.2358 * 0.2358, 0.01);
  // Position: x = v dt + jitter, jitter 0.25 * 4 cm = 1 cm (smooth: 0.5 cm).
  const double sx = std::sqrt(0.8 * (0.04 * dt * dt + 0.005 * 0.005) + 0.2 * (4.0 * dt * dt + 0.01 * 0.01));
  EXPECT_NEAR(columnStd(s.states)[0], sx, 0.01 * sx * 3);
  Parameters bad;
  bad.set("smooth_fraction", 1.5);
  EXPECT_THROW(make<Velocity3D>(bad), ParameterError);
}

TEST(StateModels, BadParametersAreExplained)
{
  Parameters p;
  p.set("z_min", 2.0);
  p.set("z_max", 1.0);
  try
  {
    make<Position3D>(p);
    FAIL() << "z_max < z_min accepted";
  }
  catch (const ParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("z_max"), std::string::npos);
  }
  Parameters q;
  q.set("init_depth", std::string("log"));
  EXPECT_THROW(make<Position3D>(q), ParameterError);
}

TEST(StereoConstraints, HypothesesTakeTheApparentRadiusAtTheAgreedDepth)
{
  Parameters p;
  p.set("object_radius", 0.05);
  auto m = make<StereoConstraints>(p);
  std::vector<ParticleSet> sets(2);
  for (auto& s : sets)
    s.resize(50, 2);
  ImageHypotheses h;
  h.view = View::Left;
  m->project(kRig, 0, sets[0], h);
  EXPECT_EQ(h.radius[0], 0.0f);  // nothing agreed yet: the observation models' fixed window
  // Both sets at the same row, disparity 30 px: depth f b / 30, apparent radius f R / z = R * 30 / b.
  sets[0].states.col(0).setConstant(330.0);
  sets[1].states.col(0).setConstant(300.0);
  sets[0].states.col(1).setConstant(200.0);
  sets[1].states.col(1).setConstant(200.0);
  m->couple(kRig, sets);
  m->project(kRig, 0, sets[0], h);
  EXPECT_NEAR(h.radius[0], 0.05 * 30.0 / 0.09, 1e-4);
}

TEST(Engine, TracksTheRenderedPendulumFromUniformInitialisation)
{
  // Converged within 30 frames and stays within a few centimetres afterwards, over several seeds.
  std::vector<double> worsts, means;
  for (unsigned long seed = 1; seed <= 8; ++seed)
  {
    const TrackRun run = track("pendulum_uncluttered.yaml", 90, seed);
    double worst = 0.0, sum = 0.0;
    for (size_t k = 30; k < run.errors.size(); ++k)
    {
      worst = std::max(worst, run.errors[k]);
      sum += run.errors[k];
    }
    worsts.push_back(worst);
    means.push_back(sum / (run.errors.size() - 30));
    std::printf("seed %lu: worst %.4f m, mean %.4f m\n", seed, worst, means.back());
    EXPECT_EQ(run.states.back(), TrackState::Tracking) << "seed " << seed;
  }
  std::sort(worsts.begin(), worsts.end());
  EXPECT_LT(worsts[worsts.size() / 2], 0.10);
  EXPECT_LT(worsts.back(), 0.15);
  EXPECT_LT(*std::max_element(means.begin(), means.end()), 0.04);
}

TEST(Engine, StereoConstraintsTracksToo)
{
  auto sc = std::make_shared<StereoConstraints>();
  sc->initialize("state_model", Parameters());
  const TrackRun run = track("pendulum_uncluttered.yaml", 60, 2, sc);
  double worst = 0.0;
  for (size_t k = 30; k < run.errors.size(); ++k)
    worst = std::max(worst, run.errors[k]);
  EXPECT_LT(worst, 0.10);
}

TEST(Engine, SameSeedSameOutputDifferentSeedDifferent)
{
  const TrackRun a = track("pendulum_cluttered.yaml", 15, 7), b = track("pendulum_cluttered.yaml", 15, 7),
            c = track("pendulum_cluttered.yaml", 15, 8);
  bool differs = false;
  for (size_t k = 0; k < a.estimates.size(); ++k)
  {
    EXPECT_EQ(a.estimates[k], b.estimates[k]) << "frame " << k;
    differs = differs || a.estimates[k] != c.estimates[k];
  }
  EXPECT_TRUE(differs);
}

// Visualisation shows weightedSets(): the set the estimate was computed from, before resampling made every
// weight 1/N and most particles copies of a few.
TEST(Engine, WeightedSetsKeepTheWeightsResamplingErases)
{
  SceneRenderer renderer(loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml"));
  for (const double threshold : { 1.0, 0.0 })  // resample every frame / never
  {
    auto colour = std::make_shared<ColourHSI>();
    colour->initialize("colour", Parameters());
    EngineConfig config;
    config.resample_threshold = threshold;
    FilterEngine engine(make<Position3D>(), { colour }, config);
    EXPECT_TRUE(engine.weightedSets().empty());
    StereoFrame f;
    f.geometry = renderer.geometry();
    cv::Mat left, right;
    for (int k = 0; k < 6; ++k)
    {
      renderer.render(k, left, right);
      f.left = left;
      f.right = right;
      f.stamp = renderer.stamp(k);
      std::string error;
      if (k == 0)
      {
        ASSERT_TRUE(engine.learnTarget(f, renderer.targetRoi(0), error)) << error;
      }
      const FrameResult r = engine.step(f);
      ASSERT_EQ(engine.weightedSets().size(), 1u);
      const ParticleSet& weighed = engine.weightedSets()[0];
      const ParticleSet& after = engine.sets()[0];
      ASSERT_EQ(weighed.size(), config.particles);
      EXPECT_NEAR(weighed.weights.sum(), 1.0, 1e-9);
      EXPECT_GT(weighed.weights.maxCoeff(), 2.0 * weighed.weights.minCoeff()) << "frame " << k;
      // The mean estimate is the weighted mean of exactly this set.
      EXPECT_LT((weightedMean(weighed.states, weighed.weights) - r.estimate.position).norm(), 1e-9) << "frame " << k;
      EXPECT_EQ(r.resampled, threshold > 0.0);
      if (r.resampled)
      {
        EXPECT_NEAR(after.weights.maxCoeff() - after.weights.minCoeff(), 0.0, 1e-12);
      }
      else
      {
        EXPECT_EQ(weighed.states, after.states);
        EXPECT_EQ(weighed.weights, after.weights);
      }
    }
  }
}

TEST(Engine, DeclaresLostWhileOccludedAndReacquires)
{
  SceneRenderer renderer(loadScene(std::string(SCENES_DIR) + "/occlusion.yaml"));
  int hidden_begin = -1, hidden_end = -1;
  for (int k = 0; k < renderer.frames(); ++k)
  {
    if (!renderer.targetVisible(k) && hidden_begin < 0)
      hidden_begin = k;
    if (hidden_begin >= 0 && hidden_end < 0 && renderer.targetVisible(k) && k > hidden_begin)
      hidden_end = k;
  }
  ASSERT_GT(hidden_begin, 30);
  ASSERT_GT(hidden_end, hidden_begin);
  const TrackRun run = track("occlusion.yaml", hidden_end + 30, 3);
  bool lost = false;
  for (int k = hidden_begin; k < hidden_end; ++k)
    lost = lost || run.states[k] != TrackState::Tracking;
  EXPECT_TRUE(lost);
  int reacquired = -1;
  for (int k = hidden_end; k < hidden_end + 30 && reacquired < 0; ++k)
    if (run.states[k] == TrackState::Tracking && run.errors[k] < 0.05)
      reacquired = k - hidden_end;
  EXPECT_GE(reacquired, 0);
  EXPECT_LE(reacquired, 15);
}

// The refining stage (progressive correction): a refining cue is consulted only while tracking, after the
// others, on a set that was resampled and jittered (so it sees N distinct hypotheses, not copies), and its
// similarity is not evidence. A refining cue alone is an ordinary cue.
namespace
{
// Records, per call, the frame, the view and how many distinct hypothesis columns it was given.
class RecordingContour : public ColourContour
{
public:
  struct Call
  {
    int frame;
    View view;
    int distinct;
    int size;  ///< hypotheses in the batch (the engine's background check scores a few more)
  };
  std::vector<Call> calls;
  int frame = 0;
  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    std::vector<float> u = hyp.u;
    std::sort(u.begin(), u.end());
    calls.push_back(
        { frame, hyp.view, static_cast<int>(std::unique(u.begin(), u.end()) - u.begin()), hyp.size() });
    ColourContour::evaluate(cache, hyp, log_likelihood, similarity);
  }
};

struct RefineRun
{
  std::vector<TrackState> states;
  std::vector<double> evidence;
  std::vector<double> errors;
};

RefineRun runWithContour(std::shared_ptr<RecordingContour> contour, bool with_colour, int frames,
                         const EngineConfig& config = EngineConfig())
{
  SceneRenderer renderer(loadScene(std::string(SCENES_DIR) + "/pendulum_uncluttered.yaml"));
  std::vector<std::shared_ptr<ObservationModel>> cues;
  if (with_colour)
  {
    auto colour = std::make_shared<ColourHSI>();
    colour->initialize("colour", Parameters());
    cues.push_back(colour);
  }
  cues.push_back(contour);
  FilterEngine engine(make<Position3D>(), cues, config);
  RefineRun run;
  StereoFrame f;
  f.geometry = renderer.geometry();
  cv::Mat left, right;
  for (int k = 0; k < frames; ++k)
  {
    renderer.render(k, left, right);
    f.left = left;
    f.right = right;
    f.stamp = renderer.stamp(k);
    if (k == 0)
    {
      contour->frame = -1;  // learning: the cue trust's measurement, before any frame
      std::string error;
      EXPECT_TRUE(engine.learnTarget(f, renderer.targetRoi(0), error)) << error;
    }
    contour->frame = k;
    const FrameResult r = engine.step(f);
    run.states.push_back(r.state);
    run.evidence.push_back(r.evidence);
    run.errors.push_back((r.estimate.position - renderer.targetPosition(k)).norm());
  }
  return run;
}
}  // namespace

TEST(Engine, RefiningCueComesSecondOnJitteredParticlesWhileTracking)
{
  auto contour = std::make_shared<RecordingContour>();
  contour->initialize("colour_contour", Parameters());
  ASSERT_TRUE(contour->refine());
  EngineConfig config;
  config.acquire = false;  // the search path: searching from the prior, then tracking
  config.particles = 1000;
  const RefineRun run = runWithContour(contour, true, 40, config);
  int tracked = 0;
  for (int k = 0; k < 40; ++k)
  {
    const bool tracking_before = k > 0 && run.states[k - 1] == TrackState::Tracking;
    int calls = 0;
    for (const auto& c : contour->calls)
      if (c.frame == k)
      {
        ++calls;
        // Resampled and jittered: (almost) every particle is its own hypothesis. Without the jitter the
        // resampled copies of the few heavy particles would repeat.
        EXPECT_GT(c.distinct, 980) << "frame " << k;
      }
    EXPECT_EQ(calls, tracking_before ? 2 : 0) << "frame " << k;  // both views of the one 3D set
    tracked += tracking_before ? 1 : 0;
  }
  EXPECT_GT(tracked, 30);
  std::vector<double> tail(run.errors.begin() + 10, run.errors.end());
  std::nth_element(tail.begin(), tail.begin() + tail.size() / 2, tail.end());
  EXPECT_LT(tail[tail.size() / 2], 0.01);  // median error: the outline pins the ball to millimetres

  // The evidence is the colour histogram's alone: the same with the contour switched off, in the frames
  // before any refinement (the runs are identical up to the first tracking frame).
  auto off = std::make_shared<RecordingContour>();
  Parameters p;
  p.set("enabled", false);
  off->initialize("colour_contour", p);
  const RefineRun plain = runWithContour(off, true, 40, config);
  EXPECT_TRUE(off->calls.empty());
  ASSERT_EQ(plain.states[0], run.states[0]);
  EXPECT_DOUBLE_EQ(plain.evidence[0], run.evidence[0]);
}

TEST(Engine, WithoutJitterTheRefiningCueSeesCopies)
{
  auto contour = std::make_shared<RecordingContour>();
  contour->initialize("colour_contour", Parameters());
  EngineConfig config;
  config.particles = 500;
  config.refine_jitter = 0.0;
  runWithContour(contour, true, 20, config);
  ASSERT_FALSE(contour->calls.empty());
  for (const auto& c : contour->calls)
    EXPECT_LT(c.distinct, 400) << "frame " << c.frame;
}

TEST(Engine, RefiningCueAloneIsAnOrdinaryCue)
{
  auto contour = std::make_shared<RecordingContour>();
  contour->initialize("colour_contour", Parameters());
  EngineConfig config;
  config.particles = 500;
  config.local_fraction = 0.0;  // the local search scores its own grid with the cue: batches of its own
  const RefineRun run = runWithContour(contour, false, 3, config);
  // Every frame, searching included, and its similarity is the evidence (so it also scores the background
  // check's few places: batches other than the particles').
  for (int k = 0; k < 3; ++k)
  {
    int calls = 0, background = 0;
    for (const auto& c : contour->calls)
      if (c.frame == k)
        (c.size == config.particles ? calls : background) += 1;
    EXPECT_EQ(calls, 2) << "frame " << k;
    EXPECT_EQ(background, 2) << "frame " << k;
  }
  EXPECT_GT(run.evidence[0], 0.0);
}

TEST(Engine, RefiningCueWhileSearchingWithTheSearchWeight)
{
  auto contour = std::make_shared<RecordingContour>();
  contour->initialize("colour_contour", Parameters());
  EngineConfig config;
  config.acquire = false;  // the search path: searching from the prior, then tracking
  config.particles = 500;
  config.refine_search_weight = 0.5;
  const RefineRun run = runWithContour(contour, true, 2, config);
  ASSERT_EQ(run.states[0], TrackState::Searching);
  int first = 0;
  for (const auto& c : contour->calls)
    first += c.frame == 0 ? 1 : 0;
  EXPECT_EQ(first, 2);  // applied in the search frame too, with the colour cue
}

TEST(Engine, RejectsBadFramesAndMissingTarget)
{
  auto colour = std::make_shared<ColourHSI>();
  colour->initialize("colour", Parameters());
  EngineConfig config;
  config.acquire = false;  // a flat grey image: there is no box to match (acquisition would refuse it)
  FilterEngine engine(make<Position3D>(), { colour }, config);
  StereoFrame f;
  f.geometry = kRig;
  f.left = cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(100));
  f.right = cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(100));
  EXPECT_THROW(engine.step(f), std::invalid_argument);  // no target yet
  std::string error;
  ASSERT_TRUE(engine.learnTarget(f, cv::Rect(100, 100, 20, 20), error)) << error;
  f.right = cv::Mat(240, 320, CV_8UC3);
  EXPECT_THROW(engine.step(f), std::invalid_argument);
  f.right = cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(100));
  f.geometry = StereoGeometry(525, 525, 319.5, 239.5, std::nan(""), 640, 480);
  EXPECT_THROW(engine.step(f), std::invalid_argument);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
