#pragma once
/// Baselines that the learned localizer is measured against (docs/baselines.md): a constant
/// predictor and a k-nearest-neighbour regressor on pooled log-mel features (optionally the
/// GCC-PHAT lags near zero). No torch: plain Eigen products, TBB over test blocks.

#include <cstdint>
#include <memory>
#include <vector>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

/// The k-nearest-neighbour baseline's feature vector and neighbourhood.
struct KnnConfig {
  int64_t k{5};                  // neighbours
  int64_t crop_frames{345};      // centre crop of the mel frames (the network's view)
  int64_t pooled_frames{23};     // the crop average-pooled to this many time bins per mel band
  bool mel_is_log{false};        // features.log_mel: the mel is log10 already (no log taken)
  double log_floor{1e-10};       // log10(mel + log_floor)
  int64_t gcc_lags{0};           // GCC-PHAT lags kept each side of zero (0: no GCC block)
  double gcc_weight{1.0};        // the GCC block's share of the distance against the mel block's
  bool distance_weighted{true};  // weights 1 / distance, else uniform
  int threads{0};                // TBB workers for Predict (0 = all cores)

  /// Throws ConfigError naming the field as "knn.<field>".
  void Validate() const;
  bool operator==(const KnnConfig&) const = default;  // every field, a field added later too
};

/// Brute-force kNN on standardized features: every dimension centred and scaled by the training
/// rows' mean and standard deviation. z is the weighted mean of the neighbours' heights, theta
/// their weighted circular mean. Deterministic: ties go to the lower training row.
class KnnBaseline {
 public:
  /// Embeds and standardizes `train` (rows with a NaN label are left out). Throws SchemaError
  /// when no labelled rows remain or the shapes cannot hold the crop or the lags, ConfigError
  /// for a bad config.
  KnnBaseline(const FeatureSet& train, const KnnConfig& config);
  ~KnnBaseline();
  KnnBaseline(KnnBaseline&&) noexcept;
  KnnBaseline& operator=(KnnBaseline&&) noexcept;

  /// One prediction per row of `test`; its shapes must equal the training set's (SchemaError).
  std::vector<Prediction> Predict(const FeatureSet& test) const;
  int64_t dimensions() const;  // length of the feature vector
  int64_t size() const;        // training rows kept

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The constant predictor: mean height and circular mean angle of the labelled rows (NaN rows
/// skipped). Throws SchemaError when there are none or the lengths differ.
Prediction ConstantPrediction(const std::vector<double>& z_m, const std::vector<double>& theta_rad);

/// Weighted circular mean atan2(sum w sin, sum w cos) in (-pi, pi]; `fallback` when the
/// resultant vanishes (opposite angles of equal weight).
double CircularMean(const std::vector<double>& theta_rad, const std::vector<double>& weights,
                    double fallback);

}  // namespace sonicboom::learning
