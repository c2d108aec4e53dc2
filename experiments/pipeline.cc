#include "sonicboom/experiments/pipeline.h"
#include "internal/records.h"
#include "internal/reference.h"
#include "internal/report.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/acoustics/daq.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/sim/strike.h"
#include "sonicboom/sim/strike_source.h"
#include "sonicboom/solid/reference_tube.h"

namespace sonicboom::experiments {

struct StrikePipeline::Impl {
  SonicBoomConfig config;
  std::unique_ptr<sim::StrikeSource> strikes;  // the engine the scene asks for
  std::unique_ptr<acoustics::StrikeSynthesizer> synth;
  // the reference solid, when randomize.reference_fraction renders some strikes with it
  std::unique_ptr<solid::ReferenceTube> reference;
};

namespace {

// the reference solid of randomize.reference_*, solved once or read from the mode cache
std::unique_ptr<solid::ReferenceTube> ReferenceRenderer(const SonicBoomConfig& config) {
  const acoustics::RandomizeConfig& r = config.randomize;
  CheckReferenceBand(r.reference_max_frequency_hz, config.audio.sample_rate_hz,
                     "randomize.reference_max_frequency_hz", "audio.sample_rate_hz");
  const solid::SolidMeshConfig defaults;
  const solid::SolidMeshConfig mesh =
      ReferenceMesh(r.reference_element_m, defaults.degree_wall, defaults.degree_thickness,
                    config.tube, "randomize.reference_element_m");
  const auto t0 = std::chrono::steady_clock::now();
  auto tube = std::make_unique<solid::ReferenceTube>(ReferenceTubeOf(
      config, mesh, r.reference_max_frequency_hz, false, config.acoustics.ModeCacheDir()));
  spdlog::info(
      "randomize.reference_fraction = {}: the reference solid, {} modes to {} Hz, {} ({:.1f} s)",
      r.reference_fraction, tube->omega_rad_s().size(), r.reference_max_frequency_hz,
      tube->from_cache() ? "from the mode cache" : "solved", MillisecondsSince(t0) / 1e3);
  return tube;
}

// the sample rendered again by the reference solid when its draw (stream kTheory) falls below
// randomize.reference_fraction; its draws and a flag (1 = rendered) join its variation either way
void PlayWithReference(const solid::ReferenceTube& tube, const SonicBoomConfig& c, int64_t frames,
                       StrikeSample* sample) {
  std::vector<double> drawn(ReferenceVariationNames().size(), 0.0);
  double rendered = 0.0;
  if (sample->valid &&
      Rng(sample->seed, Stream::kTheory).Uniform() < c.randomize.reference_fraction) {
    try {
      drawn = RenderReferenceSample(tube, c.audio.sample_rate_hz, frames, sample);
      rendered = 1.0;
      // the first contact is the one the reference played
      if (!sample->contacts.empty()) {
        sample->contacts.front().duration_s = sample->label.duration_s;
        sample->contacts.front().impulse_Ns = sample->label.impulse_Ns;
      }
    } catch (const NumericalError& e) {
      sample->valid = false;
      sample->invalid_reason = fmt::format("reference solid: {}", e.what());
      sample->audio = Eigen::MatrixXf::Zero(c.mics.count(), frames);
    }
  }
  sample->variation.insert(sample->variation.end(), drawn.begin(), drawn.end());
  sample->variation.push_back(rendered);
}

}  // namespace

acoustics::AcousticModelConfig AcousticModel(const SonicBoomConfig& config) {
  acoustics::AcousticModelConfig a;
  a.tube = config.tube;
  a.material = config.material;
  a.mics = config.mics;
  a.audio = config.audio;
  a.shell = config.shell;
  a.synth = config.acoustics;
  a.daq = config.daq;
  a.noise = config.noise;
  a.randomize = config.randomize;
  a.seed = config.seed;
  if (a.synth.render_span == acoustics::RenderSpan::kFeatures) {
    a.synth.span_after_contact_s = FeatureSpanAfterContact(config.features);
  }
  return a;
}

double FeatureSpanAfterContact(const dsp::FeatureConfig& features) {
  // the window ends half a window after the detected onset, which trails the contact by the
  // wave's travel to the discs and at most an energy frame; 5 ms more for both
  constexpr double kOnsetSlackS = 0.005;
  return 0.5 * features.window_s + features.onset_frame_s + kOnsetSlackS;
}

StrikePipeline::StrikePipeline(const SonicBoomConfig& config) : impl_(std::make_unique<Impl>()) {
  impl_->config = config;
  impl_->strikes =
      sim::MakeStrikeSource(config.tube, config.audio, config.strike, config.scene, config.rollout);
  impl_->synth = std::make_unique<acoustics::StrikeSynthesizer>(AcousticModel(config));
  if (config.randomize.reference_fraction > 0.0) impl_->reference = ReferenceRenderer(config);
}

StrikePipeline::~StrikePipeline() = default;

const SonicBoomConfig& StrikePipeline::config() const {
  return impl_->config;
}

StrikeSample StrikePipeline::Simulate(uint64_t index) const {
  const SonicBoomConfig& c = impl_->config;
  StrikeSample sample;
  sample.index = index;
  sample.seed = SampleSeed(c.seed, index);

  // strike motion, its contacts, and the first tube contact that acoustics plays
  sim::SimulatedStrike strike = impl_->strikes->Strike(index, sample.seed);
  const sim::StrikeEvents& ev = strike.events;
  // contacts whose forces acoustics gives are known once it has played them
  if (!strike.forces_from_acoustics) sample.contacts = strike.contacts;
  sample.label = ev.label;
  sample.proprio = ev.proprio;
  sample.valid = ev.valid;
  sample.invalid_reason = ev.invalid_reason;

  // this sample's randomized structure, striker and sensor chain, stored with it
  const bool randomized = c.randomize.any();
  acoustics::Variation variation;
  if (randomized) {
    variation =
        acoustics::DrawVariation(c.randomize, c.material.loss_factor, c.mics.count(), sample.seed);
    sample.variation = variation.values;
    if (variation.structure.structure_variant >= 0) {
      const std::vector<double>& drawn =
          impl_->synth->StructureValues(variation.structure.structure_variant);
      sample.variation.insert(sample.variation.end(), drawn.begin(), drawn.end());
    }
  }

  // audio; a numerical failure marks the sample invalid instead of ending the run
  const int64_t frames = c.audio.num_samples();
  try {
    if (!sample.valid) throw NumericalError("no contact to play");
    acoustics::RenderedStrike r = impl_->synth->Render(
        ev.contact, strike.contacts, ev.joint_speed_rad_s, ev.joint_speed_rate_hz, sample.seed,
        randomized ? &variation : nullptr);
    sample.audio = std::move(r.audio);
    sample.clipped = r.clipped;
    sample.label.impulse_Ns = r.impulse_ns;
    sample.label.duration_s = r.duration_s;
    // guided sampling keeps only taps whose sound exceeds the threshold
    if (c.scene.mode == sim::SceneMode::kGuided) {
      const float peak = sample.audio.cwiseAbs().maxCoeff();
      if (peak < c.scene.guided.amplitude_threshold) {
        sample.valid = false;
        sample.invalid_reason =
            fmt::format("audio peak {:.4f} below scene.guided.amplitude_threshold = {}", peak,
                        c.scene.guided.amplitude_threshold);
      }
    }
    // an engine without contact forces: its one contact has the forces acoustics played
    if (strike.forces_from_acoustics) {
      sample.contacts = strike.contacts;
      for (ContactEpisode& e : sample.contacts) {
        e.duration_s = r.duration_s;
        e.impulse_Ns = r.impulse_ns;
        e.peak_force_N = r.peak_force_n;
      }
    }
  } catch (const NumericalError& e) {
    if (sample.valid) {
      sample.valid = false;
      sample.invalid_reason = fmt::format("acoustics: {}", e.what());
    }
    sample.audio = Eigen::MatrixXf::Zero(c.mics.count(), frames);
  }

  // another theory: the fraction randomize.reference_fraction picks is rendered again by the
  // reference solid; its draws and a flag (1 = reference) join the sample's variation
  if (impl_->reference) PlayWithReference(*impl_->reference, c, frames, &sample);

  // a label must lie on the tube surface inside the contact region; never clamp it silently
  if (sample.valid) {
    const double r = std::hypot(sample.label.point_m.x(), sample.label.point_m.y());
    SONICBOOM_DEMAND(std::abs(r - c.tube.outer_radius_m) < 1e-3);
    SONICBOOM_DEMAND(sample.label.z_m >= c.tube.contact_z_min_m &&
                     sample.label.z_m <= c.tube.contact_z_max_m);
  }
  return sample;
}

std::string DatasetConfigYaml(SonicBoomConfig config) {
  config.train.threads = 0;
  config.acoustics.mode_cache_dir.clear();
  return ConfigToYaml(config);
}

DatasetInfo GeneratedDatasetInfo(const SonicBoomConfig& config, int64_t first_index, int64_t count,
                                 int64_t shard, int64_t num_shards) {
  DatasetInfo info;
  info.source = "sim";
  info.config_yaml = DatasetConfigYaml(config);
  info.sample_rate_hz = config.audio.sample_rate_hz;
  info.proprio_rate_hz = config.strike.proprio_rate_hz;
  info.channels = config.mics.count();
  info.audio_frames = config.audio.num_samples();
  info.proprio_rows = config.strike.proprio_rows;
  info.audio_int16 = config.dataset.audio_int16;
  info.global_seed = config.seed;
  info.shard = shard;
  info.num_shards = num_shards;
  info.first_index = first_index;
  info.index_count = count;
  info.variation_names = acoustics::VariationNames(config.randomize, config.mics.count());
  if (config.randomize.reference_fraction > 0.0) {
    const std::vector<std::string>& ref = ReferenceVariationNames();
    info.variation_names.insert(info.variation_names.end(), ref.begin(), ref.end());
    info.variation_names.push_back(kReferenceRenderedName);
  }
  return info;
}

GenerateResult GenerateDataset(const SonicBoomConfig& config, const std::string& out_path,
                               const GenerateRequest& request) {
  const int64_t count = request.count, first_index = request.first_index;
  const int64_t shard = request.shard, num_shards = request.num_shards;
  const int threads = request.threads;
  const bool show_progress = request.show_progress;
  if (num_shards < 1)
    throw ConfigError(fmt::format("--num-shards must be >= 1, got {}", num_shards));
  if (shard < 0 || shard >= num_shards) {
    throw ConfigError(fmt::format("--shard must be in [0, {}), got {}", num_shards, shard));
  }
  // the config's own limits on dataset.count and dataset.first_index, so that no index overflows
  constexpr int64_t kMaxCount = DatasetConfig::kMaxCount, kMaxFirst = DatasetConfig::kMaxFirstIndex;
  if (count < 1 || count > kMaxCount) {
    throw ConfigError(fmt::format("--count must be in [1, {}], got {}", kMaxCount, count));
  }
  if (first_index < 0 || first_index > kMaxFirst) {
    throw ConfigError(
        fmt::format("--first-index must be in [0, {}], got {}", kMaxFirst, first_index));
  }
  const auto start = std::chrono::steady_clock::now();
  StrikePipeline pipeline(config);

  // the indices this shard owns, i in [first_index, first_index + count) with
  // i % num_shards == shard, produced one at a time: a large count allocates nothing up front
  const int64_t end = first_index + count;
  int64_t next = first_index + (shard - first_index % num_shards + num_shards) % num_shards;
  const int64_t owned = next < end ? (end - next + num_shards - 1) / num_shards : 0;

  const DatasetInfo info = GeneratedDatasetInfo(config, first_index, count, shard, num_shards);
  // a killed run of the same shard left samples in <out>.partial: carry over what it flushed
  const int64_t first_owned = next;
  int64_t resumed = 0;
  const std::unique_ptr<DatasetWriter> resumed_writer = ResumeDatasetWriter(
      out_path, info,
      [&](int64_t row, uint64_t index) {
        return static_cast<uint64_t>(first_owned + row * num_shards) == index;
      },
      &resumed);
  DatasetWriter& writer = *resumed_writer;
  next = first_owned + resumed * num_shards;
  if (resumed > 0) {
    spdlog::info("{}: resuming after {} samples an interrupted run wrote", out_path, resumed);
  }

  // simulate and compress the audio in parallel, write in index order from one thread
  GenerateResult result;
  result.path = out_path;
  result.resumed = resumed;
  Progress progress("generate", owned - resumed, show_progress);
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_pipeline(
        static_cast<size_t>(4 * std::max(1, arena.max_concurrency())),
        tbb::make_filter<void, uint64_t>(tbb::filter_mode::serial_in_order,
                                         [&](tbb::flow_control& fc) -> uint64_t {
                                           if (next >= end) {
                                             fc.stop();
                                             return 0;
                                           }
                                           const int64_t index = next;
                                           next += num_shards;
                                           return static_cast<uint64_t>(index);
                                         }) &
            tbb::make_filter<uint64_t, std::shared_ptr<DatasetWriter::EncodedSample>>(
                tbb::filter_mode::parallel,
                [&](uint64_t index) {
                  return std::make_shared<DatasetWriter::EncodedSample>(
                      writer.Encode(pipeline.Simulate(index)));
                }) &
            tbb::make_filter<std::shared_ptr<DatasetWriter::EncodedSample>, void>(
                tbb::filter_mode::serial_in_order,
                [&](std::shared_ptr<DatasetWriter::EncodedSample> sample) {
                  writer.AppendEncoded(*sample);
                  ++result.written;
                  result.valid += sample->meta.valid ? 1 : 0;
                  result.clipped += sample->meta.clipped ? 1 : 0;
                  progress.Add();
                }));
  });
  writer.Finish();
  progress.Finish();
  // the carried-over samples count in the totals
  if (resumed > 0) {
    const DatasetReader done(out_path);
    for (int64_t row = 0; row < resumed; ++row) {
      const StrikeSample meta = done.ReadMeta(row);
      ++result.written;
      result.valid += meta.valid ? 1 : 0;
      result.clipped += meta.clipped ? 1 : 0;
    }
  }
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

