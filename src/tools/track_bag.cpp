// track_bag: run the tracker over a bag of stereo frames offline (no roscore), write a CSV and a summary.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <ros/time.h>

#include "stereo_pf/core/evaluation.h"
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
    "  --target-frame K         (default 0; without --target-roi the bag's ground_truth/target_roi of frame K)\n"
    "  --target-model FILE      load a saved target instead     --save-target FILE   save the learned one\n"
    "  --output CSV             one row per frame\n"
    "  --left-image T --right-image T --left-info T --right-info T --truth T   topic overrides\n"
    "  --rectified              images are already rectified (e.g. stereo_image_proc's image_rect_color)\n"
    "  --quiet                  only the summary line\n";

struct Options
{
  std::string bag, config, state, target_model, save_target, output;
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
}  // namespace

int main(int argc, char** argv)
{
  const Options opt = parse(argc, argv);
  ros::Time::init();
  try
  {
    stereo_pf::Tracker tracker(buildParameters(opt));
    stereo_pf::FilterEngine& engine = tracker.engine();
    std::string error;
    if (!opt.target_model.empty() && !engine.loadTarget(opt.target_model, error))
      throw std::runtime_error(error);

    stereo_pf::BagSource source(opt.bag, opt.topics, opt.rectified);
    std::ofstream csv;
    if (!opt.output.empty())
    {
      csv.open(opt.output);
      if (!csv)
        throw std::runtime_error("cannot write '" + opt.output + "'");
      csv << "frame,stamp,x,y,z,sxx,syy,szz,u_left,v_left,u_right,v_right,ess,state,ms";
      if (source.hasTruth())
        csv << ",gt_x,gt_y,gt_z,err";
      csv << "\n";
      csv.precision(9);
    }
    if (!opt.quiet)
      std::cout << "track_bag: " << opt.bag << " with " << tracker.pluginTypes().front() << ", "
                << engine.config().particles << " particles per set, seed " << engine.config().seed << "\n";

    std::vector<stereo_pf::FrameRecord> records;
    stereo_pf::BagFrame bf;
    bool learned = engine.hasTarget();
    while (source.next(bf))
    {
      if (!learned)
      {
        if (bf.index < opt.target_frame)
          continue;  // nothing to track before the target is known
        cv::Rect roi = opt.roi;
        if (!opt.has_roi)
        {
          if (!bf.has_roi)
            throw std::runtime_error("no target: give --target-roi x,y,w,h (with --target-frame K) or "
                                     "--target-model FILE; the bag has no ground_truth/target_roi for frame " +
                                     std::to_string(bf.index));
          roi = bf.roi;
        }
        if (!engine.learnTarget(bf.frame, roi, error))
          throw std::runtime_error("cannot learn the target from frame " + std::to_string(bf.index) + ": " + error);
        learned = true;
        if (!opt.save_target.empty() && !engine.saveTarget(opt.save_target, error))
          throw std::runtime_error(error);
      }
      const auto t0 = std::chrono::steady_clock::now();
      const stereo_pf::FrameResult r = engine.step(bf.frame);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

      stereo_pf::FrameRecord rec;
      rec.has_truth = bf.has_truth;
      rec.truth = bf.truth;
      rec.target_visible = bf.visible;
      rec.estimate_valid = r.estimate.valid;
      rec.estimate = r.estimate.position;
      rec.tracking = r.state == stereo_pf::TrackState::Tracking;
      rec.ms = ms;
      records.push_back(rec);

      if (csv.is_open())
      {
        const auto& e = r.estimate;
        csv << bf.index << "," << bf.frame.stamp << "," << e.position.x() << "," << e.position.y() << ","
            << e.position.z() << "," << e.covariance(0, 0) << "," << e.covariance(1, 1) << "," << e.covariance(2, 2)
            << "," << e.left.u << "," << e.left.v << "," << e.right.u << "," << e.right.v << "," << r.ess << ","
            << stereo_pf::toString(r.state) << "," << ms;
        if (source.hasTruth())
        {
          if (bf.has_truth)
            csv << "," << bf.truth.x() << "," << bf.truth.y() << "," << bf.truth.z() << "," << rec.error();
          else
            csv << ",,,,";
        }
        csv << "\n";
      }
      if (!opt.quiet && bf.index % 50 == 0)
      {
        std::printf("frame %4d  %-9s  xyz=(%.3f, %.3f, %.3f)", bf.index, stereo_pf::toString(r.state).c_str(),
                    r.estimate.position.x(), r.estimate.position.y(), r.estimate.position.z());
        if (bf.has_truth)
          std::printf("  err=%.1f cm", rec.error() * 100.0);
        std::printf("  ess=%.0f  %.2f ms\n", r.ess, ms);
      }
    }
    if (!learned)
      throw std::runtime_error("the bag has no usable frame at or after --target-frame " +
                               std::to_string(opt.target_frame));
    for (const auto& kv : source.dropReasons())
      std::cerr << "track_bag: warning: dropped " << kv.second << " frame(s): " << kv.first << "\n";
    if (records.empty())
      throw std::runtime_error("no frame could be tracked");
    std::cout << stereo_pf::summarise(records).line() << std::endl;
    return 0;
  }
  catch (const std::exception& e)
  {
    std::cerr << "track_bag: error: " << e.what() << std::endl;
    return 2;
  }
}
