#pragma once
/// Pseudo-labels for self-training on unlabelled strikes of a new tube (`train --init-from RUN
/// --pseudo-labels F`): the pretrained run answers each strike, the answers it is surest of
/// become the labels of a fine-tune. Private to experiments.

#include <cstdint>
#include <vector>

#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

struct PseudoLabelSelection {
  std::vector<int64_t> rows;    // kept records, in their order in the set
  double spread_limit_cm{0.0};  // the largest predictive spread kept, cm (NaN: no ranking)
};

/// Predictive spread of one answer on the surface, cm: sqrt(z_std^2 + (r * circular std of
/// theta)^2). NaN for an answer without a distribution.
double PredictiveSpreadCm(const learning::Prediction& p, double surface_radius_m);

/// The ceil(keep_fraction * N) records of smallest spread (ties: lower row first), at least one.
/// keep_fraction = 1 keeps every record and needs no distribution. ConfigError naming
/// --pseudo-labels for keep_fraction outside (0, 1], or below 1 when an answer carries no
/// distribution (nothing to rank by); for no predictions at all.
PseudoLabelSelection SelectPseudoLabels(const std::vector<learning::Prediction>& predictions,
                                        double keep_fraction, double surface_radius_m);

/// Rows `rows` of `features`, their labels replaced by the predictions' z and theta.
learning::FeatureSet WithPseudoLabels(const learning::FeatureSet& features,
                                      const std::vector<learning::Prediction>& predictions,
                                      const std::vector<int64_t>& rows);

}  // namespace sonicboom::experiments