// allocates a feature set of n rows with the extractor's shapes
learning::FeatureSet AllocateFeatures(const dsp::FeatureExtractor& fx, int64_t n,
                                      int64_t proprio_rows) {
  learning::FeatureSet set;
  set.channels = fx.channels();
  set.mels = fx.audio_rows();
  set.frames = fx.mel_frames();
  set.frame_hop_samples = fx.frame_hop();
  set.gcc_pairs = fx.gcc_rows();  // pairs x bands
  set.gcc_lags = fx.gcc_lags();
  set.proprio_rows = proprio_rows;
  set.proprio_features = kProprioFeatures;
  set.z_m.assign(n, std::nan(""));
  set.theta_rad.assign(n, std::nan(""));
  return set;
}

// stores one record's features in row `row` (arrays sized on the first call)
void StoreFeatures(const dsp::StrikeFeatures& f, const Eigen::MatrixXf& proprio, int64_t row,
                   learning::FeatureSet* set) {
  const int64_t mel_size = set->channels * set->mels * set->frames;
  const int64_t gcc_size = set->gcc_pairs * set->gcc_lags;
  const int64_t prop_size = set->proprio_rows * set->proprio_features;
  // (mels x frames) row-major per channel; skipped when the set holds no mel (not asked for)
  if (!set->mel.empty()) {
    float* mel = set->mel.data() + row * mel_size;
    for (int64_t c = 0; c < set->channels; ++c) {
      const Eigen::MatrixXf& m = f.mel[c];
      for (int64_t b = 0; b < set->mels; ++b) {
        for (int64_t t = 0; t < set->frames; ++t) {
          mel[(c * set->mels + b) * set->frames + t] = m(b, t);
        }
      }
    }
  }
  if (!set->gcc.empty()) {
    float* gcc = set->gcc.data() + row * gcc_size;
    for (int64_t p = 0; p < set->gcc_pairs; ++p) {
      for (int64_t l = 0; l < set->gcc_lags; ++l) gcc[p * set->gcc_lags + l] = f.gcc(p, l);
    }
  }
  // proprioception: the first proprio_rows rows, zeros where the record has fewer
  float* prop = set->proprio.data() + row * prop_size;
  std::fill(prop, prop + prop_size, 0.0f);
  for (int64_t r = 0; r < std::min<int64_t>(set->proprio_rows, proprio.rows()); ++r) {
    for (int64_t j = 0; j < set->proprio_features && j < proprio.cols(); ++j) {
      prop[r * set->proprio_features + j] = proprio(r, j);
    }
  }
}

