// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Stereo-constraints state model (thesis 5.1, 5.3, 5.4): a left and a right 2D particle set coupled by
// eq. 5.15. See include/stereo_pf/plugins/stereo_constraints.h for the parameters.
#include "stereo_pf/plugins/stereo_constraints.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <pluginlib/class_list_macros.hpp>

namespace stereo_pf
{
namespace
{
/// Floor added to the coupling factors before the log: a set whose factors are all zero (no counterpart
/// anywhere) keeps its observation weights instead of collapsing to uniform.
constexpr double kFactorFloor = 1e-300;
/// Softening of the sum-of-inverse-distances estimators on the 2D sets (pixels).
constexpr double kModeEps = 0.5;

/// Left-camera 3D point from a left pixel, the right column and the common row (rectified pair).
Eigen::Vector3d triangulatePair(const StereoGeometry& g, double ul, double ur, double v)
{
  const double z = g.fx() * g.baseline() / (ul - ur);
  return { (ul - g.cx()) * z / g.fx(), (v - g.cy()) * z / g.fy(), z };
}

/// Row order of a set's particles (stable, so equal rows keep their index order: deterministic).
std::vector<int> rowOrder(const ParticleSet& set)
{
  std::vector<int> idx(static_cast<std::size_t>(set.size()));
  std::iota(idx.begin(), idx.end(), 0);
  std::stable_sort(idx.begin(), idx.end(), [&set](int a, int b) { return set.states(a, 1) < set.states(b, 1); });
  return idx;
}
}  // namespace

void StereoConstraints::onInitialize()
{
  const Parameters& p = params();
  noise_ = p.getDouble("noise", 18.0, 0.0, 1000.0, "px per frame of random walk on u and v");
  epipolar_sigma_ = p.getDouble("epipolar_sigma", 2.0, 0.5, 100.0, "px; soft epipolar constraint (row difference)");
  max_disparity_ = p.getDouble("max_disparity", 0.0, 0.0, 1e5,
                               "px; largest disparity of the vergence window (0: from min_depth)");
  if (max_disparity_ > 0.0 && max_disparity_ < 1.0)
    throw ParameterError("parameter '" + (p.prefix().empty() ? "" : p.prefix() + "/") + "max_disparity' = " +
                         p.raw("max_disparity") + " is out of range: 0 (derive from min_depth) or [1, 100000]");
  min_depth_ = p.getDouble("min_depth", 0.3, 1e-3, 1e3,
                           "m; nearest depth of interest (gives max_disparity when that is 0)");
  vergence_softness_ = p.getDouble("vergence_softness", 2.0, 0.5, 100.0,
                                   "px; smoothing of the vergence window's edges");
  radius_ = p.getDouble("radius", 0.0, 0.0, 1e4,
                        "px; fixed apparent radius (0: object_radius at the depth both sets agree on)");
  object_radius_ = p.getDouble("object_radius", 0.035, 0.0, 10.0,
                               "m; radius of the tracked sphere (0: the observation models' fixed window)");
  naive_ = p.getString("coupling", "fast", { "fast", "naive" },
                       "fast: the grid evaluator (StereoCoupling); naive: the O(N^2) reference") == "naive";
  density_radius_px_ = p.getDouble("density_radius_px", 10.0, 0.1, 1e4,
                                   "px; radius of the density estimator in the images");
}

void StereoConstraints::checkSet(int set) const
{
  if (set != 0 && set != 1)
    throw std::out_of_range("StereoConstraints: set index " + std::to_string(set) + " (allowed: 0 = left, 1 = right)");
}

int StereoConstraints::dimension(int set) const
{
  checkSet(set);
  return 2;
}

std::vector<View> StereoConstraints::views(int set) const
{
  checkSet(set);
  return { set == 0 ? View::Left : View::Right };
}

void StereoConstraints::samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin,
                                    int end, Rng& rng) const
{
  checkSet(set);
  // Pixel centres are integers, so the image covers [-0.5, size - 0.5) (as StereoGeometry::inImage).
  std::uniform_real_distribution<double> du(-0.5, geometry.width() - 0.5);
  std::uniform_real_distribution<double> dv(-0.5, geometry.height() - 0.5);
  for (int i = begin; i < end; ++i)
  {
    particles.states(i, 0) = du(rng);
    particles.states(i, 1) = dv(rng);
  }
}

void StereoConstraints::predict(int set, double /*dt*/, ParticleSet& particles, Rng& rng) const
{
  checkSet(set);
  if (noise_ <= 0.0)
    return;
  // Thesis eq. 5.12-5.13: the same alpha on both coordinates, per frame.
  std::normal_distribution<double> n(0.0, noise_);
  const int count = particles.size();
  for (int i = 0; i < count; ++i)
  {
    particles.states(i, 0) += n(rng);
    particles.states(i, 1) += n(rng);
  }
}

