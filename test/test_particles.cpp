// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Particle sets, systematic resampling statistics, estimators, evaluation summary.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "stereo_pf/core/estimators.h"
#include "stereo_pf/eval/evaluation.h"
#include "stereo_pf/core/resampling.h"

using namespace stereo_pf;

TEST(ParticleSet, NormaliseIsLogSumExpStable)
{
  ParticleSet p;
  p.resize(3, 1);
  p.log_weights << -1000.0, -1001.0, -std::numeric_limits<double>::infinity();
  const double lm = p.normalise();
  EXPECT_NEAR(p.weights.sum(), 1.0, 1e-12);
  EXPECT_NEAR(p.weights[0] / p.weights[1], std::exp(1.0), 1e-9);
  EXPECT_EQ(p.weights[2], 0.0);
  EXPECT_NEAR(lm, -1000.0 + std::log((1.0 + std::exp(-1.0)) / 3.0), 1e-9);
}

TEST(ParticleSet, AllZeroOrNanFallsBackToUniform)
{
  ParticleSet p;
  p.resize(4, 2);
  p.log_weights.setConstant(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(p.normalise(), -std::numeric_limits<double>::infinity());
  for (int i = 0; i < 4; ++i)
    EXPECT_DOUBLE_EQ(p.weights[i], 0.25);
  EXPECT_DOUBLE_EQ(p.effectiveSampleSize(), 4.0);
}

TEST(ParticleSet, TemperingKeepsTheEssAtItsFloorAndTheOrderOfTheWeights)
{
  // 100 particles, log-likelihoods 0, -1, ..., -99 (times 10): untempered one particle takes nearly all the
  // weight. Tempered to an ESS of 20, the exponent is the largest that keeps 20 (to the bisection's step), the
  // weights keep their order, and a particle the viewing volume ruled out (-inf) keeps none.
  const int n = 100;
  ParticleSet p;
  p.resize(n, 1);
  Eigen::VectorXd prior = Eigen::VectorXd::Zero(n);
  auto likelihood = [&] {
    for (int i = 0; i < n; ++i)
      p.log_weights[i] = -10.0 * i;
    p.log_weights[5] = -std::numeric_limits<double>::infinity();
  };
  likelihood();
  p.normalise();
  ASSERT_LT(p.effectiveSampleSize(), 1.1);
  likelihood();
  // temperingPower() finds the same exponent and leaves the weights alone.
  const Eigen::VectorXd untempered = p.log_weights;
  const double power = temperingPower(prior, p.log_weights, 20.0);
  EXPECT_TRUE((p.log_weights.array() == untempered.array()).all());
  const double beta = p.temper(prior, 20.0);
  EXPECT_EQ(power, beta);
  EXPECT_GT(beta, 0.0);
  EXPECT_LT(beta, 0.1);
  EXPECT_GE(p.effectiveSampleSize(), 20.0);
  EXPECT_NEAR(p.weights.sum(), 1.0, 1e-12);
  EXPECT_EQ(p.weights[5], 0.0);
  for (int i = 1; i < n; ++i)
  {
    if (i != 5 && i != 6)
    {
      EXPECT_GT(p.weights[i - 1], p.weights[i]) << i;
    }
  }
  // The largest such exponent: a little more (one bisection step and a bit) leaves an ESS below 20.
  likelihood();
  for (int i = 0; i < n; ++i)
    p.log_weights[i] *= beta + 2.0 / 1024.0;
  p.normalise();
  EXPECT_LT(p.effectiveSampleSize(), 20.0);
  // A prior that is not uniform stays as it was: only the likelihood is tempered.
  prior[0] = std::log(0.5);
  likelihood();
  p.log_weights += prior;
  p.temper(prior, 20.0);
  EXPECT_GE(p.effectiveSampleSize(), 20.0);
  // When the likelihood already leaves the ESS, nothing changes (exponent 1).
  for (int i = 0; i < n; ++i)
    p.log_weights[i] = -0.001 * i;
  EXPECT_EQ(p.temper(Eigen::VectorXd::Zero(n), 20.0), 1.0);
  EXPECT_NEAR(p.weights[0] / p.weights[1], std::exp(0.001), 1e-12);
}

TEST(Resampling, SystematicCountsAreWithinOneOfExpected)
{
  // Systematic resampling's defining property: particle i is copied floor(N w_i) or ceil(N w_i) times.
  Rng rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial)
  {
    const int n = 500;
    Eigen::VectorXd w(n);
    for (int i = 0; i < n; ++i)
      w[i] = std::pow(u(rng), 4.0);
    w /= w.sum();
    std::vector<int> idx;
    systematicResampleIndices(w, rng, idx);
    ASSERT_EQ(static_cast<int>(idx.size()), n);
    std::vector<int> count(n, 0);
    for (int i : idx)
      ++count[i];
    for (int i = 0; i < n; ++i)
    {
      EXPECT_GE(count[i], std::floor(n * w[i]) - 1e-9);
      EXPECT_LE(count[i], std::ceil(n * w[i]) + 1e-9);
    }
  }
}

