// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/ros/tracker_outputs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <sensor_msgs/point_cloud2_iterator.h>

namespace stereo_pf
{
geometry_msgs::PointStamped toPointStamped(const std_msgs::Header& header, const StateEstimate& estimate)
{
  geometry_msgs::PointStamped p;
  p.header = header;
  p.point.x = estimate.position.x();
  p.point.y = estimate.position.y();
  p.point.z = estimate.position.z();
  return p;
}

geometry_msgs::PoseWithCovarianceStamped toPose(const std_msgs::Header& header, const StateEstimate& estimate)
{
  geometry_msgs::PoseWithCovarianceStamped pose;
  pose.header = header;
  pose.pose.pose.position.x = estimate.position.x();
  pose.pose.pose.position.y = estimate.position.y();
  pose.pose.pose.position.z = estimate.position.z();
  pose.pose.pose.orientation.w = 1.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      pose.pose.covariance[r * 6 + c] = estimate.covariance(r, c);
  for (int k = 3; k < 6; ++k)
    pose.pose.covariance[k * 6 + k] = 1e6;  // orientation is not estimated
  return pose;
}

geometry_msgs::TransformStamped toTransform(const std_msgs::Header& header, const std::string& child_frame,
                                            const StateEstimate& estimate)
{
  geometry_msgs::TransformStamped t;
  t.header = header;
  t.child_frame_id = child_frame;
  t.transform.translation.x = estimate.position.x();
  t.transform.translation.y = estimate.position.y();
  t.transform.translation.z = estimate.position.z();
  t.transform.rotation.w = 1.0;
  return t;
}

void mergeDuplicates(const Eigen::MatrixX3d& points, const Eigen::VectorXd& weights,
                     std::vector<Eigen::Vector3f>& out_points, std::vector<float>& out_weights)
{
  out_points.clear();
  out_weights.clear();
  // Resampled copies are bit-identical, so exact comparison is what we want here.
  std::map<std::tuple<double, double, double>, size_t> index;
  for (Eigen::Index i = 0; i < points.rows(); ++i)
  {
    const double x = points(i, 0), y = points(i, 1), z = points(i, 2);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
      continue;
    const double w = i < weights.size() && std::isfinite(weights[i]) ? weights[i] : 0.0;
    const auto [it, fresh] = index.emplace(std::make_tuple(x, y, z), out_points.size());
    if (fresh)
    {
      out_points.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      out_weights.push_back(static_cast<float>(w));
    }
    else
      out_weights[it->second] += static_cast<float>(w);
  }
}

void toCloud(const std_msgs::Header& header, const std::vector<Eigen::Vector3f>& points,
             const std::vector<float>& weights, sensor_msgs::PointCloud2& cloud)
{
  cloud.header = header;
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2Fields(4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                                "z", 1, sensor_msgs::PointField::FLOAT32, "weight", 1,
                                sensor_msgs::PointField::FLOAT32);
  modifier.resize(points.size());
  cloud.height = 1;
  cloud.width = static_cast<uint32_t>(points.size());
  cloud.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"), w(cloud, "weight");
  for (size_t i = 0; i < points.size(); ++i, ++x, ++y, ++z, ++w)
  {
    *x = points[i].x();
    *y = points[i].y();
    *z = points[i].z();
    *w = weights[i];
  }
}

void EstimateTrail::add(const Eigen::Vector3d& p)
{
  points_.push_back(p);
  while (static_cast<int>(points_.size()) > length_)
    points_.pop_front();
}

void EstimateTrail::update(double stamp, const Eigen::Vector3d& p, bool tracking)
{
  const bool continues = !points_.empty() && stamp > last_stamp_ && stamp - last_stamp_ <= max_gap_;
  last_stamp_ = stamp;
  if (!continues || !tracking)
    points_.clear();
  if (tracking)
    add(p);
}

void covarianceEllipsoid(const Eigen::Matrix3d& covariance, double sigma_scale, Eigen::Vector3d& scale,
                         Eigen::Vector4d& quaternion_xyzw)
{
  const Eigen::Matrix3d sym = 0.5 * (covariance + covariance.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(sym);
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d variances = sym.diagonal();
  if (solver.info() == Eigen::Success && sym.allFinite())
  {
    axes = solver.eigenvectors();
    variances = solver.eigenvalues();
    if (axes.determinant() < 0.0)
      axes.col(2) = -axes.col(2);  // a rotation, not a reflection
  }
  for (int k = 0; k < 3; ++k)
  {
    const double v = std::isfinite(variances[k]) ? std::max(variances[k], 0.0) : 0.0;
    scale[k] = std::max(2.0 * sigma_scale * std::sqrt(v), 1e-4);  // rviz drops zero-size markers
  }
  const Eigen::Quaterniond q(axes);
  quaternion_xyzw = Eigen::Vector4d(q.x(), q.y(), q.z(), q.w());
}

namespace
{
std_msgs::ColorRGBA colour(float r, float g, float b, float a)
{
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

visualization_msgs::Marker base(const std_msgs::Header& header, const std::string& ns, int type)
{
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = ns;
  m.id = 0;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  return m;
}
}  // namespace

std::array<float, 3> weightColour(double t)
{
  t = std::clamp(t, 0.0, 1.0);
  return { static_cast<float>(std::clamp(2.0 * t - 0.5, 0.0, 1.0)), static_cast<float>(1.0 - std::fabs(2.0 * t - 1.0)),
           static_cast<float>(std::clamp(1.5 - 2.0 * t, 0.0, 1.0)) };
}

visualization_msgs::MarkerArray toMarkers(const std_msgs::Header& header, const FrameResult& result,
                                          const EstimateTrail& trail, const MarkerOptions& options,
                                          const std::vector<Eigen::Vector3f>* points, const std::vector<float>* weights)
{
  visualization_msgs::MarkerArray array;
  const StateEstimate& e = result.estimate;
  if (!e.valid)
  {
    for (const char* ns : { "estimate", "covariance", "state" })
    {
      visualization_msgs::Marker m = base(header, ns, visualization_msgs::Marker::SPHERE);
      m.action = visualization_msgs::Marker::DELETE;
      array.markers.push_back(m);
    }
  }
  else
  {
    const std_msgs::ColorRGBA state_colour = result.state == TrackState::Tracking ? colour(0.1f, 0.9f, 0.2f, 0.3f) :
                                             result.state == TrackState::Lost     ? colour(0.9f, 0.1f, 0.1f, 0.3f) :
                                                                                    colour(1.0f, 0.6f, 0.0f, 0.3f);
    visualization_msgs::Marker sphere = base(header, "estimate", visualization_msgs::Marker::SPHERE);
    sphere.pose.position.x = e.position.x();
    sphere.pose.position.y = e.position.y();
    sphere.pose.position.z = e.position.z();
    sphere.scale.x = sphere.scale.y = sphere.scale.z = 2.0 * options.radius;
    sphere.color = state_colour;
    array.markers.push_back(sphere);

    visualization_msgs::Marker ellipsoid = base(header, "covariance", visualization_msgs::Marker::SPHERE);
    ellipsoid.pose.position = sphere.pose.position;
    Eigen::Vector3d scale;
    Eigen::Vector4d q;
    covarianceEllipsoid(e.covariance, options.sigma_scale, scale, q);
    ellipsoid.scale.x = scale.x();
    ellipsoid.scale.y = scale.y();
    ellipsoid.scale.z = scale.z();
    ellipsoid.pose.orientation.x = q[0];
    ellipsoid.pose.orientation.y = q[1];
    ellipsoid.pose.orientation.z = q[2];
    ellipsoid.pose.orientation.w = q[3];
    ellipsoid.color = colour(0.3f, 0.5f, 1.0f, 0.25f);
    array.markers.push_back(ellipsoid);

    visualization_msgs::Marker text = base(header, "state", visualization_msgs::Marker::TEXT_VIEW_FACING);
    text.pose.position = sphere.pose.position;
    text.pose.position.y -= 2.5 * options.radius;  // above the ball (y points down)
    text.scale.z = 0.04;
    text.color = state_colour;
    text.color.a = 1.0f;
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%s  z=%.2f m", toString(result.state).c_str(), e.position.z());
    text.text = buf;
    array.markers.push_back(text);
  }

  visualization_msgs::Marker line = base(header, "trajectory", visualization_msgs::Marker::LINE_STRIP);
  line.scale.x = 0.005;
  line.color = colour(1.0f, 1.0f, 0.2f, 0.8f);
  for (const auto& p : trail.points())
  {
    geometry_msgs::Point gp;
    gp.x = p.x();
    gp.y = p.y();
    gp.z = p.z();
    line.points.push_back(gp);
  }
  if (line.points.size() < 2)
    line.action = visualization_msgs::Marker::DELETE;  // a line strip needs two points
  array.markers.push_back(line);

  if (points && weights && points->size() == weights->size())
  {
    visualization_msgs::Marker cloud = base(header, "particles", visualization_msgs::Marker::POINTS);
    cloud.scale.x = cloud.scale.y = 0.004;
    const float heaviest = weights->empty() ? 1.0f : std::max(*std::max_element(weights->begin(), weights->end()), 1e-12f);
    cloud.points.resize(points->size());
    cloud.colors.resize(points->size());
    for (size_t i = 0; i < points->size(); ++i)
    {
      cloud.points[i].x = (*points)[i].x();
      cloud.points[i].y = (*points)[i].y();
      cloud.points[i].z = (*points)[i].z();
      const std::array<float, 3> c = weightColour((*weights)[i] / heaviest);
      cloud.colors[i] = colour(c[0], c[1], c[2], 1.0f);
    }
    if (cloud.points.empty())
      cloud.action = visualization_msgs::Marker::DELETE;
    array.markers.push_back(cloud);
  }
  return array;
}

std::string describeTrack(const FrameResult& r, const EngineConfig& c, const ViewingVolume& volume)
{
  char buf[600];
  const char* state = r.state == TrackState::Tracking ? "tracking" : r.state == TrackState::Lost ? "target lost" :
                                                                                                    "searching";
  switch (r.support)
  {
    case Support::OutsideView:
      std::snprintf(buf, sizeof(buf),
                    "target lost: the estimate left what the cameras can see (%s); searching the whole view again",
                    volume.describe().c_str());
      break;
    case Support::LikeBackground:
      std::snprintf(buf, sizeof(buf),
                    "%s: the target's appearance is found beside it too (evidence %.2f, background %.2f, needed "
                    "margin %.2f): if this lasts, the learned target is mostly background; learn it again with "
                    "~set_target on a frame where the box holds the object only%s",
                    state, r.evidence, r.background, c.background_margin,
                    r.state == TrackState::Tracking ? " (no estimate this frame)" : "");
      break;
    case Support::LowEvidence:
      std::snprintf(buf, sizeof(buf), "%s: the target is not seen (evidence %.2f < lost_similarity %.2f)%s", state,
                    r.evidence, c.lost_similarity,
                    r.state != TrackState::Tracking ?
                        "; searching (occluded, out of view, or the lighting changed?)" :
                        r.faint ? "; seen faintly (at least engine/estimate_similarity): the estimate is given, and the "
                                  "track is kept over up to engine/lost_frames such frames" :
                                  "; no estimate this frame (the track is kept over up to engine/lost_frames such frames)");
      break;
    case Support::Seen:
    case Support::Unsure:
      if (r.state == TrackState::Tracking)
        std::snprintf(buf, sizeof(buf), "tracking for %d frames (evidence %.2f, background %.2f)", r.state_frames,
                      r.evidence, r.background);
      else
        std::snprintf(buf, sizeof(buf), "%s: the target may be in view (evidence %.2f, background %.2f)", state,
                      r.evidence, r.background);
      break;
  }
  return buf;
}

}  // namespace stereo_pf
