#include "stereo_pf/core/resampling.h"

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

}  // namespace stereo_pf
