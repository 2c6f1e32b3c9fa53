// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Google Benchmark suite: what each stage of one stereo frame costs, and what whole frames cost, as the
// particle count grows. Frames are rendered in process from the shipped pendulum scenes (640x480), and
// particles sit around the true target as a tracking filter's do (not spread over the whole frustum).
// Not a test: scripts/bench builds it (target stereo_pf_bench, not part of `all`) and runs it on one core.
//
// Counters: `particles` is N per set; `items_per_second` and `per_item` (its inverse, seconds) count what
// one iteration processes, named in each benchmark's comment (particles, hypotheses or pixels).
// OpenCV runs single-threaded (main below), so every figure is the work of one core.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/engine.h"
#include "stereo_pf/core/estimators.h"
#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/particle_set.h"
#include "stereo_pf/core/random.h"
#include "stereo_pf/core/resampling.h"
#include "stereo_pf/sim/scene.h"
#include "stereo_pf/plugins/stereo_coupling.h"
#include "stereo_pf/plugins/colour_contour.h"
#include "stereo_pf/plugins/colour_hsi.h"
#include "stereo_pf/plugins/position_3d.h"
#include "stereo_pf/plugins/shape_circle.h"
#include "stereo_pf/plugins/stereo_constraints.h"
#include "stereo_pf/plugins/stereo_match.h"
#include "stereo_pf/plugins/template_match.h"
#include "stereo_pf/plugins/texture_edge.h"
#include "stereo_pf/plugins/velocity_3d.h"

using namespace stereo_pf;

namespace
{
// ---------------------------------------------------------------------------------------------------
// Scenes, particle clouds and plugins

const char* const kUncluttered = "pendulum_uncluttered";  // plain wall: the colour-only configurations
const char* const kCheckered = "checkered_cluttered";     // busy wall, checkered ball: texture and shape

// One swing of the shipped pendulums (2 s at 30 fps): frame k + 60 shows the ball where frame k does, so the
// whole-frame benchmarks can cycle through these frames for as long as they run.
constexpr int kPeriodFrames = 60;
// The frame of the per-stage benchmarks: a quarter swing in, the ball at the bottom of its arc near the image
// centre (u ~ 320, v ~ 310, radius ~ 17 px).
constexpr int kStageFrame = 15;
constexpr unsigned long kSeed = 1;

// Spread of a tracking filter's predicted cloud: the default random walks of Position3D (4 cm per axis per
// frame) and StereoConstraints (18 px).
constexpr double kSpread3D = 0.04;
constexpr double kSpreadPx = 18.0;
// Width of the Gaussian "likelihood" that weights those clouds (tighter than the cloud, as after a cue).
constexpr double kLikelihood3D = 0.02;
constexpr double kLikelihoodPx = 6.0;

const View kViews[] = { View::Left, View::Right };

// A shipped scene and its first kPeriodFrames stereo frames, each rendered on first use.
class RenderedScene
{
public:
  explicit RenderedScene(const std::string& name)
    : name_(name), renderer_(loadScene(std::string(SCENES_DIR) + "/" + name + ".yaml")), left_(kPeriodFrames),
      right_(kPeriodFrames)
  {
  }

  const std::string& name() const { return name_; }
  StereoGeometry geometry() const { return renderer_.geometry(); }