TEST(Resampling, UnbiasedOverManyDraws)
{
  Rng rng(3);
  Eigen::VectorXd w(4);
  w << 0.1, 0.2, 0.3, 0.4;
  std::vector<double> mean(4, 0.0);
  std::vector<int> idx;
  const int draws = 20000;
  for (int d = 0; d < draws; ++d)
  {
    systematicResampleIndices(w, rng, idx);
    for (int i : idx)
      mean[i] += 1.0 / (4.0 * draws);
  }
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(mean[i], w[i], 0.005);
}

TEST(Resampling, ResampleCopiesStatesAndResetsWeights)
{
  Rng rng(1);
  ParticleSet p;
  p.resize(3, 2);
  p.states << 1, 10, 2, 20, 3, 30;
  p.weights << 0.0, 1.0, 0.0;
  std::vector<int> idx;
  Eigen::MatrixXd scratch;
  systematicResample(p, rng, idx, scratch);
  for (int i = 0; i < 3; ++i)
  {
    EXPECT_EQ(p.states(i, 0), 2.0);
    EXPECT_EQ(p.states(i, 1), 20.0);
    EXPECT_DOUBLE_EQ(p.weights[i], 1.0 / 3.0);
  }
}

// The refining stage's kernel jitter: copies of one particle spread with the given covariance.
TEST(Jitter, SpreadsCopiesWithTheScaledCovariance)
{
  Rng rng(5);
  ParticleSet p;
  const int n = 20000;
  p.resize(n, 2);
  p.states.col(0).setConstant(1.0);
  p.states.col(1).setConstant(-2.0);
  Eigen::MatrixXd cov(2, 2);
  cov << 4.0, 1.2, 1.2, 1.0;
  jitter(p, cov, 0.5, rng);
  const Eigen::VectorXd w = Eigen::VectorXd::Constant(n, 1.0 / n);
  const Eigen::VectorXd m = weightedMean(p.states, w);
  const Eigen::MatrixXd c = weightedCovariance(p.states, w, m);
  EXPECT_NEAR(m[0], 1.0, 0.03);
  EXPECT_NEAR(m[1], -2.0, 0.015);
  // 0.25 * cov, within the sampling error of 20000 draws.
  EXPECT_NEAR(c(0, 0), 1.0, 0.04);
  EXPECT_NEAR(c(1, 1), 0.25, 0.01);
  EXPECT_NEAR(c(0, 1), 0.3, 0.015);
  EXPECT_DOUBLE_EQ(p.weights[0], 1.0 / n);  // weights untouched
}

