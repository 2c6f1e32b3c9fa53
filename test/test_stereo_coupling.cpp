// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Soft stereo constraints (thesis eq. 5.15): kernel shape, fast vs naive accuracy, the StereoConstraints
// state model constructed directly, and (printed, not asserted) timings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "stereo_pf/core/parameters.h"
#include "stereo_pf/plugins/stereo_coupling.h"
#include "stereo_pf/plugins/stereo_constraints.h"

using stereo_pf::CouplingParams;
using stereo_pf::ParticleSet;
using stereo_pf::StereoCoupling;
using stereo_pf::StereoGeometry;

namespace
{
const StereoGeometry kGeometry(525, 525, 320, 240, 0.09, 640, 480);

/// Two 2D weighted sets.
struct Pair
{
  Eigen::VectorXd xl, yl, wl, xr, yr, wr;
};

enum class Layout
{
  Uniform,    ///< both sets uniform over the 640 x 480 image
  Clustered,  ///< both around one target (disparity 60, rows agree), sigma 5 px
  Mixed       ///< half clustered, half uniform, a few particles outside the image
};

const char* name(Layout l)
{
  return l == Layout::Uniform ? "uniform" : l == Layout::Clustered ? "clustered" : "mixed";
}

Pair makeSets(Layout layout, int nl, int nr, unsigned seed)
{
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(0.0, 640.0), uy(0.0, 480.0), uw(0.2, 1.0);
  std::normal_distribution<double> n5(0.0, 5.0);
  Pair p;
  auto fill = [&](Eigen::VectorXd& x, Eigen::VectorXd& y, Eigen::VectorXd& w, int n, double cx, double cy) {
    x.resize(n);
    y.resize(n);
    w.resize(n);
    for (int i = 0; i < n; ++i)
    {
      const bool cluster = layout == Layout::Clustered || (layout == Layout::Mixed && i % 2 == 0);
      if (cluster)
      {
        x[i] = cx + n5(rng);
        y[i] = cy + n5(rng);
      }
      else
      {
        x[i] = ux(rng);
        y[i] = uy(rng);
      }
      if (layout == Layout::Mixed && i % 97 == 1)  // outliers beyond the image edges
      {
        x[i] = (i % 2 ? -60.0 : 700.0) + n5(rng);
        y[i] = (i % 3 ? -20.0 : 500.0) + n5(rng);
      }
      w[i] = uw(rng);
    }
    w /= w.sum();
  };
  fill(p.xl, p.yl, p.wl, nl, 400.0, 230.0);
  fill(p.xr, p.yr, p.wr, nr, 340.0, 231.0);
  return p;
}

/// max_i |a_i - b_i| / max_i b_i.
double relError(const Eigen::VectorXd& a, const Eigen::VectorXd& b)
{
  const double scale = b.maxCoeff();
  return scale > 0.0 ? (a - b).cwiseAbs().maxCoeff() / scale : (a - b).cwiseAbs().maxCoeff();
}

/// Worst excess over the stated pointwise bound, in units of the source weight (<= 0 when it holds):
/// max_i (|fast_i - exact_i| - kPointwiseRelative exact_i) / sum(w) - kAbsoluteFloor.
double boundExcess(const Eigen::VectorXd& fast, const Eigen::VectorXd& exact, double source_weight)
{
  if (fast.size() == 0)
    return -1.0;
  const Eigen::ArrayXd slack = (fast - exact).cwiseAbs().array() - StereoCoupling::kPointwiseRelative * exact.array();
  return slack.maxCoeff() / source_weight - StereoCoupling::kAbsoluteFloor;
}

/// CPU time of this thread (the test machine is shared: wall time would measure the neighbours).
double cpuSeconds()
{
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// Best of `trials` averages over `reps` calls of fn (seconds of thread CPU time per call).
template <typename F>
double timeIt(F fn, int trials, int reps)
{
  double best = HUGE_VAL;
  for (int t = 0; t < trials; ++t)
  {
    const double t0 = cpuSeconds();
    for (int k = 0; k < reps; ++k)
      fn();
    best = std::min(best, (cpuSeconds() - t0) / reps);
  }
  return best;
}

CouplingParams defaultParams()
{
  CouplingParams c;
  c.epipolar_sigma = 2.0;
  c.vergence_softness = 2.0;
  c.max_disparity = 157.5;  // 525 * 0.09 / 0.3
  return c;
}

void singleRight(double xr, double yr, Eigen::VectorXd& lf, Eigen::VectorXd& rf, bool fast)
{
  Eigen::VectorXd xl(1), yl(1), wl(1), x(1), y(1), w(1);
  xl << 300.0;
  yl << 200.0;
  wl << 1.0;
  x << xr;
  y << yr;
  w << 0.7;
  CouplingParams c;
  c.max_disparity = 200.0;
  StereoCoupling sc;
  if (fast)
    sc.compute(xl, yl, wl, x, y, w, c, lf, rf);
  else
    stereo_pf::stereoCouplingNaive(xl, yl, wl, x, y, w, c, lf, rf);
}
}  // namespace

// ------------------------------------------------------------------------------------------------ kernel

TEST(Kernel, VergenceWindowShape)
{
  CouplingParams c;
  c.max_disparity = 100.0;
  c.vergence_softness = 2.0;
  EXPECT_NEAR(stereo_pf::vergenceWindow(50.0, c), 1.0, 1e-9);
  EXPECT_NEAR(stereo_pf::vergenceWindow(20.0, c), 1.0, 1e-9);
  EXPECT_NEAR(stereo_pf::vergenceWindow(90.0, c), 1.0, 1e-6);
  EXPECT_NEAR(stereo_pf::vergenceWindow(0.0, c), 0.5, 1e-9);
  EXPECT_NEAR(stereo_pf::vergenceWindow(100.0, c), 0.5, 1e-9);
  EXPECT_LT(stereo_pf::vergenceWindow(-20.0, c), 1e-20);
  EXPECT_LT(stereo_pf::vergenceWindow(120.0, c), 1e-20);
  EXPECT_GT(stereo_pf::vergenceWindow(-20.0, c), 0.0);  // tails computed without cancellation
  EXPECT_GT(stereo_pf::vergenceWindow(120.0, c), 0.0);
  // Smooth and monotone on the near edge.
  EXPECT_LT(stereo_pf::vergenceWindow(-2.0, c), stereo_pf::vergenceWindow(0.0, c));
  EXPECT_LT(stereo_pf::vergenceWindow(0.0, c), stereo_pf::vergenceWindow(2.0, c));
  // vergence_softness 0: the hard box (0, d_max].
  c.vergence_softness = 0.0;
  EXPECT_EQ(stereo_pf::vergenceWindow(0.0, c), 0.0);
  EXPECT_EQ(stereo_pf::vergenceWindow(1e-9, c), 1.0);
  EXPECT_EQ(stereo_pf::vergenceWindow(100.0, c), 1.0);
  EXPECT_EQ(stereo_pf::vergenceWindow(100.001, c), 0.0);
}

TEST(Kernel, EpipolarGaussianShape)
{
  CouplingParams c;
  c.epipolar_sigma = 2.0;
  EXPECT_DOUBLE_EQ(stereo_pf::epipolarGaussian(0.0, c), 1.0);
  EXPECT_NEAR(stereo_pf::epipolarGaussian(2.0, c), std::exp(-0.5), 1e-12);
  EXPECT_DOUBLE_EQ(stereo_pf::epipolarGaussian(-3.0, c), stereo_pf::epipolarGaussian(3.0, c));
  EXPECT_LT(stereo_pf::epipolarGaussian(20.0, c), 1e-20);
}

// --------------------------------------------------------------------------------------- known answers

TEST(Coupling, HandBuiltCases)
{
  for (bool fast : { false, true })
  {
    SCOPED_TRACE(fast ? "fast" : "naive");
    Eigen::VectorXd lf, rf;
    singleRight(250.0, 200.0, lf, rf, fast);  // same row, disparity 50 inside (0, 200]
    ASSERT_EQ(lf.size(), 1);
    ASSERT_EQ(rf.size(), 1);
    EXPECT_NEAR(lf[0], 0.7, 1e-4);  // = wR
    EXPECT_NEAR(rf[0], 1.0, 1e-4);  // = wL
    singleRight(350.0, 200.0, lf, rf, fast);  // disparity -50: behind the cameras
    EXPECT_LT(lf[0], 1e-6);
    EXPECT_LT(rf[0], 1e-6);
    singleRight(250.0, 220.0, lf, rf, fast);  // 10 sigma off the row
    EXPECT_LT(lf[0], 1e-6);
    EXPECT_LT(rf[0], 1e-6);
    singleRight(300.0, 201.0, lf, rf, fast);  // disparity 0: half the window, half a sigma off the row
    EXPECT_NEAR(lf[0], 0.7 * 0.5 * std::exp(-0.125), 1e-4);
    singleRight(100.0, 200.0, lf, rf, fast);  // disparity 200 = d_max: the far edge
    EXPECT_NEAR(lf[0], 0.7 * 0.5, 1e-4);
  }
}

TEST(Coupling, EdgeCasesAndErrors)
{
  StereoCoupling sc;
  Eigen::VectorXd lf, rf, empty;
  const CouplingParams c = defaultParams();
  Eigen::VectorXd x(2), y(2), w(2);
  x << 300.0, std::numeric_limits<double>::quiet_NaN();
  y << 200.0, 200.0;
  w << 0.5, 0.5;
  Eigen::VectorXd xr(1), yr(1), wr(1);
  xr << 250.0;
  yr << 200.0;
  wr << 1.0;
  sc.compute(x, y, w, xr, yr, wr, c, lf, rf);
  EXPECT_NEAR(lf[0], 1.0, 1e-4);
  EXPECT_EQ(lf[1], 0.0);          // a NaN particle receives nothing...
  EXPECT_NEAR(rf[0], 0.5, 1e-4);  // ...and gives nothing
  sc.compute(empty, empty, empty, xr, yr, wr, c, lf, rf);
  EXPECT_EQ(lf.size(), 0);
  ASSERT_EQ(rf.size(), 1);
  EXPECT_EQ(rf[0], 0.0);
  EXPECT_THROW(sc.compute(x, y, wr, xr, yr, wr, c, lf, rf), std::invalid_argument);
  CouplingParams bad = c;
  bad.epipolar_sigma = 0.0;
  EXPECT_THROW(sc.compute(x, y, w, xr, yr, wr, bad, lf, rf), std::invalid_argument);
  bad = c;
  bad.vergence_softness = 0.0;  // fine for the naive form (hard box), not for the grid
  EXPECT_THROW(sc.compute(x, y, w, xr, yr, wr, bad, lf, rf), std::invalid_argument);
  EXPECT_NO_THROW(stereo_pf::stereoCouplingNaive(x, y, w, xr, yr, wr, bad, lf, rf));
}

// ----------------------------------------------------------------------------------------- fast vs naive

TEST(Coupling, FastMatchesNaive)
{
  StereoCoupling sc;
  const CouplingParams c = defaultParams();
  double worst = 0.0;
  for (Layout layout : { Layout::Uniform, Layout::Clustered, Layout::Mixed })
    for (int n : { 200, 1000, 4000 })
    {
      const Pair p = makeSets(layout, n, n, 17u + static_cast<unsigned>(n));
      Eigen::VectorXd lf, rf, lf_ref, rf_ref;
      sc.compute(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf, rf);
      stereo_pf::stereoCouplingNaive(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf_ref, rf_ref);
      const double el = relError(lf, lf_ref), er = relError(rf, rf_ref);
      std::printf("[ accuracy ] %-9s N=%4d  left %.2e  right %.2e  (max factor %.3g / %.3g, grid %zu cells)\n",
                  name(layout), n, el, er, lf_ref.maxCoeff(), rf_ref.maxCoeff(), sc.lastGridCells());
      EXPECT_EQ(sc.lastCoarsening(), 1.0);
      EXPECT_LE(el, StereoCoupling::kRelativeTolerance) << name(layout) << " N=" << n;
      EXPECT_LE(er, StereoCoupling::kRelativeTolerance) << name(layout) << " N=" << n;
      EXPECT_LE(boundExcess(lf, lf_ref, p.wr.sum()), 0.0) << name(layout) << " N=" << n;
      EXPECT_LE(boundExcess(rf, rf_ref, p.wl.sum()), 0.0) << name(layout) << " N=" << n;
      EXPECT_GT(lf_ref.maxCoeff(), 0.0);
      worst = std::max({ worst, el, er });
    }
  std::printf("[ accuracy ] worst relative error (default parameters): %.2e (stated %.0e)\n", worst,
              StereoCoupling::kRelativeTolerance);
}

TEST(Coupling, FastMatchesNaiveOtherParameters)
{
  // Narrow and wide kernels, a small and a large window, unequal set sizes.
  struct Case
  {
    double sigma, soft, d_max;
  };
  StereoCoupling sc;
  for (const Case& k : { Case{ 0.5, 0.5, 1.0 }, Case{ 1.0, 0.5, 60.0 }, Case{ 5.0, 4.0, 300.0 },
                         Case{ 2.0, 8.0, 20.0 }, Case{ 3.0, 1.0, 640.0 } })
    for (Layout layout : { Layout::Uniform, Layout::Clustered, Layout::Mixed })
    {
      CouplingParams c;
      c.epipolar_sigma = k.sigma;
      c.vergence_softness = k.soft;
      c.max_disparity = k.d_max;
      const Pair p = makeSets(layout, 700, 1100, 5u);
      Eigen::VectorXd lf, rf, lf_ref, rf_ref;
      sc.compute(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf, rf);
      stereo_pf::stereoCouplingNaive(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf_ref, rf_ref);
      ASSERT_EQ(lf.size(), 700);
      ASSERT_EQ(rf.size(), 1100);
      const double el = relError(lf, lf_ref), er = relError(rf, rf_ref);
      std::printf("[ accuracy ] sigma %.1f s %.1f d_max %5.1f %-9s left %.2e right %.2e (grid %zu, coarsening %.2f)\n",
                  k.sigma, k.soft, k.d_max, name(layout), el, er, sc.lastGridCells(), sc.lastCoarsening());
      if (sc.lastCoarsening() == 1.0)
      {
        EXPECT_LE(boundExcess(lf, lf_ref, p.wr.sum()), 0.0);
        EXPECT_LE(boundExcess(rf, rf_ref, p.wl.sum()), 0.0);
        if (lf_ref.maxCoeff() >= 2.5e-3)
        {
          EXPECT_LE(el, StereoCoupling::kRelativeTolerance);
        }
        if (rf_ref.maxCoeff() >= 2.5e-3)
        {
          EXPECT_LE(er, StereoCoupling::kRelativeTolerance);
        }
      }
      else
      {
        EXPECT_LE(el, 0.02);  // coarsened grid: the brief's 2% ceiling still holds
        EXPECT_LE(er, 0.02);
      }
    }
}

TEST(Coupling, PointwiseBoundWhenSetsDisagree)
{
  // Clusters offset so that most pairs sit in the kernel's tails (behind the cameras, beyond d_max, off
  // the row): the factors can be small, so the pointwise bound (relative + absolute floor) is what applies.
  StereoCoupling sc;
  const CouplingParams c = defaultParams();
  for (double dx : { 30.0, 10.0, -170.0 })  // 15 s behind, 5 s behind, 6 s beyond d_max = 157.5
    for (double dy : { 0.0, 9.0 })
    {
      Pair p = makeSets(Layout::Clustered, 500, 500, 8u);
      p.xr.array() += 60.0 + dx;  // right cluster around x 400 + dx: disparity -dx (left cluster at x 400)
      p.yr.array() += dy;
      Eigen::VectorXd lf, rf, lf_ref, rf_ref;
      sc.compute(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf, rf);
      stereo_pf::stereoCouplingNaive(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf_ref, rf_ref);
      std::printf("[ accuracy ] disagreeing sets dx %+6.1f dy %3.1f: max factor %.2e, abs error %.2e\n", dx, dy,
                  lf_ref.maxCoeff(), (lf - lf_ref).cwiseAbs().maxCoeff());
      EXPECT_LE(boundExcess(lf, lf_ref, 1.0), 0.0);
      EXPECT_LE(boundExcess(rf, rf_ref, 1.0), 0.0);
    }
}

// ------------------------------------------------------------------------------------- the state model

namespace
{
stereo_pf::Parameters baseParams()
{
  stereo_pf::Parameters p;
  return p.sub("state");
}

ParticleSet gaussianSet(int n, double u, double v, double sigma, std::mt19937_64& rng)
{
  std::normal_distribution<double> nd(0.0, sigma);
  ParticleSet s;
  s.resize(n, 2);
  for (int i = 0; i < n; ++i)
  {
    s.states(i, 0) = u + nd(rng);
    s.states(i, 1) = v + nd(rng);
  }
  return s;
}

/// A set with a particle at (u, v) and symmetric rings around it (equal weights: the mean is (u, v)).
ParticleSet ringSet(double u, double v, double su, double sv)
{
  ParticleSet s;
  s.resize(1 + 4 * 5, 2);
  s.states.row(0) << u, v;
  int i = 1;
  for (int r = 1; r <= 5; ++r)
  {
    const double a = su * r / 3.0, b = sv * r / 3.0;
    s.states.row(i++) << u + a, v;
    s.states.row(i++) << u - a, v;
    s.states.row(i++) << u, v + b;
    s.states.row(i++) << u, v - b;
  }
  return s;
}
}  // namespace

TEST(StereoConstraints, ShapeAndParameters)
{
  stereo_pf::StereoConstraints m;
  m.initialize("state", baseParams());
  EXPECT_EQ(m.numSets(), 2);
  EXPECT_EQ(m.dimension(0), 2);
  EXPECT_EQ(m.dimension(1), 2);
  EXPECT_THROW(m.dimension(2), std::out_of_range);
  ASSERT_EQ(m.views(0).size(), 1u);
  EXPECT_EQ(m.views(0)[0], stereo_pf::View::Left);
  EXPECT_EQ(m.views(1)[0], stereo_pf::View::Right);
  EXPECT_DOUBLE_EQ(m.noise(), 18.0);
  EXPECT_FALSE(m.naiveCoupling());
  const CouplingParams c = m.couplingParams(kGeometry);
  EXPECT_DOUBLE_EQ(c.max_disparity, 525.0 * 0.09 / 0.3);  // from min_depth 0.3 m
  EXPECT_DOUBLE_EQ(c.epipolar_sigma, 2.0);
  EXPECT_DOUBLE_EQ(c.vergence_softness, 2.0);

  stereo_pf::Parameters p = baseParams();
  p.set("min_depth", 0.01);  // 4725 px: clamped to the image width
  p.set("coupling", std::string("naive"));
  stereo_pf::StereoConstraints m2;
  m2.initialize("state", p);
  EXPECT_DOUBLE_EQ(m2.couplingParams(kGeometry).max_disparity, 640.0);
  EXPECT_TRUE(m2.naiveCoupling());
  p.set("max_disparity", 90.0);
  m2.reconfigure();  // the parameter tree is shared: reconfigure sees the new value
  EXPECT_DOUBLE_EQ(m2.couplingParams(kGeometry).max_disparity, 90.0);
}

TEST(StereoConstraints, BadParametersNameThemselves)
{
  const std::vector<std::pair<std::string, std::string>> bad = {
    { "noise", "-1" },           { "epipolar_sigma", "0" }, { "epipolar_sigma", "abc" },
    { "max_disparity", "0.5" },  { "max_disparity", "-3" }, { "min_depth", "0" },
    { "vergence_softness", "0" }, { "radius", "-2" },       { "coupling", "slow" },
    { "density_radius_px", "0" },
  };
  for (const auto& kv : bad)
  {
    stereo_pf::Parameters p = baseParams();
    p.set(kv.first, kv.second);
    stereo_pf::StereoConstraints m;
    try
    {
      m.initialize("state", p);
      ADD_FAILURE() << kv.first << " = " << kv.second << " was accepted";
    }
    catch (const stereo_pf::ParameterError& e)
    {
      EXPECT_NE(std::string(e.what()).find(kv.first), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("state/"), std::string::npos) << e.what();
    }
  }
}

TEST(StereoConstraints, PriorPredictProject)
{
  stereo_pf::StereoConstraints m;
  m.initialize("state", baseParams());
  stereo_pf::Rng rng(3);
  ParticleSet s;
  const int n = 20000;
  s.resize(n, 2);
  m.samplePrior(kGeometry, 0, s, 0, n, rng);
  for (int i = 0; i < n; ++i)
    ASSERT_TRUE(kGeometry.inImage({ s.states(i, 0), s.states(i, 1) })) << s.states.row(i);
  EXPECT_LT(s.states.col(0).minCoeff(), 5.0);  // covers the whole image
  EXPECT_GT(s.states.col(0).maxCoeff(), 634.0);
  EXPECT_LT(s.states.col(1).minCoeff(), 5.0);
  EXPECT_GT(s.states.col(1).maxCoeff(), 474.0);

  ParticleSet q;
  q.resize(n, 2);
  q.states.col(0).setConstant(320.0);
  q.states.col(1).setConstant(240.0);
  m.predict(1, 1.0 / 30.0, q, rng);
  for (int k = 0; k < 2; ++k)
  {
    const Eigen::ArrayXd c = q.states.col(k).array();
    const double mean = c.mean();
    const double sd = std::sqrt((c - mean).square().sum() / (n - 1));
    EXPECT_NEAR(sd, m.noise(), 0.1 * m.noise()) << "coordinate " << k;
    EXPECT_NEAR(mean, k == 0 ? 320.0 : 240.0, 4.0 * m.noise() / std::sqrt(static_cast<double>(n)));  // 4 standard errors
  }

  ParticleSet h;
  h.resize(3, 2);
  h.states << 10.0, 20.0, -5.0, 100.0, 639.0, 479.0;
  stereo_pf::ImageHypotheses hyp;
  hyp.view = stereo_pf::View::Right;
  m.project(kGeometry, 1, h, hyp);
  ASSERT_EQ(hyp.size(), 3);
  EXPECT_FLOAT_EQ(hyp.u[0], 10.0f);
  EXPECT_FLOAT_EQ(hyp.v[0], 20.0f);
  EXPECT_FLOAT_EQ(hyp.radius[0], 0.0f);
  EXPECT_EQ(hyp.valid[0], 1);
  EXPECT_EQ(hyp.valid[1], 0);  // outside the image
  EXPECT_EQ(hyp.valid[2], 1);
  hyp.view = stereo_pf::View::Left;  // the right set is not observed in the left image
  m.project(kGeometry, 1, h, hyp);
  EXPECT_EQ(hyp.valid[0], 0);
}

TEST(StereoConstraints, CoupleFavoursConsistentPairs)
{
  for (const char* mode : { "fast", "naive" })
  {
    SCOPED_TRACE(mode);
    stereo_pf::Parameters p = baseParams();
    p.set("coupling", std::string(mode));
    stereo_pf::StereoConstraints m;
    m.initialize("state", p);
    std::mt19937_64 rng(11);
    // Left: two equally weighted clusters on rows 200 and 300. Right: one cluster on row 200 at disparity 50.
    std::vector<ParticleSet> sets(2);
    ParticleSet a = gaussianSet(500, 400.0, 200.0, 3.0, rng), b = gaussianSet(500, 400.0, 300.0, 3.0, rng);
    sets[0].resize(1000, 2);
    sets[0].states << a.states, b.states;
    sets[1] = gaussianSet(1000, 350.0, 200.0, 3.0, rng);
    for (auto& s : sets)
      s.normalise();
    m.couple(kGeometry, sets);
    const double on_row = sets[0].weights.head(500).sum();
    EXPECT_GT(on_row, 0.9);
    EXPECT_NEAR(sets[0].weights.sum(), 1.0, 1e-12);
    EXPECT_NEAR(sets[1].weights.sum(), 1.0, 1e-12);

    // Right: two clusters on the same row, one at positive disparity (50), one behind the cameras (-50).
    ParticleSet l = gaussianSet(1000, 400.0, 200.0, 3.0, rng);
    ParticleSet r1 = gaussianSet(500, 350.0, 200.0, 3.0, rng), r2 = gaussianSet(500, 450.0, 200.0, 3.0, rng);
    sets[0] = l;
    sets[1].resize(1000, 2);
    sets[1].states << r1.states, r2.states;
    for (auto& s : sets)
      s.normalise();
    m.couple(kGeometry, sets);
    EXPECT_GT(sets[1].weights.head(500).sum(), 0.9);

    // No counterpart anywhere: the observation weights survive (no collapse to uniform).
    sets[0] = gaussianSet(100, 400.0, 100.0, 3.0, rng);
    sets[1] = gaussianSet(100, 350.0, 400.0, 3.0, rng);
    sets[0].log_weights.setLinSpaced(100, 0.0, 2.0);
    sets[0].normalise();
    sets[1].normalise();
    const Eigen::VectorXd before = sets[0].weights;
    m.couple(kGeometry, sets);
    EXPECT_LT((sets[0].weights - before).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(StereoConstraints, CoupleFastAgreesWithNaive)
{
  stereo_pf::Parameters pf = baseParams(), pn = baseParams();
  pn.set("coupling", std::string("naive"));
  stereo_pf::StereoConstraints fast, naive;
  fast.initialize("state", pf);
  naive.initialize("state", pn);
  const Pair p = makeSets(Layout::Mixed, 800, 800, 99u);
  std::vector<ParticleSet> a(2);
  a[0].resize(800, 2);
  a[1].resize(800, 2);
  a[0].states << p.xl, p.yl;
  a[1].states << p.xr, p.yr;
  a[0].log_weights = p.wl.array().log();
  a[1].log_weights = p.wr.array().log();
  a[0].normalise();
  a[1].normalise();
  std::vector<ParticleSet> b = a;
  fast.couple(kGeometry, a);
  naive.couple(kGeometry, b);
  for (int k = 0; k < 2; ++k)
    EXPECT_LE(relError(a[k].weights, b[k].weights), 2.0 * StereoCoupling::kRelativeTolerance) << "set " << k;
}

TEST(StereoConstraints, EstimateTriangulates)
{
  stereo_pf::StereoConstraints m;
  m.initialize("state", baseParams());
  const Eigen::Vector3d target(0.1, -0.05, 1.5);
  const stereo_pf::Pixel pl = kGeometry.projectLeft(target), pr = kGeometry.projectRight(target);
  std::vector<ParticleSet> sets = { ringSet(pl.u, pl.v, 3.0, 2.0), ringSet(pr.u, pr.v, 1.5, 2.5) };
  for (auto& s : sets)
    s.normalise();
  for (auto est : { stereo_pf::Estimator::Mean, stereo_pf::Estimator::Density,
                    stereo_pf::Estimator::SumInverseDistances })
  {
    const stereo_pf::StateEstimate e = m.estimate(kGeometry, sets, est, 0.03);
    ASSERT_TRUE(e.valid) << stereo_pf::toString(est);
    EXPECT_LT((e.position - target).norm(), 1e-9) << stereo_pf::toString(est) << ": " << e.position.transpose();
    EXPECT_NEAR(e.left.u, pl.u, 1e-9);
    EXPECT_NEAR(e.left.v, pl.v, 1e-9);
    EXPECT_NEAR(e.right.u, pr.u, 1e-9);
    EXPECT_NEAR(e.right.v, pr.v, 1e-9);
  }

  // Covariance: the 2D covariances through a finite-difference Jacobian of the triangulation.
  const stereo_pf::StateEstimate e = m.estimate(kGeometry, sets, stereo_pf::Estimator::Mean, 0.03);
  auto tri = [](const Eigen::Vector4d& q) {
    const double z = 525.0 * 0.09 / (q[0] - q[2]);
    return Eigen::Vector3d((q[0] - 320.0) * z / 525.0, (0.5 * (q[1] + q[3]) - 240.0) * z / 525.0, z);
  };
  const Eigen::Vector4d q0(pl.u, pl.v, pr.u, pr.v);
  Eigen::Matrix<double, 3, 4> jn;
  for (int k = 0; k < 4; ++k)
  {
    Eigen::Vector4d dq = Eigen::Vector4d::Zero();
    dq[k] = 1e-4;
    jn.col(k) = (tri(q0 + dq) - tri(q0 - dq)) / 2e-4;
  }
  Eigen::Matrix4d s4 = Eigen::Matrix4d::Zero();
  for (int k = 0; k < 2; ++k)
  {
    const Eigen::MatrixXd c = sets[k].states.rowwise() - sets[k].states.colwise().mean();
    s4.block<2, 2>(2 * k, 2 * k) = c.transpose() * c / sets[k].size();  // equal weights
  }
  const Eigen::Matrix3d expected = jn * s4 * jn.transpose();
  EXPECT_LT((e.covariance - expected).norm(), 1e-3 * expected.norm()) << e.covariance << "\n" << expected;
  EXPECT_GT(e.covariance(2, 2), e.covariance(0, 0));  // depth is the uncertain axis

  // Right image point to the right of the left one: no 3D point.
  std::vector<ParticleSet> behind = { ringSet(300.0, 200.0, 1.0, 1.0), ringSet(310.0, 200.0, 1.0, 1.0) };
  for (auto& s : behind)
    s.normalise();
  EXPECT_FALSE(m.estimate(kGeometry, behind, stereo_pf::Estimator::Mean, 0.03).valid);
}

TEST(StereoConstraints, CloudPairsByRow)
{
  stereo_pf::StereoConstraints m;
  m.initialize("state", baseParams());
  const int n = 50;
  std::vector<Eigen::Vector3d> truth;
  std::vector<ParticleSet> sets(2);
  sets[0].resize(n, 2);
  sets[1].resize(n, 2);
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(4));
  for (int k = 0; k < n; ++k)
  {
    const Eigen::Vector3d p(0.01 * k - 0.25, -0.2 + 0.008 * k, 1.0 + 0.02 * k);  // rows increase with k
    truth.push_back(p);
    const stereo_pf::Pixel l = kGeometry.projectLeft(p), r = kGeometry.projectRight(p);
    sets[0].states.row(k) << l.u, l.v;
    sets[1].states.row(perm[k]) << r.u, r.v;  // the right set in another order
  }
  Eigen::MatrixX3d pts;
  Eigen::VectorXd w;
  m.cloud(kGeometry, sets, pts, w);
  ASSERT_EQ(pts.rows(), n);
  EXPECT_NEAR(w.sum(), 1.0, 1e-12);
  for (int k = 0; k < n; ++k)
  {
    double best = 1e9;
    for (const auto& t : truth)
      best = std::min(best, (pts.row(k).transpose() - t).norm());
    EXPECT_LT(best, 1e-9) << "point " << k;
    EXPECT_NEAR(w[k], 1.0 / n, 1e-12);
  }
  // A pair at negative disparity: weight 0, a finite position (the weighted mean of the others).
  sets[1].states(perm[10], 0) = sets[0].states(10, 0) + 5.0;
  m.cloud(kGeometry, sets, pts, w);
  EXPECT_TRUE(pts.allFinite());
  EXPECT_NEAR(w.sum(), 1.0, 1e-12);
  int zero = 0;
  for (int k = 0; k < n; ++k)
    if (w[k] == 0.0)
    {
      ++zero;
      const Eigen::RowVector3d mean = w.transpose() * pts;
      EXPECT_LT((pts.row(k) - mean).norm(), 1e-9);
    }
  EXPECT_EQ(zero, 1);
}

// ---------------------------------------------------------------------------------- timings (printed)

TEST(Timing, FastVersusNaive)
{
  // Thread CPU time, best of several trials (fast) or one call (naive).
  StereoCoupling sc;
  const CouplingParams c = defaultParams();
  for (Layout layout : { Layout::Uniform, Layout::Clustered })
  {
    double fast_t[2] = { 0, 0 };
    int idx = 0;
    for (int n : { 1000, 4000 })
    {
      const Pair p = makeSets(layout, n, n, 123u);
      Eigen::VectorXd lf, rf;
      const double tf = timeIt([&] { sc.compute(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf, rf); }, 10, 20);
      const std::size_t cells = sc.lastGridCells();
      const double tn =
          timeIt([&] { stereo_pf::stereoCouplingNaive(p.xl, p.yl, p.wl, p.xr, p.yr, p.wr, c, lf, rf); }, 1, 1);
      fast_t[idx++] = tf;
      std::printf("[ timing   ] %-9s N=%4d per set: fast %7.3f ms (grid %6zu cells)  naive %8.1f ms  speed-up %4.0fx\n",
                  name(layout), n, 1e3 * tf, cells, 1e3 * tn, tn / tf);
    }
    std::printf("[ timing   ] %-9s fast 4000 / 1000 = %.2f\n", name(layout), fast_t[1] / fast_t[0]);
  }
}

TEST(Timing, StateModel)
{
  // The SC model's per-frame work without observations, on copies of the sets (copying excluded):
  // predict, project, couple (fast and naive) and estimate (Mean; Density is printed on its own because
  // its cost is that of stereo_pf::densityMode in core/estimators).
  for (const char* mode : { "fast", "naive" })
  {
    const bool naive = std::string(mode) == "naive";
    stereo_pf::Parameters params = baseParams();
    params.set("coupling", std::string(mode));
    stereo_pf::StereoConstraints m;
    m.initialize("state", params);
    for (Layout layout : { Layout::Uniform, Layout::Clustered })
    {
      enum { kPredict, kProject, kCouple, kMean, kDensity, kCount };
      double t[2][kCount] = {};
      int idx = 0;
      for (int n : { 1000, 4000 })
      {
        const Pair p = makeSets(layout, n, n, 321u);
        std::vector<ParticleSet> base(2);
        base[0].resize(n, 2);
        base[1].resize(n, 2);
        base[0].states << p.xl, p.yl;
        base[1].states << p.xr, p.yr;
        for (auto& s : base)
          s.normalise();
        stereo_pf::Rng rng(1);
        stereo_pf::ImageHypotheses hyp;
        std::vector<ParticleSet> sets = base;
        const int trials = naive ? 1 : 5, reps = naive ? 1 : 10;
        t[idx][kPredict] = timeIt([&] { m.predict(0, 1.0 / 30.0, sets[0], rng); m.predict(1, 1.0 / 30.0, sets[1], rng); },
                                  trials, reps);
        sets = base;
        t[idx][kProject] = timeIt(
            [&] {
              for (int s = 0; s < 2; ++s)
              {
                hyp.view = m.views(s).front();
                m.project(kGeometry, s, sets[s], hyp);
              }
            },
            trials, reps);
        double best = HUGE_VAL;  // couple() modifies the sets: time it on fresh copies
        for (int k = 0; k < trials * reps; ++k)
        {
          sets = base;
          const double t0 = cpuSeconds();
          m.couple(kGeometry, sets);
          best = std::min(best, cpuSeconds() - t0);
        }
        t[idx][kCouple] = best;
        t[idx][kMean] = timeIt([&] { (void)m.estimate(kGeometry, sets, stereo_pf::Estimator::Mean, 0.03); }, trials, reps);
        t[idx][kDensity] =
            timeIt([&] { (void)m.estimate(kGeometry, sets, stereo_pf::Estimator::Density, 0.03); }, 1, naive ? 1 : 3);
        ++idx;
      }
      auto frame = [&](int i) { return t[i][kPredict] + t[i][kProject] + t[i][kCouple] + t[i][kMean]; };
      std::printf("[ timing   ] StereoConstraints %-5s %-9s 1000 -> 4000 per set (ms): predict %.3f -> %.3f, project "
                  "%.3f -> %.3f, couple %.3f -> %.3f (x%.2f), estimate(mean) %.3f -> %.3f; total %.3f -> %.3f (x%.2f); "
                  "estimate(density) %.3f -> %.3f\n",
                  mode, name(layout), 1e3 * t[0][kPredict], 1e3 * t[1][kPredict], 1e3 * t[0][kProject],
                  1e3 * t[1][kProject], 1e3 * t[0][kCouple], 1e3 * t[1][kCouple], t[1][kCouple] / t[0][kCouple],
                  1e3 * t[0][kMean], 1e3 * t[1][kMean], 1e3 * frame(0), 1e3 * frame(1), frame(1) / frame(0),
                  1e3 * t[0][kDensity], 1e3 * t[1][kDensity]);
    }
  }
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
