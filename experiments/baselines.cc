#include "sonicboom/experiments/baselines.h"

#include "internal/records.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/pipeline.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;

// the labels of valid records
learning::FeatureSet LabelsOf(const ValidRecords& valid) {
  learning::FeatureSet labels;
  for (const StrikeSample& meta : valid.metas) {
    labels.z_m.push_back(meta.label.z_m);
    labels.theta_rad.push_back(meta.label.theta_rad);
  }
  return labels;
}

}  // namespace

learning::FeatureSet DatasetLabels(const std::string& dataset_path, const SonicBoomConfig& config) {
  DatasetReader reader(dataset_path);
  return LabelsOf(ReadValidRecords(reader, dataset_path, config));
}

acoustics::TdoaGeometry TdoaGeometryOf(const SonicBoomConfig& config) {
  return acoustics::MakeTdoaGeometry(config.tube, config.material, config.mics, config.shell);
}

std::vector<acoustics::TdoaCorrelations> CorrelateDataset(const std::string& dataset_path,
                                                          const SonicBoomConfig& config,
                                                          const acoustics::TdoaLocator& locator,
                                                          int threads, bool show_progress,
                                                          int64_t max_strikes,
                                                          learning::FeatureSet* labels) {
  DatasetReader reader(dataset_path);
  const DatasetInfo& info = reader.info();
  const ValidRecords valid = ReadValidRecords(reader, dataset_path, config);
  if (info.sample_rate_hz != locator.sample_rate_hz()) {
    throw SchemaError(fmt::format("{}: audio at {} Hz, the TDOA locator was made for {} Hz",
                                  dataset_path, info.sample_rate_hz, locator.sample_rate_hz()));
  }

  // at most max_strikes rows, evenly spaced
  const learning::FeatureSet all_labels = LabelsOf(valid);
  std::vector<int64_t> picked_rows;
  const int64_t total = static_cast<int64_t>(valid.rows.size());
  const int64_t n = max_strikes > 0 ? std::min(max_strikes, total) : total;
  if (labels) *labels = learning::FeatureSet{};
  for (int64_t i = 0; i < n; ++i) {
    const int64_t r = i * total / n;
    picked_rows.push_back(valid.rows[r]);
    if (labels) {
      labels->z_m.push_back(all_labels.z_m[r]);
      labels->theta_rad.push_back(all_labels.theta_rad[r]);
    }
  }

  // the onset of the feature path (the all-channel energy envelope), then the locator's band
  // correlations around it
  const dsp::FeatureConfig& fc = config.features;
  std::vector<acoustics::TdoaCorrelations> out(static_cast<size_t>(n));
  ForEachRecord(reader, picked_rows, threads, "tdoa", show_progress,
                [&](int64_t i, const StrikeSample& sample) {
                  const int64_t onset = dsp::DetectOnset(sample.audio, info.sample_rate_hz,
                                                         fc.onset_frame_s, fc.onset_threshold);
                  out[i] = locator.Correlate(sample.audio, onset);
                });
  return out;
}

std::vector<learning::Prediction> LocateByArrival(
    const std::string& dataset_path, const SonicBoomConfig& config,
    const acoustics::ArrivalLocator& locator, int threads, bool show_progress,
    learning::FeatureSet* labels, std::vector<acoustics::ArrivalEstimate>* estimates) {
  DatasetReader reader(dataset_path);
  const DatasetInfo& info = reader.info();
  const ValidRecords valid = ReadValidRecords(reader, dataset_path, config);
  if (labels) *labels = LabelsOf(valid);
  // the feature path's onset, then the picks and the fit around it
  const dsp::FeatureConfig& fc = config.features;
  std::vector<acoustics::ArrivalEstimate> found(valid.rows.size());
  ForEachRecord(reader, valid.rows, threads, "arrival", show_progress,
                [&](int64_t i, const StrikeSample& sample) {
                  const int64_t onset = dsp::DetectOnset(sample.audio, info.sample_rate_hz,
                                                         fc.onset_frame_s, fc.onset_threshold);
                  found[static_cast<size_t>(i)] = locator.Locate(sample.audio, onset);
                });
  std::vector<learning::Prediction> out(found.size());
  for (size_t i = 0; i < found.size(); ++i) {
    out[i].z_m = found[i].z_m;
    out[i].theta_rad = found[i].theta_rad;
  }
  if (estimates) *estimates = std::move(found);
  return out;
}

std::vector<learning::Prediction> LocateAll(const acoustics::TdoaLocator& locator,
                                            const std::vector<acoustics::TdoaCorrelations>& strikes,
                                            double speed_scale, int threads) {
  std::vector<learning::Prediction> out(strikes.size());
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t{0}, strikes.size(), [&](size_t i) {
      const acoustics::TdoaEstimate e = locator.Locate(strikes[i], speed_scale);
      out[i].z_m = e.z_m;
      out[i].theta_rad = e.theta_rad;
    });
  });
  return out;
}

const learning::KnnBaseline& KnnFits::Get(const std::string& train_path,
                                          const SonicBoomConfig& config,
                                          const learning::KnnConfig& knn, int threads,
                                          bool progress) {
  // everything the fit is made from: the training file, the config and every KnnConfig field
  // but the worker count, which changes nothing in it
  const std::string file_key =
      fmt::format("{}\n{}\n{}\n{}", train_path, fs::file_size(train_path),
                  fs::last_write_time(train_path).time_since_epoch().count(), ConfigToYaml(config));
  learning::KnnConfig settings = knn;
  settings.threads = 0;
  if (knn_ && file_key == file_key_ && settings == settings_) return *knn_;
  knn_.reset();  // the last fit's rows go before the next one's features are computed
  const learning::FeatureSet train = ComputeDatasetFeatures(train_path, config, threads, progress);
  knn_ = std::make_unique<learning::KnnBaseline>(train, knn);
  file_key_ = file_key;
  settings_ = settings;
  ++fitted_;
  return *knn_;
}

}  // namespace sonicboom::experiments