  // Frame k (any k >= 0): the images of frame k mod kPeriodFrames, stamped k / fps so time keeps increasing.
  StereoFrame frame(int k)
  {
    const int i = k % kPeriodFrames;
    if (left_[i].empty())
      renderer_.render(i, left_[i], right_[i]);
    StereoFrame f;
    f.left = left_[i];
    f.right = right_[i];
    f.stamp = renderer_.stamp(k);
    f.geometry = renderer_.geometry();
    return f;
  }
  // Ground truth of frame k: the target's centre and its box in the left image.
  Eigen::Vector3d target(int k) const { return renderer_.targetPosition(k % kPeriodFrames); }
  cv::Rect targetRoi(int k) const { return renderer_.targetRoi(k % kPeriodFrames); }

private:
  std::string name_;
  SceneRenderer renderer_;
  std::vector<cv::Mat> left_, right_;
};

// The scene of that name. Only the last one asked for is kept (a full period is ~110 MB of images), so
// benchmarks on the same scene are registered together.
RenderedScene& scene(const std::string& name)
{
  static std::unique_ptr<RenderedScene> current;
  if (!current || current->name() != name)
  {
    current.reset();
    current = std::make_unique<RenderedScene>(name);
  }
  return *current;
}

// A plugin constructed directly (its header is public), initialised as the engine's loader would.
template <class Model>
std::shared_ptr<Model> makeModel(const std::string& name, const Parameters& params = Parameters())
{
  auto model = std::make_shared<Model>();
  model->initialize(name, params);
  return model;
}

// The cues with the settings of config/multi_cue.yaml (the weights do not change the cost; the shape's 8 lines do).
std::shared_ptr<ObservationModel> colourCue()
{
  return makeModel<ColourHSI>("colour");
}
std::shared_ptr<ObservationModel> contourCue()
{
  return makeModel<ColourContour>("colour_contour");
}
std::shared_ptr<ObservationModel> templateCue()
{
  return makeModel<TemplateMatch>("template");
}
std::shared_ptr<ObservationModel> stereoCue()
{
  return makeModel<StereoMatch>("stereo");
}
std::shared_ptr<ObservationModel> textureCue()
{
  Parameters p;
  p.set("weight", 0.5);
  return makeModel<TextureEdge>("texture", p);
}
std::shared_ptr<ObservationModel> shapeCue()
{
  return makeModel<ShapeCircle>("shape");  // its defaults (weight 0.2, 8 lines), as config/multi_cue.yaml sets them
}

// n particles of dimension d (3 or 6): {x, y, z} ~ N(target, kSpread3D) per axis, a velocity (d = 6)
// ~ N(0, 0.3 m/s); normalised weights from a Gaussian likelihood of kLikelihood3D around the target.
ParticleSet cloud3D(const Eigen::Vector3d& target, int n, int d, Rng& rng)
{
  std::normal_distribution<double> position(0.0, kSpread3D), velocity(0.0, 0.3);
  ParticleSet set;
  set.resize(n, d);
  for (int i = 0; i < n; ++i)
  {
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k)
    {
      const double e = position(rng);
      set.states(i, k) = target[k] + e;
      d2 += e * e;
    }
    for (int k = 3; k < d; ++k)
      set.states(i, k) = velocity(rng);
    set.log_weights[i] = -d2 / (2.0 * kLikelihood3D * kLikelihood3D);
  }
  set.normalise();
  return set;
}

// The two stereo-constraints sets: {u, v} ~ N(the target's pixel in that view, kSpreadPx), normalised weights
// from a Gaussian likelihood of kLikelihoodPx around it.
std::vector<ParticleSet> cloudsSC(const StereoGeometry& g, const Eigen::Vector3d& target, int n, Rng& rng)
{
  std::normal_distribution<double> spread(0.0, kSpreadPx);
  std::vector<ParticleSet> sets(2);
  for (int s = 0; s < 2; ++s)
  {
    const Pixel centre = g.project(target, kViews[s]);
    sets[s].resize(n, 2);
    for (int i = 0; i < n; ++i)
    {
      const double du = spread(rng), dv = spread(rng);
      sets[s].states(i, 0) = centre.u + du;
      sets[s].states(i, 1) = centre.v + dv;
      sets[s].log_weights[i] = -(du * du + dv * dv) / (2.0 * kLikelihoodPx * kLikelihoodPx);
    }
    sets[s].normalise();
  }
  return sets;
}

// The sets a tracking filter of `model` holds at the stage frame of `s`.
std::vector<ParticleSet> trackingSets(const StateModel& model, RenderedScene& s, int n, Rng& rng)
{
  const Eigen::Vector3d target = s.target(kStageFrame);
  if (model.numSets() == 2)
    return cloudsSC(s.geometry(), target, n, rng);
  return { cloud3D(target, n, model.dimension(0), rng) };
}

