// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/eval/baseline_tracker.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#include <opencv2/tracking.hpp>
#include <opencv2/video/tracking.hpp>

#include "stereo_pf/core/histogram.h"

namespace stereo_pf
{
std::string toString(BaselineType type)
{
  switch (type)
  {
    case BaselineType::Csrt:
      return "csrt";
    case BaselineType::Kcf:
      return "kcf";
    case BaselineType::CamShift:
      return "camshift";
  }
  return "?";
}

BaselineType parseBaselineType(const std::string& name)
{
  for (BaselineType t : { BaselineType::Csrt, BaselineType::Kcf, BaselineType::CamShift })
    if (name == toString(t))
      return t;
  throw std::invalid_argument("unknown baseline '" + name + "' (allowed: csrt, kcf, camshift)");
}

namespace
{
// Centre of a box in OpenCV's pixel-centre convention (pixel c spans [c - 0.5, c + 0.5]).
Pixel centreOf(const cv::Rect& box)
{
  Pixel p;
  p.u = box.x + 0.5 * (box.width - 1);
  p.v = box.y + 0.5 * (box.height - 1);
  return p;
}
}  // namespace

/// One image's tracker. CSRT and KCF are opencv_contrib trackers; CamShift keeps its own hue histogram
/// and search window.
class StereoBaselineTracker::ViewTracker
{
public:
  ViewTracker(BaselineType type, const BaselineConfig& config) : type_(type), config_(config) {}

  bool init(const cv::Mat& image, const cv::Rect& box, std::string& error)
  {
    const cv::Mat& bgr = colour(image);
    if (type_ != BaselineType::CamShift)
    {
      try
      {
        if (type_ == BaselineType::Csrt)
          tracker_ = cv::TrackerCSRT::create();
        else
          tracker_ = cv::TrackerKCF::create();
        tracker_->init(bgr, box);
      }
      catch (const cv::Exception& e)
      {
        error = toString(type_) + " could not start on the box " + describeRect(box) + ": " + e.what();
        return false;
      }
      return true;
    }
    if (image.channels() != 3)
    {
      error = "camshift needs colour images (it tracks a hue histogram)";
      return false;
    }
    hueAndMask(bgr);
    const int channel = 0, bins = config_.hue_bins;
    const float hue_range[] = { 0.0f, 180.0f };
    const float* ranges[] = { hue_range };
    const cv::Mat hsv_box = hsv_(box), mask_box = mask_(box);
    cv::calcHist(&hsv_box, 1, &channel, mask_box, hist_, 1, &bins, ranges);
    // A box of grey or dark pixels has no hue to track: refuse it rather than track noise.
    const int coloured = cv::countNonZero(mask_box);
    if (coloured < std::max(9, box.area() / 20))
    {
      error = "camshift: the box " + describeRect(box) + " has too few saturated pixels (" +
              std::to_string(coloured) + ") for a hue histogram";
      return false;
    }
    cv::normalize(hist_, hist_, 0, 255, cv::NORM_MINMAX);
    backProject();
    window_ = box;
    init_mass_ = cv::sum(back_projection_(window_))[0];
    return true;
  }

  /// Track into `image`; false when the tracker reports failure (box and centre then hold its last output).
  bool update(const cv::Mat& image, cv::Rect& box, Pixel& centre)
  {
    const cv::Mat& bgr = colour(image);
    if (type_ != BaselineType::CamShift)
    {
      const bool ok = tracker_->update(bgr, box);
      centre = centreOf(box);
      return ok && box.area() > 0;
    }
    hueAndMask(bgr);
    backProject();
    cv::Rect window = window_;
    const cv::TermCriteria stop(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 10, 1.0);
    const cv::RotatedRect found = cv::CamShift(back_projection_, window, stop);
    window &= cv::Rect(0, 0, image.cols, image.rows);
    if (window.area() <= 0)
    {
      box = window_;  // collapsed: search the last window again next frame
      centre = centreOf(box);
      return false;
    }
    window_ = window;
    box = window;
    centre.u = found.center.x;  // the mass centroid, sub-pixel
    centre.v = found.center.y;
    // Too little target colour left in the window: occluded, or drifted onto something else.
    return cv::sum(back_projection_(window_))[0] >= config_.min_mass_ratio * init_mass_;
  }

private:
  // The image as 3-channel BGR (mono images are expanded; colour ones are used as they are).
  const cv::Mat& colour(const cv::Mat& image)
  {
    if (image.channels() == 3)
      return image;
    cv::cvtColor(image, bgr_, cv::COLOR_GRAY2BGR);
    return bgr_;
  }

  // HSV of the image and the mask of pixels with a meaningful hue (enough saturation and value).
  void hueAndMask(const cv::Mat& bgr)
  {
    cv::cvtColor(bgr, hsv_, cv::COLOR_BGR2HSV);
    cv::inRange(hsv_, cv::Scalar(0, config_.min_saturation, config_.min_value), cv::Scalar(180, 255, 255), mask_);
  }

  // Back-projection of the hue histogram, zero where the hue is unreliable.
  void backProject()
  {
    const int channel = 0;
    const float hue_range[] = { 0.0f, 180.0f };
    const float* ranges[] = { hue_range };
    cv::calcBackProject(&hsv_, 1, &channel, hist_, back_projection_, ranges);
    back_projection_ &= mask_;
  }

