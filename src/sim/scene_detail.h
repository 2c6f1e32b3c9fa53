// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Private helpers of the scene renderer (not installed): ray casting and silhouettes of boxes and
// cylinders, the texture pattern (scene_shapes.cpp), and the ballistic and random-walk trajectories
// (trajectory.cpp). scene.cpp dispatches to them; they know nothing of YAML.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/sim/scene.h"

namespace stereo_pf
{
namespace scene_detail
{
/// SplitMix64 finaliser: turns seeds (scene, frame, view, stream) into well-spread, platform-independent RNG
/// states; the renderer and the sensor model both derive theirs with it.
inline uint64_t mix64(uint64_t x)
{
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// Where a ray first meets a box or a cylinder.
struct SolidHit
{
  double t = std::numeric_limits<double>::infinity();  ///< ray parameter (the depth when dir.z() == 1)
  int face = -1;  ///< box: 0..5 = +x, -x, +y, -y, +z, -z; cylinder: 0 the side, 1 the +y cap, 2 the -y cap
  Eigen::Vector3d local = Eigen::Vector3d::Zero();   ///< hit point in the object's own frame, metres
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< outward unit normal in the camera frame
};

/// First hit of the ray t * dir (t > 0, from the camera) with box or cylinder `s` whose centre is at
/// `c_rel` relative to that camera and whose orientation is `rot`. False when the ray misses, or when the
/// camera is inside the object (such objects are not rendered).
bool solidRay(const SceneSphere& s, const Eigen::Matrix3d& rot, const Eigen::Vector3d& c_rel,
              const Eigen::Vector3d& dir, SolidHit& hit);

/// Exact image extent [u0, u1] x [v0, v1] (continuous pixel coordinates) of a box's or cylinder's
/// silhouette. False when part of the object is at or behind the camera plane (then it is not rendered).
bool solidExtent(const SceneCamera& cam, const SceneSphere& s, const Eigen::Matrix3d& rot,
                 const Eigen::Vector3d& c_rel, double& u0, double& u1, double& v0, double& v1);

/// Length that makes an object's own coordinates about unit size (the texture is laid out in these units).
double objectScale(const SceneSphere& s);

/// The `texture` pattern: a seeded sum of a few plane waves in the object's own (scaled) coordinates,
/// thresholded softly into blotches. A solid texture, so every shape gets it without a surface map, and it
/// turns with the object.
class TextureField
{
public:
  /// The field of object `s` (texture_seed, colour2).
  explicit TextureField(const SceneSphere& s);
  /// Weight [0, 1] of colour2 at q (object frame divided by objectScale()).
  double weight(const Eigen::Vector3d& q) const;
  /// `base` with colour2 blended in by weight(q).
  cv::Vec3d mix(const cv::Vec3d& base, const Eigen::Vector3d& q) const;

private:
  static constexpr int kWaves = 8;
  Eigen::Vector3d wave_[kWaves];  ///< direction times spatial frequency
  double phase_[kWaves];          ///< phase of each wave, radians
  cv::Vec3d colour2_;             ///< BGR of the blotches
};

/// Albedo (BGR) at a box or cylinder hit: face colour, then the checker or texture pattern.
cv::Vec3d solidAlbedo(const SceneSphere& s, const TextureField* texture, const SolidHit& hit);

/// Ballistic position at time t (tr.type == Ballistic).
Eigen::Vector3d ballisticAt(const Trajectory& tr, double t);
/// Random-walk position at time t (tr.type == RandomWalk).
Eigen::Vector3d randomWalkAt(const Trajectory& tr, double t);
/// Empty when a ballistic trajectory is usable, otherwise what is wrong.
std::string validateBallistic(const Trajectory& tr);
/// Empty when a random-walk trajectory is usable, otherwise what is wrong.
std::string validateRandomWalk(const Trajectory& tr);

}  // namespace scene_detail
}  // namespace stereo_pf