void ResizeArrays(int64_t n, learning::FeatureSet* set) {
  set->mel.assign(n * set->channels * set->mels * set->frames, 0.0f);
  set->gcc.assign(n * set->gcc_pairs * set->gcc_lags, 0.0f);
  set->proprio.assign(n * set->proprio_rows * set->proprio_features, 0.0f);
}

}  // namespace

Eigen::MatrixXf ReferenceNoiseClip(const SonicBoomConfig& config) {
  const double fs = config.audio.sample_rate_hz;
  const int channels = config.mics.count();
  const dsp::FeatureConfig& features = config.features;

  // a recording: checked against the audio config
  if (!features.gating_noise_wav.empty()) {
    const std::string& path = features.gating_noise_wav;
    AudioClip clip;
    try {
      clip = ReadWav(path);
    } catch (const IoError& e) {
      throw IoError(fmt::format("features.gating_noise_wav: {}", e.what()));
    }
    if (std::abs(clip.sample_rate_hz - fs) > 1e-6) {
      throw ConfigError(
          fmt::format("features.gating_noise_wav: {} is sampled at {} Hz; "
                      "audio.sample_rate_hz is {} Hz",
                      path, clip.sample_rate_hz, fs));
    }
    if (clip.channels() != channels) {
      throw ConfigError(
          fmt::format("features.gating_noise_wav: {} has {} channels; it needs one "
                      "per microphone ({})",
                      path, clip.channels(), channels));
    }
    if (clip.frames() < features.gating_n_fft) {
      throw ConfigError(
          fmt::format("features.gating_noise_wav: {} has {} frames, shorter than "
                      "one gate frame (features.gating_n_fft = {})",
                      path, clip.frames(), features.gating_n_fft));
    }
    // (ReadWav refused non-finite samples)
    return std::move(clip.samples);
  }

  // the noise model with no contact: records through the DAQ chain on zero strain, the motor
  // held at the peak joint speed of a mean strike sweep (stationary, like the reference's
  // constant-motion no-contact recording; no motor when the robot holds still), each record
  // with its own draw of the per-strike channel gains and tone phases
  const int64_t frames = config.audio.num_samples();
  const acoustics::DaqChain daq(config.daq, config.noise, channels, fs, frames);
  const std::vector<double> joint_speed_rad_s =
      sim::NoContactJointSpeed(config.strike, config.scene, config.audio);
  return acoustics::NoiseModelClip(daq, channels, frames, joint_speed_rad_s,
                                   config.strike.proprio_rate_hz, config.seed);
}

