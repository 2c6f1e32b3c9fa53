// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// my_cues/MeanColour: an example stereo_pf cue from a package of its own (docs/writing_a_cue.md walks through it).
// It compares the mean colour of a window around each hypothesis with the mean colour of the user's box: a weak
// cue on its own, but short enough to read in one sitting, and it exercises every hook a cue must provide.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <pluginlib/class_list_macros.hpp>
#include <stereo_pf/observation_model.h>

namespace my_cues
{
using stereo_pf::FeatureCache;
using stereo_pf::ImageHypotheses;
using stereo_pf::View;

/// Mean-colour likelihood. The window of a hypothesis is a square of half-size `window_scale` x its apparent
/// radius (3D state models), or of side `window` pixels for a 2D hypothesis (radius <= 0: the stereo-constraints
/// model). Its mean colour m (BGR in [0, 1]; a mono image counts as grey) is compared with the target's t by
/// d = |m - t| / sqrt(3): log-likelihood -d^2 / (2 sigma^2), similarity 1 - d / tolerance clamped to [0, 1].
///
/// Parameters (in the cue's namespace): sigma (0.05, 0.001..1), tolerance (0.25, 0.01..1), window_scale
/// (0.6, 0.1..2), window (11 px, 3..101), margin (0.2, 0..0.45: the share of each side of the box left out when
/// learning, to keep the background out). All of them can be changed between frames (reconfigure()).
class MeanColour : public stereo_pf::ObservationModel
{
public:
  bool learnTarget(FeatureCache& cache, View view, const cv::Rect& roi, std::string& error) override
  {
    const cv::Mat& image = cache.image(view);
    const int dx = static_cast<int>(margin_ * roi.width), dy = static_cast<int>(margin_ * roi.height);
    const cv::Rect inner = cv::Rect(roi.x + dx, roi.y + dy, roi.width - 2 * dx, roi.height - 2 * dy) &
                           cv::Rect(0, 0, image.cols, image.rows);
    if (inner.area() < 4)
    {
      error = "the box " + std::to_string(roi.width) + "x" + std::to_string(roi.height) + " at (" +
              std::to_string(roi.x) + ", " + std::to_string(roi.y) + ") keeps fewer than 4 pixels inside the image";
      return false;
    }
    const cv::Scalar m = cv::mean(image(inner));
    for (int c = 0; c < 3; ++c)
      target_[c] = m[image.channels() >= 3 ? c : 0] / 255.0;
    has_target_ = true;
    return true;
  }

  bool hasTarget() const override { return has_target_; }

  void evaluate(FeatureCache& cache, const ImageHypotheses& hyp, Eigen::Ref<Eigen::VectorXd> log_likelihood,
                Eigen::Ref<Eigen::VectorXd> similarity) override
  {
    const cv::Mat& image = cache.image(hyp.view);
    const double worst = -1.0 / (2.0 * sigma_ * sigma_);  // the log-likelihood of the largest distance, d = 1
    for (int i = 0; i < hyp.size(); ++i)
    {
      log_likelihood[i] = worst;
      similarity[i] = 0.0;
      std::array<double, 3> m;
      if (!has_target_ || !hyp.valid[i] || !meanAround(image, hyp.u[i], hyp.v[i], hyp.radius[i], m))
        continue;
      double d2 = 0.0;
      for (int c = 0; c < 3; ++c)
        d2 += (m[c] - target_[c]) * (m[c] - target_[c]);
      d2 /= 3.0;
      log_likelihood[i] = -d2 / (2.0 * sigma_ * sigma_);
      similarity[i] = std::max(0.0, 1.0 - std::sqrt(d2) / tolerance_);
    }
  }

  void saveTarget(cv::FileStorage& fs) const override
  {
    if (!has_target_)
      return;
    fs << name() << "{";
    fs << "type" << "my_cues/MeanColour";
    fs << "mean_bgr" << std::vector<double>(target_.begin(), target_.end());
    fs << "}";
  }