void StereoConstraints::project(const StereoGeometry& geometry, int set, const ParticleSet& particles,
                                ImageHypotheses& hyp) const
{
  checkSet(set);
  const int count = particles.size();
  hyp.resize(count);
  const bool own_view = hyp.view == views(set).front();
  for (int i = 0; i < count; ++i)
  {
    const Pixel px{ particles.states(i, 0), particles.states(i, 1) };
    hyp.u[i] = static_cast<float>(px.u);
    hyp.v[i] = static_cast<float>(px.v);
    hyp.radius[i] = static_cast<float>(radius_ > 0.0 ? radius_ : apparent_radius_);
    hyp.valid[i] = own_view && std::isfinite(px.u) && std::isfinite(px.v) && geometry.inImage(px) ? 1 : 0;
  }
}

CouplingParams StereoConstraints::couplingParams(const StereoGeometry& geometry) const
{
  CouplingParams c;
  c.epipolar_sigma = epipolar_sigma_;
  c.vergence_softness = vergence_softness_;
  if (max_disparity_ > 0.0)
  {
    c.max_disparity = max_disparity_;
  }
  else
  {
    // Nearest depth of interest -> largest disparity; no disparity can exceed the image width.
    const double d = geometry.fx() * geometry.baseline() / min_depth_;
    if (!(d > 0.0) || !std::isfinite(d))
      throw std::invalid_argument("StereoConstraints: cannot derive max_disparity from the geometry (" +
                                  geometry.validate() + "); set max_disparity");
    c.max_disparity = std::max(1.0, std::min(d, static_cast<double>(geometry.width())));
  }
  return c;
}

void StereoConstraints::couple(const StereoGeometry& geometry, std::vector<ParticleSet>& sets)
{
  if (sets.size() != 2 || sets[0].dimension() != 2 || sets[1].dimension() != 2)
    throw std::invalid_argument("StereoConstraints::couple needs two 2D sets (left, right)");
  for (ParticleSet& s : sets)
    if (s.weights.size() != s.size())
      s.normalise();
  const CouplingParams c = couplingParams(geometry);
  const ParticleSet& l = sets[0];
  const ParticleSet& r = sets[1];
  // Both factors come from the weights as they were before either set is modified.
  if (naive_)
    stereoCouplingNaive(l.states.col(0), l.states.col(1), l.weights, r.states.col(0), r.states.col(1), r.weights, c,
                        left_factor_, right_factor_);
  else
    coupling_.compute(l.states.col(0), l.states.col(1), l.weights, r.states.col(0), r.states.col(1), r.weights, c,
                      left_factor_, right_factor_);
  sets[0].log_weights.array() += (left_factor_.array().max(0.0) + kFactorFloor).log();
  sets[1].log_weights.array() += (right_factor_.array().max(0.0) + kFactorFloor).log();
  sets[0].normalise();
  sets[1].normalise();
  // The depth both sets agree on sets the apparent size of the object for the next frame's hypotheses:
  // r = fx R / z = R d / b.
  const double disparity = sets[0].weights.dot(sets[0].states.col(0)) - sets[1].weights.dot(sets[1].states.col(0));
  apparent_radius_ = object_radius_ > 0.0 && disparity > 0.0 ?
                         std::clamp(object_radius_ * disparity / geometry.baseline(), 2.0, 0.5 * geometry.height()) :
                         0.0;
}

