// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// The particle-filter engine: owns the particle sets and the RNG, runs one stereo frame through
// predict -> project -> observe -> couple -> normalise -> estimate -> resample.
#pragma once

#include <array>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "stereo_pf/core/acquisition.h"
#include "stereo_pf/core/estimators.h"
#include "stereo_pf/core/feature_cache.h"
#include "stereo_pf/core/local_search.h"
#include "stereo_pf/core/map_proposals.h"
#include "stereo_pf/core/match_depth_filter.h"
#include "stereo_pf/core/parameters.h"
#include "stereo_pf/core/random.h"
#include "stereo_pf/core/stereo_frame.h"
#include "stereo_pf/core/viewing_volume.h"
#include "stereo_pf/observation_model.h"
#include "stereo_pf/state_model.h"

namespace stereo_pf
{
/// Track state from the likelihood evidence.
enum class TrackState
{
  Searching,  ///< no lock yet (start, reset)
  Tracking,   ///< evidence above found_similarity
  Lost        ///< evidence fell below lost_similarity for lost_frames frames
};
/// "searching", "tracking" or "lost".
std::string toString(TrackState state);

/// What one frame's evidence says about the object (FrameResult::support); decides the track state.
enum class Support
{
  Seen,            ///< evidence >= found_similarity and above the background by background_margin; while not
                   ///< tracking, also within reacquire_margin of the last track's evidence and within reach of
                   ///< where it last saw the object (reacquire_speed_factor), while tracking within hold_margin
                   ///< of it (as it follows the track's seen frames: hold_follow)
  Unsure,          ///< between the thresholds: neither counts towards nor breaks a run of seen or unseen frames
  LowEvidence,     ///< evidence < lost_similarity (and no view alone sees the object: one_view_unsure)
  LikeBackground,  ///< background locations score as well as the best particle (within background_margin)
  OutsideView      ///< the estimate, or every particle of a set, left the viewing volume: lost at once
};
/// "seen", "unsure", "low evidence", "like background" or "outside view".
std::string toString(Support support);

/// Engine tunables (the `~engine/...` namespace, or the top level of the CLI config).
struct EngineConfig
{
  int particles = 1000;               ///< per set
  double resample_threshold = 1.0;    ///< resample when ESS < threshold * N (1.0: every frame, as the thesis)
  /// Likelihood tempering of the first stage of a frame with refining cues (while tracking): the other cues'
  /// likelihood is raised to the largest power in (0, 1] that leaves an ESS of at least min_ess * N. They
  /// count every pixel as independent evidence, far sharper than what they know: untempered, a handful of
  /// particles took the weight, and the refining cues then searched only around those. The refining cues
  /// themselves are tempered only down to the far smaller refine_min_ess (to min_ess the precision they give was
  /// lost: the pendulum 0.5 -> 1 cm); the published covariance adds the first stage's spread to theirs. 0: off.
  double min_ess = 0.1;
  /// Screening (a cascade) while tracking: in each stage, once the first cue has weighed the set, the cues after
  /// it weigh only the particles that carry screen_mass of the weights the first cue alone gives, tempered as
  /// that stage's are (min_ess, refine_min_ess); the others weigh nothing. A particle the first cue finds
  /// negligible is not worth the others' cost. This frame's recovery jumps are always weighed. 1: every particle.
  double screen_mass = 0.999;
  Estimator estimator = Estimator::Mean;
  double density_radius = 0.03;       ///< radius of the density estimate, in state units (m, or px for 2D sets)
  unsigned long seed = 1;             ///< RNG seed
  double nominal_dt = 1.0 / 30.0;     ///< dt used for the first frame and for non-increasing stamps
  double found_similarity = 0.65;     ///< best mean cue similarity at or above this counts as "object seen"
  double lost_similarity = 0.45;      ///< below this counts as "object not seen"
  /// A frame of the track whose evidence is low (support low evidence: below lost_similarity, and no camera alone
  /// sees the object) still gives its estimate (FrameResult::published()) when that evidence reaches this: the object
  /// is seen faintly. Below it the estimate is the prediction, not a sighting: an object passing behind an occluder at
  /// speed went on in the estimate for three such frames, 0.3-0.8 m off (drawn scene, a ball at 2.5 m). Over stress
  /// draws 1-6 at seeds 1-3 (at e1c73ec, when every frame of a track gave its estimate), of the low-evidence frames with
  /// the object in view 0 of 52 below 0.3 were within 2 % of range, 34 of 85 from 0.3 up; of the like-background ones
  /// (which give none, whatever their evidence) 0 of 38. Re-scored offline with 0.2, 0.25, 0.3 and none given (the
  /// filter does not change): 384, 385, 388 and 386 of 540 runs successful; the real pitches (seeds 1-10) had every
  /// reference frame's estimate in 34, 32, 31 and 28 of 40 runs. 0: every low-evidence frame gives its estimate.
  double estimate_similarity = 0.3;
  int found_frames = 2;               ///< seen frames, no unseen one between, to switch to Tracking
  int lost_frames = 4;                ///< unseen frames, no seen one between, to switch to Lost
  /// Unsure frames in a row (neither seen nor unseen) after which a track is Lost too (0: never): a track
  /// whose evidence stays between the thresholds cannot vouch for its estimate, which drifts onto the
  /// background as soon as that scores as well.
  int unsure_frames = 10;
  /// Once the target has been tracked, finding it again (from Searching or Lost) needs evidence within this of
  /// what the object showed in its last track's seen frames (the measure hold_follow moves, as it was when the
  /// track ended), besides found_similarity: a look-alike or a patch of backdrop that scores well above
  /// found_similarity, but below the object itself, is not taken for it while it is hidden. Held to the first
  /// frame's evidence instead (learned there, hence inflated), the shipped occlusion scene took up to 16 frames
  /// to be found again (Position3D, seeds 1-10; now 5) and the drawn dev set's hidden spans were followed by a
  /// re-acquisition in 9 of 90 (now 15; the stress page's draw: 9 of 54 either way, and one more run locked on a
  /// distractor after an occluder). 1: found_similarity alone.
  double reacquire_margin = 0.05;
  /// Once the target has been tracked, finding it again also needs the estimate within reach of where the track
  /// last saw the object: (reacquire_speed_factor times the speed it had there, plus reacquire_min_speed) times the
  /// time since. The speed is fitted to the track's seen estimates of the last 0.3 s (one alone: the state's
  /// velocity). An object hidden by an occluder comes out about where its motion took it; a look-alike that took
  /// the lost track is mostly elsewhere. 0 (either): no bound.
  double reacquire_speed_factor = 2.0;
  double reacquire_min_speed = 1.0;  ///< m/s
  /// While Tracking, a frame counts as seen only with evidence within this of track_reference (as hold_follow
  /// moves it) too; below it, as unsure (unsure_frames of them in a row lose the track). A track that has left
  /// the object for something scoring well above found_similarity but well below the object (a patch of its
  /// colour, the view after the object has left it) is not kept by that; the object's own evidence varies by
  /// ~0.15 along a track. 1: off.
  double hold_margin = 0.2;
  /// The measure hold_margin applies to follows the evidence of the track's seen frames by this much per frame,
  /// never above track_reference: an object whose look changes slowly (a box turning a face of another colour to
  /// the camera, followed by the adapting cues, anchored to the box) is kept, while a sudden drop (the track left
  /// on a patch of the object's colour) is still unsure, since unsure frames do not move it. Kept while the
  /// track is lost: reacquire_margin applies to it. 0: the first track's evidence alone.
  double hold_follow = 0.05;
  /// A frame whose evidence is below lost_similarity, but in which one camera alone sees the object (some
  /// particle's mean similarity over the evidence cues in that view at least found_similarity), is unsure rather
  /// than unseen: the track is kept (for unsure_frames) while the object is hidden from the other camera's cues.
  /// On a real pitch the ball passed in front of a bright panel seen by the right camera only: its right-view
  /// cues fell to 0-0.3 while the left view's stayed at 0.7-0.8, and the track was lost 5 frames before the
  /// pitch's end. A view "sees" the object when its cues' mean similarity is at least midway between
  /// lost_similarity and found_similarity. Such a frame is like the background (background_margin) only when that
  /// view's best similarity is within the margin of its own background's, not the mean of the two views'. false:
  /// the mean over both views alone decides.
  bool one_view_unsure = true;
  double respawn_fraction = 0.2;      ///< fraction of each set redrawn every frame while not Tracking
  /// While Tracking: the share of each set moved every frame to where the cues' target maps see the target
  /// (the recovery search: a fast object's jump, a bounce, the real object beside a distractor), each with the
  /// velocity of a jump from the track's last estimate the evidence saw, seen or unsure, over the time since
  /// (StateModel::setArrival). None from the prior.
  double tracking_respawn_fraction = 0.05;
  /// The recovery search runs on every recovery_period-th frame while Tracking (1: every frame). Its target maps
  /// and the frame-wide particles it proposes cost more than the rest of a step; a wrong lock or a jump is found
  /// a few frames later instead, at a fraction of the cost.
  int recovery_period = 4;
  /// Prior weight of such a recovery particle relative to a predicted one: the chance that the object jumped
  /// rather than moved as the dynamics say. Small: a look-alike elsewhere takes the track only when it explains
  /// the images much better, or consistently over frames.
  double jump_weight = 0.05;
  /// m/s: no recovery jump goes farther from the track's last estimate the evidence saw than this speed allows in
  /// the time since (0: no bound). The fastest an object the tracker follows moves: Velocity3D's max_speed.
  double max_jump_speed = 40.0;
  /// While Tracking: the share of each set moved every frame around where the local search (LocalSearch) finds
  /// the object near the position its last image motion predicts, at its present apparent size (what lets a
  /// fast or approaching object be followed), with the same prior weight and arrival velocity as the recovery
  /// search's. 0: no local search.
  double local_fraction = 0.1;
  /// m/s^2: the local search's pairs are proposed at the depth of its matches filtered over the track's frames
  /// (MatchDepthFilter) with this acceleration noise along the depth, not at each frame's own match: a far
  /// object's depth then averages over frames instead of taking each frame's disparity error. 0: each match as it is.
  double local_depth_acceleration = 60.0;
  /// m/s: while no image motion of the track is known yet (its first frame after the box, or after it was found
  /// again), the local search reaches as far as this speed takes the object in the frame's interval: a fast
  /// object has moved out of a window of two radii by the first frame after the box. The wide window is searched
  /// only when nothing within two radii scores found_similarity (a slow object is taken where it is). 20 m/s is the
  /// fastest ball the tracker is meant for. Drawn scenes (draws 1-3, tracker seeds 1-3): runs that never converge
  /// 40 -> 34, successful 171 against 173 (the runs it starts now are lost later; single runs flip either way); the
  /// real pitches at seeds 1-20 as before (the ball is found within two radii). 0: two radii.
  double start_speed = 20.0;
  /// s; the return watch. A lost track found again farther from where it lost the object than the object's own
  /// motion explains (reacquire_speed_factor times its speed there, times the time since, plus two radii) may have
  /// taken a look-alike while the object was hidden: for this long after, every frame, the local search also looks
  /// for the object within that reach of where it was lost. When it sees it there as a track must (found_similarity,
  /// and within hold_margin of what the object scores: the search's pair, the lower of its two views, scores below
  /// the best particle of a cloud), away from the track, found_frames frames in a row, every set moves back there.
  /// Two look-alikes differ only in where they are: the object comes out where it went in. 0: no watch.
  double return_watch = 3.0;
  /// s; the look-alike memory. While Tracking, a place away from the track where a recovery jump scores as a track
  /// must (hold_margin below what the object scores, and found_similarity), on a frame that sees the object on the
  /// track, holds another object like it: remembered until this long after it was last seen, and once seen on two
  /// such frames, a lost track is not found again there. Its particles within two radii, plus reacquire_min_speed
  /// times the time since, of the place weigh nothing and are no evidence; the best of them that scores so renews the
  /// memory where it is in the image. On drawn scenes a ball left the view while its twin stayed: the lost track was
  /// found again on the twin and kept it for the rest of the clip (38 % of range RMS at every seed; now it is lost
  /// until the ball comes back: 1.0-2.7 % on one scene; 1.5 % at one seed of the other, whose other two seeds still
  /// end on the twin: at one of them the track moves to it while tracking, as it crosses in front of the ball). Needs
  /// a state whose sets are seen in both views (not the stereo-constraints model). 0: off.
  double lookalike_memory = 3.0;
  /// Share of the redrawn particles proposed from the observation models' target maps (a left pixel drawn
  /// where the target's appearance is, a right pixel along the same row), the rest from the prior.
  double proposal_fraction = 0.5;
  double proposal_min_depth = 0.3;    ///< nearest depth (m) a proposal may have: bounds the disparity searched
  /// The published covariance adds (centre_sigma x the learned radius)^2 on each axis: the object's centre is
  /// inferred from its visible surface and outline as if it were a sphere, which a box, a cylinder or a partly
  /// hidden object is not; the particle cloud's spread says nothing about that. On the drawn scenes (6 draws x 30
  /// at tracker seeds 1-3) the truth lay inside the 95 % ellipsoid in 81.9-96.3 % of tracked frames per draw
  /// without it (cylinders 59 % on one draw), in 85.9-98.8 % with 0.25 (with 0.15, recomputed from the same runs'
  /// estimates and the scenes' radii: 84.8-98.4 %). 0: the cloud's alone.
  double centre_sigma = 0.25;
  /// Progressive correction for refining cues (ObservationModel::refine()): after the other cues, each set is
  /// resampled and every particle jittered by N(0, refine_jitter^2 C), C the set's weighted covariance, before
  /// the refining cues weigh it; not on a frame where the other cues see nothing at all (below lost_similarity, and
  /// nothing or no better than the background: no region to refine). 0: no jitter (the copies of a particle then
  /// stay identical).
  double refine_jitter = 1.0;
  /// The refining cues are as sharp as the disparity they measure, and a particle the jitter took onto another
  /// surface that happens to match across the views can take all the weight: the estimate is then that one
  /// particle, off by its whole distance from the rest (a 1.3 cm box at 0.56 m, drawn scene: one particle 7 cm
  /// off took 0.96 of the weight, ESS 1.1, and the track went 14 and then 22 % of range short). So their
  /// likelihood is raised to the largest power in (0, 1] that leaves an ESS of at least refine_min_ess * N
  /// (min_ess's rule, with the resampled set's uniform prior); a frame whose refined ESS is above it is not
  /// touched. 0: untempered, as before (tempered down to min_ess, 0.1, the precision they give was lost).
  double refine_min_ess = 0.01;
  /// While searching or lost, refining cues are applied together with the others, their weight multiplied by
  /// this (0: skipped then, the default: an outline of the target's colour is also found on clutter of that
  /// colour, and the search did no better with it). They are never part of the evidence.
  double refine_search_weight = 0.0;
  /// The viewing volume (ViewingVolume): particles whose hypotheses leave it weigh nothing, and an estimate
  /// outside it is no estimate (the track is lost and the sets are redrawn from the prior). Far limit: the
  /// depth at which the disparity falls to min_disparity px (fx b / min_disparity: 94 m for the thesis rig).
  double min_disparity = 0.5;
  /// m; a nearer far limit (0: min_disparity alone sets it).
  double max_depth = 0.0;
  /// px; with a learned object size (targetRadius()), a nearer far limit still: the depth at which the object's
  /// image radius falls to this (fx R / min_apparent_radius). Beyond it the object is not resolved, and any
  /// speck of texture matches a cue scaled down to it (0: no such limit).
  double min_apparent_radius = 1.0;
  /// Background check: the evidence cues also score this many locations along the best particle's image rows,
  /// away from it (same apparent size and disparity); the median of their similarities is the background
  /// (FrameResult::background). 0: no check.
  int background_samples = 16;
  /// The best particle counts as seen only when its similarity exceeds the background by this much; a frame
  /// where it does not is "like background" (not seen): a target whose appearance is everywhere, e.g. learned
  /// from a box that holds mostly wall, is never tracked.
  double background_margin = 0.2;
  /// Acquisition (learnTarget): match the user's box in the right image (matchBox), learn the object's metric
  /// size from it, and start the particles around that 3D point, tracking. False: the thesis's start, the
  /// particles spread over the viewing volume and searching (the size then comes from `object_radius`).
  bool acquire = true;
  /// Acquisition also measures each cue's trust (measureCueTrust): how well it told the object from the rest of
  /// that frame; a cue's weight and its share of the evidence are scaled by it. False: every cue trusted.
  bool cue_trust = true;
  /// The colour cues see each frame's pixels times the gain that brings that view's brightness (mean grey level)
  /// back to the learning frame's left image (FeatureCache::setGain(), clamped to 0.5..2): a camera's auto gain or
  /// exposure, or a right camera brighter than the left, then moves no colour between intensity bins. False:
  /// the pixels as they are.
  bool gain_compensation = true;
  /// The models adapt (ObservationModel::adapt()) on a seen frame only when the best particle's two views agree at
  /// least this well (the lowest similarity there of the cues comparing the views; a set seen in one view only is
  /// not checked). An occluder coming over the object is seen by the two cameras at other disparities than the
  /// object: the views disagree while the adapting models would take in its look (drawn scene, a board over a box:
  /// the best particle's stereo similarity 0.98 -> 0.70-0.75, and the colour histogram followed the board). 0: off.
  double adapt_min_stereo = 0.85;

