#include "stereo_pf/plugins/point_model_3d.h"

#include <cmath>

namespace stereo_pf
{
void PointModel3D::readCommonParameters()
{
  const Parameters& p = params();
  noise_ = p.getDouble("noise", 0.04, 0.0, 10.0);
  z_min_ = p.getDouble("z_min", 0.3, 0.01, 1000.0);
  z_max_ = p.getDouble("z_max", 3.0, 0.01, 1000.0);
  if (z_max_ <= z_min_)
    throw ParameterError("parameter '" + p.prefix() + "/z_max' (" + std::to_string(z_max_) + ") must exceed z_min (" +
                         std::to_string(z_min_) + ")");
  init_depth_ = p.getString("init_depth", "volume", { "volume", "depth", "disparity" });
  object_radius_ = p.getDouble("object_radius", 0.035, 0.001, 10.0);
}

std::vector<View> PointModel3D::views(int) const
{
  return { View::Left, View::Right };
}

void PointModel3D::samplePrior(const StereoGeometry& g, int, ParticleSet& particles, int begin, int end,
                               Rng& rng) const
{
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double zmin3 = z_min_ * z_min_ * z_min_, zmax3 = z_max_ * z_max_ * z_max_;
  const double dmin = g.disparity(z_max_), dmax = g.disparity(z_min_);
  for (int i = begin; i < end; ++i)
  {
    Eigen::Vector3d p;
    // Rejection sampling: draw over the left frustum, keep points the right camera sees too.
    for (int attempt = 0; attempt < 1000; ++attempt)
    {
      const Pixel px{ unit(rng) * g.width() - 0.5, unit(rng) * g.height() - 0.5 };
      double z;
      if (init_depth_ == "volume")  // density grows with z^2 in a frustum
        z = std::cbrt(zmin3 + unit(rng) * (zmax3 - zmin3));
      else if (init_depth_ == "depth")
        z = z_min_ + unit(rng) * (z_max_ - z_min_);
      else
        z = g.depth(dmin + unit(rng) * (dmax - dmin));
      p = g.backProject(px, z);
      if (g.inImage(g.projectRight(p)))
        break;
    }
    particles.states.row(i).setZero();
    particles.states.row(i).head<3>() = p.transpose();
  }
}

bool PointModel3D::seedFromStereo(const StereoGeometry& g, int, ParticleSet& particles, int row, const Pixel& left,
                                  const Pixel& right) const
{
  Eigen::Vector3d p;
  if (!g.triangulate(left, right.u, p) || p.z() < z_min_ || p.z() > z_max_)
    return false;
  particles.states.row(row).head<3>() = p.transpose();
  return true;
}

void PointModel3D::project(const StereoGeometry& g, int, const ParticleSet& particles, ImageHypotheses& hyp) const
{
  const int n = particles.size();
  hyp.resize(n);
  const double* xs = particles.states.col(0).data();
  const double* ys = particles.states.col(1).data();
  const double* zs = particles.states.col(2).data();
  const double shift = hyp.view == View::Right ? g.fx() * g.baseline() : 0.0;
  for (int i = 0; i < n; ++i)
  {
    const double z = zs[i];
    if (!(z > 1e-3))
    {
      hyp.u[i] = hyp.v[i] = hyp.radius[i] = 0.0f;
      hyp.valid[i] = 0;
      continue;
    }
    const double inv_z = 1.0 / z;
    const double u = (g.fx() * xs[i] - shift) * inv_z + g.cx();
    const double v = g.fy() * ys[i] * inv_z + g.cy();
    hyp.u[i] = static_cast<float>(u);
    hyp.v[i] = static_cast<float>(v);
    hyp.radius[i] = static_cast<float>(g.fx() * object_radius_ * inv_z);
    hyp.valid[i] = g.inImage({ u, v }) ? 1 : 0;
  }
}

StateEstimate PointModel3D::estimate(const StereoGeometry& g, const std::vector<ParticleSet>& sets, Estimator estimator,
                                     double density_radius) const
{
  const ParticleSet& p = sets.front();
  StateEstimate e;
  const Eigen::MatrixXd xyz = p.states.leftCols(3);
  const Eigen::VectorXd position = stereo_pf::estimate(xyz, p.weights, estimator, density_radius, 1e-3);
  e.position = position;
  e.covariance = weightedCovariance(xyz, p.weights, position);
  e.valid = e.position.allFinite() && e.position.z() > 1e-3;
  if (e.valid)
  {
    e.left = g.projectLeft(e.position);
    e.right = g.projectRight(e.position);
  }
  if (p.dimension() >= 6)
    e.velocity = p.states.middleCols(3, 3).transpose() * p.weights;
  return e;
}

void PointModel3D::cloud(const StereoGeometry&, const std::vector<ParticleSet>& sets, Eigen::MatrixX3d& points,
                         Eigen::VectorXd& weights) const
{
  points = sets.front().states.leftCols(3);
  weights = sets.front().weights;
}

}  // namespace stereo_pf
