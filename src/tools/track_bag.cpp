// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// track_bag: run the tracker (or an OpenCV baseline) over a bag of stereo frames offline (no roscore),
// write a CSV and a summary.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <ros/time.h>

#include "stereo_pf/eval/baseline_tracker.h"
#include "stereo_pf/eval/evaluation.h"
#include "stereo_pf/ros/bag_source.h"
#include "stereo_pf/ros/plugin_loader.h"
#include "stereo_pf/ros/yaml_parameters.h"

namespace
{
const char* kUsage =
    "usage: track_bag BAG [options]\n"
    "  --config YAML            parameters (see config/tracker.yaml for every one and its default)\n"
    "  --set NS/KEY=VALUE       override one parameter (repeatable), e.g. --set state_model/noise=0.02\n"
    "  --state TYPE             state model: Position3D, Velocity3D or StereoConstraints (stereo_pf/ optional)\n"
    "  --particles N            particles (per set)            --seed S   RNG seed\n"
    "  --target-roi x,y,w,h     learn the target from this box of the left image of frame K\n"
    "  --target-frame K         first frame tracked (default 0); without --target-roi the box is the bag's\n"
    "                           ground_truth/target_roi of frame K\n"
    "  --target-model FILE      load a saved target instead (looked for from frame K on)\n"
    "  --save-target FILE       save the learned target\n"
    "  --output CSV             one row per frame: the estimate, its variances and images, ess, state, ms, the\n"
    "                           evidence and background similarity and what they said (support), the\n"
    "                           covariances sxy, sxz, syz, the truth; x..szz and sxy..syz only while tracking\n"
    "                           (what the nodelet publishes as valid)\n"
    "  --left-image T --right-image T --left-info T --right-info T --truth T   topic overrides\n"
    "  --rectified              images are already rectified (e.g. stereo_image_proc's image_rect_color)\n"
    "  --quiet                  only the summary line\n"
    "  --baseline NAME          instead of a particle filter, OpenCV's csrt, kcf or camshift in each image, both\n"
    "                           started from the target box (right box by template matching), centres triangulated;\n"
    "                           the filter's options (--config --set --state --particles --seed --target-model\n"
    "                           --save-target) are refused with it. CSV: sxx..szz, ess, evidence, background and\n"
    "                           sxy..syz are empty, and x..szz too in frames without a 3D estimate (state lost)\n";

struct Options
{
  std::string bag, config, state, target_model, save_target, output;
  std::string baseline;       ///< OpenCV baseline instead of the particle filter (empty: the filter)
  std::vector<std::string> overrides;
  int particles = -1;
  long seed = -1;
  bool has_roi = false;
  cv::Rect roi;
  int target_frame = 0;
  bool rectified = false, quiet = false;
  stereo_pf::BagTopics topics;
};

[[noreturn]] void usageError(const std::string& message)
{
  std::cerr << "track_bag: " << message << "\n" << kUsage;
  std::exit(1);
}

int toInt(const std::string& flag, const std::string& v)
{
  try
  {
    size_t used = 0;
    const long x = std::stol(v, &used);
    if (used != v.size())
      throw std::invalid_argument(v);
    return static_cast<int>(x);
  }
  catch (const std::exception&)
  {
    usageError(flag + " expects an integer, got '" + v + "'");
  }
}

Options parse(int argc, char** argv)
{
  Options o;
  std::vector<std::string> args(argv + 1, argv + argc);
  for (size_t i = 0; i < args.size(); ++i)
  {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= args.size())
        usageError(a + " needs a value");
      return args[++i];
    };
    if (a == "-h" || a == "--help")
    {
      std::cout << kUsage;
      std::exit(0);
    }
    else if (a == "--config")
      o.config = value();
    else if (a == "--set")
      o.overrides.push_back(value());
    else if (a == "--state")
      o.state = value();
    else if (a == "--particles")
      o.particles = toInt(a, value());
    else if (a == "--seed")
      o.seed = toInt(a, value());
    else if (a == "--target-roi")
    {
      const std::string v = value();
      int x, y, w, h;
      char c1, c2, c3;
      std::istringstream s(v);
      if (!(s >> x >> c1 >> y >> c2 >> w >> c3 >> h) || c1 != ',' || c2 != ',' || c3 != ',' || w <= 0 || h <= 0)
        usageError("--target-roi expects x,y,w,h with positive w and h, got '" + v + "'");
      o.roi = cv::Rect(x, y, w, h);
      o.has_roi = true;
    }
    else if (a == "--target-frame")
      o.target_frame = toInt(a, value());
    else if (a == "--target-model")
      o.target_model = value();
    else if (a == "--save-target")
      o.save_target = value();
    else if (a == "--output")
      o.output = value();
    else if (a == "--left-image")
      o.topics.left_image = value();
    else if (a == "--right-image")
      o.topics.right_image = value();
    else if (a == "--left-info")
      o.topics.left_info = value();
    else if (a == "--right-info")
      o.topics.right_info = value();
    else if (a == "--truth")
      o.topics.truth = value();
    else if (a == "--rectified")
      o.rectified = true;
    else if (a == "--quiet")
      o.quiet = true;
    else if (a == "--baseline")
      o.baseline = value();
    else if (!a.empty() && a[0] == '-')
      usageError("unknown option '" + a + "'");
    else if (o.bag.empty())
      o.bag = a;
    else
      usageError("more than one bag given ('" + o.bag + "', '" + a + "')");
  }
  if (o.bag.empty())
    usageError("no bag given");
  if (o.target_frame < 0)
    usageError("--target-frame must be >= 0");
  if (o.has_roi && !o.target_model.empty())
    usageError("give either --target-roi or --target-model, not both");
  if (!o.baseline.empty())
  {
    try
    {
      stereo_pf::parseBaselineType(o.baseline);
    }
    catch (const std::invalid_argument& e)
    {
      usageError(std::string("--baseline: ") + e.what());
    }
    // Refused rather than ignored: a run that silently drops --seed or --config would be misread.
    const std::pair<bool, const char*> filter_only[] = {
      { !o.config.empty(), "--config" },        { !o.overrides.empty(), "--set" },
      { !o.state.empty(), "--state" },          { o.particles >= 0, "--particles" },
      { o.seed >= 0, "--seed" },                { !o.target_model.empty(), "--target-model" },
      { !o.save_target.empty(), "--save-target" }
    };
    for (const auto& f : filter_only)
      if (f.first)
        usageError(std::string(f.second) + " configures the particle filter; --baseline " + o.baseline +
                   " starts from --target-roi or the bag's ground_truth/target_roi and takes no filter options");
  }
  return o;
}

