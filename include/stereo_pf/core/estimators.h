// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Point estimates of a weighted particle cloud (thesis 6.4) and its weighted covariance.
#pragma once

#include <string>

#include <Eigen/Core>

namespace stereo_pf
{
/// The estimators of thesis 6.4.
enum class Estimator
{
  Mean,                  ///< weighted mean (6.4.1)
  SumInverseDistances,   ///< particle maximising sum_j w_j / d_ij^2 (6.4.2)
  Density                ///< as above, only over particles within a radius (6.4.3)
};

/// Parse "mean", "sum_inverse_distances" or "density"; throws std::invalid_argument listing them otherwise.
Estimator estimatorFromString(const std::string& name);
/// The name parsed by estimatorFromString.
std::string toString(Estimator estimator);

/// Weighted mean of the rows of `points` (N x D) with normalised `weights`.
Eigen::VectorXd weightedMean(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights);

/// Weighted covariance (D x D) around `mean`.
Eigen::MatrixXd weightedCovariance(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights,
                                   const Eigen::VectorXd& mean);

/// Index of the particle with the largest sum over the others of w_j / (d_ij^2 + eps^2).
/// Particles of zero weight neither score nor contribute. `eps` keeps coincident particles finite.
/// With max_candidates > 0 only that many evenly spaced particles are scored (against all others), so the
/// cost is O(max_candidates * N) instead of O(N^2); 0 scores every particle.
int sumInverseDistancesMode(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, double eps,
                            int max_candidates = 0);

/// As sumInverseDistancesMode but only over neighbours within `radius` (grid hashing on the first three
/// coordinates). When the cloud is tighter than the radius every particle is a neighbour, so `max_candidates`
/// bounds the cost as for sumInverseDistancesMode. Returns the argmax index.
int densityMode(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, double radius, double eps,
                int max_candidates = 0);

/// How many candidates estimate() scores for the two modes (the cost stays O(256 N) for any N).
constexpr int kModeCandidates = 256;

/// Estimate of `points` (N x D) with the chosen estimator; the modes return the winning particle's row
/// (scored over kModeCandidates evenly spaced candidates).
Eigen::VectorXd estimate(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, Estimator estimator,
                         double density_radius, double eps);

}  // namespace stereo_pf