  /// Read from `params` (missing keys keep their defaults); throws ParameterError.
  static EngineConfig fromParameters(const Parameters& params);
  /// The engine's parameter table (engine.cpp declares each parameter there once): name, default (these
  /// members' initial values), range, description, and whether it can be changed while running.
  static const std::vector<ParameterSpec>& table();
};

/// Result of one frame.
struct FrameResult
{
  StateEstimate estimate;              ///< 3D estimate and image positions
  TrackState state = TrackState::Searching;
  double ess = 0.0;                    ///< effective sample size before resampling (minimum over sets)
  double evidence = 0.0;               ///< best particle's mean cue similarity in [0, 1]
  /// Median similarity at background locations (EngineConfig::background_samples); what the evidence must beat
  /// by background_margin (0 when not measured).
  double background = 0.0;
  Support support = Support::Unsure;   ///< what this frame's evidence says
  int state_frames = 0;                ///< consecutive frames in `state`, this one included
  /// The sets were found outside the viewing volume or lost to the background: redrawn from the prior at the
  /// next frame.
  bool reinitialised = false;
  double log_marginal = 0.0;           ///< log mean likelihood (sum over sets)
  bool resampled = false;
  double dt = 0.0;                     ///< seconds since the previous frame
  /// Particles the screening (EngineConfig::screen_mass) left out of the cues after a stage's first, summed over
  /// the frame's stages and sets.
  int screened = 0;
  /// Support low evidence, but the evidence reaches EngineConfig::estimate_similarity: the object is seen faintly.
  bool faint = false;

