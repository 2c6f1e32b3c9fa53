// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Soft stereo constraints (thesis 5.4, eq. 5.15): naive reference and a fast grid evaluation.
//
// Method of StereoCoupling::compute ("Gaussian gridding" with an exact cumulative along the rows).
// Write sigma for epipolar_sigma, s for vergence_softness, D for max_disparity. Split each Gaussian into
// two equal halves, sigma_a = sigma_b = sigma / sqrt(2) (and s / sqrt(2) along x), so that
//   g(dy)  = sqrt(2 pi) sigma * Integral G_a(t - y_R) G_b(y_L - t) dt                  (G = normal pdf)
//   f(d)   = Integral G_b(x_L - u) F(u) du,   F(u) = Phi_a(u - x_R) - Phi_a(u - D - x_R)
// where Phi_a is the normal cdf of width s_a. For the left factors, sum over the right particles:
//   left_factor(x, y) = sqrt(2 pi) sigma * Integral Integral G_b(y - t) G_b(x - u) A(t, u) dt du,
//   A(t, u) = sum_j wR_j G_a(t - yR_j) [C_j(u) - C_j(u - D)],   C_j(u) = Phi_a(u - xR_j).
// Both integrals are taken with the trapezoidal rule on a regular grid of nodes (rows t_r, columns u_m):
//  1. splat: each right particle adds wR_j G_a(t_r - yR_j) to ~12 rows, and the increments
//     C_j(u_m) - C_j(u_{m-1}) to ~13 columns (the cumulative's tail mass is folded into the end nodes,
//     so nothing is lost along x);
//  2. a prefix sum along each row turns the increments into sum_j ... C_j(u_m), exact at every node;
//     the node spacing divides D exactly, so C(u_m - D) is the same row D/h columns earlier;
//  3. read: F = C[m] - C[m - D/h] on the read columns, and each left particle sums G_b-weighted nodes
//     (~12 x 12) of F.
// The integrands (products of Gaussians and Gaussian-smoothed steps) are entire functions, so the
// trapezoidal rule converges spectrally: its relative error is about 2 exp(-2 pi^2 tau^2 / h^2) with
// tau = sigma / 2 (resp. s / 2), the width of the product. Nodes are spaced h = 0.6 sigma across rows
// and h <= 0.6 s along rows: 2 exp(-13.7) ~ 2e-6 of each factor. On top of that there is an absolute floor:
// the Gaussians are cut at 5 sigma_a / 5 sigma_b and Phi is read from a table (error 1.2e-7), which
// misplaces at most ~1e-6 of the source weight (pairs deep in the kernel's tails, beyond ~4 sigma or
// ~4 s outside the window, lose their relative accuracy; their values are < 1e-4 of the peak). Stated:
//   |fast_i - exact_i| <= 1e-5 exact_i + 2e-6 sum(w of the other set)        (kPointwiseRelative/Floor)
// hence <= 1e-3 of the largest factor whenever that is >= 2.5e-3 sum(w) (kRelativeTolerance), which holds
// for any pair of sets that agree anywhere; even uniform sets over a 640 x 480 image give ~5e-3.
// Measured against stereoCouplingNaive (test/test_stereo_coupling.cpp): 2e-6 .. 4e-6 of the largest
// factor on uniform, clustered and mixed sets of 200..4000 particles; floor <= 7e-7 over a sweep of
// sigma 0.5..6, s 0.5..8, d_max 1..100 including sets that disagree.
// The right factors use the mirrored box: the same passes with the roles swapped and C[m + D/h] - C[m].
//
// Cost: O(N k^2) with k ~ 12 per set for splat and read, plus O(cells) for the prefix sums, where the grid
// covers only the query particles' bounding box (+ 5 sigma_b) widened by D along x. Clustered (tracking)
// sets give a grid of a few thousand cells; sets spread over a 640 x 480 image ~3e5 cells. The grid never
// grows with N; above kMaxGridCells the spacing is widened (lastCoarsening() > 1; error grows as above).
#include "stereo_pf/plugins/stereo_coupling.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stereo_pf
{
namespace
{
constexpr double kSqrt2Pi = 2.5066282746310002;
constexpr double kInvSqrt2 = 0.70710678118654752;
/// Gaussians (and the transition of Phi) are cut at this many of their standard deviations.
constexpr double kCut = 5.0;
/// Nominal node spacing in units of the full kernel width (sigma or s).
constexpr double kSpacing = 0.6;

/// Upper-tail probability Q(z) = 1 - Phi(z), accurate for large z.
double upperTail(double z)
{
  return 0.5 * std::erfc(z * kInvSqrt2);
}

/// Normal cdf from a table with linear interpolation: |error| <= step^2 / 8 * max|Phi''| = 1.2e-7.
/// erfc() per node would cost as much as the rest of the splat together.
class NormalCdfTable
{
public:
  NormalCdfTable() : values_(static_cast<std::size_t>(2 * kRange * kPerUnit) + 2)
  {
    for (std::size_t i = 0; i < values_.size(); ++i)
      values_[i] = upperTail(kRange - static_cast<double>(i) / kPerUnit);
  }
  double operator()(double z) const
  {
    if (z <= -kRange)
      return 0.0;
    if (z >= kRange)
      return 1.0;
    const double t = (z + kRange) * kPerUnit;
    const auto i = static_cast<std::size_t>(t);
    const double frac = t - static_cast<double>(i);
    return values_[i] + frac * (values_[i + 1] - values_[i]);
  }

private:
  static constexpr double kRange = 8.0;     // Phi(-8) = 6e-16
  static constexpr double kPerUnit = 512.0;
  std::vector<double> values_;
};

const NormalCdfTable& normalCdf()
{
  static const NormalCdfTable table;  // thread-safe initialisation, built once (~8k entries)
  return table;
}

/// Samples of exp(-z^2 / 2) on a regular grid of step dz (in units of the standard deviation).
struct GaussianRun
{
  explicit GaussianRun(double step) : dz(step), q(std::exp(-step * step)) {}
  /// out[k] = exp(-(z0 + k dz)^2 / 2) for k in [0, n): two exp() calls and a ratio recurrence
  /// (e[k+1] / e[k] = exp(-z0 dz - dz^2 / 2) q^k) instead of n calls.
  void operator()(double z0, int n, double* out) const;
  double dz, q;
};

void GaussianRun::operator()(double z0, int n, double* out) const
{
  double e = std::exp(-0.5 * z0 * z0);
  double ratio = std::exp(-z0 * dz - 0.5 * dz * dz);
  for (int k = 0; k < n; ++k)
  {
    out[k] = e;
    e *= ratio;
    ratio *= q;
  }
}

void checkSizes(const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr, const CoordRef& yr,
                const CoordRef& wr)
{
  if (xl.size() != yl.size() || xl.size() != wl.size() || xr.size() != yr.size() || xr.size() != wr.size())
    throw std::invalid_argument("stereo coupling: x, y and w of each set must have the same size (left " +
                                std::to_string(xl.size()) + "/" + std::to_string(yl.size()) + "/" +
                                std::to_string(wl.size()) + ", right " + std::to_string(xr.size()) + "/" +
                                std::to_string(yr.size()) + "/" + std::to_string(wr.size()) + ")");
}

void checkParams(const CouplingParams& p, bool need_softness)
{
  if (!(p.epipolar_sigma > 0.0) || !std::isfinite(p.epipolar_sigma))
    throw std::invalid_argument("stereo coupling: epipolar_sigma must be > 0, got " + std::to_string(p.epipolar_sigma));
  if (!(p.max_disparity > 0.0) || !std::isfinite(p.max_disparity))
    throw std::invalid_argument("stereo coupling: max_disparity must be > 0, got " + std::to_string(p.max_disparity));
  const bool ok = need_softness ? p.vergence_softness > 0.0 : p.vergence_softness >= 0.0;
  if (!ok || !std::isfinite(p.vergence_softness))
    throw std::invalid_argument(std::string("stereo coupling: vergence_softness must be ") +
                                (need_softness ? "> 0" : ">= 0") + ", got " + std::to_string(p.vergence_softness));
}

inline bool finite2(double a, double b)
{
  return std::isfinite(a) && std::isfinite(b);
}

/// Index window [lo, hi] of the nodes origin + k h within [c - r, c + r], clipped to [0, n - 1]; false when
/// empty. Works in double first so far-away particles cannot overflow the int conversion.
inline bool nodeWindow(double c, double r, double origin, double h, int n, int& lo, int& hi)
{
  const double lo_f = std::max(0.0, std::ceil((c - r - origin) / h));
  const double hi_f = std::min(n - 1.0, std::floor((c + r - origin) / h));
  if (!(lo_f <= hi_f))
    return false;
  lo = static_cast<int>(lo_f);
  hi = static_cast<int>(hi_f);
  return true;
}
}  // namespace

double vergenceWindow(double disparity, const CouplingParams& params)
{
  const double d = disparity;
  const double d_max = params.max_disparity;
  const double s = params.vergence_softness;
  if (!(s > 0.0))
    return (d > 0.0 && d <= d_max) ? 1.0 : 0.0;
  // Phi(a) - Phi(b) = Q(b) - Q(a): evaluate with the tail that does not cancel on either side.
  if (d <= 0.5 * d_max)
    return upperTail(-d / s) - upperTail(-(d - d_max) / s);
  return upperTail((d - d_max) / s) - upperTail(d / s);
}

double epipolarGaussian(double dy, const CouplingParams& params)
{
  const double z = dy / params.epipolar_sigma;
  return std::exp(-0.5 * z * z);
}

void stereoCouplingNaive(const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr,
                         const CoordRef& yr, const CoordRef& wr, const CouplingParams& params,
                         Eigen::VectorXd& left_factor, Eigen::VectorXd& right_factor)
{
  checkSizes(xl, yl, wl, xr, yr, wr);
  checkParams(params, false);
  const Eigen::Index nl = xl.size(), nr = xr.size();
  left_factor.setZero(nl);
  right_factor.setZero(nr);
  for (Eigen::Index i = 0; i < nl; ++i)
  {
    if (!finite2(xl[i], yl[i]))
      continue;
    for (Eigen::Index j = 0; j < nr; ++j)
    {
      if (!finite2(xr[j], yr[j]))
        continue;
      const double g = epipolarGaussian(yr[j] - yl[i], params);
      if (g == 0.0)  // underflow: the product is exactly 0, skip the erfc pair
        continue;
      const double k = g * vergenceWindow(xl[i] - xr[j], params);
      left_factor[i] += wr[j] * k;
      right_factor[j] += wl[i] * k;
    }
  }
}

void StereoCoupling::compute(const CoordRef& xl, const CoordRef& yl, const CoordRef& wl, const CoordRef& xr,
                             const CoordRef& yr, const CoordRef& wr, const CouplingParams& params,
                             Eigen::VectorXd& left_factor, Eigen::VectorXd& right_factor)
{
  checkSizes(xl, yl, wl, xr, yr, wr);
  checkParams(params, true);
  last_grid_cells_ = 0;
  last_coarsening_ = 1.0;
  // Left factors: d = x_L - x_R, the right set is the source. Right factors: the mirror image.
  if (!field(xr, yr, wr, xl, yl, params, true, left_factor) || !field(xl, yl, wl, xr, yr, params, false, right_factor))
  {
    // Only for a box narrower than a node (tiny max_disparity) over a wide region: exact fallback.
    last_grid_cells_ = 0;
    stereoCouplingNaive(xl, yl, wl, xr, yr, wr, params, left_factor, right_factor);
  }
}

bool StereoCoupling::field(const CoordRef& xs, const CoordRef& ys, const CoordRef& ws, const CoordRef& xq,
                           const CoordRef& yq, const CouplingParams& params, bool box_below, Eigen::VectorXd& out)
{
  const Eigen::Index nq = xq.size(), ns = xs.size();
  out.setZero(nq);

  // Bounding box of the queries: the grid only needs to exist where it is read.
  double qx0 = HUGE_VAL, qx1 = -HUGE_VAL, qy0 = HUGE_VAL, qy1 = -HUGE_VAL;
  for (Eigen::Index i = 0; i < nq; ++i)
  {
    if (!finite2(xq[i], yq[i]))
      continue;
    qx0 = std::min(qx0, xq[i]);
    qx1 = std::max(qx1, xq[i]);
    qy0 = std::min(qy0, yq[i]);
    qy1 = std::max(qy1, yq[i]);
  }
  if (!(qx0 <= qx1) || ns == 0)
    return true;

  const double sigma = params.epipolar_sigma;
  const double soft = params.vergence_softness;
  const double d_max = params.max_disparity;
  const double sy_half = sigma * kInvSqrt2;  // sigma_a = sigma_b across rows
  const double sx_half = soft * kInvSqrt2;   // s_a = s_b along rows
  const double ry = kCut * sy_half, rx = kCut * sx_half;

  // Node spacing: nominal, widened only if the grid would exceed kMaxGridCells.
  double hy = kSpacing * sigma;
  double hx = kSpacing * soft;
  const double width = (qx1 - qx0) + 2.0 * rx;
  const double height = (qy1 - qy0) + 2.0 * ry;
  const double nominal_cells = (height / hy + 2.0) * ((width + d_max) / hx + 2.0);
  double coarsening = 1.0;
  if (nominal_cells > static_cast<double>(kMaxGridCells))
  {
    coarsening = std::sqrt(nominal_cells / static_cast<double>(kMaxGridCells)) * 1.05;
    hy *= coarsening;
    hx *= coarsening;
  }
  // The box edge must fall on a node: D = dn * hx exactly, so C(u - D) is dn columns away.
  const int dn = std::max(1, static_cast<int>(std::ceil(d_max / hx - 1e-9)));
  hx = d_max / dn;
  // Only for a box narrower than the coarsened spacing (dn = 1 forced hx = d_max) or absurd coordinates:
  // checked in double before any conversion to int.
  if (!(height / hy + 1.0 <= 2.0 * kMaxGridCells) || !(width / hx + 1.0 + dn <= 2.0 * kMaxGridCells) ||
      !((height / hy + 1.0) * (width / hx + 1.0 + dn) <= 2.0 * kMaxGridCells))
    return false;

  const double y0 = qy0 - ry;
  const int rows = static_cast<int>(std::floor(height / hy)) + 1;
  const double x0_read = qx0 - rx;
  const int cols_read = static_cast<int>(std::floor(width / hx)) + 1;
  const int cols = cols_read + dn;
  // Cumulative columns: read node m is at x0_read + m hx; the cumulative array starts dn columns earlier
  // for the left factors (C(u) - C(u - D)) and at the read origin for the right ones (C(u + D) - C(u)).
  const double x0_cum = box_below ? x0_read - d_max : x0_read;
  const std::size_t cells = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
  last_grid_cells_ = std::max(last_grid_cells_, cells);
  last_coarsening_ = std::max(last_coarsening_, coarsening);
  grid_.assign(cells, 0.0);
  if (grid_.capacity() > 2 * cells + (std::size_t(1) << 20))
    grid_.shrink_to_fit();  // don't hold tens of MB from a wide search once the sets have converged

  const int max_win_y = static_cast<int>(std::ceil(2.0 * ry / hy)) + 2;
  const int max_win_x = static_cast<int>(std::ceil(2.0 * rx / hx)) + 3;
  weights_.resize(static_cast<std::size_t>(max_win_y + max_win_x));
  double* wy = weights_.data();
  double* wx = weights_.data() + max_win_y;
  const NormalCdfTable& cdf = normalCdf();
  const GaussianRun gauss_y(hy / sy_half), gauss_x(hx / sx_half);
  const double dz_x = hx / sx_half;

  // 1. Splat: Gaussian across rows, increments of the cumulative Phi_a along the row.
  for (Eigen::Index j = 0; j < ns; ++j)
  {
    const double x = xs[j], y = ys[j], w = ws[j];
    if (!finite2(x, y) || !(w > 0.0) || !std::isfinite(w))
      continue;
    int r_lo = 0, r_hi = 0, k_lo = 0, k_hi = 0;
    // A window entirely left of the grid adds a constant to every node of C, which cancels in
    // C[m + dn] - C[m]; entirely right of it, zero: either way the particle can be skipped.
    if (!nodeWindow(y, ry, y0, hy, rows, r_lo, r_hi) || !nodeWindow(x, rx, x0_cum, hx, cols, k_lo, k_hi))
      continue;
    // Increments; the first one carries all mass below the window and the one after the window the
    // rest up to 1, so the prefix sum reproduces Phi_a exactly at every node (up to the table error).
    int nk = 0;
    double prev = 0.0;
    const double z0 = (x0_cum + k_lo * hx - x) / sx_half;
    for (int k = 0; k <= k_hi - k_lo; ++k)
    {
      const double p = cdf(z0 + k * dz_x);
      wx[nk++] = w * (p - prev);
      prev = p;
    }
    if (k_hi + 1 < cols)
      wx[nk++] = w * (1.0 - prev);
    const int ny = r_hi - r_lo + 1;
    gauss_y((y0 + r_lo * hy - y) / sy_half, ny, wy);
    // Rank-1 update of the window; Eigen maps give SIMD loops the compiler would not risk (aliasing).
    const Eigen::Map<const Eigen::VectorXd> wxv(wx, nk);
    for (int r = 0; r < ny; ++r)
      Eigen::Map<Eigen::VectorXd>(grid_.data() + static_cast<std::size_t>(r_lo + r) * cols + k_lo, nk) += wy[r] * wxv;
  }

  // 2. Prefix sums along the rows give C at every node; then, in place, the box F[m] = C[m + dn] - C[m]
  // on the read columns (ascending m only reads columns not yet overwritten).
  // Four rows at a time: each prefix sum is a serial chain of additions, four chains overlap.
  int r = 0;
  for (; r + 4 <= rows; r += 4)
  {
    double* row = grid_.data() + static_cast<std::size_t>(r) * cols;
    double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
    for (int k = 0; k < cols; ++k)
    {
      a0 = row[k] += a0;
      a1 = row[k + cols] += a1;
      a2 = row[k + 2 * cols] += a2;
      a3 = row[k + 3 * cols] += a3;
    }
  }
  for (; r < rows; ++r)
  {
    double* row = grid_.data() + static_cast<std::size_t>(r) * cols;
    double acc = 0.0;
    for (int k = 0; k < cols; ++k)
      acc = row[k] += acc;
  }
  for (r = 0; r < rows; ++r)
  {
    double* row = grid_.data() + static_cast<std::size_t>(r) * cols;
    for (int m = 0; m < cols_read; ++m)
      row[m] = row[m + dn] - row[m];
  }

  // 3. Read: trapezoidal rule with G_b weights over F (the box difference of step 2).
  // norm = (sqrt(2 pi) sigma) * hy / (2 pi sigma_a sigma_b) * hx / (sqrt(2 pi) s_b); the exps are unnormalised.
  const double norm = (2.0 * hy / (kSqrt2Pi * sigma)) * (hx / (kSqrt2Pi * sx_half));
  for (Eigen::Index i = 0; i < nq; ++i)
  {
    const double x = xq[i], y = yq[i];
    if (!finite2(x, y))
      continue;
    int r_lo = 0, r_hi = 0, m_lo = 0, m_hi = 0;
    if (!nodeWindow(y, ry, y0, hy, rows, r_lo, r_hi) || !nodeWindow(x, rx, x0_read, hx, cols_read, m_lo, m_hi))
      continue;
    const int ny = r_hi - r_lo + 1, nm = m_hi - m_lo + 1;
    gauss_y((y0 + r_lo * hy - y) / sy_half, ny, wy);
    gauss_x((x0_read + m_lo * hx - x) / sx_half, nm, wx);
    double acc = 0.0;
    for (int r = 0; r < ny; ++r)
    {
      const double* row = grid_.data() + static_cast<std::size_t>(r_lo + r) * cols + m_lo;
      double s0 = 0.0, s1 = 0.0;  // two chains: the sum is latency-bound otherwise
      int m = 0;
      for (; m + 1 < nm; m += 2)
      {
        s0 += wx[m] * row[m];
        s1 += wx[m + 1] * row[m + 1];
      }
      if (m < nm)
        s0 += wx[m] * row[m];
      acc += wy[r] * (s0 + s1);
    }
    // The exact sum is non-negative; clamping the rounding noise only reduces the error.
    out[i] = std::max(0.0, acc * norm);
  }
  return true;
}

}  // namespace stereo_pf
