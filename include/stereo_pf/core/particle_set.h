// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Particles in structure-of-arrays storage with log-weights.
#pragma once

#include <Eigen/Core>

namespace stereo_pf
{
/// A weighted particle set. `states` is N x D column-major, so each state coordinate is one contiguous
/// array (structure of arrays): states.col(k) is coordinate k of every particle.
struct ParticleSet
{
  Eigen::MatrixXd states;        ///< N x D particle states
  Eigen::VectorXd log_weights;   ///< N unnormalised log-weights (accumulated this step)
  Eigen::VectorXd weights;       ///< N normalised weights (sum 1), valid after normalise()

  /// Number of particles.
  int size() const { return static_cast<int>(states.rows()); }
  /// State dimension.
  int dimension() const { return static_cast<int>(states.cols()); }
  /// Resize to n particles of dimension d with uniform weights.
  void resize(int n, int d);
  /// Set all weights to 1/N and log-weights to 0.
  void setUniform();
  /// Normalise log_weights into weights (log-sum-exp, robust to -inf and NaN, which count as zero weight).
  /// Returns log(mean of exp(log_weights)), the log marginal likelihood of this step; when every weight
  /// is zero the weights fall back to uniform and -infinity is returned.
  double normalise();
  /// Effective sample size 1 / sum(w^2) of the normalised weights.
  double effectiveSampleSize() const;
  /// Likelihood tempering: log_weights are prior_log plus a log-likelihood; scale that likelihood by the
  /// largest exponent in (0, 1] whose weights keep an effective sample size of at least min_ess (found by
  /// bisection, to 1/1024), and normalise. Returns the exponent (1: untouched). -inf terms stay -inf.
  double temper(const Eigen::VectorXd& prior_log, double min_ess);
};

/// temper()'s exponent without touching any weights: the largest power beta in (0, 1] (bisection, to 1/1024) for
/// which prior_log + beta * (log_weights - prior_log) keeps an effective sample size of at least min_ess; 1 when
/// the untempered weights already do. Entries not finite in either vector weigh nothing.
double temperingPower(const Eigen::VectorXd& prior_log, const Eigen::VectorXd& log_weights, double min_ess);

}  // namespace stereo_pf