StateEstimate StereoConstraints::estimate(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets,
                                          Estimator estimator, double /*density_radius*/) const
{
  StateEstimate out;
  if (sets.size() != 2 || !geometry.valid())
    return out;
  for (const ParticleSet& s : sets)
    if (s.size() == 0 || s.dimension() != 2 || s.weights.size() != s.size())
      return out;  // not a pair of normalised 2D sets: nothing to triangulate
  Eigen::Vector2d px[2];
  Eigen::Matrix2d cov[2];
  for (int k = 0; k < 2; ++k)
  {
    const ParticleSet& s = sets[k];
    px[k] = stereo_pf::estimate(s.states, s.weights, estimator, density_radius_px_, kModeEps);
    // Spread of the posterior (about the mean, whichever point estimate is reported).
    const Eigen::VectorXd mean = weightedMean(s.states, s.weights);
    cov[k] = weightedCovariance(s.states, s.weights, mean);
  }
  const double ul = px[0].x(), vl = px[0].y(), ur = px[1].x(), vr = px[1].y();
  out.left = { ul, vl };
  out.right = { ur, vr };
  const double d = ul - ur;
  if (!(d > 0.0) || !std::isfinite(d))
    return out;  // behind the cameras or at infinity: no 3D point

  const double v = 0.5 * (vl + vr);  // rows agree up to noise after rectification
  out.position = triangulatePair(geometry, ul, ur, v);
  const double x = out.position.x(), y = out.position.y(), z = out.position.z();
  // Jacobian of (x, y, z) with respect to (uL, vL, uR, vR): z = fx b / d, x = (uL - cx) z / fx,
  // y = ((vL + vR) / 2 - cy) z / fy.
  Eigen::Matrix<double, 3, 4> j;
  const double hz = 0.5 * z / geometry.fy();
  j << z / geometry.fx() - x / d, 0.0, x / d, 0.0,  //
      -y / d, hz, y / d, hz,                          //
      -z / d, 0.0, z / d, 0.0;
  Eigen::Matrix4d pixel_cov = Eigen::Matrix4d::Zero();
  pixel_cov.topLeftCorner<2, 2>() = cov[0];
  pixel_cov.bottomRightCorner<2, 2>() = cov[1];
  out.covariance = j * pixel_cov * j.transpose();
  out.valid = true;
  return out;
}

void StereoConstraints::cloud(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets,
                              Eigen::MatrixX3d& points, Eigen::VectorXd& weights) const
{
  if (sets.size() != 2)
    throw std::invalid_argument("StereoConstraints::cloud needs two sets (left, right)");
  const ParticleSet& l = sets[0];
  const ParticleSet& r = sets[1];
  const int nl = l.size(), nr = r.size();
  const int n = std::min(nl, nr);
  points.setZero(n, 3);
  weights.setZero(n);
  if (n == 0)
    return;
  const std::vector<int> order_l = rowOrder(l), order_r = rowOrder(r);
  // Rank k of the pairing picks the matching quantile of the larger set when the sizes differ.
  auto pick = [n](const std::vector<int>& order, int k) {
    const int size = static_cast<int>(order.size());
    if (size == n)
      return order[static_cast<std::size_t>(k)];
    const long q = n > 1 ? std::lround(static_cast<double>(k) * (size - 1) / (n - 1)) : (size - 1) / 2;
    return order[static_cast<std::size_t>(q)];
  };

  std::vector<unsigned char> ok(static_cast<std::size_t>(n), 0);
  double sum = 0.0;
  int valid_count = 0;
  for (int k = 0; k < n; ++k)
  {
    const int il = pick(order_l, k), ir = pick(order_r, k);
    const double ul = l.states(il, 0), ur = r.states(ir, 0);
    const double d = ul - ur;
    if (!(d > 0.0) || !std::isfinite(d) || !std::isfinite(l.states(il, 1)) || !std::isfinite(r.states(ir, 1)))
      continue;
    points.row(k) = triangulatePair(geometry, ul, ur, 0.5 * (l.states(il, 1) + r.states(ir, 1))).transpose();
    const double w = l.weights.size() == nl && r.weights.size() == nr ? l.weights[il] * r.weights[ir] : 1.0;
    weights[k] = std::isfinite(w) && w > 0.0 ? w : 0.0;
    sum += weights[k];
    ok[static_cast<std::size_t>(k)] = 1;
    ++valid_count;
  }
  if (valid_count == 0)
    return;  // every point at the origin with weight 0
  if (!(sum > 0.0))
  {
    // Valid pairs whose weight products vanished: keep them, equally weighted.
    for (int k = 0; k < n; ++k)
      weights[k] = ok[static_cast<std::size_t>(k)] ? 1.0 : 0.0;
    sum = valid_count;
  }
  weights /= sum;
  // Invalid pairs sit at the weighted mean of the valid ones, with weight 0: no NaN for consumers.
  const Eigen::RowVector3d mean = weights.transpose() * points;
  for (int k = 0; k < n; ++k)
    if (!ok[static_cast<std::size_t>(k)])
      points.row(k) = mean;
}

bool StereoConstraints::seedFromStereo(const StereoGeometry&, int set, ParticleSet& particles, int row,
                                       const Pixel& left, const Pixel& right) const
{
  if (!(left.u - right.u > 0.0))
    return false;
  const Pixel& px = set == 0 ? left : right;
  particles.states(row, 0) = px.u;
  particles.states(row, 1) = px.v;
  return true;
}

}  // namespace stereo_pf

PLUGINLIB_EXPORT_CLASS(stereo_pf::StereoConstraints, stereo_pf::StateModel)
