// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Base class of state-model plugins: what a particle is, how it moves, where it appears in the images,
// and how the two views' likelihoods combine into weights.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "stereo_pf/core/estimators.h"
#include "stereo_pf/core/hypotheses.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/core/particle_set.h"
#include "stereo_pf/core/random.h"
#include "stereo_pf/core/stereo_geometry.h"

namespace stereo_pf
{
/// A 3D estimate with its uncertainty.
struct StateEstimate
{
  bool valid = false;                                       ///< false when no 3D point can be formed
  Eigen::Vector3d position = Eigen::Vector3d::Zero();       ///< left optical frame, metres
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity(); ///< of the position, m^2
  Pixel left, right;                                        ///< the estimate in each image
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();       ///< m/s when the model has velocity
};

class StateModel
{
public:
  virtual ~StateModel() = default;
  StateModel(const StateModel&) = delete;
  StateModel& operator=(const StateModel&) = delete;

  /// Store name and parameters (scoped to `~/<name>`), then call onInitialize(). Throws ParameterError.
  void initialize(const std::string& name, const Parameters& params);

  /// Number of particle sets the model keeps (1 for 3D models, 2 for stereo constraints: left, right).
  virtual int numSets() const { return 1; }
  /// State dimension of every particle of set `set`.
  virtual int dimension(int set) const = 0;
  /// The views set `set` is observed in (the 3D models: both; stereo constraints: its own image).
  virtual std::vector<View> views(int set) const = 0;

  /// Draw rows [begin, end) of `particles` from the prior (initialisation and re-spreading when lost).
  virtual void samplePrior(const StereoGeometry& geometry, int set, ParticleSet& particles, int begin, int end,
                           Rng& rng) const = 0;
  /// Optional: put particle `row` of set `set` at the object seen at `left` in the left image and `right`
  /// in the right image (same row after rectification), keeping whatever else the prior drew for it
  /// (e.g. velocity). Used for detection-driven proposals. Return false when the pair is not a valid state
  /// for this model (e.g. outside its depth range) or the model does not support it (the default).
  virtual bool seedFromStereo(const StereoGeometry& /*geometry*/, int /*set*/, ParticleSet& /*particles*/, int /*row*/,
                              const Pixel& /*left*/, const Pixel& /*right*/) const
  {
    return false;
  }
  /// Optional: particle `row`, just placed by seedFromStereo where the cues see the target, is taken to have
  /// come there from the estimate `from` in `dt` seconds: a jump the dynamics could not follow (a bounce, a
  /// throw's first frames, a lock taken back from a distractor). `from` is the track's last estimate the evidence
  /// saw (the previous frame's unless the object went unseen since) and `dt` the time since. Models with a
  /// velocity set it to that jump so the next prediction follows it. Default: nothing.
  virtual void setArrival(const StateEstimate& /*from*/, double /*dt*/, int /*set*/, ParticleSet& /*particles*/,
                          int /*row*/) const
  {
  }
  /// Dynamics: move every particle of `particles` by dt seconds (dt > 0; first frame uses the nominal period).
  virtual void predict(int set, double dt, ParticleSet& particles, Rng& rng) const = 0;
  /// Where each particle of `particles` would appear in `hyp.view` (hyp is resized to N).
  virtual void project(const StereoGeometry& geometry, int set, const ParticleSet& particles,
                       ImageHypotheses& hyp) const = 0;
  /// Optional hook after every set has been weighted by the observations and normalised, before
  /// resampling: couple the sets (the stereo-constraints model applies eq. 5.15 here). Implementations
  /// update log_weights and renormalise. Default: nothing.
  virtual void couple(const StereoGeometry& /*geometry*/, std::vector<ParticleSet>& /*sets*/) {}
  /// The 3D estimate of the normalised sets.
  virtual StateEstimate estimate(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets,
                                 Estimator estimator, double density_radius) const = 0;
  /// One 3D point and weight per particle for display (the stereo-constraints model pairs its sets).
  virtual void cloud(const StereoGeometry& geometry, const std::vector<ParticleSet>& sets, Eigen::MatrixX3d& points,
                     Eigen::VectorXd& weights) const = 0;
  /// Re-read tunables after the parameters changed; called between frames. Default: onInitialize().
  virtual void reconfigure() { onInitialize(); }
  /// The object's metric radius as learned with the target (FilterEngine::learnTarget measures it from the box
  /// and its stereo match, the target file stores it); 0: unknown. Models that give their hypotheses an apparent
  /// size use it unless their own `object_radius` parameter overrides it.
  void setLearnedRadius(double radius) { learned_radius_ = radius > 0.0 ? radius : 0.0; }
  double learnedRadius() const { return learned_radius_; }

  /// Instance name.
  const std::string& name() const { return name_; }

protected:
  StateModel() = default;
  /// Read the model's parameters from params(); throw ParameterError on bad values.
  virtual void onInitialize() = 0;
  /// The model's parameter namespace.
  const Parameters& params() const { return params_; }

  /// The radius to use: `configured` when positive (the user's override), else the learned one, else
  /// `fallback` (nothing learned yet, e.g. a target file from before sizes were stored).
  double objectRadius(double configured, double fallback) const
  {
    return configured > 0.0 ? configured : learned_radius_ > 0.0 ? learned_radius_ : fallback;
  }

private:
  std::string name_;
  Parameters params_;
  double learned_radius_ = 0.0;
};

}  // namespace stereo_pf
