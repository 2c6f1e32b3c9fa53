// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/acquisition.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace stereo_pf
{
std::string boxText(const cv::Rect& box)
{
  std::ostringstream o;
  o << box.x << "," << box.y << "," << box.width << "," << box.height;
  return o.str();
}

namespace
{
/// Candidates (peaks of the correlation along the rows, best first) checked left against right before giving up.
constexpr size_t kMaxCandidates = 4;

BoxMatch failure(const cv::Rect& box, const std::string& why)
{
  BoxMatch m;
  m.error = "box " + boxText(box) + ": " + why;
  return m;
}

/// The weighted template: for each used pixel of the left window, its offset in the window, its weight and
/// its channel values with each channel's weighted mean removed.
struct Template
{
  std::vector<cv::Point> offsets;
  std::vector<float> weights;
  std::vector<float> centred;  ///< offsets.size() * channels values
  double norm2 = 0.0;          ///< sum of w * centred^2
  double weight_sum = 0.0;     ///< sum of w over pixels
};

/// Fill `t`'s values from the window of `image` (CV_32F, any channels) whose top-left corner is `at`.
void fillTemplate(const cv::Mat& image, cv::Point at, Template& t)
{
  const int channels = image.channels();
  std::vector<double> sum(channels, 0.0);
  t.centred.resize(t.offsets.size() * channels);
  for (size_t i = 0; i < t.offsets.size(); ++i)
  {
    const float* px = image.ptr<float>(at.y + t.offsets[i].y) + (at.x + t.offsets[i].x) * channels;
    const double w = t.weights[i];
    for (int c = 0; c < channels; ++c)
    {
      t.centred[i * channels + c] = px[c];
      sum[c] += w * px[c];
    }
  }
  t.norm2 = 0.0;
  for (size_t i = 0; i < t.offsets.size(); ++i)
    for (int c = 0; c < channels; ++c)
    {
      float& v = t.centred[i * channels + c];
      v = static_cast<float>(v - sum[c] / t.weight_sum);
      t.norm2 += t.weights[i] * static_cast<double>(v) * v;
    }
}

/// Weighted zero-mean normalised correlation of `t` with the window of `image` whose top-left corner is `at`.
double correlate(const Template& t, const cv::Mat& image, cv::Point at)
{
  const int channels = image.channels();
  double s_sum[4] = { 0.0, 0.0, 0.0, 0.0 }, s2_sum = 0.0, cross = 0.0;
  for (size_t i = 0; i < t.offsets.size(); ++i)
  {
    const float* px = image.ptr<float>(at.y + t.offsets[i].y) + (at.x + t.offsets[i].x) * channels;
    const double w = t.weights[i];
    for (int c = 0; c < channels; ++c)
    {
      s_sum[c] += w * px[c];
      s2_sum += w * px[c] * px[c];
      cross += w * t.centred[i * channels + c] * px[c];
    }
  }
  // Per channel, sum w (t - mt)(s - ms) = sum w (t - mt) s, since sum w (t - mt) = 0.
  double var_s = s2_sum;
  for (int c = 0; c < channels; ++c)
    var_s -= s_sum[c] * s_sum[c] / t.weight_sum;
  return var_s > 1e-9 && t.norm2 > 0.0 ? cross / std::sqrt(t.norm2 * var_s) : 0.0;
}

/// Half the size of a sphere's image along one image axis: of the interval between the two planes through the
/// optical centre that touch the sphere (exact for a pinhole camera; `c` is the centre's coordinate along that
/// axis, `z` its depth, `f` the focal length along that axis; 0 when the sphere reaches the camera). Its middle
/// is StereoGeometry::projectSphere().
double sphereHalfExtent(double c, double z, double r, double f)
{
  const double d = std::hypot(c, z);
  if (!(r < d) || !(z > 0.0))
    return 0.0;
  const double a = std::atan2(c, z), b = std::asin(r / d);
  return 0.5 * f * (std::tan(a + b) - std::tan(a - b));
}

/// The sphere whose images have box centres (left u, v), right u and box half-sizes (hu, hv): starts from
/// the triangulated box centres and removes the perspective shift of a sphere's image from the projection
/// of its centre (which grows with the sphere's angular size and its distance off the axis).
void sphereFromBoxes(const StereoGeometry& g, const Pixel& left, double right_u, double hu, double hv,
                     Eigen::Vector3d& centre, double& radius)
{
  g.triangulate(left, right_u, centre);
  radius = 0.5 * (hu * centre.z() / g.fx() + hv * centre.z() / g.fy());
  for (int it = 0; it < 8; ++it)
  {
    const double half_u = sphereHalfExtent(centre.x(), centre.z(), radius, g.fx());
    const double half_v = sphereHalfExtent(centre.y(), centre.z(), radius, g.fy());
    if (!(half_u > 0.0 && half_v > 0.0))
      return;
    const Pixel l = g.projectLeft(centre), ml = g.projectSphere(centre, radius, View::Left);
    const double r_u = g.projectRight(centre).u, mr_u = g.projectSphere(centre, radius, View::Right).u;
    const Pixel corrected{ left.u - (ml.u - l.u), left.v - (ml.v - l.v) };
    Eigen::Vector3d next;
    if (!g.triangulate(corrected, right_u - (mr_u - r_u), next))
      return;
    centre = next;
    radius *= 0.5 * (hu / half_u + hv / half_v);
  }
}
}  // namespace

BoxMatch matchBox(const StereoFrame& frame, const cv::Rect& box, const BoxMatchOptions& o)
{
  const std::string invalid = frame.validate();
  if (!invalid.empty())
    return failure(box, "unusable frame: " + invalid);
  const cv::Rect image(0, 0, frame.left.cols, frame.left.rows);
  if (box.width < 3 || box.height < 3)
    return failure(box, "too small to match (at least 3x3 pixels)");
  if ((box & image) != box)
    return failure(box, "not inside the " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                            " image");

  // The window: the box grown to ring_scale, clipped to the image.
  const double cu = box.x + (box.width - 1) / 2.0, cv_ = box.y + (box.height - 1) / 2.0;
  const double hu = box.width / 2.0, hv = box.height / 2.0;
  const double scale = std::max(1.0, o.ring_scale);
  const cv::Rect grown(static_cast<int>(std::floor(cu - hu * scale + 0.5)),
                       static_cast<int>(std::floor(cv_ - hv * scale + 0.5)), static_cast<int>(std::ceil(2 * hu * scale)),
                       static_cast<int>(std::ceil(2 * hv * scale)));
  const cv::Rect window = grown & image;

  cv::Mat left, right;
  frame.left.convertTo(left, CV_32F);
  frame.right.convertTo(right, CV_32F);

  // Weights: the inscribed ellipse counts fully, the ring around it (the outline against the surroundings)
  // partly; the window's corners not at all.
  Template t;
  for (int y = window.y; y < window.y + window.height; ++y)
    for (int x = window.x; x < window.x + window.width; ++x)
    {
      const double du = (x - cu) / hu, dv = (y - cv_) / hv;
      const double r = std::sqrt(du * du + dv * dv);
      const double w = r <= 1.0 ? 1.0 : (r <= scale ? o.ring_weight : 0.0);
      if (w <= 0.0)
        continue;
      t.offsets.emplace_back(x - window.x, y - window.y);
      t.weights.push_back(static_cast<float>(w));
      t.weight_sum += w;
    }
  fillTemplate(left, window.tl(), t);
  // Under one grey level of spread: nothing to correlate (a flat box on a flat background).
  if (t.norm2 < t.weight_sum * 1.0)
    return failure(box, "has no contrast to match in the right image (a uniform region)");

  // Candidate disparities: 0 (infinitely far) up to where the window leaves the right image.
  const int max_d = window.x;
  BoxMatch m;
  m.first_disparity = 0;
  m.scores.assign(max_d + 1, -1.0);
  for (int d = 0; d <= max_d; ++d)
    m.scores[d] = correlate(t, right, cv::Point(window.x - d, window.y));

  // The peaks, best first, each farther than `apart` from every better one (not a shoulder of it).
  const int apart = std::max(2, box.width / 2);
  std::vector<int> peaks;
  for (int d = 0; d <= max_d; ++d)
    if ((d == 0 || m.scores[d] >= m.scores[d - 1]) && (d == max_d || m.scores[d] >= m.scores[d + 1]))
      peaks.push_back(d);
  std::stable_sort(peaks.begin(), peaks.end(), [&](int a, int b) { return m.scores[a] > m.scores[b]; });
  std::vector<int> distinct;
  for (int d : peaks)
    if (std::none_of(distinct.begin(), distinct.end(), [&](int k) { return std::abs(d - k) <= apart; }))
      distinct.push_back(d);

  // Left-right check: what the right image shows at a candidate disparity, looked for in the left image along the
  // same rows, must be found back at the box, not elsewhere. A patch of the surroundings that happens to
  // correlate with the box (the box's own outline blurred, a smooth backdrop) fails it: its best match in the
  // left image is where that patch itself lies. The best candidates that fail it are passed over.
  auto backCheck = [&](int d, int& back_best) {
    const int xr = window.x - d;
    Template b = t;  // the same pixels and weights, from the right image
    fillTemplate(right, cv::Point(xr, window.y), b);
    const int max_back = left.cols - window.width - xr;
    double best_score = -2.0, near_score = -2.0;
    back_best = d;
    for (int k = 0; k <= max_back; ++k)
    {
      const double s = correlate(b, left, cv::Point(xr + k, window.y));
      if (s > best_score)
      {
        best_score = s;
        back_best = k;
      }
      if (std::abs(k - d) <= apart)
        near_score = std::max(near_score, s);
    }
    return near_score >= best_score - o.ambiguity_margin;
  };
  // The object's size across in baselines that a candidate implies is the box's size over the disparity.
  const int extent = std::max(box.width, box.height);
  auto plausible = [&](int d) { return !(o.max_size_baselines > 0.0) || extent <= o.max_size_baselines * d; };
  int best = distinct.front();  // never empty: the highest score is a peak
  size_t chosen = distinct.size();
  int rejected = -1, rejected_back = 0;
  int oversized = -1;  // a candidate that passed but implied too large an object, when a later one is taken
  for (size_t k = 0; k < distinct.size() && k < kMaxCandidates && m.scores[distinct[k]] >= o.min_score; ++k)
  {
    int back = 0;
    if (backCheck(distinct[k], back))
    {
      // The first that passes, unless a later one that passes implies a plausible size and it does not.
      const bool sized = plausible(distinct[k]);
      if (sized && chosen != distinct.size())
        oversized = best;
      if (chosen == distinct.size() || sized)
      {
        chosen = k;
        best = distinct[k];
      }
      if (sized)
        break;
      continue;
    }
    if (rejected < 0)
    {
      rejected = distinct[k];
      rejected_back = back;
    }
  }
  m.score = m.scores[best];

  std::ostringstream why;
  why.precision(2);
  why.setf(std::ios::fixed);
  // A refusal still reports the scores along the rows (BoxMatch::scores), as a match does.
  auto refuse = [&]() {
    BoxMatch f = failure(box, why.str());
    f.scores = m.scores;
    return f;
  };
  if ((m.score < o.min_score || chosen == distinct.size()) && o.ring_weight > 0.0)
  {
    // The ring carries the outline against what lies behind the object; close up, the two cameras see
    // different surroundings (and sides) of it, and the ring then spoils the match: the object alone may still
    // match (a cylinder 0.72 m away in a JPEG-compressed grey image: 0.44 with the ring, 0.76 without, its
    // depth 5 % short as its two sides differ between the views).
    BoxMatchOptions core = o;
    core.ring_weight = 0.0;
    BoxMatch alone = matchBox(frame, box, core);
    if (alone.ok)
      return alone;
  }
  if (m.score < o.min_score)
  {
    why << "no match in the right image along rows " << box.y << ".." << box.y + box.height - 1
        << " (best correlation " << m.score << " at disparity " << best << ", below " << o.min_score << ")";
    // What the best candidate would mean: close up, the two cameras see the object from directions far apart.
    const StereoGeometry& g = frame.geometry;
    if (best > 0 && g.baseline() > 0.0)
      why << "; there it would be " << g.fx() * g.baseline() / best << " m away, seen by the two cameras from "
          << std::atan2(static_cast<double>(best), g.fx()) * 180.0 / M_PI
          << " degrees apart (if it is that close, its sides and what lies behind it differ between the views: "
             "teach it from further away)";
    return refuse();
  }
  if (chosen == distinct.size())
  {
    why << "no consistent match in the right image: its best candidate, disparity " << rejected << " (correlation "
        << m.scores[rejected] << "), shows something that matches the left image better at disparity "
        << rejected_back << " (something else in the view, not the box's object)";
    return refuse();
  }
  // The strongest other candidate not shown to be something else: one about as good as the best is checked too.
  // Beside a match of a plausible size, one implying a larger object is no rival (it would not be taken).
  const bool sized = plausible(best);
  for (size_t k = chosen + 1; k < distinct.size(); ++k)
  {
    const int d = distinct[k];
    int back = 0;
    if (sized && !plausible(d))
      continue;
    if (m.scores[d] > m.score - o.ambiguity_margin && k <= chosen + kMaxCandidates && !backCheck(d, back))
      continue;
    m.second_score = m.scores[d];
    m.second_disparity = d;
    break;
  }
  if (m.second_score > m.score - o.ambiguity_margin)
  {
    why << "ambiguous: it matches the right image at disparity " << best << " (correlation " << m.score
        << ") and at " << m.second_disparity << " (" << m.second_score
        << "); draw a tighter box or teach the target on a frame where only one such object is in view";
    BoxMatch f = refuse();
    f.second_score = m.second_score;
    f.second_disparity = m.second_disparity;
    return f;
  }

  // Sub-pixel: the vertex of the parabola through the best score and its neighbours.
  double d = best;
  if (best > 0 && best < max_d)
  {
    const double a = m.scores[best - 1], b = m.scores[best], c = m.scores[best + 1];
    const double curvature = a - 2 * b + c;
    if (curvature < 0.0)
      d += std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
  }
  if (d < o.min_disparity)
  {
    why << "too far to measure: disparity " << d << " px is below " << o.min_disparity << " px";
    return refuse();
  }

  const StereoGeometry& g = frame.geometry;
  if (oversized >= 0)
  {
    // Taken, but the user should know: what the box holds is mostly what lies behind the object, and the cues
    // learn from the box. (`why` is still empty: nothing was refused.)
    why << "box " << boxText(box) << ": its best match along the rows, disparity " << oversized << " (correlation "
        << m.scores[oversized] << "), would put the object ";
    if (oversized > 0)
      why << "at " << g.fx() * g.baseline() / oversized << " m, " << static_cast<double>(extent) / oversized
          << " baselines across";
    else
      why << "infinitely far";
    why << "; taken at disparity " << d << " (" << m.score
        << ") instead. The box shows mostly what lies behind the object: a box tight around it teaches the object, "
           "not its surroundings";
    m.warning = why.str();
  }
  m.ok = true;
  m.disparity = d;
  m.left = Pixel{ cu, cv_ };
  m.right = Pixel{ cu - d, cv_ };
  sphereFromBoxes(g, m.left, m.right.u, hu, hv, m.centre, m.radius);
  const double z = m.centre.z();
  m.depth_sigma = z * z / (g.fx() * g.baseline()) * 0.25;
  return m;
}

}  // namespace stereo_pf
