// `features`: mel spectrograms and GCC-PHAT of a WAV or a dataset.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/array_file.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// what the file's "mel" array holds
std::string MelLayout(const dsp::FeatureConfig& f) {
  if (f.audio_representation == dsp::AudioRepresentation::kWaveform) {
    return "waveform: the window's samples, one row per channel";
  }
  return fmt::format("power mel, n_fft {}, hop {}, {} HTK bands, {}", f.n_fft, f.hop, f.n_mels,
                     f.log_mel ? "log10" : "no log");
}

}  // namespace

CommandResult RunFeatures(const GlobalOptions& g, const std::string& in, const std::string& out,
                          const std::string& proprio_csv, bool force) {
  CheckOutput(g, {out, "--out", force}, {{in, "--in"}, {proprio_csv, "--proprio"}});
  CheckConfigSidecar({out, "--out", force});
  const SonicBoomConfig config = Resolve(g);
  std::vector<NamedArray> arrays;
  int64_t n = 1;
  learning::FeatureSet set;
  if (fs::path(in).extension() == ".h5") {
    // every valid sample of a dataset
    set = ComputeDatasetFeatures(in, config, g.threads, !g.quiet);
    n = set.size();
    arrays.push_back({"z_m", {n}, std::vector<float>(set.z_m.begin(), set.z_m.end())});
    arrays.push_back(
        {"theta_rad", {n}, std::vector<float>(set.theta_rad.begin(), set.theta_rad.end())});
    arrays.push_back({"mel", {n, set.channels, set.mels, set.frames}, set.mel});
    arrays.push_back({"gcc", {n, set.gcc_pairs, set.gcc_lags}, set.gcc});
    arrays.push_back({"proprio", {n, set.proprio_rows, set.proprio_features}, set.proprio});
  } else {
    // one WAV (and optional robot log)
    const hardware::Capture cap = hardware::LoadCapture(in, proprio_csv, CaptureChecksFor(config));
    set = ComputeRecordFeatures(cap.audio, cap.sample_rate_hz, cap.proprio, config);
    arrays.push_back({"mel", {set.channels, set.mels, set.frames}, set.mel});
    arrays.push_back({"gcc", {set.gcc_pairs, set.gcc_lags}, set.gcc});
    if (cap.proprio.size() > 0) {
      arrays.push_back({"proprio", {set.proprio_rows, set.proprio_features}, set.proprio});
    }
  }
  WriteArrayFile(out, "sonicboom.features", arrays,
                 {{"source", in},
                  {"config_yaml", ConfigToYaml(config)},
                  {"mel_layout", MelLayout(config.features)},
                  {"gcc_layout", "15 pairs in combinations order x lags -max..+max samples"}});
  WriteConfigBeside(out, config);  // once the features are in place
  json j = {{"path", out},
            {"samples", n},
            {"mel_shape", {set.channels, set.mels, set.frames}},
            {"gcc_shape", {set.gcc_pairs, set.gcc_lags}}};
  return {j.dump(), fmt::format("wrote {}: mel {} x {} x {}, GCC-PHAT {} x {} ({} sample{})\n", out,
                                set.channels, set.mels, set.frames, set.gcc_pairs, set.gcc_lags, n,
                                n == 1 ? "" : "s")};
}

void RegisterFeatures(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string in, out, proprio;
    bool force = false;
  };
  auto o = std::make_shared<Options>();
  auto* features =
      app.add_subcommand("features", "mel spectrograms and GCC-PHAT of a WAV or dataset");
  features->add_option("--in", o->in, "WAV file or dataset (.h5)")->required();
  features->add_option("--out", o->out, "features file (.h5)")->required();
  features->add_option("--proprio", o->proprio, "robot log CSV for a WAV input");
  features->add_flag("--force", o->force,
                     "replace an existing output (once the new one is complete)");
  features->callback([&g, run, o] {
    *run = [&g, o] { return RunFeatures(g, o->in, o->out, o->proprio, o->force); };
  });
}

}  // namespace sonicboom::experiments