// Report N and the cost per item; `items` is what one iteration processes.
void setItems(benchmark::State& state, int n, long items)
{
  state.counters["particles"] = n;
  state.SetItemsProcessed(state.iterations() * items);
  state.counters["per_item"] = benchmark::Counter(static_cast<double>(state.iterations() * items),
                                                  benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// The particle counts of every per-particle benchmark, and those of the O(N^2) reference.
void particleCounts(benchmark::internal::Benchmark* b)
{
  for (const int n : { 200, 400, 800, 1000, 1500, 2000, 4000 })
    b->Arg(n);
  b->Unit(benchmark::kMicrosecond);
}
void naiveCounts(benchmark::internal::Benchmark* b)
{
  for (const int n : { 200, 400, 800, 1000, 1500, 2000 })
    b->Arg(n);
  b->Unit(benchmark::kMicrosecond);
}

// ---------------------------------------------------------------------------------------------------
// Per-frame work of the FeatureCache (independent of N; both views; items = pixels of both images).
// On the cluttered checkered scene, the busiest image the cues meet. Each iteration starts a new frame
// (cache.reset) so the product is recomputed into the buffers kept from the previous frame, as in the engine.

// Runs `product` on both views of a fresh frame per iteration.
template <class Product>
void cacheBenchmark(benchmark::State& state, Product product)
{
  RenderedScene& s = scene(kCheckered);
  const StereoFrame frame = s.frame(kStageFrame);
  FeatureCache cache;
  for (auto _ : state)
  {
    cache.reset(frame);
    for (const View v : kViews)
      benchmark::DoNotOptimize(product(cache, v).data);
  }
  state.SetItemsProcessed(state.iterations() * 2 * frame.left.total());
}

// The HSI bin-index image the colour cue reads (one lookup per pixel).
void BM_FeatureCache_HsiBins(benchmark::State& state)
{
  auto colour = makeModel<ColourHSI>("colour");
  cacheBenchmark(state, [&](FeatureCache& c, View v) -> const cv::Mat& { return colour->binImage(c, v); });
}
BENCHMARK(BM_FeatureCache_HsiBins)->Unit(benchmark::kMicrosecond);

// The 8-bit grey image (the shape cue's only product; the texture cue bins it).
void BM_FeatureCache_Gray(benchmark::State& state)
{
  cacheBenchmark(state, [](FeatureCache& c, View v) -> const cv::Mat& { return c.gray(v); });
}
BENCHMARK(BM_FeatureCache_Gray)->Unit(benchmark::kMicrosecond);

// Grey image plus the texture cue's edge-bin image (integer Sobel, magnitude and bin in one pass).
void BM_FeatureCache_GrayEdgeBins(benchmark::State& state)
{
  auto texture = makeModel<TextureEdge>("texture");
  cacheBenchmark(state, [&](FeatureCache& c, View v) -> const cv::Mat& { return texture->binImage(c, v); });
}
BENCHMARK(BM_FeatureCache_GrayEdgeBins)->Unit(benchmark::kMicrosecond);

// Grey image plus the cache's generic float Sobel x, y and magnitude (eq. 4.1); no shipped cue asks for it,
// it is the reference the edge-bin pass above replaced.
void BM_FeatureCache_GraySobelMagnitude(benchmark::State& state)
{
  cacheBenchmark(state, [](FeatureCache& c, View v) -> const cv::Mat& { return c.gradientMagnitude(v); });
}
BENCHMARK(BM_FeatureCache_GraySobelMagnitude)->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------------------------------------------
// State models (items = particles over every set: N for the 3D models, 2 N for StereoConstraints)

// predict() over every set with the default dynamics and dt = 1/30 s. The cloud diffuses over the
// iterations; the cost does not depend on where the particles are.
template <class Model>
void BM_Predict(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  RenderedScene& s = scene(kUncluttered);
  auto model = makeModel<Model>("state_model");
  Rng rng(kSeed);
  std::vector<ParticleSet> sets = trackingSets(*model, s, n, rng);
  for (auto _ : state)
  {
    for (int k = 0; k < static_cast<int>(sets.size()); ++k)
      model->predict(k, 1.0 / 30.0, sets[k], rng);
    benchmark::DoNotOptimize(sets[0].states.data());
    benchmark::ClobberMemory();
  }
  setItems(state, n, n * static_cast<long>(sets.size()));
}
BENCHMARK_TEMPLATE(BM_Predict, Position3D)->Apply(particleCounts);
BENCHMARK_TEMPLATE(BM_Predict, Velocity3D)->Apply(particleCounts);
BENCHMARK_TEMPLATE(BM_Predict, StereoConstraints)->Apply(particleCounts);

// project() of every set into each of its views: the hypotheses the cues score (items = hypotheses: 2 N
// for every model, both views of one 3D set or one view of each SC set).
template <class Model>
void BM_Project(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  RenderedScene& s = scene(kUncluttered);
  const StereoGeometry g = s.geometry();
  auto model = makeModel<Model>("state_model");
  Rng rng(kSeed);
  const std::vector<ParticleSet> sets = trackingSets(*model, s, n, rng);
  ImageHypotheses hyp;
  long items = 0;
  for (auto _ : state)
  {
    items = 0;
    for (int k = 0; k < static_cast<int>(sets.size()); ++k)
      for (const View v : model->views(k))
      {
        hyp.view = v;
        model->project(g, k, sets[k], hyp);
        benchmark::DoNotOptimize(hyp.u.data());
        items += n;
      }
  }
  setItems(state, n, items);
}
BENCHMARK_TEMPLATE(BM_Project, Position3D)->Apply(particleCounts);
BENCHMARK_TEMPLATE(BM_Project, StereoConstraints)->Apply(particleCounts);

// ---------------------------------------------------------------------------------------------------
// Observation models: evaluate() on a batch of N Position3D hypotheses in each view (items = 2 N hypotheses).
// The frame's per-image products are computed before the loop, so this is the per-hypothesis cost alone
// (add the FeatureCache figures above for a frame). The cue learns the target at the stage frame.

void BM_Evaluate(benchmark::State& state, std::shared_ptr<ObservationModel> (*make_cue)(), const char* scene_name)
{
  const int n = static_cast<int>(state.range(0));
  RenderedScene& s = scene(scene_name);
  const StereoFrame frame = s.frame(kStageFrame);
  FeatureCache cache;
  cache.reset(frame);
  const std::shared_ptr<ObservationModel> cue = make_cue();
  std::string error;
  if (!cue->learnTarget(cache, View::Left, s.targetRoi(kStageFrame), error))
  {
    state.SkipWithError(error.c_str());
    return;
  }
  auto model = makeModel<Position3D>("state_model");
  Rng rng(kSeed);
  const std::vector<ParticleSet> sets = trackingSets(*model, s, n, rng);
  ImageHypotheses hyp[2];
  for (int k = 0; k < 2; ++k)
  {
    hyp[k].view = kViews[k];
    model->project(frame.geometry, 0, sets[0], hyp[k]);
  }
  Eigen::VectorXd log_likelihood(n), similarity(n);
  for (const ImageHypotheses& h : hyp)
    cue->evaluate(cache, h, log_likelihood, similarity);  // computes and caches the per-image products
  for (auto _ : state)
    for (const ImageHypotheses& h : hyp)
    {
      cue->evaluate(cache, h, log_likelihood, similarity);
      benchmark::DoNotOptimize(log_likelihood.data());
      benchmark::DoNotOptimize(similarity.data());
    }
  setItems(state, n, 2L * n);
}
// Colour histogram with surround ring, on the plain-wall scene (its cost does not depend on the image).
BENCHMARK_CAPTURE(BM_Evaluate, ColourHSI, colourCue, kUncluttered)->Apply(particleCounts);
// Sub-pixel colour outline (its P map made once per frame, like the bin image), same scene.
BENCHMARK_CAPTURE(BM_Evaluate, ColourContour, contourCue, kUncluttered)->Apply(particleCounts);
// Edge-intensity histogram, on the scene where texture carries information.
BENCHMARK_CAPTURE(BM_Evaluate, TextureEdge, textureCue, kCheckered)->Apply(particleCounts);
// Radial measurement lines across the perspective silhouette, same scene.
BENCHMARK_CAPTURE(BM_Evaluate, ShapeCircle, shapeCue, kCheckered)->Apply(particleCounts);

// ---------------------------------------------------------------------------------------------------
// Target maps (the recovery search's proposals, on every recovery_period-th frame of a track, and every frame
// while searching): both views' maps of one frame, from a fresh cache, so the grey image or bins they read are
// made too. The cue learns from a box of half-size `range(0)` px about the ball's centre: the scene's ball (~17
// px) and a small object's (6 px), whose template map is matched on a less shrunk image.

void BM_TargetMap(benchmark::State& state, std::shared_ptr<ObservationModel> (*make_cue)())
{
  const int half = static_cast<int>(state.range(0));
  RenderedScene& s = scene(kUncluttered);
  const StereoFrame frame = s.frame(kStageFrame);
  FeatureCache cache;
  cache.reset(frame);
  const std::shared_ptr<ObservationModel> cue = make_cue();
  const cv::Rect ball = s.targetRoi(kStageFrame);
  const cv::Point centre(ball.x + ball.width / 2, ball.y + ball.height / 2);
  std::string error;
  if (!cue->learnTarget(cache, View::Left, cv::Rect(centre.x - half, centre.y - half, 2 * half, 2 * half), error))
  {
    state.SkipWithError(error.c_str());
    return;
  }
  cv::Mat map;
  for (auto _ : state)
  {
    cache.reset(frame);
    for (const View v : kViews)
    {
      if (!cue->targetMap(cache, v, map))
      {
        state.SkipWithError("no target map");
        return;
      }
      benchmark::DoNotOptimize(map.data);
    }
  }
  state.counters["map_cols"] = map.cols;
}
BENCHMARK_CAPTURE(BM_TargetMap, ColourHSI, colourCue)->Arg(17)->Arg(6)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_TargetMap, TemplateMatch, templateCue)->Arg(17)->Arg(6)->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------------------------------------------
// Stereo-constraints coupling (eq. 5.15) between the two SC sets with the model's default parameters
// (items = 2 N particles, both factors).

// Runs `coupling` (fast or naive) on the SC sets of the stage frame.
template <class Coupling>
void couplingBenchmark(benchmark::State& state, Coupling coupling)
{
  const int n = static_cast<int>(state.range(0));
  RenderedScene& s = scene(kUncluttered);
  auto model = makeModel<StereoConstraints>("state_model");
  const CouplingParams params = model->couplingParams(s.geometry());
  Rng rng(kSeed);
  const std::vector<ParticleSet> sets = trackingSets(*model, s, n, rng);
  const ParticleSet& l = sets[0];
  const ParticleSet& r = sets[1];
  Eigen::VectorXd left_factor(n), right_factor(n);
  for (auto _ : state)
  {
    coupling(l.states.col(0), l.states.col(1), l.weights, r.states.col(0), r.states.col(1), r.weights, params,
             left_factor, right_factor);
    benchmark::DoNotOptimize(left_factor.data());
    benchmark::DoNotOptimize(right_factor.data());
  }
  setItems(state, n, 2L * n);
}

// The O(N) grid evaluation StereoConstraints::couple() uses (`grid_cells`: the larger of its two grids).
void BM_Coupling_Fast(benchmark::State& state)
{
  StereoCoupling fast;
  couplingBenchmark(state, [&fast](const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr,
                                   const CoordRef& yr, const CoordRef& wr, const CouplingParams& p,
                                   Eigen::VectorXd& lf, Eigen::VectorXd& rf) {
    fast.compute(xl, yl, wl, xr, yr, wr, p, lf, rf);
  });
  state.counters["grid_cells"] = static_cast<double>(fast.lastGridCells());
}
BENCHMARK(BM_Coupling_Fast)->Apply(particleCounts);

// The exact O(N^2) double sum (coupling: naive), up to 2000 particles.
void BM_Coupling_Naive(benchmark::State& state)
{
  couplingBenchmark(state, stereoCouplingNaive);
}
BENCHMARK(BM_Coupling_Naive)->Apply(naiveCounts);

// ---------------------------------------------------------------------------------------------------
// Resampling and estimation on a weighted Position3D cloud (items = N particles).

// Systematic resampling in place (index walk over the CDF, gather of the states, weights reset). The weights
// are restored before each call (a copy of N doubles, included: a few per cent) so every call resamples the
// same likelihood-shaped weights rather than the uniform ones the previous call left.
void BM_Resample_Systematic(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  Rng rng(kSeed);
  ParticleSet set = cloud3D(scene(kUncluttered).target(kStageFrame), n, 3, rng);
  const Eigen::VectorXd weights = set.weights;
  std::vector<int> indices;
  Eigen::MatrixXd scratch;
  for (auto _ : state)
  {
    set.weights = weights;
    systematicResample(set, rng, indices, scratch);
    benchmark::DoNotOptimize(set.states.data());
    benchmark::ClobberMemory();
  }
  setItems(state, n, n);
}
BENCHMARK(BM_Resample_Systematic)->Apply(particleCounts);

// The systematic index walk alone (thesis Fig. 3.2), weights untouched.
void BM_Resample_SystematicIndices(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  Rng rng(kSeed);
  const ParticleSet set = cloud3D(scene(kUncluttered).target(kStageFrame), n, 3, rng);
  std::vector<int> indices;
  for (auto _ : state)
  {
    systematicResampleIndices(set.weights, rng, indices);
    benchmark::DoNotOptimize(indices.data());
  }
  setItems(state, n, n);
}
BENCHMARK(BM_Resample_SystematicIndices)->Apply(particleCounts);

// One thesis 6.4 estimator through estimate(), as PointModel3D::estimate calls it (density radius 3 cm, the
// engine default; eps 1 mm; the modes score kModeCandidates = 256 candidates against all N).
void BM_Estimator(benchmark::State& state, Estimator estimator)
{
  const int n = static_cast<int>(state.range(0));
  Rng rng(kSeed);
  const ParticleSet set = cloud3D(scene(kUncluttered).target(kStageFrame), n, 3, rng);
  for (auto _ : state)
  {
    Eigen::VectorXd position = estimate(set.states, set.weights, estimator, 0.03, 1e-3);
    benchmark::DoNotOptimize(position.data());
  }
  setItems(state, n, n);
}
BENCHMARK_CAPTURE(BM_Estimator, mean, Estimator::Mean)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Estimator, sum_inverse_distances, Estimator::SumInverseDistances)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Estimator, density, Estimator::Density)->Apply(particleCounts);

