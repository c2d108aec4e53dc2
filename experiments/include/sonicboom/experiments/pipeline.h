#pragma once
/// The data path wired end to end: sim strike -> acoustics -> dataset file -> features.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/sample.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// The acoustic part of a config, as the strike renderer takes it (with acoustics.render_span =
/// features, the span derived from the config's features section).
acoustics::AcousticModelConfig AcousticModel(const SonicBoomConfig& config);

/// How long after a strike's first contact the features read, s: half the window (centred on
/// the detected onset), an onset frame and 5 ms of slack for the onset's lag behind the contact.
double FeatureSpanAfterContact(const dsp::FeatureConfig& features);

/// The config a simulated dataset was generated with (its stored config_yaml resolved), or none:
/// a file from a capture or import, or of an earlier version whose keys have changed. path names
/// the file in errors.
std::optional<SonicBoomConfig> SimulatedWith(const DatasetInfo& info, const std::string& path);

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
  int64_t written{0};  // samples in the file (resumed ones included)
  int64_t valid{0};
  int64_t clipped{0};
  int64_t resumed{0};   // carried over from an interrupted run's partial file
  bool skipped{false};  // the file was already complete with this identity: nothing generated
  double wall_s{0.0};
};

/// Writes samples first_index .. first_index + count - 1 that belong to `shard` of `num_shards`
/// (index % num_shards == shard) into `out_path`, in index order, using `threads` workers.
/// The file appears under its final name only when complete. An interrupted run of the same
/// shard resumes: the samples its <out_path>.partial had flushed are kept (ResumeDatasetWriter).
/// ConfigError for a count or first index outside DatasetConfig's limits, naming --count or
/// --first-index. The config a generated dataset stores as its identity: the resolved config
/// without the settings of the machine that ran it (train.threads, acoustics.mode_cache_dir), so
/// that shards generated with other thread counts or cache directories merge.
std::string DatasetConfigYaml(SonicBoomConfig config);

/// What a generated dataset file records about itself (its identity, SameDatasetIdentity):
/// DatasetConfigYaml, rates, shapes, seed, shard and the generated range.
DatasetInfo GeneratedDatasetInfo(const SonicBoomConfig& config, int64_t first_index, int64_t count,
                                 int64_t shard, int64_t num_shards);

/// Which strikes a generation writes, and how.
struct GenerateRequest {
  int64_t count{0};        // strikes
  int64_t first_index{0};  // sample index of the first (each draw derives from seed and index)
  int64_t shard{0};        // this shard owns the indices i with i % num_shards == shard
  int64_t num_shards{1};
  int threads{1};
  bool show_progress{false};
};

GenerateResult GenerateDataset(const SonicBoomConfig& config, const std::string& out_path,
                               const GenerateRequest& request);

/// The reference noise clip the feature path gates against (features.gating), (mics x samples)
/// at audio.sample_rate_hz. With features.gating_noise_wav set: that WAV (a no-contact recording,
/// one channel per mic, at the audio rate, at least features.gating_n_fft frames, finite), errors
/// naming the key and the file. Otherwise acoustics::NoiseModelClip: kReferenceNoiseRecords records
/// (audio.record_duration_s each) of the noise model with no contact, end to end: the DAQ chain
/// (daq.*, noise.*: ambient and preamp floor, motor tones, recorded noise, converter) on zero
/// strain, the motor held at the peak joint speed of a minimum-jerk sweep of the mean angle
/// (strike.sweep_min_deg, sweep_max_deg) over strike.sweep_duration_s, no motor when scene.mode is
/// stationary. Each record draws its own per-strike channel gains and tone phases, so that the
/// thresholds cover their spread. Deterministic in the config.
Eigen::MatrixXf ReferenceNoiseClip(const SonicBoomConfig& config);

/// Features of the valid samples of a dataset file (rows in file order), with labels.
/// `sample_indices` (optional) receives the global index of each row.
learning::FeatureSet ComputeDatasetFeatures(const std::string& dataset_path,
                                            const SonicBoomConfig& config, int threads,
                                            bool show_progress,
                                            std::vector<uint64_t>* sample_indices = nullptr);

/// Features of single records, set up once (the gate's reference clip, FFT plans, filterbanks)
/// for records of `channels` channels at `sample_rate_hz`, then computed many times.
class RecordFeaturizer {
 public:
  /// Every feature of the whole window, as datasets hold them.
  RecordFeaturizer(const SonicBoomConfig& config, double sample_rate_hz, int channels);
  /// Only what a model reads (Localizer::needs()): its modalities, and of the mel spectrogram
  /// only its crop; the arrays of other modalities stay empty. No gate without mel or GCC.
  RecordFeaturizer(const SonicBoomConfig& config, double sample_rate_hz, int channels,
                   const learning::FeatureNeeds& needs);
  ~RecordFeaturizer();
  RecordFeaturizer(const RecordFeaturizer&) = delete;
  RecordFeaturizer& operator=(const RecordFeaturizer&) = delete;
  /// audio (C x T), proprio (K x 10, may be empty: zeros) -> one feature row.
  learning::FeatureSet Compute(const Eigen::MatrixXf& audio, const Eigen::MatrixXf& proprio) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Features of one record (C x T) and its proprioception (K x 10, may be empty: zeros).
/// Both feature paths gate against ReferenceNoiseClip(config) when features.gating is on.
learning::FeatureSet ComputeRecordFeatures(const Eigen::MatrixXf& audio, double sample_rate_hz,
                                           const Eigen::MatrixXf& proprio,
                                           const SonicBoomConfig& config);

/// A dataset's features split into the training's two inputs.
struct FeatureSplit {
  learning::FeatureSet train, val;
};

/// Splits `all` (rows from `data`, global indices `sample_indices`) into train and validation
/// with SplitRows(config.train.val_fraction, config.seed), in place: the validation rows are
/// copied out and the training rows packed into all's own arrays, so that the peak memory is
/// the set plus its validation rows, not twice the set (18 000 strikes of 2 s records hold 12 GB
/// of features). ConfigError naming `data` when either side would be empty.
FeatureSplit SplitFeatures(const SonicBoomConfig& config, learning::FeatureSet&& all,
                           const std::vector<uint64_t>& sample_indices, const std::string& data);

/// Trains config.model with config.train into run_dir on a split. `fine_tune` starts from a
/// pretrained run.
learning::Metrics TrainOnSplit(const SonicBoomConfig& config, const FeatureSplit& split,
                               const std::string& run_dir, bool resume, bool quiet,
                               const learning::FineTune& fine_tune = {},
                               const learning::DataParallel& parallel = {});

/// SplitFeatures, then TrainOnSplit. `all` is consumed: pass std::move(set), or a copy.
learning::Metrics TrainOnFeatures(const SonicBoomConfig& config, learning::FeatureSet all,
                                  const std::vector<uint64_t>& sample_indices,
                                  const std::string& data, const std::string& run_dir, bool resume,
                                  bool quiet, const learning::FineTune& fine_tune = {},
                                  const learning::DataParallel& parallel = {});

/// Splits rows into train and validation by a hash of (seed, sample index): stable under any
/// reordering or sharding. Two rows or more always split when 0 < val_fraction < 1 (were every
/// draw on one side, the row whose draw lies nearest the other moves there). Returns (train
/// rows, validation rows).
std::pair<std::vector<int64_t>, std::vector<int64_t>> SplitRows(
    const std::vector<uint64_t>& sample_indices, double val_fraction, uint64_t seed);

}  // namespace sonicboom::experiments
