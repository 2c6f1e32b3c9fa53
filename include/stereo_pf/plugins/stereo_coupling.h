// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Soft stereo constraints between a left and a right 2D particle set (thesis 5.4, eq. 5.15).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace stereo_pf
{
/// Shape of the coupling kernel K(d, dy) = f(d) * g(dy) with d = x_L - x_R (disparity) and
/// dy = y_R - y_L:
///  - g: epipolar constraint, Gaussian across rows, exp(-dy^2 / (2 sigma_y^2));
///  - f: vergence constraint, a flat-topped window along the row: the box 1[0 < d <= max_disparity]
///    smoothed by a Gaussian of `vergence_softness` pixels, i.e.
///    f(d) = Phi(d / s) - Phi((d - max_disparity) / s), ~1 inside (0, max_disparity], falling off smoothly
///    outside (it suppresses matches that would put the object behind the cameras, d <= 0).
struct CouplingParams
{
  double epipolar_sigma = 2.0;       ///< sigma_y, pixels (> 0)
  double max_disparity = 200.0;      ///< d_max, pixels (> 0; disparity of the nearest depth of interest)
  double vergence_softness = 2.0;    ///< s, pixels (> 0 for StereoCoupling; 0 means a hard box in the naive form)
};

/// Read-only view of a coordinate or weight array: a VectorXd, or a column of a ParticleSet's states
/// (column-major, so contiguous) without a copy.
using CoordRef = Eigen::Ref<const Eigen::VectorXd>;

/// f(d) above (a hard box 1[0 < d <= d_max] when vergence_softness is 0). Accurate in both tails.
double vergenceWindow(double disparity, const CouplingParams& params);
/// g(dy) above (peak 1 at dy = 0).
double epipolarGaussian(double dy, const CouplingParams& params);

/// Reference O(N^2) evaluation of eq. 5.15, kept for tests and benchmarks:
///   left_factor[i]  = sum_j wR[j] f(xL[i] - xR[j]) g(yR[j] - yL[i])
///   right_factor[j] = sum_i wL[i] f(xL[i] - xR[j]) g(yR[j] - yL[i])
/// Weights must be non-negative (they need not sum to 1). Particles with a non-finite coordinate neither
/// contribute nor receive (factor 0). Throws std::invalid_argument on mismatched sizes or
/// epipolar_sigma <= 0, max_disparity <= 0, vergence_softness < 0.
void stereoCouplingNaive(const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr,
                         const CoordRef& yr, const CoordRef& wr, const CouplingParams& params,
                         Eigen::VectorXd& left_factor, Eigen::VectorXd& right_factor);

/// Fast evaluation of the same sums (see stereo_coupling.cpp for the method and its error bound):
/// O(N k^2) with k ~ 12 plus a grid pass over the particles' bounding region (bounded by the image plus
/// max_disparity, independent of N). Reuses internal buffers between calls; not thread-safe per instance.
class StereoCoupling
{
public:
  /// Stated accuracy, whenever the grid is not coarsened (lastCoarsening() == 1), for every particle i:
  ///   |fast_i - exact_i| <= kPointwiseRelative * exact_i + kAbsoluteFloor * sum(weights of the other set).
  static constexpr double kPointwiseRelative = 1e-5;
  /// See kPointwiseRelative (cut Gaussian tails and the tabulated normal cdf).
  static constexpr double kAbsoluteFloor = 2e-6;
  /// Consequence of the two above: max_i |fast_i - exact_i| <= kRelativeTolerance * max_i exact_i whenever
  /// max_i exact_i >= 2.5e-3 * sum(weights of the other set), i.e. whenever the sets agree anywhere (uniform
  /// sets over a 640 x 480 image already give ~5e-3).
  static constexpr double kRelativeTolerance = 1e-3;
  /// Grids larger than this many cells are coarsened (which degrades the accuracy, see the .cpp).
  static constexpr std::size_t kMaxGridCells = std::size_t(1) << 22;

  /// Same outputs as stereoCouplingNaive. Throws std::invalid_argument on mismatched sizes or
  /// epipolar_sigma <= 0, max_disparity <= 0, vergence_softness <= 0.
  /// When max_disparity is so small (below the node spacing) that the grid would still exceed
  /// 2 kMaxGridCells after coarsening, it falls back to the exact naive sums (lastGridCells() is then 0).
  void compute(const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr, const CoordRef& yr,
               const CoordRef& wr, const CouplingParams& params, Eigen::VectorXd& left_factor,
               Eigen::VectorXd& right_factor);

  /// Cells of the larger of the two grids used by the last compute() (diagnostics, benchmarks).
  std::size_t lastGridCells() const { return last_grid_cells_; }
  /// Factor by which the last compute() widened the nominal node spacing to stay under kMaxGridCells
  /// (1 when it did not, i.e. when the stated tolerance holds).
  double lastCoarsening() const { return last_coarsening_; }

private:
  /// One side: splat the source set's cumulative vergence profile onto a grid around the query set,
  /// then read it at the queries. `box_below` selects d = x_query - x_source (left factors) versus
  /// d = x_source - x_query (right factors).
  /// Returns false (and `out` is to be recomputed) when the grid would exceed 2 kMaxGridCells even after coarsening.
  bool field(const CoordRef& xs, const CoordRef& ys, const CoordRef& ws, const CoordRef& xq, const CoordRef& yq,
             const CouplingParams& params, bool box_below, Eigen::VectorXd& out);

  std::vector<double> grid_;     ///< rows x columns, cumulative sums along the rows
  std::vector<double> weights_;  ///< per-particle window weights (scratch)
  std::size_t last_grid_cells_ = 0;  ///< see lastGridCells()
  double last_coarsening_ = 1.0;     ///< see lastCoarsening()
};

}  // namespace stereo_pf
