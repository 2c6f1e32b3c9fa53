// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The ballistic and random-walk trajectories of synthetic scenes (see scene.h, scene_detail.h). Both are
// closed forms of t, so frame k never depends on which frames were rendered before.
#include <cmath>
#include <sstream>

#include "scene_detail.h"

namespace stereo_pf
{
namespace scene_detail
{
namespace
{
constexpr double kTwoPi = 6.28318530717958647692;

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

std::string text(const Eigen::Vector3d& v)
{
  std::ostringstream s;
  s << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

// Smallest s > 0 with y + vy s + g s^2 / 2 = floor, or +inf when the centre never gets there.
double timeToFloor(double y, double vy, double g, double floor)
{
  const double d = floor - y;  // >= 0: still on the free side
  const double inf = std::numeric_limits<double>::infinity();
  if (std::abs(g) < 1e-12)
    return vy > 0.0 ? d / vy : inf;
  const double disc = vy * vy + 2.0 * g * d;
  if (disc < 0.0)
    return inf;
  const double root = std::sqrt(disc);
  double best = inf;
  for (double s : { (-vy - root) / g, (-vy + root) / g })
    if (s > 1e-12 && s < best)
      best = s;
  return best;
}

// Terms of the random walk: per axis, a few sinusoids of different frequencies.
constexpr int kTerms = 3;
// Frequency ratios kept apart so that the cross terms of one axis average out quickly (the RMS speed is
// then close to its long-run value after a few periods); jittered per axis and seed.
constexpr double kRatios[kTerms] = { 0.6, 1.0, 1.55 };

struct WalkTerms
{
  double amplitude[3][kTerms];
  double omega[3][kTerms];
  double phase[3][kTerms];
};

// Amplitudes fill the extent exactly (sum of |amplitude| = extent per axis, so the centre can never leave
// it); the common frequency scale is then chosen so that the long-run RMS speed, sqrt(sum (A w)^2 / 2),
// is `speed`.
WalkTerms walkTerms(const Trajectory& tr)
{
  WalkTerms w;
  cv::RNG rng(0x9E3779B97F4A7C15ULL ^ tr.seed);
  double power = 0.0;
  for (int a = 0; a < 3; ++a)
  {
    double weights[kTerms], sum = 0.0;
    for (int j = 0; j < kTerms; ++j)
    {
      weights[j] = rng.uniform(0.5, 1.0);
      sum += weights[j];
      w.omega[a][j] = kRatios[j] * rng.uniform(0.9, 1.1);
      w.phase[a][j] = rng.uniform(0.0, kTwoPi);
    }
    for (int j = 0; j < kTerms; ++j)
    {
      w.amplitude[a][j] = tr.extent[a] * weights[j] / sum;
      power += 0.5 * std::pow(w.amplitude[a][j] * w.omega[a][j], 2);
    }
  }
  const double scale = power > 0.0 ? tr.speed / std::sqrt(power) : 0.0;
  for (int a = 0; a < 3; ++a)
    for (int j = 0; j < kTerms; ++j)
      w.omega[a][j] *= scale;
  return w;
}

}  // namespace

Eigen::Vector3d ballisticAt(const Trajectory& tr, double t)
{
  const double tau = std::max(0.0, t - tr.t0);
  // Free flight on every axis; the floor only changes the vertical (y) motion.
  Eigen::Vector3d p = tr.position + tau * tr.velocity + 0.5 * tau * tau * tr.gravity;
  if (!tr.has_floor)
    return p;
  double y = tr.position.y(), vy = tr.velocity.y(), left = tau;
  const double g = tr.gravity.y();
  // Flight by flight: each bounce keeps `restitution` of the vertical speed. A ball that loses it all
  // (or bounces ever shorter) comes to rest on the floor.
  for (int bounce = 0; bounce < 10000; ++bounce)
  {
    const double s = timeToFloor(y, vy, g, tr.floor_y);
    if (left < s)
    {
      p.y() = std::min(tr.floor_y, y + vy * left + 0.5 * g * left * left);
      return p;
    }
    left -= s;
    vy = -tr.restitution * (vy + g * s);
    y = tr.floor_y;
    if (std::abs(vy) < 1e-6)
      break;
    if (tr.restitution == 1.0)
    {
      // Lossless: every later flight is the same, so skip whole ones (the loop would run out otherwise).
      const double period = timeToFloor(y, vy, g, tr.floor_y);
      if (std::isfinite(period))
        left = std::fmod(left, period);
    }
  }
  p.y() = tr.floor_y;
  return p;
}

Eigen::Vector3d randomWalkAt(const Trajectory& tr, double t)
{
  const WalkTerms w = walkTerms(tr);
  Eigen::Vector3d p = tr.position;
  for (int a = 0; a < 3; ++a)
    for (int j = 0; j < kTerms; ++j)
      p[a] += w.amplitude[a][j] * std::sin(w.omega[a][j] * t + w.phase[a][j]);
  return p;
}

std::string validateBallistic(const Trajectory& tr)
{
  if (!finite(tr.position) || !finite(tr.velocity) || !finite(tr.gravity) || !std::isfinite(tr.t0))
    return "ballistic start, velocity, gravity and t0 must be finite";
  if (!tr.has_floor)
    return "";
  if (!std::isfinite(tr.floor_y))
    return "ballistic floor_y must be finite";
  if (!(tr.restitution >= 0.0 && tr.restitution <= 1.0))
    return "ballistic restitution must be in [0, 1]";
  if (tr.position.y() > tr.floor_y)
  {
    std::ostringstream s;
    s << "ballistic start " << text(tr.position) << " is below the floor (y is down: start y must be <= floor_y "
      << tr.floor_y << ")";
    return s.str();
  }
  return "";
}

std::string validateRandomWalk(const Trajectory& tr)
{
  if (!finite(tr.position))
    return "random_walk centre must be finite";
  if (!finite(tr.extent) || (tr.extent.array() < 0.0).any() || !(tr.extent.maxCoeff() > 0.0))
    return "random_walk extent must be >= 0 on every axis and > 0 on at least one, got " + text(tr.extent);
  if (!(tr.speed > 0.0) || !std::isfinite(tr.speed))
    return "random_walk speed must be > 0";
  return "";
}

}  // namespace scene_detail

Trajectory Trajectory::ballistic(const Eigen::Vector3d& start, const Eigen::Vector3d& velocity,
                                 const Eigen::Vector3d& gravity, double t0)
{
  Trajectory t;
  t.type = Type::Ballistic;
  t.position = start;
  t.velocity = velocity;
  t.gravity = gravity;
  t.t0 = t0;
  return t;
}

Trajectory Trajectory::randomWalk(const Eigen::Vector3d& centre, const Eigen::Vector3d& extent, double speed,
                                  uint64_t seed)
{
  Trajectory t;
  t.type = Type::RandomWalk;
  t.position = centre;
  t.extent = extent;
  t.speed = speed;
  t.seed = seed;
  return t;
}

}  // namespace stereo_pf
