// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/estimators.h"

#include <cmath>
#include <stdexcept>
#include <map>
#include <tuple>
#include <vector>

namespace stereo_pf
{
Estimator estimatorFromString(const std::string& name)
{
  if (name == "mean")
    return Estimator::Mean;
  if (name == "sum_inverse_distances")
    return Estimator::SumInverseDistances;
  if (name == "density")
    return Estimator::Density;
  throw std::invalid_argument("unknown estimator '" + name + "' (allowed: mean, sum_inverse_distances, density)");
}

std::string toString(Estimator estimator)
{
  switch (estimator)
  {
    case Estimator::Mean:
      return "mean";
    case Estimator::SumInverseDistances:
      return "sum_inverse_distances";
    case Estimator::Density:
      return "density";
  }
  return "mean";
}

Eigen::VectorXd weightedMean(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights)
{
  return points.transpose() * weights;
}

Eigen::MatrixXd weightedCovariance(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights,
                                   const Eigen::VectorXd& mean)
{
  const Eigen::MatrixXd centred = points.rowwise() - mean.transpose();
  return centred.transpose() * weights.asDiagonal() * centred;
}

namespace
{
// Stride between scored candidates: every particle when max_candidates is 0 or not smaller than n.
int candidateStride(int n, int max_candidates)
{
  return max_candidates > 0 && n > max_candidates ? (n + max_candidates - 1) / max_candidates : 1;
}
}  // namespace

int sumInverseDistancesMode(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, double eps,
                            int max_candidates)
{
  const int n = static_cast<int>(points.rows());
  const int d = static_cast<int>(points.cols());
  const double eps2 = eps * eps;
  const int stride = candidateStride(n, max_candidates);
  int best = 0;
  double best_score = -1.0;
  for (int i = 0; i < n; i += stride)
  {
    if (!(weights[i] > 0.0))
      continue;
    double score = 0.0;
    for (int j = 0; j < n; ++j)
    {
      if (j == i || !(weights[j] > 0.0))
        continue;
      double d2 = 0.0;
      for (int k = 0; k < d; ++k)
      {
        const double diff = points(i, k) - points(j, k);
        d2 += diff * diff;
      }
      score += weights[j] / (d2 + eps2);
    }
    if (score > best_score)
    {
      best_score = score;
      best = i;
    }
  }
  return best;
}

int densityMode(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, double radius, double eps,
                int max_candidates)
{
  const int n = static_cast<int>(points.rows());
  const int d = static_cast<int>(points.cols());
  const int hashed = std::min(d, 3);
  const double r2 = radius * radius;
  const double eps2 = eps * eps;
  // Hash particles into cells of side `radius`: neighbours within the radius are in the 3^k adjacent cells.
  auto cellOf = [&](int i, int k) { return static_cast<long>(std::floor(points(i, k) / radius)); };
  using Cell = std::tuple<long, long, long>;
  std::map<Cell, std::vector<int>> grid;
  for (int i = 0; i < n; ++i)
    if (weights[i] > 0.0)
      grid[Cell(cellOf(i, 0), hashed > 1 ? cellOf(i, 1) : 0, hashed > 2 ? cellOf(i, 2) : 0)].push_back(i);

  const int stride = candidateStride(n, max_candidates);
  int best = 0;
  double best_score = -1.0;
  for (int i = 0; i < n; i += stride)
  {
    if (!(weights[i] > 0.0))
      continue;
    const long c0 = cellOf(i, 0), c1 = hashed > 1 ? cellOf(i, 1) : 0, c2 = hashed > 2 ? cellOf(i, 2) : 0;
    double score = 0.0;
    for (long a = c0 - 1; a <= c0 + 1; ++a)
      for (long b = (hashed > 1 ? c1 - 1 : 0); b <= (hashed > 1 ? c1 + 1 : 0); ++b)
        for (long c = (hashed > 2 ? c2 - 1 : 0); c <= (hashed > 2 ? c2 + 1 : 0); ++c)
        {
          const auto cell = grid.find(Cell(a, b, c));
          if (cell == grid.end())
            continue;
          for (const int j : cell->second)
          {
            if (j == i)
              continue;
            double d2 = 0.0;
            for (int k = 0; k < d; ++k)
            {
              const double diff = points(i, k) - points(j, k);
              d2 += diff * diff;
            }
            if (d2 <= r2)
              score += weights[j] / (d2 + eps2);
          }
        }
    if (score > best_score)
    {
      best_score = score;
      best = i;
    }
  }
  return best;
}

Eigen::VectorXd estimate(const Eigen::MatrixXd& points, const Eigen::VectorXd& weights, Estimator estimator,
                         double density_radius, double eps)
{
  switch (estimator)
  {
    case Estimator::SumInverseDistances:
      return points.row(sumInverseDistancesMode(points, weights, eps, kModeCandidates)).transpose();
    case Estimator::Density:
      return points.row(densityMode(points, weights, density_radius, eps, kModeCandidates)).transpose();
    case Estimator::Mean:
      break;
  }
  return weightedMean(points, weights);
}

}  // namespace stereo_pf
