#include "stereo_pf/core/feature_cache.h"

#include <opencv2/imgproc.hpp>

namespace stereo_pf
{
void FeatureCache::reset(const StereoFrame& frame)
{
  frame_ = frame;  // cv::Mat headers only: no pixel copy
  ++frame_id_;
}

const cv::Mat& FeatureCache::get(View view, const std::string& key, const Compute& compute)
{
  Entry& e = entries_[key];
  const int k = static_cast<int>(view);
  if (e.frame_id[k] != frame_id_)
  {
    compute(frame_.image(view), e.mat[k]);
    e.frame_id[k] = frame_id_;
    ++compute_count_;
  }
  return e.mat[k];
}

const cv::Mat& FeatureCache::gray(View view)
{
  return get(view, "gray", [](const cv::Mat& image, cv::Mat& out) {
    if (image.channels() == 3)
      cv::cvtColor(image, out, cv::COLOR_BGR2GRAY);
    else
      image.copyTo(out);
  });
}

const cv::Mat& FeatureCache::gradientX(View view)
{
  const cv::Mat& g = gray(view);
  return get(view, "sobel_x", [&g](const cv::Mat&, cv::Mat& out) { cv::Sobel(g, out, CV_32F, 1, 0, 3); });
}

const cv::Mat& FeatureCache::gradientY(View view)
{
  const cv::Mat& g = gray(view);
  return get(view, "sobel_y", [&g](const cv::Mat&, cv::Mat& out) { cv::Sobel(g, out, CV_32F, 0, 1, 3); });
}

const cv::Mat& FeatureCache::gradientMagnitude(View view)
{
  const cv::Mat& gx = gradientX(view);
  const cv::Mat& gy = gradientY(view);
  return get(view, "sobel_magnitude", [&gx, &gy](const cv::Mat&, cv::Mat& out) { cv::magnitude(gx, gy, out); });
}

}  // namespace stereo_pf