  /// The estimate is a position the user is given: valid, the target is tracked (searching or lost, the cloud's
  /// mean is where the filter looks, not where the object is), and this frame's evidence sees the object: support
  /// seen or unsure, or low evidence that still sees it faintly (`faint`, EngineConfig::estimate_similarity). A track
  /// keeps its state over up to lost_frames frames of low evidence, so that one bad frame does not lose it; where its
  /// evidence falls below that too, or the background beside it scores as well, its estimate is the prediction, not
  /// a sighting, and is not given. The nodelet publishes it, track_bag writes it, only then.
  bool published() const
  {
    return state == TrackState::Tracking && estimate.valid &&
           (support == Support::Seen || support == Support::Unsure || faint);
  }
};

class FilterEngine
{
public:
  /// Takes shared ownership of the plugins (their ClassLoader must outlive the engine's use of them).
  FilterEngine(std::shared_ptr<StateModel> state_model, std::vector<std::shared_ptr<ObservationModel>> observation_models,
               const EngineConfig& config);

  /// Queue a new configuration (thread-safe); it is applied at the start of the next step() (never mid-step).
  /// A new seed or particle count resets the filter.
  void setConfig(const EngineConfig& config);
  /// The configuration in force.
  const EngineConfig& config() const { return config_; }
  /// Ask plugins to re-read their parameters at the start of the next step().
  void requestPluginReconfigure();

