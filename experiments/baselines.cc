#include "sonicboom/experiments/baselines.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <mutex>

#include <fmt/format.h>

#include "sonicboom/acoustics/features.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/progress.h"

namespace sonicboom::experiments {
namespace {

// the valid rows of a dataset and their metadata
void ValidRows(const DatasetReader& reader, const std::string& path, std::vector<int64_t>* rows,
               learning::FeatureSet* labels) {
  for (int64_t i = 0; i < reader.size(); ++i) {
    const StrikeSample meta = reader.ReadMeta(i);
    if (!meta.valid) continue;
    rows->push_back(i);
    labels->z_m.push_back(meta.label.z_m);
    labels->theta_rad.push_back(meta.label.theta_rad);
  }
  if (rows->empty()) throw SchemaError(fmt::format("{}: no valid samples", path));
}

}  // namespace

learning::FeatureSet DatasetLabels(const std::string& dataset_path) {
  DatasetReader reader(dataset_path);
  std::vector<int64_t> rows;
  learning::FeatureSet labels;
  ValidRows(reader, dataset_path, &rows, &labels);
  return labels;
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
  std::vector<int64_t> all_rows;
  learning::FeatureSet all_labels;
  ValidRows(reader, dataset_path, &all_rows, &all_labels);
  if (info.sample_rate_hz != locator.sample_rate_hz()) {
    throw SchemaError(fmt::format("{}: audio at {} Hz, the TDOA locator was made for {} Hz",
                                  dataset_path, info.sample_rate_hz, locator.sample_rate_hz()));
  }

  // at most max_strikes rows, evenly spaced
  std::vector<int64_t> picked;
  const int64_t total = static_cast<int64_t>(all_rows.size());
  const int64_t n = max_strikes > 0 ? std::min(max_strikes, total) : total;
  for (int64_t r = 0; r < n; ++r) picked.push_back(r * total / n);
  if (labels) {
    *labels = learning::FeatureSet{};
    for (int64_t r : picked) {
      labels->z_m.push_back(all_labels.z_m[r]);
      labels->theta_rad.push_back(all_labels.theta_rad[r]);
    }
  }

  // the onset of the feature path, then the locator's band correlations around it
  const acoustics::FeatureExtractor fx(config.features, info.sample_rate_hz, info.channels);
  std::vector<acoustics::TdoaCorrelations> out(static_cast<size_t>(n));
  std::mutex read_mutex;
  Progress progress("tdoa", n, show_progress);
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(int64_t{0}, n, [&](int64_t i) {
      StrikeSample sample;
      {
        std::lock_guard<std::mutex> lock(read_mutex);
        sample = reader.Read(all_rows[picked[i]]);
      }
      const acoustics::StrikeFeatures f = fx.Compute(sample.audio);
      const int64_t onset = f.window_start + fx.window_samples() / 2;
      out[i] = locator.Correlate(sample.audio, onset);
      progress.Add();
    });
  });
  progress.Finish();
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

}  // namespace sonicboom::experiments