stereo_pf::Parameters buildParameters(const Options& o)
{
  stereo_pf::Parameters p;
  if (!o.config.empty())
    stereo_pf::loadYamlFile(o.config, p);
  if (!o.state.empty())
    p.set("state_model/type", o.state.find('/') == std::string::npos ? "stereo_pf/" + o.state : o.state);
  if (o.particles >= 0)
    p.set("engine/particles", o.particles);
  if (o.seed >= 0)
    p.set("engine/seed", static_cast<int>(o.seed));
  for (const auto& a : o.overrides)
    stereo_pf::applyOverride(a, p);
  return p;
}

/// One frame's output of whichever method runs, as the CSV row and the summary take it. Empty optionals
/// are empty CSV fields: a baseline has no covariance or ESS, and no 3D point while lost.
struct StepResult
{
  std::optional<Eigen::Vector3d> position;  ///< the 3D estimate, when valid
  std::optional<Eigen::Matrix3d> covariance;  ///< its covariance, m^2
  std::optional<stereo_pf::Pixel> left, right;  ///< the estimate in each image
  std::optional<double> ess;                ///< effective sample size
  std::optional<double> evidence, background;  ///< FrameResult's evidence and background similarity
  std::string support;                      ///< what the frame's evidence said (toString(Support))
  stereo_pf::TrackState state = stereo_pf::TrackState::Searching;
};