  /// Forget the particles (re-drawn from the prior at the next frame) and reseed the RNG; keeps the target.
  /// Thread-safe: takes effect at the start of the next step().
  void reset();

  /// Learn the target from `roi` in the left image of `frame` (every observation model learns it) and, with
  /// `acquire`, acquire it: the box is matched along the right image's rows (matchBox), which gives its 3D
  /// centre and metric radius; the radius goes to the state model (StateModel::setLearnedRadius) and the target
  /// file, and the next step() starts the particles around that point in Tracking (a reset() after this call
  /// does not undo it). Returns false with `error` set when any model cannot learn the box or the match fails
  /// (ambiguous, none, too far: the error names the box); then every model that had a target keeps it.
  bool learnTarget(const StereoFrame& frame, const cv::Rect& roi, std::string& error);
  /// True when every enabled observation model has a target.
  bool hasTarget() const;
  /// Save / load every model's target (OpenCV YAML/XML file). False with `error` on failure; a load that fails
  /// (a model missing from the file, a malformed entry) leaves every model that had a target with it.
  bool saveTarget(const std::string& path, std::string& error) const;
  bool loadTarget(const std::string& path, std::string& error);

  /// Run one frame. The frame must be valid (StereoFrame::validate() empty) and a target learned;
  /// throws std::invalid_argument otherwise.
  FrameResult step(const StereoFrame& frame);

