#pragma once
/// The whole resolved configuration of a run: one struct per stage, one YAML file.
/// Keys and units: docs/conventions.md (defaults tables: `sonicboom config --markdown`).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "sonicboom/acoustics/arrival.h"
#include "sonicboom/acoustics/randomize.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/archive.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/learning/learning.h"
#include "sonicboom/sim/rollout.h"
#include "sonicboom/sim/scene.h"
#include "sonicboom/sim/strike.h"

namespace sonicboom::experiments {

/// Dataset generation.
struct DatasetConfig {
  // limits of count and first_index, for the config and for `generate --count/--first-index`
  static constexpr int64_t kMaxCount = 1'000'000'000;
  static constexpr int64_t kMaxFirstIndex = 1'000'000'000'000'000;

  int64_t count{1000};     // samples in a generated dataset
  int64_t first_index{0};  // global index of the first sample
  bool audio_int16{true};  // store the DAQ's 16-bit output losslessly as int16

  void Serialize(Archive* a);
};

/// The demo's dataset sizes.
struct DemoConfig {
  int64_t train_count{1600};  // training strikes (a fifth held for validation)
  int64_t test_count{400};    // held-out strikes, disjoint sample indices

  void Serialize(Archive* a);
};

struct SonicBoomConfig {
  uint64_t seed{1};  // global seed: sample i uses SampleSeed(seed, i)
  TubeConfig tube;
  MaterialConfig material;
  MicArrayConfig mics;
  AudioConfig audio;
  sim::StrikeConfig strike;
  sim::SceneConfig scene;        // objects and strike mode
  sim::RolloutConfig rollout;    // used when strike.engine = mujoco or the scene needs it
  acoustics::ShellConfig shell;  // the discretized tube (numerical modes, FD)
  acoustics::SynthConfig acoustics;
  acoustics::DaqConfig daq;
  acoustics::NoiseConfig noise;
  acoustics::RandomizeConfig randomize;  // per-sample structure, striker and sensor draws
  acoustics::ArrivalConfig arrival;      // the training-free arrival locator (a baseline)
  dsp::FeatureConfig features;
  learning::ModelConfig model;
  learning::TrainConfig train;
  DatasetConfig dataset;
  DemoConfig demo;

  void Serialize(Archive* a);
  /// Cross-field checks of every section; throws ConfigError naming the key.
  void Validate() const;
};

/// Where a config comes from: embedded defaults (+ an optional embedded layer), files, overrides.
struct ConfigSources {
  std::vector<std::string> files;      // --config, merged in order
  std::vector<std::string> overrides;  // --set key=value
  std::string embedded_yaml;           // e.g. the demo's defaults, applied before files
  std::string embedded_name{"embedded defaults"};
  // further embedded layers (name, YAML), after embedded_yaml and before the files
  std::vector<std::pair<std::string, std::string>> embedded_layers;
  int64_t seed{-1};  // --seed, >= 0 overrides `seed`
};

/// Resolves and validates a config. Throws ConfigError / IoError naming the culprit.
SonicBoomConfig ResolveConfig(const ConfigSources& sources);
/// shell.grid_spacing_m = 0 resolved (ResolveConfig does it): the spacing DerivedGridSpacing gives
/// for the band the modes are solved to (acoustics::SolvedModeBandHz); a set spacing stays.
void ResolveDerivedGrid(SonicBoomConfig* config);

/// The resolved config as YAML.
std::string ConfigToYaml(const SonicBoomConfig& config);

}  // namespace sonicboom::experiments