namespace {

// The gate's reference clip for records at (rate, channels), or an empty matrix when gating is
// off. `what` names the records in errors.
Eigen::MatrixXf GatingClipFor(const SonicBoomConfig& config, double sample_rate_hz, int channels,
                              const std::string& what) {
  if (!config.features.gating) return {};
  if (std::abs(sample_rate_hz - config.audio.sample_rate_hz) > 1e-6 ||
      channels != config.mics.count()) {
    throw ConfigError(fmt::format(
        "{}: records at {} Hz with {} channels, but this command's config gates "
        "(features.gating) against a reference noise clip at audio.sample_rate_hz = {} Hz with "
        "one channel per mic ({}); give the records' own rate and mics (--config, --set) or set "
        "features.gating=false",
        what, sample_rate_hz, channels, config.audio.sample_rate_hz, config.mics.count()));
  }
  spdlog::debug("spectral gating against {}", config.features.gating_noise_wav.empty()
                                                  ? "the noise model's reference clip"
                                                  : config.features.gating_noise_wav);
  return ReferenceNoiseClip(config);
}

}  // namespace

std::optional<SonicBoomConfig> SimulatedWith(const DatasetInfo& info, const std::string& path) {
  if (info.config_yaml.empty() || info.source != "sim") return std::nullopt;
  ConfigSources sources;
  sources.embedded_yaml = info.config_yaml;
  sources.embedded_name = path + " (its config)";
  try {
    return ResolveConfig(sources);
  } catch (const ConfigError&) {
    return std::nullopt;
  }
}