  /// The particle sets after the last step (normalised weights; after resampling when it happened).
  const std::vector<ParticleSet>& sets() const { return sets_; }
  /// The particle sets of the last step as weighed, just before its final resampling (equal to sets() when
  /// it did not resample): after resampling every weight is 1/N, so this is what visualisation shows.
  const std::vector<ParticleSet>& weightedSets() const { return weighted_sets_; }
  /// The feature cache of the last frame (debug drawing, tests).
  FeatureCache& cache() { return cache_; }
  /// The state model.
  const StateModel& stateModel() const { return *state_model_; }
  /// The observation models.
  const std::vector<std::shared_ptr<ObservationModel>>& observationModels() const { return observation_models_; }
  /// The hypotheses of the last step, per set and per view (debug drawing).
  const std::vector<std::vector<ImageHypotheses>>& hypotheses() const { return hypotheses_; }
  /// The viewing volume of the last step's frame (default-constructed before the first step).
  const ViewingVolume& viewingVolume() const { return volume_; }
  /// The object's metric radius learned with the target (0: none learned).
  double targetRadius() const { return target_radius_; }
  /// The last successful acquisition's match (BoxMatch::ok false before any).
  const BoxMatch& acquisition() const { return acquisition_; }
  /// Each observation model's trust (same order as observationModels()): how well it told the object from the
  /// frame it was learned on (measureCueTrust); its weight and its share of the evidence are scaled by it. All 1
  /// before a target, for a target learned without acquisition, or loaded from a file that has none.
  const std::vector<double>& cueTrust() const { return cue_trust_; }
  /// The brightness (FeatureCache::brightness()) of the left image the target was learned from, which each frame's
  /// gains bring the views back to (EngineConfig::gain_compensation); -1 before a target, or for one loaded from a
  /// file that has none until the first step.
  double targetBrightness() const { return target_brightness_; }
  /// The cache of the last step's frame (its gains: FeatureCache::gain()).
  const FeatureCache& featureCache() const { return cache_; }

private:
  void applyPending();
  void initialiseParticles(const StereoGeometry& geometry);
  /// Redraw `count` random rows of set `set`: a `proposal_share` of them at the prepared proposals, the rest
  /// from the prior; while tracking (`arrival` given) only proposals, each arriving from *arrival in dt.
  void respawn(const StereoGeometry& geometry, int set, int count, double proposal_share,
               const StateEstimate* arrival, double dt);
  /// Draw `count` stereo pairs where the cues' target maps agree (MapProposals); `near`: while tracking, the
  /// estimate whose disparity bounds the pairs' (within a factor kDisparityReach); otherwise, once a track has seen
  /// the object, only within reacquireReach(stamp) of where it did.
  void prepareProposals(const StereoGeometry& geometry, int count, const StateEstimate* near, double stamp);
  /// Drop the prepared proposals farther from `from` than max_jump_speed allows in `since` seconds.
  void dropFasterJumps(const StereoGeometry& geometry, const StateEstimate& from, double since);
  static constexpr double kDisparityReach = 1.5;
  /// While tracking: run the local search near the last estimates' image track and append `count` pairs around
  /// its match to the proposals (none when the evidence cues score its best match below lost_similarity);
  /// returns how many. `stamp`: this frame's (the track's image motion is carried over the time since its last place,
  /// at most kMaxPredictedPeriods frame periods; with no motion known, the search reaches start_speed times that).
  int proposeLocally(const StereoGeometry& geometry, int count, double stamp);
  /// The local search's scorers: the cues that weigh a track (not the refining ones, nor those comparing the two
  /// views, nor untrusted ones) add their log-likelihoods, and the mean similarity of those that are evidence...
  void scoreLocally(const ImageHypotheses& hyp, Eigen::VectorXd& ll, Eigen::VectorXd& sim);
  /// ... and the cues comparing the two views add theirs for left i with right i.
  void scorePairsLocally(const ImageHypotheses& left, const ImageHypotheses& right, Eigen::VectorXd& ll);
  /// The local search (local_search_) for `track` in this frame, scored by scoreLocally() and scorePairsLocally().
  LocalMatch searchLocally(const StereoGeometry& geometry, const ImageTrack& track);
  /// The return watch (EngineConfig::return_watch), on the frame a lost track is found again (`estimate`, at
  /// `stamp`): watch where the object was lost when that estimate is beyond the object's own reach from there.
  void startReturnWatch(const StateEstimate& estimate, double stamp);
  /// ... and on every later tracking frame while it runs: look for the object within its own reach of where it was
  /// lost; after found_frames frames in a row that find it there, away from the track, move every set there (the
  /// result's estimate with them). Returns true when it moved them.
  bool watchForReturn(const StereoGeometry& geometry, double stamp, FrameResult& result);
  /// How far the object can have gone by its own motion from where the watched track lost it, at `stamp`, m.
  double ownReach(double stamp) const;
  /// Set `s`'s hypotheses in `view` this frame (null: the set is not seen in it).
  const ImageHypotheses* hypothesesOf(int s, View view) const;
  /// The look-alike memory (EngineConfig::lookalike_memory): row `i` of set `s`'s 3D position, triangulated from its
  /// hypotheses in the two views (false when the set is not seen in both)...
  bool rowPosition(const StereoGeometry& geometry, int s, int i, Eigen::Vector3d& position) const;
  /// ... how far a remembered look-alike reaches at `stamp` (two radii, plus reacquire_min_speed times the time
  /// since it was seen), m ...
  double lookalikeReach(double seen_stamp, double stamp) const;
  /// ... remember one seen at `position` (the entry whose reach holds it is renewed, else one is added) ...
  void rememberLookalike(const Eigen::Vector3d& position, double stamp);
  /// ... and while lost: set `s`'s particles whose left image lies within reach of one seen kLookalikeSightings times
  /// weigh nothing and are no evidence (the best of them scoring as a track must renews it, where it is); while
  /// tracking, only the rows `only` marks (a recovery jump's).
  void excludeLookalikes(const StereoGeometry& geometry, int s, double cues, double stamp,
                         const std::vector<int>* only = nullptr);
  /// True when an enabled cue is not a refining one (refining cues then come second, after the others).
  bool anyNonRefiningCue() const;
  /// True when `m`'s similarity counts towards the evidence that the target is seen (among the cues that compare each
  /// view with the target and are not refining): when it identifies the target (ObservationModel::identifiesTarget),
  /// or when no enabled cue that does could count.
  bool isEvidence(const ObservationModel& m) const;
  /// After a step: keep the tracking estimate's image position, disparity and apparent size for proposeLocally(),
  /// when the evidence saw the object (`vouched`); a frame that saw nothing keeps the last place the evidence saw.
  void rememberTrack(bool vouched, double stamp);
  /// No track for proposeLocally() to follow (a fresh cloud, a jump, an invalid estimate): it and its depth filter
  /// start again from the next vouched estimate.
  void forgetTrack();
  /// A Seen estimate: kept in sightings_, seen_speed_ fitted to them.
  void recordSighting(const StateEstimate& estimate, double stamp);
  /// Draw every set around the acquired point (acquisition_): its left pixel jittered by a fraction of the apparent
  /// radius, its disparity by half a pixel, through StateModel::seedFromStereo (rows it rejects keep their
  /// prior draw).
  void seedAroundAcquisition(const StereoGeometry& geometry);
  /// Draw every set around the pair (left, left - disparity), its left pixel jittered by `lateral` px (sd), its
  /// disparity by half a pixel, through StateModel::seedFromStereo; uniform weights. With `from`, each seeded
  /// particle arrives from it in `dt` (StateModel::setArrival).
  void seedAround(const StereoGeometry& geometry, const Pixel& left, double disparity, double lateral,
                  const StateEstimate* from, double dt);
  /// After a frame in which the tracked object was seen: every model's adapt() at the best particle's views, for
  /// each set whose best particle's views agree (viewsAgreeForAdaptation).
  void adaptTargets();
  /// Whether set s's particle i is seen alike in its two views, by adapt_min_stereo (true without both views).
  bool viewsAgreeForAdaptation(int s, Eigen::Index i);
  /// The cache's gain for each view this frame (EngineConfig::gain_compensation); the brightness the target
  /// was learned at is taken from this frame when there is none yet (a target file without it).
  void compensateGain();
  /// Classify the frame's evidence (Support) against the thresholds and the background.
  Support judge(double evidence, double background, bool background_measured, bool one_view, bool in_reach) const;
  /// Whether `estimate`, found while not Tracking at `stamp`, lies within reach of where the last track saw the
  /// object (reacquire_speed_factor, reacquire_min_speed); true when there is no such place, no bound, or `stamp`
  /// is not after that place's (stamps gone back: a bag played again).
  bool withinReacquireReach(const StateEstimate& estimate, double stamp) const;
  /// How far from where the last track saw the object (seen_estimate_) it can be at `stamp`: (reacquire_speed_factor
  /// x its speed there + reacquire_min_speed) x the time since; infinite when there is no bound.
  double reacquireReach(double stamp) const;
  /// Note the interval `dt` since the last frame and return the interval to predict over: while tracking, at most
  /// kMaxPredictedPeriods frame periods (framePeriod).
  double predictionInterval(double dt);
  /// The camera's frame period: the median of the last intervals (nominal_dt until three are known).
  double framePeriod() const;
  /// Track state machine; a loss to the background or the volume re-initialises the sets.
  void updateTrackState(Support support, FrameResult& result);
  /// Give the particles of set `s` whose hypotheses leave the viewing volume zero weight (log-weight -inf);
  /// returns how many are inside.
  int boundToViewingVolume(int s);
  /// Median trust-weighted mean similarity of the evidence cues (`is_evidence`) at background locations along
  /// the rows of particle `best` of set `s` (its hypotheses shifted sideways, away from it); false when too few
  /// locations fit. `view_background`: the same of each view's cues alone (left, right; NaN for a view the set is
  /// not seen in).
  template <class IsEvidence>
  bool backgroundSimilarity(int s, int best, IsEvidence is_evidence, double& background, double (&view_background)[2]);
  /// The median of `values` (not empty).
  double median(const Eigen::VectorXd& values);
  /// Every model's target as OpenCV YAML text, and back: learnTarget/loadTarget restore it when any model fails.
  std::string snapshotTargets() const;
  void restoreTargets(const std::string& snapshot);
  /// How observe() uses one model: its weight is multiplied by `weight` (0: not evaluated), and its
  /// similarity counts as evidence when `evidence`.
  struct Use
  {
    double weight = 0.0;
    bool evidence = false;
  };
  /// Project set `s` and add to its log-weights the log-likelihoods of the models as `take(model)` (a Use)
  /// says; returns the total trust of the per-view cue evaluations added to sum_sim_ (each added times its
  /// model's trust; comparesViews models: none).
  /// With `screen` (EngineConfig::screen_mass below 1), the models after the first weigh only the particles the
  /// first leaves standing (screenOut()); the rest end at -inf and without evidence.
  struct Screen
  {
    const Eigen::VectorXd* prior = nullptr;  ///< the stage's prior log-weights, as tempering takes them
    double min_ess = 0.0;                    ///< the stage's tempering target (an ESS, not a share)
    const std::vector<int>* keep = nullptr;  ///< particles flagged here are never screened out (may be null)
  };
  template <class Take>
  double observe(const StereoGeometry& geometry, int s, Take take, const Screen* screen = nullptr);
  /// Flags in screened_ the particles of set `s` outside the smallest group that carries screen_mass of the
  /// weights `log_weights` give, tempered to `screen`'s target, and marks their hypotheses invalid (saved in
  /// screen_valid_, for observe() to restore). Returns how many it flagged.
  int screenOut(int s, const Screen& screen, const Eigen::VectorXd& log_weights);
  /// Unflags the particles flagged in `flags` whose image in `h` (a set's first view) lies within two apparent
  /// radii of the unflagged particles' mean image: they landed on the track. Returns how many stay flagged.
  int awayFromTrack(const ImageHypotheses& h, std::vector<int>& flags) const;
  /// Refining-stage weights of set `p` (hypotheses `h` of its first view) kept within the share of the particles
  /// flagged in jumped_ (those on the track join the rest: awayFromTrack()) and of the rest. Returns that stage's
  /// log marginal likelihood when it split the set (its weights then sum to one), else 0.
  double keepJumpShares(ParticleSet& p, const ImageHypotheses& h);
  /// Progressive correction, the second stage of a tracking frame: set `s`, weighed by the first-stage cues, is
  /// normalised, resampled and jittered over the region they allow (refine_jitter times their covariance), then
  /// weighed by the cues `refining(model)` selects alone, this frame's recovery jumps and the rest each within
  /// the share the first stage gave them (keepJumpShares()). Returns the log marginal likelihood so far; sets
  /// `escaped` when the jittered set left the viewing volume.
  template <class Refining>
  double refineSecondStage(const StereoGeometry& geometry, int s, Refining refining, bool& escaped);

