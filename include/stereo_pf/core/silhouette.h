// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The image of a sphere under perspective (shared by the cues that look at the object's outline).
#pragma once

#include <cmath>

namespace stereo_pf
{
/// The middle of a sphere's image is the projection of its centre scaled about the principal point by
/// z^2 / (z^2 - r^2) (z: the centre's depth, r: the radius; this returns that factor, 1 when the sphere reaches
/// the camera's plane). Along either image axis the planes through the optical centre that touch the sphere are
/// at angles a +- b (tan a = c / z, sin b = r / hypot(c, z), c: the centre's coordinate along the axis), and the
/// middle of tan(a - b) .. tan(a + b), tan a (1 + tan^2 b) / (1 - tan^2 a tan^2 b), is (c / z) z^2 / (z^2 - r^2).
/// Off the axis a near sphere's image thus lies farther out (a ball of 6 cm at 0.7 m, 0.3 m off the axis: by
/// 0.3 % of the focal length, less in the view whose axis it is nearer, so that its disparity would read 0.7 %
/// too large from the centres' projections). The 3D state models give the cues that middle; box acquisition
/// takes it out.
inline double sphereImageScale(double z, double r2)
{
  const double z2 = z * z;
  return z2 > r2 ? z2 / (z2 - r2) : 1.0;
}

/// The image of a sphere centred at (u, v) with apparent radius r = f R / z (the 3D state models' convention;
/// (u, v) is the middle of the image, as ImageHypotheses give it) in a pinhole camera of focal length f and
/// principal point (cx, cy): off the optical axis it is an ellipse, elongated away from the principal point (by
/// 1 / cos(theta), ~6 % at 20 deg, theta: the sphere centre's angle off the axis). A circle of radius r would
/// fit it best with a larger radius, i.e. a closer depth. Writes the ellipse's radial unit vector (ex, ey) and
/// semi-axes a (radial) >= b; returns false, writing nothing, when the circle is exact enough (on the axis) or
/// the formula breaks down (the sphere reaching 90 deg off the axis). Along a direction at angle psi to (ex, ey)
/// the outline lies at a b / sqrt(b^2 cos^2 psi + a^2 sin^2 psi) from (u, v).
inline bool sphereSilhouette(float u, float v, float r, float f, float cx, float cy, float& ex, float& ey, float& a,
                             float& b)
{
  const float dx = u - cx, dy = v - cy;
  const float rho = std::sqrt(dx * dx + dy * dy);
  if (!(rho > 1e-3f * f))
    return false;
  // The silhouette cone spans theta - alpha .. theta + alpha radially (alpha: the angular radius), and the
  // middle of the image lies at m = tan t (1 + tan^2 alpha) / (1 - tan^2 t tan^2 alpha) (t: theta), slightly
  // beyond the centre's projection: solve that for tan t, alpha first taken at the middle's angle (it changes
  // by a fraction of a percent). The fixed point is tan t = m (1 - (r / f)^2) (sphereImageScale()); that closed
  // form is cheaper, but differs in the last bits and, through the filter's sensitivity to such differences,
  // failed Tracking.ABallThrownAtTheCameraIsFollowedByTheLocalSearch (worst error 5.8 % of range for 1.7 %).
  const float m = rho / f;
  float t = m, cos_t = 1.0f, sin_a = 0.0f, tan_a = 0.0f;
  for (int it = 0; it < 2; ++it)
  {
    cos_t = 1.0f / std::sqrt(1.0f + t * t);
    sin_a = r * cos_t / f;  // sin(alpha) = R / distance
    if (!(sin_a < 0.9f))
      return false;
    tan_a = sin_a / std::sqrt(1.0f - sin_a * sin_a);
    const float s = tan_a * tan_a;
    t = 2.0f * m / ((1.0f + s) + std::sqrt((1.0f + s) * (1.0f + s) + 4.0f * m * m * s));
  }
  cos_t = 1.0f / std::sqrt(1.0f + t * t);
  sin_a = r * cos_t / f;
  tan_a = sin_a / std::sqrt(1.0f - sin_a * sin_a);
  const float den = 1.0f - t * tan_a;
  if (!(den > 0.05f))
    return false;
  // Its perpendicular half-width is f sin(alpha) / sqrt(cos^2 theta - sin^2 alpha).
  const float t_far = (t + tan_a) / den, t_near = (t - tan_a) / (1.0f + t * tan_a);
  const float perpendicular2 = cos_t * cos_t - sin_a * sin_a;
  if (!(perpendicular2 > 0.0f))
    return false;
  ex = dx / rho;
  ey = dy / rho;
  a = 0.5f * f * (t_far - t_near);
  b = f * sin_a / std::sqrt(perpendicular2);
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