/// What track_bag runs over the bag: the particle filter or an OpenCV baseline, behind one loop.
class Method
{
public:
  virtual ~Method() = default;
  /// For the progress header, e.g. "stereo_pf/Position3D, 1000 particles per set, seed 1".
  virtual std::string describe() const = 0;
  /// True once the target is known (learned, or loaded before the first frame).
  virtual bool hasTarget() const = 0;
  /// Learn the target from `roi` of the left image; false with `error` when that is impossible.
  virtual bool learn(const stereo_pf::StereoFrame& frame, const cv::Rect& roi, std::string& error) = 0;
  /// Track one frame (timed by the caller).
  virtual StepResult step(const stereo_pf::StereoFrame& frame) = 0;
};

/// The particle filter configured from the options (plugins through pluginlib).
class FilterMethod : public Method
{
public:
  explicit FilterMethod(const Options& o)
    : params_(buildParameters(o)), tracker_(params_), save_target_(o.save_target), quiet_(o.quiet)
  {
    // A misspelt key would otherwise be ignored without a word (the nodelet's own keys are not ours to read).
    for (const auto& m : stereo_pf::unknownParameters(params_, stereo_pf::kRosRuntimeParameters))
      std::cerr << "track_bag: warning: " << m << "\n";
    std::string error;
    if (!o.target_model.empty() && !engine().loadTarget(o.target_model, error))
      throw std::runtime_error(error);
  }

  std::string describe() const override
  {
    const auto& c = tracker_.engine().config();
    return tracker_.pluginTypes().front() + ", " + std::to_string(c.particles) + " particles per set, seed " +
           std::to_string(c.seed);
  }
  bool hasTarget() const override { return tracker_.engine().hasTarget(); }
  bool learn(const stereo_pf::StereoFrame& frame, const cv::Rect& roi, std::string& error) override
  {
    if (!engine().learnTarget(frame, roi, error))
      return false;
    const stereo_pf::BoxMatch& a = engine().acquisition();
    if (a.ok && !a.warning.empty())
      std::fprintf(stderr, "track_bag: warning: %s\n", a.warning.c_str());
    if (a.ok && !quiet_)
      std::printf("acquired: disparity %.2f px (score %.2f), centre (%.3f, %.3f, %.3f) m, radius %.2f cm\n",
                  a.disparity, a.score, a.centre.x(), a.centre.y(), a.centre.z(), 100.0 * a.radius);
    if (a.ok && !quiet_)
    {
      std::printf("cue trust:");
      for (size_t k = 0; k < engine().observationModels().size(); ++k)
        std::printf(" %s %.2f", engine().observationModels()[k]->name().c_str(), engine().cueTrust()[k]);
      std::printf("\n");
    }
    if (!save_target_.empty() && !engine().saveTarget(save_target_, error))
      throw std::runtime_error(error);
    return true;
  }
  StepResult step(const stereo_pf::StereoFrame& frame) override
  {
    const stereo_pf::FrameResult r = engine().step(frame);
    StepResult s;
    if (r.published())  // as the nodelet publishes it
    {
      s.position = r.estimate.position;
      s.covariance = r.estimate.covariance;
    }
    s.left = r.estimate.left;
    s.right = r.estimate.right;
    s.ess = r.ess;
    s.evidence = r.evidence;
    s.background = r.background;
    s.support = stereo_pf::toString(r.support);
    s.state = r.state;
    return s;
  }

private:
  stereo_pf::FilterEngine& engine() { return tracker_.engine(); }

  stereo_pf::Parameters params_;  // before tracker_: it is built from it
  stereo_pf::Tracker tracker_;
  std::string save_target_;
  bool quiet_ = false;
};

