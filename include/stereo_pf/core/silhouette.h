// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The image of a sphere under perspective (shared by the cues that look at the object's outline).
#pragma once

#include <cmath>

namespace stereo_pf
{
/// The image of a sphere whose centre projects to (u, v) with apparent radius r = f R / z (the 3D state
/// models' convention) in a pinhole camera of focal length f and principal point (cx, cy): off the optical
/// axis it is an ellipse, elongated away from the principal point (by 1 / cos(theta), ~6 % at 20 deg) and
/// centred slightly further out. A circle of radius r would fit it best with a larger radius, i.e. a closer
/// depth. Writes the ellipse's centre (cu, cv), radial unit vector (ex, ey) and semi-axes a (radial) >= b;
/// returns false, writing nothing, when the circle is exact enough (on the axis) or the formula breaks down
/// (the sphere reaching 90 deg off the axis). Along a direction at angle psi to (ex, ey) the outline lies at
/// a b / sqrt(b^2 cos^2 psi + a^2 sin^2 psi) from (cu, cv).
inline bool sphereSilhouette(float u, float v, float r, float f, float cx, float cy, float& cu, float& cv, float& ex,
                             float& ey, float& a, float& b)
{
  const float dx = u - cx, dy = v - cy;
  const float rho = std::sqrt(dx * dx + dy * dy);
  if (!(rho > 1e-3f * f))
    return false;
  const float t = rho / f;                               // tan(theta), theta: centre's angle off the axis
  const float cos_t = 1.0f / std::sqrt(1.0f + t * t);
  const float sin_a = r * cos_t / f;                     // sin(alpha) = R / distance: angular radius
  if (!(sin_a < 0.9f))
    return false;
  const float tan_a = sin_a / std::sqrt(1.0f - sin_a * sin_a);
  const float den = 1.0f - t * tan_a;
  if (!(den > 0.05f))
    return false;
  // The silhouette cone spans theta - alpha .. theta + alpha radially; its perpendicular half-width is
  // f sin(alpha) / sqrt(cos^2 theta - sin^2 alpha).
  const float t_far = (t + tan_a) / den, t_near = (t - tan_a) / (1.0f + t * tan_a);
  const float perpendicular2 = cos_t * cos_t - sin_a * sin_a;
  if (!(perpendicular2 > 0.0f))
    return false;
  ex = dx / rho;
  ey = dy / rho;
  const float centre = 0.5f * f * (t_far + t_near);
  a = 0.5f * f * (t_far - t_near);
  b = f * sin_a / std::sqrt(perpendicular2);
  cu = cx + ex * centre;
  cv = cy + ey * centre;
  return true;
}

/// Pixel offset (dx, dy) of step `step` along a digital line from a pixel in direction (c, s) (a unit
/// vector): one pixel per step along the dominant axis, the other coordinate rounded, so every step is a
/// distinct pixel and the pattern is the same from any start pixel. Its exact position along the line is
/// dx c + dy s.
inline void digitalLineStep(double c, double s, int step, int& dx, int& dy)
{
  if (std::abs(c) >= std::abs(s))
  {
    dx = c > 0 ? step : -step;
    dy = static_cast<int>(std::lround(step * s / std::abs(c)));
  }
  else
  {
    dy = s > 0 ? step : -step;
    dx = static_cast<int>(std::lround(step * c / std::abs(s)));
  }
}

}  // namespace stereo_pf
