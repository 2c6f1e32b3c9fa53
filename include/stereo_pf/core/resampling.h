// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Systematic resampling (thesis Fig. 3.2).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "stereo_pf/core/particle_set.h"
#include "stereo_pf/core/random.h"

namespace stereo_pf
{
/// Indices chosen by systematic resampling of normalised `weights`: one u1 ~ U[0, 1/N),
/// u_j = u1 + (j-1)/N, each taken where it falls in the CDF. `indices` gets N entries.
void systematicResampleIndices(const Eigen::VectorXd& weights, Rng& rng, std::vector<int>& indices);

/// Resample `set` in place (states copied by the indices above) and reset weights to 1/N.
/// `scratch` is reused between calls to avoid allocation.
void systematicResample(ParticleSet& set, Rng& rng, std::vector<int>& indices, Eigen::MatrixXd& scratch);

/// Kernel jitter after resampling (the regularised particle filter's "roughening"): add to every particle a
/// draw from N(0, scale^2 cov), `cov` being the D x D weighted covariance the set had before it was
/// resampled, so the copies of one particle spread over the region the weights said the state is in. When
/// `cov` is not positive definite (e.g. a coordinate every particle agrees on) its diagonal is used, negative
/// entries as 0. scale <= 0 leaves the set unchanged. Throws std::invalid_argument when `cov` is not D x D.
void jitter(ParticleSet& set, const Eigen::MatrixXd& cov, double scale, Rng& rng);

}  // namespace stereo_pf