/// An OpenCV tracker in each image, triangulated (stereo_pf::StereoBaselineTracker).
class BaselineMethod : public Method
{
public:
  explicit BaselineMethod(const std::string& name) : tracker_(name) {}

  std::string describe() const override
  {
    return "the " + stereo_pf::toString(tracker_.type()) + " baseline (OpenCV, one tracker per image)";
  }
  bool hasTarget() const override { return tracker_.initialised(); }
  bool learn(const stereo_pf::StereoFrame& frame, const cv::Rect& roi, std::string& error) override
  {
    return tracker_.init(frame, roi, error);
  }
  StepResult step(const stereo_pf::StereoFrame& frame) override
  {
    const stereo_pf::BaselineEstimate e = tracker_.update(frame);
    StepResult s;
    if (e.valid)
      s.position = e.position;
    if (e.left_found)
      s.left = e.left;
    if (e.right_found)
      s.right = e.right;
    s.state = e.valid ? stereo_pf::TrackState::Tracking : stereo_pf::TrackState::Lost;
    return s;
  }

private:
  stereo_pf::StereoBaselineTracker tracker_;
};

/// The CSV (when asked for) and the records the summary is computed from: one row per tracked frame,
/// whichever method produced it.
class Recorder
{
public:
  /// `path` empty: no CSV. `with_truth`: the bag has ground truth (adds gt_x,gt_y,gt_z,err).
  Recorder(const std::string& path, bool with_truth) : with_truth_(with_truth)
  {
    if (path.empty())
      return;
    csv_.open(path);
    if (!csv_)
      throw std::runtime_error("cannot write '" + path + "'");
    csv_ << "frame,stamp,x,y,z,sxx,syy,szz,u_left,v_left,u_right,v_right,ess,state,ms,evidence,background,support,"
            "sxy,sxz,syz";
    if (with_truth_)
      csv_ << ",gt_x,gt_y,gt_z,err";
    csv_ << "\n";
    csv_.precision(9);
  }

  /// Record frame `bf` tracked in `ms` milliseconds; returns the record (for progress output).
  const stereo_pf::FrameRecord& add(const stereo_pf::BagFrame& bf, const StepResult& r, double ms)
  {
    stereo_pf::FrameRecord rec;
    rec.has_truth = bf.has_truth;
    rec.truth = bf.truth;
    rec.target_visible = bf.visible;
    rec.estimate_valid = r.position.has_value();
    if (r.position)
      rec.estimate = *r.position;
    rec.tracking = r.state == stereo_pf::TrackState::Tracking;
    rec.ms = ms;
    records_.push_back(rec);
    if (csv_.is_open())
      writeRow(bf, r, rec);
    return records_.back();
  }

  /// Every frame recorded so far.
  const std::vector<stereo_pf::FrameRecord>& records() const { return records_; }

private:
  void writeRow(const stereo_pf::BagFrame& bf, const StepResult& r, const stereo_pf::FrameRecord& rec)
  {
    csv_ << bf.index << "," << bf.frame.stamp;
    for (int i = 0; i < 3; ++i)
      field(r.position ? std::optional<double>((*r.position)[i]) : std::nullopt);
    auto covariance = [&](int i, int j) {
      return r.covariance ? std::optional<double>((*r.covariance)(i, j)) : std::nullopt;
    };
    for (int i = 0; i < 3; ++i)
      field(covariance(i, i));
    for (const auto& px : { r.left, r.right })
    {
      field(px ? std::optional<double>(px->u) : std::nullopt);
      field(px ? std::optional<double>(px->v) : std::nullopt);
    }
    field(r.ess);
    csv_ << "," << stereo_pf::toString(r.state) << "," << rec.ms;
    field(r.evidence);
    field(r.background);
    csv_ << "," << r.support;
    field(covariance(0, 1));
    field(covariance(0, 2));
    field(covariance(1, 2));
    if (with_truth_)
    {
      if (bf.has_truth)
        csv_ << "," << bf.truth.x() << "," << bf.truth.y() << "," << bf.truth.z() << "," << rec.error();
      else
        csv_ << ",,,,";
    }
    csv_ << "\n";
  }
  // ",value", or "," for a value the method does not have.
  void field(const std::optional<double>& v)
  {
    csv_ << ",";
    if (v)
      csv_ << *v;
  }