  bool loadTarget(const cv::FileNode& node, std::string& error) override
  {
    // `node` is the map saveTarget() wrote under name().
    const cv::FileNode mean = node["mean_bgr"];
    if (!mean.isSeq() || mean.size() != 3)
    {
      error = name() + ": the target has no 'mean_bgr' list of 3 numbers";
      return false;
    }
    std::vector<double> m;
    mean >> m;
    for (double x : m)
      if (!(x >= 0.0 && x <= 1.0))
      {
        error = name() + ": 'mean_bgr' holds " + std::to_string(x) + ", outside [0, 1]";
        return false;
      }
    std::copy(m.begin(), m.end(), target_.begin());
    has_target_ = true;
    return true;
  }

  void reconfigure() override
  {
    ObservationModel::reconfigure();  // enabled, weight, refine
    readParameters();
  }

protected:
  void onInitialize() override { readParameters(); }

private:
  static constexpr int kSamples = 7;  // per side of the window: a fixed cost per hypothesis, whatever its size

  /// Read and check every parameter before changing any (a bad value throws ParameterError and keeps the old ones).
  void readParameters()
  {
    const stereo_pf::Parameters& p = params();
    // The last argument describes the parameter: dynparam and the reconfigure GUIs show it.
    const double sigma = p.getDouble("sigma", 0.05, 0.001, 1.0, "log-likelihood -d^2 / (2 sigma^2), d: distance");
    const double tolerance = p.getDouble("tolerance", 0.25, 0.01, 1.0, "similarity 1 - d / tolerance");
    const double window_scale = p.getDouble("window_scale", 0.6, 0.1, 2.0, "window half-size in apparent radii");
    const int window = p.getInt("window", 11, 3, 101, "px; window side of hypotheses without a radius");
    const double margin = p.getDouble("margin", 0.2, 0.0, 0.45, "share of each side of the box left out when learning");
    sigma_ = sigma;
    tolerance_ = tolerance;
    window_scale_ = window_scale;
    window_ = window;
    margin_ = margin;
  }

  /// The mean colour of the window of a hypothesis at (u, v) with apparent radius r; false when the centre is not
  /// finite or fewer than a quarter of the samples fall inside the image.
  bool meanAround(const cv::Mat& image, float u, float v, float r, std::array<double, 3>& m) const
  {
    if (!std::isfinite(u) || !std::isfinite(v))
      return false;
    const double half = r > 0.0f ? std::max(1.0, window_scale_ * r) : 0.5 * (window_ - 1);
    const int channels = image.channels();
    double sum[3] = { 0.0, 0.0, 0.0 };
    int inside = 0;
    for (int sy = 0; sy < kSamples; ++sy)
    {
      const int y = static_cast<int>(std::lround(v - half + 2.0 * half * sy / (kSamples - 1)));
      if (y < 0 || y >= image.rows)
        continue;
      const uint8_t* row = image.ptr<uint8_t>(y);
      for (int sx = 0; sx < kSamples; ++sx)
      {
        const int x = static_cast<int>(std::lround(u - half + 2.0 * half * sx / (kSamples - 1)));
        if (x < 0 || x >= image.cols)
          continue;
        const uint8_t* px = row + x * channels;
        for (int c = 0; c < 3; ++c)
          sum[c] += px[channels >= 3 ? c : 0];
        ++inside;
      }
    }
    if (4 * inside < kSamples * kSamples)
      return false;
    for (int c = 0; c < 3; ++c)
      m[c] = sum[c] / (255.0 * inside);
    return true;
  }

  std::array<double, 3> target_{ { 0.0, 0.0, 0.0 } };
  bool has_target_ = false;
  double sigma_ = 0.05, tolerance_ = 0.25, window_scale_ = 0.6, margin_ = 0.2;
  int window_ = 11;
};

}  // namespace my_cues

PLUGINLIB_EXPORT_CLASS(my_cues::MeanColour, stereo_pf::ObservationModel)
