#pragma once
/// The baselines on dataset files (`sonicboom baseline`, docs/baselines.md): labels of the valid
/// samples, and the analytic TDOA locator run over a dataset's raw audio.

#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/acoustics/arrival.h"
#include "sonicboom/acoustics/tdoa.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/learning/baselines.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// Labels of the valid samples of a dataset, in file order (the rows ComputeDatasetFeatures
/// gives), in a FeatureSet with no feature arrays. Throws SchemaError when none is valid.
learning::FeatureSet DatasetLabels(const std::string& dataset_path, const SonicBoomConfig& config);

/// The TDOA locator of a config: its tube, material, microphones and seams.
acoustics::TdoaGeometry TdoaGeometryOf(const SonicBoomConfig& config);

/// Band GCC envelopes of the valid samples of a dataset around their onsets, the onset being the
/// one FeatureExtractor finds with config.features (StrikeFeatures::window_start + half the
/// window). With max_strikes > 0, at most that many rows, evenly spaced in file order. `labels`
/// (optional) receives their labels. Reading is serial, the rest runs on `threads` workers.
std::vector<acoustics::TdoaCorrelations> CorrelateDataset(const std::string& dataset_path,
                                                          const SonicBoomConfig& config,
                                                          const acoustics::TdoaLocator& locator,
                                                          int threads, bool show_progress,
                                                          int64_t max_strikes,
                                                          learning::FeatureSet* labels);

/// Locates every strike at one speed scale, on `threads` workers; deterministic.
std::vector<learning::Prediction> LocateAll(const acoustics::TdoaLocator& locator,
                                            const std::vector<acoustics::TdoaCorrelations>& strikes,
                                            double speed_scale, int threads);

/// The arrival-time locator over every valid sample of a dataset (onsets as CorrelateDataset
/// finds them), on `threads` workers; `labels` (optional) receives their labels, `estimates`
/// (optional) the picks and fitted speeds.
std::vector<learning::Prediction> LocateByArrival(
    const std::string& dataset_path, const SonicBoomConfig& config,
    const acoustics::ArrivalLocator& locator, int threads, bool show_progress,
    learning::FeatureSet* labels, std::vector<acoustics::ArrivalEstimate>* estimates);

/// The last kNN fitted, kept for the test sets that follow (reproduce scores four scenarios
/// against one training set; a fit of 18 000 strikes computes their features, minutes here).
/// The fit is keyed by the training file (path, size, modification time), the config and the
/// kNN's settings; another key fits again and drops the last.
class KnnFits {
 public:
  /// The kNN of `train_path`'s features under `config`, fitted on `threads` workers.
  const learning::KnnBaseline& Get(const std::string& train_path, const SonicBoomConfig& config,
                                   const learning::KnnConfig& knn, int threads, bool progress);
  int64_t fitted() const { return fitted_; }  // fits made so far

 private:
  std::string file_key_;          // the training file and the config
  learning::KnnConfig settings_;  // the kNN's, worker count zeroed
  std::unique_ptr<learning::KnnBaseline> knn_;
  int64_t fitted_{0};
};

}  // namespace sonicboom::experiments
