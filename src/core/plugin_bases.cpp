// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// Non-virtual initialisation of the plugin base classes (DESIGN style 2).
#include "stereo_pf/observation_model.h"
#include "stereo_pf/state_model.h"

#include <limits>
#include <stdexcept>

namespace stereo_pf
{
void ObservationModel::initialize(const std::string& name, const Parameters& params)
{
  name_ = name;
  params_ = params;
  readCommon();
  onInitialize();
}

void ObservationModel::readCommon()
{
  enabled_ = params_.getBool("enabled", true, "use this cue (false: it scores nothing)");
  weight_ = params_.getDouble("weight", defaultWeight(), 0.0, 100.0, "exponent on this cue's likelihood");
  refine_ = params_.getBool("refine", refinesByDefault(),
                            "a refining cue: while tracking, applied after the others on the resampled, jittered set "
                            "(see engine/refine_jitter)");
}

void ObservationModel::reconfigure()
{
  readCommon();
}

void ObservationModel::evaluatePair(FeatureCache&, const ImageHypotheses&, const ImageHypotheses&,
                                    Eigen::Ref<Eigen::VectorXd>, Eigen::Ref<Eigen::VectorXd>)
{
  throw std::logic_error(name_ + ": evaluatePair() called on a model that does not compare views");
}

void StateModel::initialize(const std::string& name, const Parameters& params)
{
  name_ = name;
  params_ = params;
  onInitialize();
}

}  // namespace stereo_pf