// The refining stage's kernel jitter: N(0, C) added to every particle (Cholesky of the 3x3 C, 3 N normals).
void BM_Jitter(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  Rng rng(kSeed);
  ParticleSet set = cloud3D(scene(kUncluttered).target(kStageFrame), n, 3, rng);
  const Eigen::MatrixXd covariance = weightedCovariance(set.states, set.weights, weightedMean(set.states, set.weights));
  for (auto _ : state)
  {
    jitter(set, covariance, 1e-3, rng);  // small, so the cloud barely drifts over the iterations
    benchmark::DoNotOptimize(set.states.data());
    benchmark::ClobberMemory();
  }
  setItems(state, n, n);
}
BENCHMARK(BM_Jitter)->Apply(particleCounts);

// The weighted 3x3 covariance around the weighted mean (the mean computed once, outside the loop).
void BM_WeightedCovariance(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  Rng rng(kSeed);
  const ParticleSet set = cloud3D(scene(kUncluttered).target(kStageFrame), n, 3, rng);
  const Eigen::VectorXd mean = weightedMean(set.states, set.weights);
  for (auto _ : state)
  {
    Eigen::MatrixXd covariance = weightedCovariance(set.states, set.weights, mean);
    benchmark::DoNotOptimize(covariance.data());
  }
  setItems(state, n, n);
}
BENCHMARK(BM_WeightedCovariance)->Apply(particleCounts);