  BaselineType type_;
  BaselineConfig config_;
  cv::Ptr<cv::Tracker> tracker_;         ///< CSRT / KCF
  cv::Mat bgr_, hsv_, mask_, back_projection_, hist_;  ///< scratch buffers and CamShift's histogram
  cv::Rect window_;                      ///< CamShift's search window
  double init_mass_ = 0.0;               ///< CamShift: back-projection mass in the initial box
};

StereoBaselineTracker::StereoBaselineTracker(BaselineType type, const BaselineConfig& config)
  : type_(type), config_(config)
{
}

StereoBaselineTracker::StereoBaselineTracker(const std::string& type, const BaselineConfig& config)
  : StereoBaselineTracker(parseBaselineType(type), config)
{
}

StereoBaselineTracker::~StereoBaselineTracker() = default;

RightMatch StereoBaselineTracker::matchRight(const StereoFrame& frame, const cv::Rect& left_roi, int max_disparity,
                                             double min_score)
{
  RightMatch m;
  const cv::Rect roi = left_roi & cv::Rect(0, 0, frame.left.cols, frame.left.rows);
  if (roi.area() <= 0 || frame.right.size() != frame.left.size() || max_disparity < 0)
    return m;
  // Rectified pair: the right view of the box is on the same rows, shifted left by the disparity.
  const int x0 = std::max(0, roi.x - max_disparity);
  const cv::Rect band(x0, roi.y, roi.x + roi.width - x0, roi.height);
  cv::Mat scores;
  cv::matchTemplate(frame.right(band), frame.left(roi), scores, cv::TM_CCOEFF_NORMED);
  double best = 0.0;
  cv::Point at;
  cv::minMaxLoc(scores, nullptr, &best, nullptr, &at);
  if (!std::isfinite(best))
    return m;  // a uniform template has no defined correlation
  // Sub-pixel peak: a parabola through the best score and its neighbours.
  double offset = 0.0;
  if (at.x > 0 && at.x + 1 < scores.cols)
  {
    const double a = scores.at<float>(0, at.x - 1), b = best, c = scores.at<float>(0, at.x + 1);
    const double curvature = a - 2.0 * b + c;
    if (curvature < 0.0)
      offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
  }
  m.score = best;
  m.disparity = roi.x - (x0 + at.x + offset);
  m.roi = cv::Rect(x0 + at.x, roi.y, roi.width, roi.height);
  m.found = best >= min_score;
  return m;
}

bool StereoBaselineTracker::init(const StereoFrame& frame, const cv::Rect& left_roi, std::string& error)
{
  initialised_ = false;
  left_.reset();
  right_.reset();
  initial_right_roi_ = cv::Rect();
  const std::string invalid = frame.validate();
  if (!invalid.empty())
  {
    error = invalid;
    return false;
  }
  const cv::Rect roi = left_roi & cv::Rect(0, 0, frame.left.cols, frame.left.rows);
  if (roi.width < 4 || roi.height < 4)
  {
    error = "the target box " + describeRect(left_roi) + " leaves less than 4x4 pixels inside the image";
    return false;
  }
  const RightMatch match = matchRight(frame, roi, config_.max_disparity, config_.min_match_score);
  if (!match.found)
  {
    std::ostringstream s;
    s << "the target box " << describeRect(roi) << " has no match in the right image within "
      << config_.max_disparity << " px of disparity (best score " << match.score << ", need "
      << config_.min_match_score << ")";
    error = s.str();
    return false;
  }
  auto left = std::make_unique<ViewTracker>(type_, config_);
  auto right = std::make_unique<ViewTracker>(type_, config_);
  if (!left->init(frame.left, roi, error))
  {
    error = "left image: " + error;
    return false;
  }
  if (!right->init(frame.right, match.roi, error))
  {
    error = "right image: " + error;
    return false;
  }
  left_ = std::move(left);
  right_ = std::move(right);
  initial_right_roi_ = match.roi;
  initialised_ = true;
  return true;
}

BaselineEstimate StereoBaselineTracker::update(const StereoFrame& frame)
{
  if (!initialised_)
    throw std::logic_error("StereoBaselineTracker::update before a successful init");
  const std::string invalid = frame.validate();
  if (!invalid.empty())
    throw std::invalid_argument("StereoBaselineTracker::update: " + invalid);
  BaselineEstimate e;
  e.left_found = left_->update(frame.left, e.left_box, e.left);
  e.right_found = right_->update(frame.right, e.right_box, e.right);
  // In a rectified pair both centres lie on one row; boxes rows apart are on different things (a tracker
  // drifted onto a look-alike), and triangulating them would report a confident wrong point.
  if (e.left_found && e.right_found && std::abs(e.left.v - e.right.v) <= config_.max_row_difference)
  {
    // Rows agree up to tracker noise: use their mean.
    Pixel left = e.left;
    left.v = 0.5 * (e.left.v + e.right.v);
    e.valid = frame.geometry.triangulate(left, e.right.u, e.position) && e.position.allFinite();
  }
  return e;
}

}  // namespace stereo_pf