namespace {

// a dataset rendered over its features' span (acoustics.render_span = features) is silent after
// it: features that read further are refused
void CheckRenderedSpan(const DatasetInfo& info, const SonicBoomConfig& config,
                       const std::string& path) {
  // a file of an earlier version, whose keys have changed, was rendered over the record
  const std::optional<SonicBoomConfig> made_with = SimulatedWith(info, path);
  if (!made_with) return;
  const SonicBoomConfig& made = *made_with;
  if (made.acoustics.render_span != acoustics::RenderSpan::kFeatures) return;
  const double rendered = FeatureSpanAfterContact(made.features);
  const double read = FeatureSpanAfterContact(config.features);
  if (read > rendered + 1e-9) {
    throw ConfigError(fmt::format(
        "{}: rendered with acoustics.render_span = features for features.window_s = {} s (the "
        "vibration stops {:.1f} ms after the contact), but features.window_s = {} s reads "
        "{:.1f} ms after it: generate it again for this window, or with "
        "acoustics.render_span = record",
        path, made.features.window_s, 1e3 * rendered, config.features.window_s, 1e3 * read));
  }
}

// A simulated dataset's own record length and rate, as a message adds them: " (its own config:
// ...)", or nothing when unknown (an import, an earlier version).
std::string OwnAudioConfig(const DatasetInfo& info, const std::string& path) {
  const std::optional<SonicBoomConfig> own = SimulatedWith(info, path);
  if (!own) return "";
  return fmt::format(
      " (its own config: audio.record_duration_s = {} s at audio.sample_rate_hz = {} Hz)",
      own->audio.record_duration_s, own->audio.sample_rate_hz);
}

}  // namespace

