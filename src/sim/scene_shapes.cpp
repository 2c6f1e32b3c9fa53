// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Boxes and cylinders in synthetic scenes: ray casting, exact silhouette extents, patterns and drawing
// (see scene.h, scene_detail.h).
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "scene_detail.h"

namespace stereo_pf
{
namespace scene_detail
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Range of (A + B cos p + C sin p) / (D + E cos p + F sin p) over p: the image coordinate (before fx and
// cx) of a circle's points, numerator the lateral coordinate, denominator the depth. Setting the
// derivative to zero leaves (AE - BD) sin p + (CD - AF) cos p + (CE - BF) = 0: two angles, the extremes.
void circleRange(double a, double b, double c, double d, double e, double f, double& lo, double& hi)
{
  auto at = [&](double p) { return (a + b * std::cos(p) + c * std::sin(p)) / (d + e * std::cos(p) + f * std::sin(p)); };
  const double p = a * e - b * d, q = c * d - a * f, k = c * e - b * f;
  const double amp = std::hypot(p, q);
  if (amp < 1e-300)
  {
    lo = hi = at(0.0);
    return;
  }
  const double psi = std::atan2(q, p);  // p sin x + q cos x = amp sin(x + psi)
  const double base = std::asin(std::clamp(-k / amp, -1.0, 1.0));
  const double x1 = at(base - psi), x2 = at(kPi - base - psi);
  lo = std::min(x1, x2);
  hi = std::max(x1, x2);
}

// Slab test of a ray (origin o, direction d, both in the box's frame) against the box of half sizes h.
bool rayBoxLocal(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& h, double& t, int& face)
{
  double t_in = -kInf, t_out = kInf;
  face = -1;
  for (int a = 0; a < 3; ++a)
  {
    if (std::abs(d[a]) < 1e-15)
    {
      if (std::abs(o[a]) > h[a])
        return false;
      continue;
    }
    const double t_minus = (-h[a] - o[a]) / d[a], t_plus = (h[a] - o[a]) / d[a];
    // Entering through the -a face when moving towards +a, through the +a face otherwise.
    const double enter = d[a] > 0.0 ? t_minus : t_plus, leave = d[a] > 0.0 ? t_plus : t_minus;
    if (enter > t_in)
    {
      t_in = enter;
      face = d[a] > 0.0 ? 2 * a + 1 : 2 * a;
    }
    t_out = std::min(t_out, leave);
  }
  if (face < 0 || t_in > t_out || t_in <= 1e-9)
    return false;
  t = t_in;
  return true;
}

// A ray against the cylinder x^2 + z^2 <= r^2, |y| <= h in its own frame: the intersection of an infinite
// tube and a slab, both convex, so the entry is the later of the two entries.
bool rayCylinderLocal(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double r, double h, double& t, int& face)
{
  double side_in = -kInf, side_out = kInf;
  const double qa = d.x() * d.x() + d.z() * d.z();
  const double qb = o.x() * d.x() + o.z() * d.z();
  const double qc = o.x() * o.x() + o.z() * o.z() - r * r;
  if (qa < 1e-30)
  {
    if (qc > 0.0)
      return false;
  }
  else
  {
    const double disc = qb * qb - qa * qc;
    if (disc < 0.0)
      return false;
    const double root = std::sqrt(disc);
    side_in = (-qb - root) / qa;
    side_out = (-qb + root) / qa;
  }
  double cap_in = -kInf, cap_out = kInf;
  int cap_face = -1;
  if (std::abs(d.y()) < 1e-15)
  {
    if (std::abs(o.y()) > h)
      return false;
  }
  else
  {
    const double t_minus = (-h - o.y()) / d.y(), t_plus = (h - o.y()) / d.y();
    cap_in = d.y() > 0.0 ? t_minus : t_plus;
    cap_out = d.y() > 0.0 ? t_plus : t_minus;
    cap_face = d.y() > 0.0 ? 2 : 1;
  }
  const double t_in = std::max(side_in, cap_in), t_out = std::min(side_out, cap_out);
  if (!(t_in <= t_out) || !(t_in > 1e-9) || !std::isfinite(t_in))
    return false;
  t = t_in;
  face = side_in >= cap_in ? 0 : cap_face;
  return true;
}

// Checker cell parity of a box face: the first count runs along the face's horizontal edge (x, or z on
// the +-x faces), the second along its other edge (y, or z on the +-y faces).
bool boxChecker(const SceneSphere& s, const SolidHit& hit)
{
  const int axis = hit.face / 2;
  const int first = axis == 0 ? 2 : 0, second = axis == 1 ? 2 : 1;
  auto cell = [&](int k, int count) {
    const double f = (hit.local[k] + s.size[k] / 2) / s.size[k];
    return static_cast<long>(std::floor(std::clamp(f, 0.0, 0.999999) * count));
  };
  return (cell(first, s.checker_longitude) + cell(second, s.checker_latitude)) % 2 == 1;
}

// Checker cell parity of a cylinder: squares around the axis (0 facing the camera when unturned) times
// rows along it; each cap continues the row next to it.
bool cylinderChecker(const SceneSphere& s, const SolidHit& hit)
{
  const double lon = std::atan2(hit.local.x(), -hit.local.z());
  long i = static_cast<long>(std::floor(lon / (2.0 * kPi) * s.checker_longitude));
  long j = 0;
  if (hit.face == 0)
  {
    const double f = (hit.local.y() + s.height / 2) / s.height;
    j = static_cast<long>(std::floor(std::clamp(f, 0.0, 0.999999) * s.checker_latitude));
  }
  else if (hit.face == 1)
    j = s.checker_latitude - 1;
  return ((i + j) % 2 + 2) % 2 == 1;
}

}  // namespace

bool solidRay(const SceneSphere& s, const Eigen::Matrix3d& rot, const Eigen::Vector3d& c_rel,
              const Eigen::Vector3d& dir, SolidHit& hit)
{
  // The camera and the ray in the object's own frame.
  const Eigen::Vector3d o = rot.transpose() * (-c_rel);
  const Eigen::Vector3d d = rot.transpose() * dir;
  double t = 0.0;
  int face = -1;
  Eigen::Vector3d n_local;
  if (s.shape == SceneSphere::Shape::Box)
  {
    if (!rayBoxLocal(o, d, s.size / 2, t, face))
      return false;
    n_local = Eigen::Vector3d::Zero();
    n_local[face / 2] = face % 2 == 0 ? 1.0 : -1.0;
  }
  else if (s.shape == SceneSphere::Shape::Cylinder)
  {
    if (!rayCylinderLocal(o, d, s.radius, s.height / 2, t, face))
      return false;
    const Eigen::Vector3d p = o + t * d;
    n_local = face == 0 ? Eigen::Vector3d(p.x(), 0.0, p.z()) / s.radius :
                          Eigen::Vector3d(0.0, face == 1 ? 1.0 : -1.0, 0.0);
  }
  else
  {
    return false;
  }
  hit.t = t;
  hit.face = face;
  hit.local = o + t * d;
  hit.normal = rot * n_local;
  return true;
}

bool solidExtent(const SceneCamera& cam, const SceneSphere& s, const Eigen::Matrix3d& rot,
                 const Eigen::Vector3d& c_rel, double& u0, double& u1, double& v0, double& v1)
{
  constexpr double kNear = 1e-3;  // as for squares: nothing at or behind the camera plane is rendered
  double xl = kInf, xh = -kInf, yl = kInf, yh = -kInf;  // X/Z and Y/Z ranges
  if (s.shape == SceneSphere::Shape::Box)
  {
    // A convex polyhedron's silhouette is the hull of its projected corners.
    for (int i = 0; i < 8; ++i)
    {
      const Eigen::Vector3d corner(i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5);
      const Eigen::Vector3d p = c_rel + rot * corner.cwiseProduct(s.size);
      if (p.z() <= kNear)
        return false;
      xl = std::min(xl, p.x() / p.z());
      xh = std::max(xh, p.x() / p.z());
      yl = std::min(yl, p.y() / p.z());
      yh = std::max(yh, p.y() / p.z());
    }
  }
  else if (s.shape == SceneSphere::Shape::Cylinder)
  {
    // A cylinder is the convex hull of its two cap circles: its extremes are theirs.
    const Eigen::Vector3d e1 = s.radius * rot.col(0), e2 = s.radius * rot.col(2);
    for (double side : { -0.5, 0.5 })
    {
      const Eigen::Vector3d p = c_rel + side * s.height * rot.col(1);
      if (p.z() - std::hypot(e1.z(), e2.z()) <= kNear)
        return false;
      double lo = 0.0, hi = 0.0;
      circleRange(p.x(), e1.x(), e2.x(), p.z(), e1.z(), e2.z(), lo, hi);
      xl = std::min(xl, lo);
      xh = std::max(xh, hi);
      circleRange(p.y(), e1.y(), e2.y(), p.z(), e1.z(), e2.z(), lo, hi);
      yl = std::min(yl, lo);
      yh = std::max(yh, hi);
    }
  }
  else
  {
    return false;
  }
  u0 = cam.cx + cam.fx * xl;
  u1 = cam.cx + cam.fx * xh;
  v0 = cam.cy + cam.fy * yl;
  v1 = cam.cy + cam.fy * yh;
  return true;
}

double objectScale(const SceneSphere& s)
{
  switch (s.shape)
  {
    case SceneSphere::Shape::Box:
      return s.size.maxCoeff() / 2;
    case SceneSphere::Shape::Cylinder:
      return std::max(s.radius, s.height / 2);
    default:
      return s.radius;
  }
}

TextureField::TextureField(const SceneSphere& s) : colour2_(s.colour2)
{
  // Random directions, spatial frequencies of 5..9 rad per object unit (blotches about a fifth to a third of
  // the object across) and phases, all from the seed only.
  cv::RNG rng(0xD1B54A32D192ED03ULL ^ s.texture_seed);
  for (int i = 0; i < kWaves; ++i)
  {
    Eigen::Vector3d dir(rng.gaussian(1.0), rng.gaussian(1.0), rng.gaussian(1.0));
    if (dir.norm() < 1e-6)
      dir = Eigen::Vector3d::UnitX();
    wave_[i] = dir.normalized() * rng.uniform(5.0, 9.0);
    phase_[i] = rng.uniform(0.0, 2.0 * kPi);
  }
}

double TextureField::weight(const Eigen::Vector3d& q) const
{
  double v = 0.0;
  for (int i = 0; i < kWaves; ++i)
    v += std::sin(wave_[i].dot(q) + phase_[i]);
  v /= std::sqrt(kWaves / 2.0);  // unit variance
  // A soft threshold: blotches with smooth edges, about half the surface each colour.
  const double x = std::clamp((v + 0.35) / 0.7, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

cv::Vec3d TextureField::mix(const cv::Vec3d& base, const Eigen::Vector3d& q) const
{
  const double w = weight(q);
  return (1.0 - w) * base + w * colour2_;
}

cv::Vec3d solidAlbedo(const SceneSphere& s, const TextureField* texture, const SolidHit& hit)
{
  cv::Vec3d albedo = s.colour;
  if (s.shape == SceneSphere::Shape::Box && s.face_colours.size() == 6)
    albedo = s.face_colours[static_cast<size_t>(hit.face)];
  if (s.checkered)
  {
    const bool odd = s.shape == SceneSphere::Shape::Box ? boxChecker(s, hit) : cylinderChecker(s, hit);
    if (odd)
      albedo = s.colour2;
  }
  else if (texture)
  {
    albedo = texture->mix(albedo, hit.local / objectScale(s));
  }
  return albedo;
}

}  // namespace scene_detail

Eigen::Matrix3d SceneSphere::orientation(double t) const
{
  const double n = spin_axis.norm();
  const Eigen::Vector3d axis = n > 0.0 ? Eigen::Vector3d(spin_axis / n) : Eigen::Vector3d::UnitY();
  return Eigen::AngleAxisd(yaw + spin * t, axis).toRotationMatrix();
}

void SceneRenderer::drawSolid(const SceneSphere& s, double t, View view, cv::Mat& img, cv::Mat& depth) const
{
  using scene_detail::SolidHit;
  const SceneCamera& cam = imagingCamera(view);  // the right camera carries the rectification residual
  const Eigen::Vector3d c = s.trajectory.at(t) - cameraOrigin(view);
  const Eigen::Matrix3d rot = s.orientation(t);
  double bu0 = 0.0, bu1 = 0.0, bv0 = 0.0, bv1 = 0.0;
  if (!scene_detail::solidExtent(cam, s, rot, c, bu0, bu1, bv0, bv1))
    return;
  const int u0 = std::max(0, static_cast<int>(std::floor(bu0)) - 1);
  const int u1 = std::min(cam.width - 1, static_cast<int>(std::ceil(bu1)) + 1);
  const int v0 = std::max(0, static_cast<int>(std::floor(bv0)) - 1);
  const int v1 = std::min(cam.height - 1, static_cast<int>(std::ceil(bv1)) + 1);
  if (u0 > u1 || v0 > v1)
    return;
  const int w = u1 - u0 + 1, h = v1 - v0 + 1;

  std::optional<scene_detail::TextureField> texture;
  if (s.textured)
    texture.emplace(s);
  const double ambient = scene_.light.ambient;
  auto cast = [&](double u, double v, SolidHit& hit) {
    const Eigen::Vector3d d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);  // t along it is the depth
    return scene_detail::solidRay(s, rot, c, d, hit);
  };
  auto colour = [&](const SolidHit& hit) {
    const double shade = ambient + (1.0 - ambient) * std::max(0.0, hit.normal.dot(light_));
    return shade * scene_detail::solidAlbedo(s, texture ? &*texture : nullptr, hit);
  };

  // Faces hit through every pixel corner (each shared by four pixels) and centre. A pixel whose five
  // rays all hit one face is inside it; one with no hit and no such neighbour is outside; the rest (the
  // silhouette, creases between faces) are supersampled 4 x 4, which anti-aliases both.
  SolidHit scratch;
  cv::Mat1i corner(h + 1, w + 1);
  for (int r = 0; r <= h; ++r)
    for (int q = 0; q <= w; ++q)
      corner(r, q) = cast(u0 + q - 0.5, v0 + r - 0.5, scratch) ? scratch.face : -1;
  std::vector<SolidHit> centre(static_cast<size_t>(w) * h);
  cv::Mat1b kind(h, w);  // 0 outside, 1 inside one face, 2 to supersample
  for (int r = 0; r < h; ++r)
    for (int q = 0; q < w; ++q)
    {
      SolidHit& hit = centre[static_cast<size_t>(r) * w + q];
      const int f = cast(u0 + q, v0 + r, hit) ? hit.face : -1;
      const bool same =
          corner(r, q) == f && corner(r, q + 1) == f && corner(r + 1, q) == f && corner(r + 1, q + 1) == f;
      kind(r, q) = same ? (f < 0 ? 0 : 1) : 2;
    }
  // A thin corner of the silhouette can poke into a pixel between its five rays: look next to any hit.
  cv::Mat1b near_hit;
  cv::dilate(kind != 0, near_hit, cv::Mat());

  constexpr int kSub = 4;
  for (int r = 0; r < h; ++r)
  {
    const int row = v0 + r;
    cv::Vec3b* px = img.ptr<cv::Vec3b>(row);
    float* dp = depth.ptr<float>(row);
    for (int q = 0; q < w; ++q)
    {
      const int col = u0 + q;
      const SolidHit& mid = centre[static_cast<size_t>(r) * w + q];
      cv::Vec3d value(0, 0, 0);
      double alpha = 0.0, z = mid.face >= 0 ? mid.t : std::numeric_limits<double>::infinity();
      if (kind(r, q) == 1)
      {
        value = colour(mid);
        alpha = 1.0;
      }
      else if (kind(r, q) == 2 || near_hit(r, q))
      {
        int hits = 0;
        for (int i = 0; i < kSub; ++i)
          for (int j = 0; j < kSub; ++j)
          {
            SolidHit sub;
            if (!cast(col + (j + 0.5) / kSub - 0.5, row + (i + 0.5) / kSub - 0.5, sub))
              continue;
            value += colour(sub);
            ++hits;
            if (mid.face < 0)
              z = std::min(z, sub.t);
          }
        if (hits == 0)
          continue;
        value /= hits;
        alpha = static_cast<double>(hits) / (kSub * kSub);
      }
      else
      {
        continue;
      }
      const float zf = static_cast<float>(z);
      if (zf >= dp[col])
        continue;
      for (int ch = 0; ch < 3; ++ch)
        px[col][ch] = cv::saturate_cast<uint8_t>(alpha * value[ch] + (1.0 - alpha) * px[col][ch]);
      if (alpha >= 0.5)
        dp[col] = zf;
    }
  }
}

}  // namespace stereo_pf
