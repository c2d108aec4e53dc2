#pragma once
/// The data path wired end to end: sim strike -> acoustics -> dataset file -> features.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/sample.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// The acoustic part of a config, as the strike renderer takes it.
acoustics::AcousticModelConfig AcousticModel(const SonicBoomConfig& config);

/// Immutable models of one config, shared by all worker threads.
class StrikePipeline {
 public:
  explicit StrikePipeline(const SonicBoomConfig& config);
  ~StrikePipeline();
  StrikePipeline(const StrikePipeline&) = delete;
  StrikePipeline& operator=(const StrikePipeline&) = delete;

  /// Sample `index` of the dataset: depends only on (config.seed, index). Never throws for a
  /// numerically failed strike: the sample comes back invalid with a reason.
  StrikeSample Simulate(uint64_t index) const;
  const SonicBoomConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Summary of a generate run.
struct GenerateResult {
  std::string path;
  int64_t written{0};
  int64_t valid{0};
  int64_t clipped{0};
  double wall_s{0.0};
};

/// Writes samples first_index .. first_index + count - 1 that belong to `shard` of `num_shards`
/// (index % num_shards == shard) into `out_path`, in index order, using `threads` workers.
/// The file appears under its final name only when complete.
GenerateResult GenerateDataset(const SonicBoomConfig& config, const std::string& out_path,
                               int64_t count, int64_t first_index, int64_t shard,
                               int64_t num_shards, int threads, bool show_progress);

/// Features of the valid samples of a dataset file (rows in file order), with labels.
/// `sample_indices` (optional) receives the global index of each row.
learning::FeatureSet ComputeDatasetFeatures(const std::string& dataset_path,
                                            const SonicBoomConfig& config, int threads,
                                            bool show_progress,
                                            std::vector<uint64_t>* sample_indices = nullptr);

/// Features of one record (C x T) and its proprioception (K x 10, may be empty: zeros).
learning::FeatureSet ComputeRecordFeatures(const Eigen::MatrixXf& audio, double sample_rate_hz,
                                           const Eigen::MatrixXf& proprio,
                                           const SonicBoomConfig& config);

/// Splits rows into train and validation by a hash of (seed, sample index): stable under any
/// reordering or sharding. Returns (train rows, validation rows).
std::pair<std::vector<int64_t>, std::vector<int64_t>> SplitRows(
    const std::vector<uint64_t>& sample_indices, double val_fraction, uint64_t seed);

}  // namespace sonicboom::experiments