learning::FeatureSet ComputeDatasetFeatures(const std::string& dataset_path,
                                            const SonicBoomConfig& config, int threads,
                                            bool show_progress,
                                            std::vector<uint64_t>* sample_indices) {
  DatasetReader reader(dataset_path);
  const DatasetInfo& info = reader.info();
  CheckRenderedSpan(info, config, dataset_path);
  if (config.features.gating && config.features.gating_noise_wav.empty() &&
      info.source == "hardware") {
    spdlog::warn(
        "{}: hardware records gated against the simulated noise model; set "
        "features.gating_noise_wav to a no-contact recording",
        dataset_path);
  }
  const Eigen::MatrixXf noise =
      GatingClipFor(config, info.sample_rate_hz, info.channels, dataset_path);
  dsp::FeatureExtractor fx(config.features, info.sample_rate_hz, info.channels,
                           noise.size() > 0 ? &noise : nullptr);

  // valid rows only
  const ValidRecords valid = ReadValidRecords(reader, dataset_path, config);
  const std::vector<StrikeSample>& metas = valid.metas;
  const int64_t n = static_cast<int64_t>(valid.rows.size());
  if (info.proprio_rows < config.strike.proprio_rows) {
    throw SchemaError(
        fmt::format("{}: proprio windows have {} rows, the model needs "
                    "strike.proprio_rows = {}",
                    dataset_path, info.proprio_rows, config.strike.proprio_rows));
  }
  learning::FeatureSet set = AllocateFeatures(fx, n, config.strike.proprio_rows);
  ResizeArrays(n, &set);
  if (sample_indices) sample_indices->resize(n);
  for (int64_t r = 0; r < n; ++r) {
    set.z_m[r] = metas[r].label.z_m;
    set.theta_rad[r] = metas[r].label.theta_rad;
    if (sample_indices) (*sample_indices)[r] = metas[r].index;
  }

  // reading is serial (HDF5), feature extraction parallel
  ForEachRecord(reader, valid.rows, threads, "features", show_progress,
                [&](int64_t r, const StrikeSample& sample) {
                  StoreFeatures(fx.Compute(sample.audio), sample.proprio, r, &set);
                });
  return set;
}

ValidRecords ReadValidRecords(const DatasetReader& reader, const std::string& path,
                              const SonicBoomConfig& config) {
  // records of the length the file's config states (a file edited by hand, or another tool's)
  const DatasetInfo& info = reader.info();
  if (info.audio_frames != config.audio.num_samples()) {
    throw SchemaError(fmt::format(
        "{}: records of {} frames at {} Hz{}, but this command's config reads "
        "audio.record_duration_s = {} s at audio.sample_rate_hz = {} Hz, {} frames",
        path, info.audio_frames, info.sample_rate_hz, OwnAudioConfig(info, path),
        config.audio.record_duration_s, config.audio.sample_rate_hz, config.audio.num_samples()));
  }
  // labels on the tube: a height beyond its ends is in other units (millimetres?) or damage
  const double half_length_m = 0.5 * config.tube.length_m;
  ValidRecords valid;
  for (int64_t i = 0; i < reader.size(); ++i) {
    StrikeSample meta = reader.ReadMeta(i);
    if (!meta.valid) continue;
    const double z = meta.label.z_m, theta = meta.label.theta_rad;
    if (std::abs(z) > half_length_m + 1e-3 || std::abs(theta) > std::numbers::pi + 1e-6) {
      throw SchemaError(fmt::format(
          "{}: sample row {} (index {}) is labelled z = {} m, theta = {} rad, off the tube "
          "(|z| <= {} m, |theta| <= pi): labels are in metres and radians, tube frame",
          path, i, meta.index, z, theta, half_length_m));
    }
    valid.rows.push_back(i);
    valid.metas.push_back(std::move(meta));
  }
  if (valid.rows.empty()) throw SchemaError(fmt::format("{}: no valid samples", path));
  return valid;
}

