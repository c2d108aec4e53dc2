// `synth`: one strike as a 6-channel WAV with its label beside it.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/pipeline.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

CommandResult RunSynth(const GlobalOptions& g, const std::string& out_wav, int64_t index,
                       bool force) {
  const SonicBoomConfig config = Resolve(g);
  if (fs::path(out_wav).extension() != ".wav") {
    throw ConfigError(fmt::format("--out {}: a synthesized strike is a .wav file", out_wav));
  }
  const std::string stem = (fs::path(out_wav).parent_path() / fs::path(out_wav).stem()).string();
  CheckOutput(g, {out_wav, "--out", force}, {});
  CheckConfigSidecar({out_wav, "--out", force});
  CheckOutput(g, {stem + ".json", "the label beside --out", force}, {});
  if (index < 0) throw ConfigError(fmt::format("--index must be >= 0, got {}", index));
  StrikePipeline pipeline(config);
  const StrikeSample s = pipeline.Simulate(static_cast<uint64_t>(index));
  if (!s.valid) {
    throw NumericalError(
        fmt::format("strike {} (seed {}) is invalid: {}", index, config.seed, s.invalid_reason));
  }
  // label sidecar and config first, the WAV last: a WAV on disk means the set is complete
  json label = LabelJson(s.label);
  label["index"] = s.index;
  label["seed"] = s.seed;
  label["global_seed"] = config.seed;
  label["sample_rate_hz"] = config.audio.sample_rate_hz;
  label["clipped"] = s.clipped;
  label["frame"] = "tube";
  WriteTextAtomic(stem + ".json", label.dump(2) + "\n");
  WriteConfigBeside(out_wav, config);
  try {
    WriteWav(out_wav, AudioClip{s.audio, config.audio.sample_rate_hz}, true);
  } catch (...) {
    fs::remove(stem + ".json");
    throw;
  }
  json j = {{"wav", out_wav},       {"label", stem + ".json"},
            {"z_m", s.label.z_m},   {"theta_rad", s.label.theta_rad},
            {"clipped", s.clipped}, {"peak", s.audio.cwiseAbs().maxCoeff()}};
  return {j.dump(), fmt::format("wrote {} (6 channels, {} Hz) and {}: z = {:.4f} m, theta = "
                                "{:.4f} rad\n",
                                out_wav, config.audio.sample_rate_hz, stem + ".json", s.label.z_m,
                                s.label.theta_rad)};
}

void RegisterSynth(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string out;
    int64_t index = 0;
    bool force = false;
  };
  auto o = std::make_shared<Options>();
  auto* synth = app.add_subcommand("synth", "one strike as a 6-channel WAV plus a JSON label");
  synth->add_option("--out", o->out, "WAV file (.wav; the label goes beside it as .json)")
      ->required();
  synth->add_option("--index", o->index, "sample index (with --seed it fixes the strike)");
  synth->add_flag("--force", o->force, "replace an existing WAV and label");
  synth->callback(
      [&g, run, o] { *run = [&g, o] { return RunSynth(g, o->out, o->index, o->force); }; });
}

}  // namespace sonicboom::experiments
