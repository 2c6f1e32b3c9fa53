// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/resampling.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>

namespace stereo_pf
{
void systematicResampleIndices(const Eigen::VectorXd& weights, Rng& rng, std::vector<int>& indices)
{
  const int n = static_cast<int>(weights.size());
  indices.resize(n);
  if (n == 0)
    return;
  const double step = 1.0 / n;
  std::uniform_real_distribution<double> uniform(0.0, step);
  double u = uniform(rng);
  double cdf = weights[0];
  int i = 0;
  for (int j = 0; j < n; ++j)
  {
    // Walk the CDF; the bound on i guards against the last CDF value being a hair below 1.
    while (u > cdf && i < n - 1)
      cdf += weights[++i];
    indices[j] = i;
    u += step;
  }
}

void systematicResample(ParticleSet& set, Rng& rng, std::vector<int>& indices, Eigen::MatrixXd& scratch)
{
  systematicResampleIndices(set.weights, rng, indices);
  scratch.resize(set.size(), set.dimension());
  // Copy column by column: each coordinate is contiguous (structure of arrays).
  for (int k = 0; k < set.dimension(); ++k)
  {
    const double* src = set.states.col(k).data();
    double* dst = scratch.col(k).data();
    for (int j = 0; j < set.size(); ++j)
      dst[j] = src[indices[j]];
  }
  set.states.swap(scratch);
  set.setUniform();
}

void jitter(ParticleSet& set, const Eigen::MatrixXd& cov, double scale, Rng& rng)
{
  const int d = set.dimension();
  if (cov.rows() != d || cov.cols() != d)
    throw std::invalid_argument("jitter: covariance is " + std::to_string(cov.rows()) + "x" +
                                std::to_string(cov.cols()) + ", the set has dimension " + std::to_string(d));
  if (!(scale > 0.0) || set.size() == 0)
    return;
  // The kernel's square root: Cholesky factor, or the diagonal's square roots for a degenerate covariance.
  Eigen::MatrixXd root = Eigen::MatrixXd::Zero(d, d);
  const Eigen::LLT<Eigen::MatrixXd> llt(cov);
  if (llt.info() == Eigen::Success && cov.allFinite())
    root = llt.matrixL();
  else
    for (int k = 0; k < d; ++k)
      root(k, k) = std::isfinite(cov(k, k)) && cov(k, k) > 0.0 ? std::sqrt(cov(k, k)) : 0.0;
  root *= scale;
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::MatrixXd draws(set.size(), d);
  for (int k = 0; k < d; ++k)
    for (int i = 0; i < set.size(); ++i)
      draws(i, k) = gauss(rng);
  set.states.noalias() += draws * root.transpose();  // row i: (root * z_i)^T
}

}  // namespace stereo_pf