void ForEachRecord(const DatasetReader& reader, const std::vector<int64_t>& rows, int threads,
                   const std::string& name, bool show_progress,
                   const std::function<void(int64_t, const StrikeSample&)>& fn) {
  const int64_t n = static_cast<int64_t>(rows.size());
  std::mutex read_mutex;
  Progress progress(name, n, show_progress);
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(int64_t{0}, n, [&](int64_t i) {
      StrikeSample sample;
      {
        std::lock_guard<std::mutex> lock(read_mutex);
        sample = reader.Read(rows[i]);
      }
      fn(i, sample);
      progress.Add();
    });
  });
  progress.Finish();
}

struct RecordFeaturizer::Impl {
  Impl(const SonicBoomConfig& config, double sample_rate_hz, int channels,
       const dsp::FeatureRequest& request)
      : noise(request.mel || request.gcc ? GatingClipFor(config, sample_rate_hz, channels, "record")
                                         : Eigen::MatrixXf()),
        fx(config.features, sample_rate_hz, channels, noise.size() > 0 ? &noise : nullptr),
        request(request),
        proprio_rows(config.strike.proprio_rows) {}
  Eigen::MatrixXf noise;  // (C x T) reference clip of the gate, empty without gating
  dsp::FeatureExtractor fx;
  dsp::FeatureRequest request;
  int64_t proprio_rows;
};

RecordFeaturizer::RecordFeaturizer(const SonicBoomConfig& config, double sample_rate_hz,
                                   int channels)
    : impl_(std::make_unique<Impl>(config, sample_rate_hz, channels, dsp::FeatureRequest{})) {}

RecordFeaturizer::RecordFeaturizer(const SonicBoomConfig& config, double sample_rate_hz,
                                   int channels, const learning::FeatureNeeds& needs)
    : impl_(
          std::make_unique<Impl>(config, sample_rate_hz, channels,
                                 dsp::FeatureRequest{needs.audio, needs.gcc, needs.mel_first_frame,
                                                     needs.audio ? needs.mel_frames : 0})) {}

RecordFeaturizer::~RecordFeaturizer() = default;

learning::FeatureSet RecordFeaturizer::Compute(const Eigen::MatrixXf& audio,
                                               const Eigen::MatrixXf& proprio) const {
  const dsp::FeatureRequest& request = impl_->request;
  learning::FeatureSet set = AllocateFeatures(impl_->fx, 1, impl_->proprio_rows);
  if (request.mel_frames >= 0) set.frames = request.mel_frames;
  ResizeArrays(1, &set);
  // arrays of parts not asked for stay empty
  if (!request.mel) set.mel.clear();
  if (!request.gcc) set.gcc.clear();
  StoreFeatures(impl_->fx.Compute(audio, request), proprio, 0, &set);
  return set;
}

learning::FeatureSet ComputeRecordFeatures(const Eigen::MatrixXf& audio, double sample_rate_hz,
                                           const Eigen::MatrixXf& proprio,
                                           const SonicBoomConfig& config) {
  return RecordFeaturizer(config, sample_rate_hz, static_cast<int>(audio.rows()))
      .Compute(audio, proprio);
}

std::pair<std::vector<int64_t>, std::vector<int64_t>> SplitRows(
    const std::vector<uint64_t>& sample_indices, double val_fraction, uint64_t seed) {
  // each row's draw in [0, 1): below val_fraction it validates
  std::vector<double> draw(sample_indices.size());
  for (size_t r = 0; r < sample_indices.size(); ++r) {
    Rng rng(SampleSeed(seed, sample_indices[r]), Stream::kSplit);
    draw[r] = rng.Uniform();
  }
  // a few rows may all fall on one side: then the row of the lowest draw validates (or that of
  // the highest trains), so that any two rows split when val_fraction is inside (0, 1)
  std::vector<bool> validates(draw.size());
  for (size_t r = 0; r < draw.size(); ++r) validates[r] = draw[r] < val_fraction;
  const auto lowest = std::min_element(draw.begin(), draw.end());
  const auto highest = std::max_element(draw.begin(), draw.end());
  const auto count = std::count(validates.begin(), validates.end(), true);
  if (draw.size() >= 2 && val_fraction > 0.0 && val_fraction < 1.0) {
    if (count == 0) validates[lowest - draw.begin()] = true;
    if (count == static_cast<std::ptrdiff_t>(draw.size()))
      validates[highest - draw.begin()] = false;
  }
  std::pair<std::vector<int64_t>, std::vector<int64_t>> split;
  for (size_t r = 0; r < draw.size(); ++r) {
    (validates[r] ? split.second : split.first).push_back(static_cast<int64_t>(r));
  }
  return split;
}