  std::shared_ptr<StateModel> state_model_;
  std::vector<std::shared_ptr<ObservationModel>> observation_models_;
  EngineConfig config_;

  std::mutex pending_mutex_;
  std::unique_ptr<EngineConfig> pending_config_;
  bool pending_plugin_reconfigure_ = false;
  bool pending_reset_ = false;

  Rng rng_;
  FeatureCache cache_;
  std::vector<ParticleSet> sets_;
  std::vector<ParticleSet> weighted_sets_;  ///< sets_ before the last step's final resampling
  std::vector<ParticleSet> coarse_sets_;    ///< with refining cues: the sets as the other cues weighed them
  std::vector<std::vector<ImageHypotheses>> hypotheses_;
  bool initialised_ = false;
  double last_stamp_ = 0.0;
  /// The last intervals between increasing stamps (a ring; interval_count_ of them known): the camera's period.
  static constexpr int kFrameIntervals = 9;
  static constexpr double kMaxPredictedPeriods = 3.5;  ///< the longest interval a track is predicted over, in periods
  std::array<double, kFrameIntervals> frame_intervals_{};
  int interval_next_ = 0;
  int interval_count_ = 0;
  StateEstimate last_estimate_;  ///< the previous frame's estimate while Tracking (invalid otherwise)
  /// The track's last estimate the evidence saw (Seen or Unsure; invalid while not Tracking), and its stamp: where
  /// a jump arrives from.
  StateEstimate vouched_estimate_;
  double vouched_stamp_ = 0.0;
  /// The last estimate of a Tracking frame whose support was Seen, and its stamp: kept while the track is lost, it
  /// bounds where the object can be found again (withinReacquireReach). Invalid before the first track of a target.
  StateEstimate seen_estimate_;
  double seen_stamp_ = 0.0;
  double seen_speed_ = 0.0;  ///< m/s, the object's speed there (recordSighting)
  /// The Seen estimates of the last kSpeedWindow seconds (stamp, position), oldest first: the speed is fitted to
  /// them, not taken from one frame (recordSighting).
  std::deque<std::pair<double, Eigen::Vector3d>> sightings_;
  static constexpr double kSpeedWindow = 0.3;
  /// The last two tracking estimates the evidence saw (vouched): their left pixels, disparities and stamps (newest
  /// first) and how many are known: the local search's image motion.
  Pixel track_left_[2];
  double track_disparity_[2] = { 0.0, 0.0 };
  double track_stamp_[2] = { 0.0, 0.0 };
  int track_known_ = 0;
  MatchDepthFilter match_depth_;  ///< the local search's matches' depth (local_depth_acceleration)
  /// One local match's disparity error, px (what the search tells apart), and the least spread of its proposals.
  static constexpr double kLocalDisparitySigma = 0.5;
  static constexpr double kMinLocalDisparitySpread = 0.05;
  double track_radius_ = 0.0;  ///< the tracked hypotheses' median apparent radius in the left image, px
  LocalSearch local_search_;
  /// The return watch (return_watch): where and when the last track lost the object and its speed there (the
  /// anchor; invalid: no watch), until when it runs, and how many frames in a row found the object there.
  StateEstimate watch_anchor_;
  double watch_anchor_stamp_ = 0.0;
  double watch_anchor_speed_ = 0.0;
  double watch_until_ = 0.0;
  int watch_hits_ = 0;
  /// The look-alike memory (lookalike_memory): where other objects like the target were seen, when last, and how many
  /// times (one sighting bars nothing: kLookalikeSightings); and this frame's sighting by the recovery search (kept
  /// when the frame turns out seen).
  struct Lookalike
  {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    double stamp = 0.0;
    int sightings = 1;
  };
  static constexpr int kLookalikeSightings = 2;
  static constexpr size_t kMaxLookalikes = 8;
  std::vector<Lookalike> lookalikes_;
  bool lookalike_sighted_ = false;
  Eigen::Vector3d lookalike_sighting_ = Eigen::Vector3d::Zero();
  int local_proposals_ = 0;  ///< how many of proposals_ (the last ones) the local search made this frame
  /// Per set: this frame's recovery jumps are its first jump_rows_[s] particles (0: none). The refining stage
  /// keeps their share and the rest's apart (see refineSecondStage()).
  std::vector<int> jump_rows_;
  /// Per view (left, right): the evidence cues' similarity summed over cues for every particle of the set being
  /// observed, and their trust summed (EngineConfig::one_view_unsure).
  Eigen::VectorXd view_sim_[2];
  double view_cues_[2] = { 0.0, 0.0 };
  TrackState state_ = TrackState::Searching;
  int seen_count_ = 0;
  int unseen_count_ = 0;
  int unsure_count_ = 0;  ///< unsure frames in a row while tracking
  int state_frames_ = 0;
  /// The evidence on the first seen frame of the first track since the target was learned or loaded (-1: none
  /// yet): what the object itself scores, the cap of hold_reference_ and the measure a recovery jump to another
  /// place is held to (reacquire_margin).
  double track_reference_ = -1.0;
  /// What hold_margin and reacquire_margin apply to (EngineConfig::hold_follow): track_reference_, following the
  /// tracks' seen frames; kept while lost.
  double hold_reference_ = -1.0;
  ViewingVolume volume_;
  /// The last acquisition from a box (its match: acquisition_), applied at the next step.
  struct Acquired
  {
    bool pending = false;
    double radius_px = 0.0;   ///< the box's half-size, px
  };
  Acquired acquired_;
  BoxMatch acquisition_;
  std::vector<double> cue_trust_;  ///< per observation model, see cueTrust()
  double target_radius_ = 0.0;
  /// Brightness (FeatureCache::brightness()) of the left image the target was learned from (-1: unknown).
  double target_brightness_ = -1.0;

