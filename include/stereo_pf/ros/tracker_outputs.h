// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Building the tracker's output messages from engine results: the estimate (point, pose, TF), the
// particle cloud with a weight field, and the rviz markers (estimate sphere, covariance ellipsoid,
// recent trajectory). Message construction only; publishing stays in the nodelet.
#pragma once

#include <array>
#include <deque>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <geometry_msgs/PointStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "stereo_pf/core/engine.h"

namespace stereo_pf
{
/// The estimate as a point.
geometry_msgs::PointStamped toPointStamped(const std_msgs::Header& header, const StateEstimate& estimate);

/// The estimate as a pose with covariance: position covariance from the particles; the orientation is not
/// estimated (identity, variances 1e6 rad^2).
geometry_msgs::PoseWithCovarianceStamped toPose(const std_msgs::Header& header, const StateEstimate& estimate);

/// The TF transform header.frame_id -> child_frame at the estimate.
geometry_msgs::TransformStamped toTransform(const std_msgs::Header& header, const std::string& child_frame,
                                            const StateEstimate& estimate);

/// Merge particles at identical positions (the copies made by resampling), summing their weights, so the
/// weight of each distinct point is the fraction of the set there: after resampling this is the weight
/// the particle had before it was copied. Points that are not finite are dropped.
void mergeDuplicates(const Eigen::MatrixX3d& points, const Eigen::VectorXd& weights, std::vector<Eigen::Vector3f>& out_points,
                     std::vector<float>& out_weights);

/// A PointCloud2 with float32 fields x, y, z, weight (unordered, height 1).
void toCloud(const std_msgs::Header& header, const std::vector<Eigen::Vector3f>& points,
             const std::vector<float>& weights, sensor_msgs::PointCloud2& cloud);

/// Marker settings (read once at start-up).
struct MarkerOptions
{
  double radius = 0.035;        ///< radius of the estimate sphere, m
  double sigma_scale = 2.0;     ///< the covariance ellipsoid spans this many standard deviations
  int trajectory_length = 90;   ///< estimates kept in the trajectory line
};

/// The recent estimates (fixed length).
class EstimateTrail
{
public:
  /// Keep the last `length` estimates; a gap of more than `max_gap` seconds starts a new line.
  explicit EstimateTrail(int length = 90, double max_gap = 1.0) : length_(length), max_gap_(max_gap) {}
  /// Append a point (the oldest goes when the trail is full).
  void add(const Eigen::Vector3d& p);
  /// Append the estimate of the frame stamped `stamp` (seconds) while the target is tracked. The line starts
  /// afresh when the time goes backwards or stands still (a bag or a scene played again), after more than
  /// max_gap seconds without an estimate, and whenever the target is not tracked (the estimate then follows
  /// the search, not the object, and a re-acquired object may be far from where it was lost).
  void update(double stamp, const Eigen::Vector3d& p, bool tracking);
  /// Forget every point.
  void clear() { points_.clear(); }
  /// The points, oldest first.
  const std::deque<Eigen::Vector3d>& points() const { return points_; }

private:
  int length_;
  double max_gap_;
  double last_stamp_ = 0.0;
  std::deque<Eigen::Vector3d> points_;
};

/// Markers in namespaces "estimate" (sphere coloured by track state: green tracking, orange searching,
/// red lost), "covariance" (ellipsoid), "trajectory" (line strip) and "state" (text). When the estimate
/// is invalid the estimate markers are deleted. With `points` and `weights` (mergeDuplicates' output) also
/// "particles": one point each, coloured by weight relative to the heaviest (weightColour); in one message
/// with the estimate, rviz draws them for the same frame (a separate cloud display lags a frame or two behind).
visualization_msgs::MarkerArray toMarkers(const std_msgs::Header& header, const FrameResult& result,
                                          const EstimateTrail& trajectory, const MarkerOptions& options,
                                          const std::vector<Eigen::Vector3f>* points = nullptr,
                                          const std::vector<float>* weights = nullptr);

/// The colour of a particle of relative weight t in [0, 1] (weight / heaviest weight): blue (light) -> green
/// -> red (heavy), as red, green, blue in [0, 1]. The debug images and the markers use it.
std::array<float, 3> weightColour(double t);

/// The track state of one frame in words (~status message, diagnostics summary), saying what to do when
/// something is wrong: a target the background explains as well (learn it again), an estimate that left what
/// the cameras see, evidence too low for too long.
std::string describeTrack(const FrameResult& result, const EngineConfig& config, const ViewingVolume& volume);

/// Eigen decomposition of a covariance into the scale (full axis lengths for `sigma_scale` standard
/// deviations) and orientation (quaternion x, y, z, w) of its ellipsoid; right-handed, finite.
void covarianceEllipsoid(const Eigen::Matrix3d& covariance, double sigma_scale, Eigen::Vector3d& scale,
                         Eigen::Vector4d& quaternion_xyzw);

}  // namespace stereo_pf
