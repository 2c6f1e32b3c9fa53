// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/particle_set.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stereo_pf
{
void ParticleSet::resize(int n, int d)
{
  states.setZero(n, d);
  setUniform();
}

void ParticleSet::setUniform()
{
  const int n = size();
  log_weights.setZero(n);
  weights.setConstant(n, n > 0 ? 1.0 / n : 0.0);
}

double ParticleSet::normalise()
{
  const int n = size();
  weights.resize(n);
  double max_lw = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i)
  {
    const double lw = log_weights[i];
    if (std::isfinite(lw) && lw > max_lw)
      max_lw = lw;
  }
  if (!std::isfinite(max_lw))
  {
    // Every particle has zero (or NaN) likelihood: nothing to prefer, keep them all equally.
    setUniform();
    return -std::numeric_limits<double>::infinity();
  }
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
  {
    const double lw = log_weights[i];
    const double w = std::isfinite(lw) ? std::exp(lw - max_lw) : 0.0;
    weights[i] = w;
    sum += w;
  }
  weights /= sum;
  return max_lw + std::log(sum / n);
}

double ParticleSet::effectiveSampleSize() const
{
  const double s = weights.squaredNorm();
  return s > 0.0 ? 1.0 / s : 0.0;
}

double ParticleSet::temper(const Eigen::VectorXd& prior_log, double min_ess)
{
  normalise();
  const int n = size();
  if (!(min_ess > 0.0) || effectiveSampleSize() >= min_ess || prior_log.size() != n)
    return 1.0;
  const double beta = temperingPower(prior_log, log_weights, min_ess);
  for (int i = 0; i < n; ++i)
    if (std::isfinite(prior_log[i]) && std::isfinite(log_weights[i]))
      log_weights[i] = prior_log[i] + beta * (log_weights[i] - prior_log[i]);
  normalise();
  return beta;
}

double temperingPower(const Eigen::VectorXd& prior_log, const Eigen::VectorXd& log_weights, double min_ess)
{
  const Eigen::Index n = std::min(prior_log.size(), log_weights.size());
  // The finite particles' prior and log-likelihood gathered once, then per beta one vectorised pass of
  // exponentials.
  Eigen::ArrayXd prior(n), loglik(n);
  Eigen::Index m = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    if (std::isfinite(prior_log[i]) && std::isfinite(log_weights[i]))
    {
      prior[m] = prior_log[i];
      loglik[m++] = log_weights[i] - prior_log[i];
    }
  Eigen::ArrayXd w(m);
  auto ess = [&](double beta) {
    if (m == 0)
      return 0.0;
    w = prior.head(m) + beta * loglik.head(m);
    w = (w - w.maxCoeff()).exp();
    const double sum = w.sum(), sum2 = w.square().sum();
    return sum2 > 0.0 ? sum * sum / sum2 : 0.0;
  };
  if (!(min_ess > 0.0) || ess(1.0) >= min_ess)
    return 1.0;
  double lo = 0.0, hi = 1.0;  // ess(lo) keeps min_ess (the prior's spread, or as near as it comes)
  for (int k = 0; k < 10; ++k)
  {
    const double mid = 0.5 * (lo + hi);
    (ess(mid) >= min_ess ? lo : hi) = mid;
  }
  return std::max(lo, 1.0 / 1024.0);
}

}  // namespace stereo_pf