  bool with_truth_;
  std::ofstream csv_;
  std::vector<stereo_pf::FrameRecord> records_;
};
}  // namespace

int main(int argc, char** argv)
{
  const Options opt = parse(argc, argv);
  ros::Time::init();
  try
  {
    std::unique_ptr<Method> method;
    if (opt.baseline.empty())
      method = std::make_unique<FilterMethod>(opt);
    else
      method = std::make_unique<BaselineMethod>(opt.baseline);

    stereo_pf::BagSource source(opt.bag, opt.topics, opt.rectified);
    Recorder recorder(opt.output, source.hasTruth());
    if (!opt.quiet)
      std::cout << "track_bag: " << opt.bag << " with " << method->describe() << "\n";

    stereo_pf::BagFrame bf;
    bool learned = method->hasTarget();
    std::string error;
    while (source.next(bf))
    {
      // Tracking starts at --target-frame: a box is learned there, and a loaded target is looked for from there
      // (so that a target saved from one clip can be tried on a later part of another).
      if (bf.index < opt.target_frame)
        continue;
      if (!learned)
      {
        cv::Rect roi = opt.roi;
        if (!opt.has_roi)
        {
          if (!bf.has_roi)
            throw std::runtime_error(std::string("no target: give --target-roi x,y,w,h (with --target-frame K)") +
                                     (opt.baseline.empty() ? " or --target-model FILE" : "") +
                                     "; the bag has no ground_truth/target_roi for frame " + std::to_string(bf.index));
          roi = bf.roi;
        }
        if (!method->learn(bf.frame, roi, error))
          throw std::runtime_error("cannot learn the target from frame " + std::to_string(bf.index) + ": " + error);
        learned = true;
      }
      const auto t0 = std::chrono::steady_clock::now();
      const StepResult r = method->step(bf.frame);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const stereo_pf::FrameRecord& rec = recorder.add(bf, r, ms);

      if (!opt.quiet && bf.index % 50 == 0)
      {
        std::printf("frame %4d  %-9s", bf.index, stereo_pf::toString(r.state).c_str());
        if (r.position)
          std::printf("  xyz=(%.3f, %.3f, %.3f)", r.position->x(), r.position->y(), r.position->z());
        else
          std::printf("  no 3D estimate");
        if (bf.has_truth && rec.estimate_valid)
          std::printf("  err=%.1f cm", rec.error() * 100.0);
        if (r.ess)
          std::printf("  ess=%.0f", *r.ess);
        std::printf("  %.2f ms\n", ms);
      }
    }
    // Reasons first: when nothing was usable they are the explanation (e.g. an uncalibrated camera_info).
    for (const auto& kv : source.dropReasons())
      std::cerr << "track_bag: warning: dropped " << kv.second << " frame(s): " << kv.first << "\n";
    const std::string none_after =
        "the bag has no usable frame at or after --target-frame " + std::to_string(opt.target_frame);
    if (!learned)
      throw std::runtime_error(none_after);
    if (recorder.records().empty())  // a loaded target, and no frame from --target-frame on
      throw std::runtime_error(opt.target_frame > 0 ? none_after : std::string("no frame could be tracked"));
    std::cout << stereo_pf::summarise(recorder.records()).line() << std::endl;
    return 0;
  }
  catch (const std::exception& e)
  {
    std::cerr << "track_bag: error: " << e.what() << std::endl;
    return 2;
  }
}
