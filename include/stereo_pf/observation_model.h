// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Base class of observation-model plugins (colour, texture, shape, ...): batch likelihoods of image
// hypotheses. A new cue is one .cpp deriving from this, one line in observation_plugins.xml.
#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/hypotheses.h"
#include "stereo_pf/core/parameters.h"

namespace stereo_pf
{
class ObservationModel
{
public:
  virtual ~ObservationModel() = default;
  ObservationModel(const ObservationModel&) = delete;
  ObservationModel& operator=(const ObservationModel&) = delete;

  /// Store the plugin's name and its parameter namespace (`params` is already scoped to `~/<name>`),
  /// read the common parameters `enabled`, `weight` and `refine`, then call onInitialize().
  /// Throws ParameterError on invalid parameters.
  void initialize(const std::string& name, const Parameters& params);

  /// Learn the target appearance from `roi` of `view` in the frame held by `cache`.
  /// Returns false (with `error` set) when the region is unusable (empty, outside the image, ...).
  /// The engine passes View::Left and the user's box, once the box was matched in the right image; the cue is then
  /// evaluated in both views. If any cue fails, the others' targets are restored (saveTarget/loadTarget).
  virtual bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) = 0;
  /// True once a target has been learned or loaded.
  virtual bool hasTarget() const = 0;
  /// Optional: false for a model with no target of its own (e.g. one comparing the two views): it saves nothing,
  /// and a target file needs no entry for it (files saved before it was configured still load).
  virtual bool learnsTarget() const { return true; }