  // detection-driven proposals of this frame: (left pixel, right pixel) pairs
  std::vector<std::pair<Pixel, Pixel>> proposals_;
  MapProposals map_proposals_;

  // scratch buffers kept across frames
  Eigen::VectorXd scratch_ll_, scratch_sim_, sum_sim_, prior_log_, refine_prior_;
  int screened_count_ = 0;  ///< this frame's FrameResult::screened so far
  std::vector<int> screen_keep_;                        ///< particles a stage never screens out
  Eigen::VectorXd preview_log_weights_;                ///< a set's log-weights with the first model's preview
  std::vector<char> screened_;                          ///< per particle: screened out in this stage
  std::vector<std::vector<unsigned char>> screen_valid_;  ///< each view's valid flags before screening
  std::vector<std::pair<double, int>> screen_order_;   ///< (tempered weight, particle); the heavy ones best first
  ImageHypotheses background_hyp_, adapt_hyp_, adapt_right_hyp_;
  Eigen::VectorXd background_ll_, background_sim_, background_sum_;
  Eigen::VectorXd view_background_sum_[2];  ///< background_sum_ of each view alone
  std::vector<double> median_scratch_;
  std::vector<double> background_values_;
  std::vector<float> radius_scratch_;
  std::vector<int> resample_indices_;
  Eigen::MatrixXd resample_scratch_;
  std::vector<int> jumped_;  ///< which particles are (first stage) or descend from (refining stage) recovery jumps
};

}  // namespace stereo_pf