// ---------------------------------------------------------------------------------------------------
// Whole frames: FilterEngine::step (feature cache, predict, project, cues, normalise, couple, estimate,
// resample every frame, track state) with default parameters and N particles per set (items = particles over
// every set). The engine learns the target at frame 0 and tracks one full swing before timing starts; the
// timed frames continue the swing (a new frame per iteration, cycling through the period). Counters:
// `tracking`, the share of timed frames in the Tracking state, and `err_cm`, the mean 3D error, show the
// filter is locked on as in real use.

// The configurations measured.
enum class StepConfig
{
  Default,            // the default tracker (config/tracker.yaml): Velocity3D + ColourHSI + TemplateMatch +
                      // ColourContour + StereoMatch + ShapeCircle, recovery and local search, on
                      // pendulum_uncluttered
  DefaultNoSearch,    // the same without the recovery and local search (their cost is the difference)
  DefaultNoRecovery,  // the same without the recovery search alone (its cost is the difference to Default)
  Position3DDefault,  // Position3D with the default cues and searches
  Position3DColour,   // Position3D + ColourHSI + ColourContour on pendulum_uncluttered
  Position3DHistogram,  // Position3D + ColourHSI alone (the thesis's colour model) on pendulum_uncluttered
  Position3DAllCues,  // Position3D + ColourHSI, ColourContour, TextureEdge, ShapeCircle on checkered_cluttered
  SCColour,           // StereoConstraints + ColourHSI + ColourContour on pendulum_uncluttered
  SCHistogram,        // StereoConstraints + ColourHSI alone on pendulum_uncluttered
  Velocity3DColour    // Velocity3D + ColourHSI + ColourContour on pendulum_uncluttered
};