  /// Evaluate every hypothesis of one view: write the model's log-likelihood into `log_likelihood[i]`
  /// (any constant offset is irrelevant) and a similarity in [0, 1] into `similarity[i]` (1 = looks
  /// exactly like the target; used for the track state). Invalid hypotheses must get a finite low
  /// log-likelihood and similarity 0. Both outputs have hyp.size() entries. While tracking, the cues after a
  /// stage's first also see the particles that one found negligible marked invalid (EngineConfig::screen_mass;
  /// with the first's preview(), the first too): skipping invalid hypotheses before any per-pixel work is what
  /// makes the screening save time.
  /// hyp.radius <= 0 (or not finite) marks a 2D hypothesis without a size (the stereo-constraints model): use a
  /// fixed window of the cue's own. Called several times per frame (per set and view, per stage, and on samples
  /// beside the best particle): keep no state between calls. The best particle's mean similarity over the
  /// evidence cues, against the background's, decides the track state (EngineConfig::found_similarity,
  /// lost_similarity, background_margin).
  virtual void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                        Eigen::Ref<Eigen::VectorXd> similarity) = 0;

  /// Optional: a cheaper, coarser evaluate() (same arguments and log-likelihood scale, no similarity) that the
  /// engine uses, while tracking, to choose the particles worth a full evaluation when this model is a stage's
  /// first (EngineConfig::screen_mass). Return false (the default) when the model has none: its evaluate() then
  /// does the choosing.
  virtual bool preview(FeatureCache& /*cache*/, const ImageHypotheses& /*hyp*/,
                       Eigen::Ref<Eigen::VectorXd> /*log_likelihood*/)
  {
    return false;
  }

  /// Optional: true for a model that scores a hypothesis by comparing its left and right images with each
  /// other (stereo matching) instead of comparing each image with the target. The engine then calls
  /// evaluatePair() once per particle set observed in both images, instead of evaluate() per view; sets
  /// observed in one image only (the stereo-constraints model's 2D sets, whose pairing is the coupling's job)
  /// are not scored by it. Its similarity does not count towards the evidence that the target is seen
  /// (two views that agree say nothing about what they show).
  virtual bool comparesViews() const { return false; }
  /// Optional: true for a model that only refines an object the other cues have found. The engine skips it
  /// while searching or lost, where what it rewards (e.g. any surface whose two views agree) would compete
  /// with the target's cues for the particles instead of sharpening them.
  virtual bool onlyWhileTracking() const { return false; }
  /// Optional: false for a model whose similarity does not say whether it is the target that is seen, because it
  /// learns nothing of the target's appearance (the shape cue fits any round outline of the target's size). It
  /// weighs the particles like any other cue, but, like the cues comparing the views and the refining ones, it is
  /// left out of the evidence that the target is seen (EngineConfig::found_similarity and the rest), unless no
  /// enabled cue that identifies the target could count there.
  virtual bool identifiesTarget() const { return true; }
  /// Evaluate hypothesis pairs: entry i of `left` (View::Left) and of `right` (View::Right) are the same
  /// particle. Same outputs and rules as evaluate(). Only called when comparesViews(); the default throws
  /// std::logic_error.
  virtual void evaluatePair(FeatureCache& cache, const ImageHypotheses& left, const ImageHypotheses& right,
                            Eigen::Ref<Eigen::VectorXd> log_likelihood, Eigen::Ref<Eigen::VectorXd> similarity);

  /// Optional: a map of how much each place looks like the target (CV_8UC1, 0..255) for the engine's
  /// detection-driven proposals (searching, lost, and the recovery search while tracking), e.g. a colour
  /// back-projection. It covers the whole image, at its size or at any lower resolution of about its aspect:
  /// the engine resizes it to its grid of kTargetMapCell x kTargetMapCell-pixel cells, so a map at a lower resolution
  /// (the template's is matched on a shrunk image; the colour histogram's is made on the cells) costs less and
  /// proposes about the same. Compute it through `cache` so it is made once per frame. Return false when the model
  /// has no such map (the default) or no target.
  virtual bool targetMap(FeatureCache& /*cache*/, View /*view*/, cv::Mat& /*map*/) { return false; }
  /// Side of the cells targetMap()'s maps are brought to, pixels: a map of image.cols / kTargetMapCell x
  /// image.rows / kTargetMapCell is used as it is.
  static constexpr int kTargetMapCell = 4;

  /// Optional: follow the object's appearance. The engine calls this after each frame in which the tracked
  /// object was seen (Support::Seen while tracking), once per particle set and view, with `estimate` holding one
  /// hypothesis: that set's best-weighted particle. A model that adapts must stay anchored to what it learned from
  /// the box. Default: nothing.
  virtual void adapt(FeatureCache& /*cache*/, const ImageHypotheses& /*estimate*/) {}
  /// Optional: the track was lost; an adapting model goes back to what it learned from the box, which is what the
  /// object is searched for by (a turning box is found again by its first face, not by the last one seen).
  /// Default: nothing.
  virtual void forgetAdaptation() {}

  /// Write the learned target under this plugin's name into an open cv::FileStorage.
  virtual void saveTarget(cv::FileStorage& fs) const = 0;
  /// Read the target written by saveTarget (`node` is the map it wrote under name()); false with `error` set when
  /// absent or inconsistent. Also restores targets after a failed learn or load: saving then loading must round-trip.
  virtual bool loadTarget(const cv::FileNode& node, std::string& error) = 0;

  /// Re-read tunables after the parameters changed (dynamic reconfigure). Called between frames.
  /// The default re-reads `enabled`, `weight` and `refine` only.
  virtual void reconfigure();

  /// Instance name (its parameter namespace).
  const std::string& name() const { return name_; }
  /// False when switched off by the `enabled` parameter.
  bool enabled() const { return enabled_; }
  /// Exponent on this model's likelihood (multiplies its log-likelihood), parameter `weight` (default
  /// defaultWeight()).
  double weight() const { return weight_; }
  /// True for a refining cue (parameter `refine`, default refinesByDefault()): one whose likelihood is much
  /// sharper than a particle cloud spread by the dynamics can sample (a sub-pixel outline, a disparity). While
  /// tracking, the engine applies refining cues after the others, on the set resampled and jittered over the
  /// region the others allow (EngineConfig::refine_jitter), and leaves them out of the evidence; while
  /// searching or lost it skips them (or tempers them: EngineConfig::refine_search_weight). Without any other
  /// enabled cue a refining cue is an ordinary one.
  bool refine() const { return refine_; }

protected:
  ObservationModel() = default;
  /// Read the plugin's own parameters from params(); throw ParameterError on bad values. Keep it cheap and free
  /// of side effects: no frame or target exists yet, and instances are also built only to validate parameters.
  virtual void onInitialize() = 0;
  /// The plugin's parameter namespace.
  const Parameters& params() const { return params_; }
  /// Default of the `refine` parameter (false: an ordinary cue).
  virtual bool refinesByDefault() const { return false; }
  /// Default of the `weight` parameter (1: the likelihood as the model states it).
  virtual double defaultWeight() const { return 1.0; }

private:
  void readCommon();
  std::string name_;
  Parameters params_;
  bool enabled_ = true;
  double weight_ = 1.0;
  bool refine_ = false;
};

}  // namespace stereo_pf
