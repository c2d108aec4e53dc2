// Which of a pretrained run's answers to unlabelled strikes become labels
// (internal/pseudo_labels.h).
#include "internal/pseudo_labels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {

double PredictiveSpreadCm(const learning::Prediction& p, double surface_radius_m) {
  if (!p.has_uncertainty()) return std::numeric_limits<double>::quiet_NaN();
  const double along_m = surface_radius_m * learning::VonMisesCircularStd(p.theta_kappa);
  return 100.0 * std::hypot(p.z_std_m, along_m);
}

PseudoLabelSelection SelectPseudoLabels(const std::vector<learning::Prediction>& predictions,
                                        double keep_fraction, double surface_radius_m) {
  if (!(keep_fraction > 0.0 && keep_fraction <= 1.0)) {
    throw ConfigError(fmt::format(
        "--pseudo-labels {}: the kept fraction of the unlabelled strikes must lie in (0, 1]",
        keep_fraction));
  }
  if (predictions.empty()) throw ConfigError("--pseudo-labels: no strikes to label");
  const auto n = static_cast<int64_t>(predictions.size());
  PseudoLabelSelection s;
  s.rows.resize(static_cast<size_t>(n));
  std::iota(s.rows.begin(), s.rows.end(), int64_t{0});
  if (keep_fraction == 1.0) {
    s.spread_limit_cm = std::numeric_limits<double>::quiet_NaN();
    return s;
  }
  // spread of every answer, cm: the ranking
  std::vector<double> spread(static_cast<size_t>(n));
  for (int64_t r = 0; r < n; ++r) {
    spread[static_cast<size_t>(r)] =
        PredictiveSpreadCm(predictions[static_cast<size_t>(r)], surface_radius_m);
    if (!std::isfinite(spread[static_cast<size_t>(r)])) {
      throw ConfigError(fmt::format(
          "--pseudo-labels {}: the pretrained run gives strike {} no predictive distribution, "
          "so its answers cannot be ranked; use --pseudo-labels 1 (keep all)",
          keep_fraction, r));
    }
  }
  // the smallest ceil(f N), then back in set order
  const auto keep = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(keep_fraction * n - 1e-9)));
  std::stable_sort(s.rows.begin(), s.rows.end(), [&](int64_t a, int64_t b) {
    return spread[static_cast<size_t>(a)] < spread[static_cast<size_t>(b)];
  });
  s.rows.resize(static_cast<size_t>(keep));
  s.spread_limit_cm = spread[static_cast<size_t>(s.rows.back())];
  std::sort(s.rows.begin(), s.rows.end());
  return s;
}

learning::FeatureSet WithPseudoLabels(const learning::FeatureSet& features,
                                      const std::vector<learning::Prediction>& predictions,
                                      const std::vector<int64_t>& rows) {
  learning::FeatureSet out = features.SelectRows(rows);
  for (size_t k = 0; k < rows.size(); ++k) {
    const learning::Prediction& p = predictions[static_cast<size_t>(rows[k])];
    out.z_m[k] = p.z_m;
    out.theta_rad[k] = p.theta_rad;
  }
  return out;
}

}  // namespace sonicboom::experiments
