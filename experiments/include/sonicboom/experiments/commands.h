#pragma once
/// One function per CLI subcommand. Each returns its machine-readable result as a JSON string
/// and its human-readable report as text; the CLI prints one of the two on stdout.

#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/experiments/config.h"

namespace sonicboom::experiments {

/// Options shared by every subcommand.
struct GlobalOptions {
  ConfigSources sources;
  int threads{0};                          // 0 = all cores
  bool quiet{false};
  bool json{false};
};

/// What a command produced.
struct CommandResult {
  std::string json;                        // one JSON object
  std::string text;                        // human-readable report
};

CommandResult RunDemo(const GlobalOptions& g, const std::string& out_dir);
CommandResult RunGenerate(const GlobalOptions& g, const std::string& out, int64_t count,
                          int64_t first_index, int64_t shard, int64_t num_shards);
CommandResult RunMerge(const GlobalOptions& g, const std::string& out,
                       const std::vector<std::string>& shards);
CommandResult RunSynth(const GlobalOptions& g, const std::string& out_wav, int64_t index);
CommandResult RunModes(const GlobalOptions& g, const std::string& boundary, bool ideal,
                       int64_t count);
/// The fidelity ladder's speed-accuracy table (docs/fidelity.md): every rung against the finest
/// FD reference on `strikes` test strikes over `window_s` after the onset.
CommandResult RunFidelity(const GlobalOptions& g, const std::string& out_md, int64_t strikes,
                          double window_s, bool quick);
CommandResult RunFeatures(const GlobalOptions& g, const std::string& in, const std::string& out,
                          const std::string& proprio_csv);
CommandResult RunTrain(const GlobalOptions& g, const std::string& data, const std::string& out_dir,
                       bool resume);
CommandResult RunEval(const GlobalOptions& g, const std::string& model_dir,
                      const std::string& data);
CommandResult RunLocalize(const GlobalOptions& g, const std::string& model_dir,
                          const std::string& wav, const std::string& proprio_csv);
CommandResult RunFk(const GlobalOptions& g, const std::string& joints);
CommandResult RunInspect(const GlobalOptions& g, const std::string& path);
CommandResult RunConfig(const GlobalOptions& g);

/// The demo's embedded config layer (small model, short training).
const std::string& DemoConfigYaml();

}  // namespace sonicboom::experiments