TEST(Jitter, DegenerateCovarianceUsesItsDiagonalAndZeroScaleNothing)
{
  Rng rng(6);
  ParticleSet p;
  p.resize(5000, 3);
  p.states.setZero();
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(3, 3);
  cov(0, 0) = 1.0;  // the other two coordinates: every particle agrees (not positive definite)
  cov(2, 2) = -1e-12;
  const Eigen::MatrixXd before = p.states;
  jitter(p, cov, 0.0, rng);
  EXPECT_EQ(p.states, before);
  jitter(p, cov, 1.0, rng);
  EXPECT_TRUE(p.states.allFinite());
  EXPECT_NEAR(std::sqrt(p.states.col(0).squaredNorm() / p.size()), 1.0, 0.05);
  EXPECT_EQ(p.states.col(1).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(p.states.col(2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_THROW(jitter(p, Eigen::MatrixXd::Identity(2, 2), 1.0, rng), std::invalid_argument);
}

TEST(Estimators, MeanAndCovariance)
{
  Eigen::MatrixXd pts(4, 2);
  pts << 0, 0, 2, 0, 0, 2, 2, 2;
  Eigen::VectorXd w = Eigen::VectorXd::Constant(4, 0.25);
  const Eigen::VectorXd m = weightedMean(pts, w);
  EXPECT_NEAR(m[0], 1.0, 1e-12);
  EXPECT_NEAR(m[1], 1.0, 1e-12);
  const Eigen::MatrixXd c = weightedCovariance(pts, w, m);
  EXPECT_NEAR(c(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(c(1, 1), 1.0, 1e-12);
  EXPECT_NEAR(c(0, 1), 0.0, 1e-12);
}

TEST(Estimators, ModesPickTheDenseBlobWhereTheMeanFails)
{
  // Thesis Fig. 6.4: two blobs; the mean falls between them, the modes land in the heavier one.
  Rng rng(11);
  std::normal_distribution<double> n(0.0, 0.01);
  const int a = 300, b = 200;
  Eigen::MatrixXd pts(a + b, 3);
  for (int i = 0; i < a + b; ++i)
  {
    const double cx = i < a ? 0.0 : 1.0;
    pts.row(i) << cx + n(rng), n(rng), 1.0 + n(rng);
  }
  Eigen::VectorXd w = Eigen::VectorXd::Constant(a + b, 1.0 / (a + b));
  const Eigen::VectorXd mean = estimate(pts, w, Estimator::Mean, 0.05, 1e-3);
  EXPECT_NEAR(mean[0], 0.4, 0.02);
  const Eigen::VectorXd sid = estimate(pts, w, Estimator::SumInverseDistances, 0.05, 1e-3);
  EXPECT_LT(std::abs(sid[0]), 0.03);
  const Eigen::VectorXd dens = estimate(pts, w, Estimator::Density, 0.05, 1e-3);
  EXPECT_LT(std::abs(dens[0]), 0.03);
}

TEST(Estimators, DensityAgreesWithBruteForce)
{
  Rng rng(5);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  Eigen::MatrixXd pts(400, 3);
  for (int i = 0; i < 400; ++i)
    pts.row(i) << u(rng), u(rng), 1.0 + u(rng);
  Eigen::VectorXd w = Eigen::VectorXd::Random(400).cwiseAbs();
  w /= w.sum();
  const double radius = 0.05, eps = 1e-3;
  int best = -1;
  double best_score = -1.0;
  for (int i = 0; i < 400; ++i)
  {
    double s = 0.0;
    for (int j = 0; j < 400; ++j)
    {
      const double d2 = (pts.row(i) - pts.row(j)).squaredNorm();
      if (j != i && d2 <= radius * radius)
        s += w[j] / (d2 + eps * eps);
    }
    if (s > best_score)
      best_score = s, best = i;
  }
  EXPECT_EQ(densityMode(pts, w, radius, eps), best);
  // Scoring a subset of candidates picks the best among them.
  int best_even = -1;
  double best_even_score = -1.0;
  for (int i = 0; i < 400; i += 2)
  {
    double s = 0.0;
    for (int j = 0; j < 400; ++j)
    {
      const double d2 = (pts.row(i) - pts.row(j)).squaredNorm();
      if (j != i && d2 <= radius * radius)
        s += w[j] / (d2 + eps * eps);
    }
    if (s > best_even_score)
      best_even_score = s, best_even = i;
  }
  EXPECT_EQ(densityMode(pts, w, radius, eps, 200), best_even);
}

TEST(Estimators, ParsesNamesAndRejectsUnknown)
{
  EXPECT_EQ(estimatorFromString("density"), Estimator::Density);
  EXPECT_EQ(toString(estimatorFromString("sum_inverse_distances")), "sum_inverse_distances");
  try
  {
    estimatorFromString("median");
    FAIL();
  }
  catch (const std::invalid_argument& e)
  {
    EXPECT_NE(std::string(e.what()).find("mean"), std::string::npos);
  }
}

TEST(Evaluation, ConvergenceRmsAndOcclusion)
{
  std::vector<FrameRecord> r(60);
  for (int k = 0; k < 60; ++k)
  {
    r[k].has_truth = true;
    r[k].estimate_valid = true;
    r[k].truth = Eigen::Vector3d(0, 0, 1);
    r[k].tracking = k >= 5;
    const double err = k < 5 ? 0.3 : 0.01;
    r[k].estimate = r[k].truth + Eigen::Vector3d(err, 0, 0);
    r[k].ms = 1.0;
  }
  // Hidden 30..39: declared lost; re-acquired 3 frames after it reappears.
  for (int k = 30; k < 40; ++k)
  {
    r[k].target_visible = false;
    r[k].tracking = k < 32;
    r[k].estimate.x() = 0.5;
  }
  for (int k = 40; k < 43; ++k)
    r[k].estimate.x() = 0.2;
  const TrackSummary s = summarise(r, 0.05, 10);
  EXPECT_EQ(s.convergence_frame, 5);
  EXPECT_EQ(s.occlusions, 1);
  EXPECT_EQ(s.occlusions_declared_lost, 1);
  EXPECT_EQ(s.max_reacquire_frames, 3);
  EXPECT_EQ(s.frames_above_10cm_after, 3);
  EXPECT_NEAR(s.mean_ms, 1.0, 1e-12);
  EXPECT_NE(s.line().find("converged_at=5"), std::string::npos);
}

TEST(Evaluation, NeverConverges)
{
  std::vector<FrameRecord> r(20);
  for (auto& f : r)
    f.has_truth = true;  // no valid estimate: infinite error
  EXPECT_EQ(summarise(r).convergence_frame, -1);
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
