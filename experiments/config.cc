#include "sonicboom/experiments/config.h"

#include <fmt/format.h>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/config_io.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::experiments {

void DatasetConfig::Serialize(Archive* a) {
  a->Visit("count", &count, Bounds::Closed(1, double(kMaxCount)));
  a->Visit("first_index", &first_index, Bounds::Closed(0, double(kMaxFirstIndex)));
  a->Visit("audio_int16", &audio_int16);
}

void DemoConfig::Serialize(Archive* a) {
  a->Visit("train_count", &train_count, Bounds::Closed(10, 1e9));
  a->Visit("test_count", &test_count, Bounds::Closed(1, 1e9));
}

void SonicBoomConfig::Serialize(Archive* a) {
  int64_t seed_value = static_cast<int64_t>(seed);
  a->Visit("seed", &seed_value, Bounds::Closed(0, 9.007199254740992e15));
  seed = static_cast<uint64_t>(seed_value);
  a->Visit("tube", &tube);
  a->Visit("material", &material);
  a->Visit("mics", &mics);
  a->Visit("audio", &audio);
  a->Visit("strike", &strike);
  a->Visit("scene", &scene);
  a->Visit("rollout", &rollout);
  a->Visit("shell", &shell);
  a->Visit("acoustics", &acoustics);
  a->Visit("daq", &daq);
  a->Visit("noise", &noise);
  a->Visit("randomize", &randomize);
  a->Visit("arrival", &arrival);
  a->Visit("features", &features);
  a->Visit("model", &model);
  a->Visit("train", &train);
  a->Visit("dataset", &dataset);
  a->Visit("demo", &demo);
}

void SonicBoomConfig::Validate() const {
  tube.Validate();
  mics.Validate(tube);
  shell.Validate(tube);
  strike.Validate();
  scene.Validate();
  rollout.Validate();
  if (strike.engine == sim::StrikeEngine::kKinematic && scene.mode != sim::SceneMode::kStrike) {
    throw ConfigError(
        fmt::format("strike.engine = kinematic cannot simulate scene.mode {}; set "
                    "strike.engine = mujoco",
                    NameOf(scene.mode)));
  }
  model.Validate();
  train.Validate();
  if (audio.onset_time_s >= audio.record_duration_s) {
    throw ConfigError(
        fmt::format("audio.onset_time_s = {} must lie inside the record "
                    "(audio.record_duration_s = {})",
                    audio.onset_time_s, audio.record_duration_s));
  }
  if (audio.onset_jitter_s > audio.onset_time_s ||
      audio.onset_time_s + audio.onset_jitter_s >= audio.record_duration_s) {
    throw ConfigError(
        fmt::format("audio.onset_jitter_s = {}: the first contact, drawn in "
                    "audio.onset_time_s +- audio.onset_jitter_s = [{}, {}] s, must "
                    "lie inside the record [0, audio.record_duration_s = {})",
                    audio.onset_jitter_s, audio.onset_time_s - audio.onset_jitter_s,
                    audio.onset_time_s + audio.onset_jitter_s, audio.record_duration_s));
  }
  const double proprio_s = strike.proprio_rows / strike.proprio_rate_hz;
  if (proprio_s > audio.record_duration_s) {
    throw ConfigError(
        fmt::format("strike.proprio_rows / strike.proprio_rate_hz = {} s is longer "
                    "than the record (audio.record_duration_s = {})",
                    proprio_s, audio.record_duration_s));
  }
  daq.Validate(mics.count());
  noise.Validate();
  randomize.Validate();
  arrival.Validate(audio.sample_rate_hz);
  randomize.CheckLossLaw(material.loss_factor);
  if (randomize.material() && acoustics.model != acoustics::VibrationModel::kModal) {
    throw ConfigError(
        fmt::format("randomize: the material ranges (youngs_modulus_scale, "
                    "density_scale, temperature_c, loss_*) scale the numerical "
                    "modes and need acoustics.model = modal, not {}",
                    NameOf(acoustics.model)));
  }
  if (randomize.highpass_hz.size() == 2 &&
      !(randomize.highpass_hz[1] < 0.5 * audio.sample_rate_hz)) {
    throw ConfigError(
        fmt::format("randomize.highpass_hz reaches {} Hz, not below the Nyquist "
                    "frequency {} Hz (audio.sample_rate_hz / 2)",
                    randomize.highpass_hz[1], 0.5 * audio.sample_rate_hz));
  }
  if (acoustics.max_frequency_hz >= 0.5 * audio.sample_rate_hz) {
    throw ConfigError(
        fmt::format("acoustics.max_frequency_hz = {} must be below Nyquist "
                    "(audio.sample_rate_hz / 2 = {})",
                    acoustics.max_frequency_hz, 0.5 * audio.sample_rate_hz));
  }
}

void ResolveDerivedGrid(SonicBoomConfig* config) {
  if (config->shell.grid_spacing_m != 0.0) return;
  const double band_hz = acoustics::SolvedModeBandHz(
      config->acoustics, config->audio.sample_rate_hz, config->randomize);
  config->shell.grid_spacing_m =
      acoustics::DerivedGridSpacing(config->tube, config->material, band_hz);
}

SonicBoomConfig ResolveConfig(const ConfigSources& sources) {
  // layers: struct defaults, embedded layer, files in order, --set overrides, --seed
  ConfigLayers layers;
  if (!sources.embedded_yaml.empty()) layers.AddText(sources.embedded_yaml, sources.embedded_name);
  for (const auto& [name, yaml] : sources.embedded_layers) layers.AddText(yaml, name);
  for (const auto& file : sources.files) layers.AddFile(file);
  for (const auto& assignment : sources.overrides) layers.AddOverride(assignment);
  if (sources.seed >= 0) layers.AddOverride(fmt::format("seed={}", sources.seed));
  SonicBoomConfig config;
  layers.ReadInto(&config);
  // shell.grid_spacing_m = 0: the grid the solved mode band needs, written into the config
  ResolveDerivedGrid(&config);
  config.Validate();
  // the resolved config states the integrator step that the contact time scale implies
  if (config.strike.engine == sim::StrikeEngine::kMujoco ||
      config.scene.mode != sim::SceneMode::kStrike) {
    config.rollout.timestep_s = config.rollout.ResolvedTimestep();
  }
  return config;
}

std::string ConfigToYaml(const SonicBoomConfig& config) {
  SonicBoomConfig copy = config;
  return ToYaml(copy);
}

}  // namespace sonicboom::experiments