namespace {

// train.rotate_rings turns a record by 120 degrees: the discs must be rings of three, 120
// degrees apart in channel order, every ring at the same angles; train.mirror_rings mirrors it
// about theta 0, where disc 0 of each ring must then sit
void CheckRingsTurn(const SonicBoomConfig& config) {
  if (!config.train.rotate_rings && !config.train.mirror_rings) return;
  const char* key = config.train.mirror_rings ? "train.mirror_rings" : "train.rotate_rings";
  const MicArrayConfig& mics = config.mics;
  const int count = mics.count();
  bool ok = count % 3 == 0;
  for (int c = 0; ok && c < count; ++c) {
    const double want = mics.theta_deg[static_cast<size_t>(c / 3 * 3)] + 120.0 * (c % 3);
    const double off = std::remainder(mics.theta_deg[static_cast<size_t>(c)] - want, 360.0);
    const double ring_off = std::remainder(
        mics.theta_deg[static_cast<size_t>(c)] - mics.theta_deg[static_cast<size_t>(c % 3)], 360.0);
    ok = std::abs(off) < 1e-6 && std::abs(ring_off) < 1e-6 &&
         mics.z_m[static_cast<size_t>(c)] == mics.z_m[static_cast<size_t>(c / 3 * 3)];
  }
  if (!ok) {
    throw ConfigError(fmt::format(
        "{} = true needs mics.theta_deg in rings of three, 120 degrees apart in channel order "
        "and at the same angles in every ring, each ring at one mics.z_m",
        key));
  }
  if (config.train.mirror_rings && std::abs(std::remainder(mics.theta_deg[0], 360.0)) > 1e-6) {
    throw ConfigError(fmt::format(
        "train.mirror_rings = true mirrors about theta 0: needs mics.theta_deg[0] = 0 (got {})",
        mics.theta_deg[0]));
  }
}

}  // namespace

FeatureSplit SplitFeatures(const SonicBoomConfig& config, learning::FeatureSet&& all,
                           const std::vector<uint64_t>& sample_indices, const std::string& data) {
  const auto [train_rows, val_rows] =
      SplitRows(sample_indices, config.train.val_fraction, config.seed);
  if (train_rows.empty() || val_rows.empty()) {
    throw ConfigError(
        fmt::format("{}: {} valid samples cannot be split into train and validation "
                    "with train.val_fraction = {}",
                    data, all.size(), config.train.val_fraction));
  }
  FeatureSplit split;
  split.val = all.SelectRows(val_rows);
  all.KeepRows(train_rows);  // SplitRows lists each side ascending
  split.train = std::move(all);
  return split;
}

learning::Metrics TrainOnSplit(const SonicBoomConfig& config, const FeatureSplit& split,
                               const std::string& run_dir, bool resume, bool quiet,
                               const learning::FineTune& fine_tune,
                               const learning::DataParallel& parallel) {
  CheckRingsTurn(config);
  spdlog::info("training on {} strikes, validating on {}", split.train.size(), split.val.size());
  return learning::TrainEnsemble(split.train, split.val, config.model, config.train,
                                 config.tube.outer_radius_m, config.seed, run_dir, resume, !quiet,
                                 fine_tune, parallel);
}

learning::Metrics TrainOnFeatures(const SonicBoomConfig& config, learning::FeatureSet all,
                                  const std::vector<uint64_t>& sample_indices,
                                  const std::string& data, const std::string& run_dir, bool resume,
                                  bool quiet, const learning::FineTune& fine_tune,
                                  const learning::DataParallel& parallel) {
  return TrainOnSplit(config, SplitFeatures(config, std::move(all), sample_indices, data), run_dir,
                      resume, quiet, fine_tune, parallel);
}

}  // namespace sonicboom::experiments