void BM_Step(benchmark::State& state, StepConfig config)
{
  const int n = static_cast<int>(state.range(0));
  RenderedScene& s = scene(config == StepConfig::Position3DAllCues ? kCheckered : kUncluttered);
  std::shared_ptr<StateModel> model;
  if (config == StepConfig::SCColour || config == StepConfig::SCHistogram)
    model = makeModel<StereoConstraints>("state_model");
  else if (config == StepConfig::Velocity3DColour || config == StepConfig::Default ||
           config == StepConfig::DefaultNoSearch || config == StepConfig::DefaultNoRecovery)
    model = makeModel<Velocity3D>("state_model");
  else
    model = makeModel<Position3D>("state_model");
  const bool default_cues = config == StepConfig::Default || config == StepConfig::DefaultNoSearch ||
                            config == StepConfig::DefaultNoRecovery || config == StepConfig::Position3DDefault;
  std::vector<std::shared_ptr<ObservationModel>> cues = { colourCue() };
  if (default_cues)
    cues.push_back(templateCue());
  if (config != StepConfig::Position3DHistogram && config != StepConfig::SCHistogram)
    cues.push_back(contourCue());
  if (default_cues)
  {
    cues.push_back(stereoCue());
    cues.push_back(shapeCue());
  }
  if (config == StepConfig::Position3DAllCues)
  {
    cues.push_back(textureCue());
    cues.push_back(shapeCue());
  }
  EngineConfig engine_config;
  engine_config.particles = n;
  engine_config.seed = kSeed;
  if (!default_cues)
    engine_config.local_fraction = 0.0;  // as these configurations were measured before the local search
  if (config == StepConfig::DefaultNoSearch)
    engine_config.local_fraction = 0.0;
  if (config == StepConfig::DefaultNoSearch || config == StepConfig::DefaultNoRecovery)
    engine_config.tracking_respawn_fraction = 0.0;
  FilterEngine engine(model, cues, engine_config);
  std::string error;
  if (!engine.learnTarget(s.frame(0), s.targetRoi(0), error))
  {
    state.SkipWithError(error.c_str());
    return;
  }
  int k = 0;
  for (; k < kPeriodFrames; ++k)
    engine.step(s.frame(k));

  long frames = 0, tracking = 0, screened = 0;
  double error_sum = 0.0;
  for (auto _ : state)
  {
    const FrameResult r = engine.step(s.frame(k));
    benchmark::DoNotOptimize(r.estimate.position.data());
    tracking += r.state == TrackState::Tracking ? 1 : 0;
    screened += r.screened;
    error_sum += (r.estimate.position - s.target(k)).norm();
    ++frames;
    ++k;
  }
  setItems(state, n, n * static_cast<long>(model->numSets()));
  state.counters["tracking"] = frames > 0 ? static_cast<double>(tracking) / frames : 0.0;
  state.counters["err_cm"] = frames > 0 ? 100.0 * error_sum / frames : 0.0;
  state.counters["screened"] = frames > 0 ? static_cast<double>(screened) / frames : 0.0;
}
// Registered per scene (see scene()): the colour-only configurations first ("colour": the default cues,
// histogram and outline; "histogram": the thesis's colour model alone).
BENCHMARK_CAPTURE(BM_Step, Default, StepConfig::Default)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Default_without_searches, StepConfig::DefaultNoSearch)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Default_without_recovery, StepConfig::DefaultNoRecovery)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Position3D_default_cues, StepConfig::Position3DDefault)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Position3D_colour, StepConfig::Position3DColour)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Position3D_histogram, StepConfig::Position3DHistogram)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, StereoConstraints_colour, StepConfig::SCColour)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, StereoConstraints_histogram, StepConfig::SCHistogram)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Velocity3D_colour, StepConfig::Velocity3DColour)->Apply(particleCounts);
BENCHMARK_CAPTURE(BM_Step, Position3D_all_cues, StepConfig::Position3DAllCues)->Apply(particleCounts);

}  // namespace

// BENCHMARK_MAIN with OpenCV on one thread: the figures are one core's work, as the tracker's budget is stated.
int main(int argc, char** argv)
{
  cv::setNumThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv))
    return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
