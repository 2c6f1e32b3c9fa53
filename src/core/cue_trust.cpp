// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
#include "stereo_pf/core/cue_trust.h"

#include <algorithm>
#include <cmath>

namespace stereo_pf
{
std::vector<double> measureCueTrust(FeatureCache& cache, const std::vector<std::shared_ptr<ObservationModel>>& models,
                                    const Pixel& left, const Pixel& right, double radius_px,
                                    const CueTrustOptions& options)
{
  const int n = static_cast<int>(models.size());
  std::vector<double> contrast(n, 0.0);  // summed over the views measured
  std::vector<int> views(n, 0);
  const double width = cache.geometry().width(), height = cache.geometry().height();
  const double r = std::max(1.0, radius_px);
  for (const auto& [view, at] : { std::make_pair(View::Left, left), std::make_pair(View::Right, right) })
  {
    // Hypothesis 0 is the object; the others are grid places whose window lies in the image, away from it.
    ImageHypotheses hyp;
    hyp.view = view;
    std::vector<Pixel> places{ at };
    for (int y = 0; y < options.rows; ++y)
      for (int x = 0; x < options.columns; ++x)
      {
        const Pixel p{ (x + 0.5) * width / options.columns, (y + 0.5) * height / options.rows };
        if (std::hypot(p.u - at.u, p.v - at.v) > options.exclusion * r && p.u > r && p.v > r && p.u < width - 1 - r &&
            p.v < height - 1 - r)
          places.push_back(p);
      }
    if (places.size() < 4)
      continue;  // the object fills the frame: nothing to compare with
    hyp.resize(static_cast<int>(places.size()));
    for (int j = 0; j < hyp.size(); ++j)
    {
      hyp.u[j] = static_cast<float>(places[j].u);
      hyp.v[j] = static_cast<float>(places[j].v);
      hyp.radius[j] = static_cast<float>(r);
      hyp.valid[j] = 1;
    }
    Eigen::VectorXd ll(hyp.size()), sim(hyp.size());
    std::vector<double> background;
    for (int k = 0; k < n; ++k)
    {
      ObservationModel& m = *models[k];
      if (!m.enabled() || m.comparesViews())
        continue;
      ll.setZero();
      sim.setZero();
      m.evaluate(cache, hyp, ll, sim);
      background.assign(sim.data() + 1, sim.data() + sim.size());
      const auto q = background.begin() +
                     std::min<long>(static_cast<long>(background.size()) - 1,
                                    static_cast<long>(options.quantile * static_cast<double>(background.size())));
      std::nth_element(background.begin(), q, background.end());
      contrast[k] += sim[0] - *q;
      ++views[k];
    }
  }
  std::vector<double> trust(n, 1.0);
  bool any = false;
  for (int k = 0; k < n; ++k)
    if (views[k] > 0)
    {
      trust[k] = std::clamp(contrast[k] / views[k] / options.margin, 0.0, 1.0);
      any = any || trust[k] > 0.0;
    }
  if (!any)
    std::fill(trust.begin(), trust.end(), 1.0);
  return trust;
}

}  // namespace stereo_pf
