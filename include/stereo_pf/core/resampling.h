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

}  // namespace stereo_pf
