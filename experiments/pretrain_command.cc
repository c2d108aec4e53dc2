// `pretrain`: the recommended sim-to-real recipe in one resumable command: randomized strikes of a
// tube as built, the transfer model trained on them, its intervals calibrated on structures
// beyond the training pool (docs/transfer.md, "One command").
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "embedded_configs.h"
#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

// structures of the calibration family's pool
constexpr int64_t kCalibrationStructures = 8;

struct PretrainOptions {
  int64_t strikes{3000};              // training strikes
  int64_t calibration_strikes{400};   // strikes beyond the pool the intervals are fitted on
  std::string out;                    // run directory
  bool force{false};                  // replace a finished run
  bool keep_data{false};              // keep the generated datasets in OUT/data
  // how the intervals are fitted to the calibration strikes (chosen on the as-built validation
  // families: docs/transfer.md, "Honest intervals")
  learning::IntervalFit calibration_fit{learning::IntervalFit::kLikelihood};
};

// the stationary scene with strikes anywhere on the tube (not on ts4's 2 cm marks)
constexpr const char* kPretrainDefaultsYaml = R"(scene:
  stationary:
    z_grid_m: 0
)";

// the recipe's layers over the defaults, before the user's --config and --set
ConfigSources RecipeSources(const GlobalOptions& g, bool beyond) {
  ConfigSources sources = g.sources;
  sources.embedded_layers = {{"configs/ts4.yaml (embedded)", kEmbedded_ts4_yaml},
                             {"configs/randomized.yaml (embedded)", kEmbedded_randomized_yaml},
                             {"configs/built.yaml (embedded)", kEmbedded_built_yaml},
                             {"configs/transfer.yaml (embedded)", kEmbedded_transfer_yaml},
                             {"pretrain defaults", kPretrainDefaultsYaml}};
  // calibration: the preset's and the as-built structure ranges each widened 1.5x
  if (beyond) {
    sources.embedded_layers.insert(sources.embedded_layers.begin() + 3,
                                   {"configs/beyond.yaml (embedded)", kEmbedded_beyond_yaml});
    sources.embedded_layers.insert(
        sources.embedded_layers.begin() + 5,
        {"configs/built_beyond.yaml (embedded)", kEmbedded_built_beyond_yaml});
  }
  return sources;
}

// the ranges configs/built_beyond.yaml sets, as the calibration config resolved them (a user's
// layer may override them)
json CalibrationRanges(const SonicBoomConfig& calibration) {
  const YAML::Node layer = YAML::Load(kEmbedded_built_beyond_yaml)["randomize"];
  const YAML::Node resolved = YAML::Load(ConfigToYaml(calibration))["randomize"];
  json ranges = json::object();
  for (const auto& entry : layer) {
    const std::string key = entry.first.as<std::string>();
    ranges[key] = resolved[key].as<std::vector<double>>();
  }
  return ranges;
}

// one dataset of the recipe: reused when complete (its valid count then unknown: -1), resumed
// from its .partial when interrupted
int64_t GenerateStage(const SonicBoomConfig& config, const std::string& path,
                      const GenerateRequest& options) {
  if (fs::exists(path)) {
    spdlog::info("{}: complete; reused", path);
    return -1;
  }
  return GenerateDataset(config, path, options).valid;
}

// the training stage: a finished one (its metrics in `done`) is reused, an interrupted one
// continues from its checkpoint
learning::Metrics TrainStage(const SonicBoomConfig& config, const std::string& data,
                             const std::string& model_dir, const std::string& done,
                             const GlobalOptions& g) {
  if (fs::exists(done)) {
    spdlog::info("{}: trained; reused", model_dir);
    learning::Metrics m;
    const json j = json::parse(ReadText(done));
    m.med_cm = j.at("med_cm");
    m.angle_err_deg = j.at("angle_err_deg");
    m.n = j.at("n");
    return m;
  }
  MakeDirectories(model_dir);
  WriteTextAtomic((fs::path(model_dir) / "config.yaml").string(), ConfigToYaml(config));
  const learning::Metrics m = TrainOnDataset(config, data, model_dir, true, g.threads, g.quiet);
  for (const std::string& member : learning::EnsembleMembers(model_dir)) {
    WriteTextAtomic((fs::path(member) / "config.yaml").string(), ConfigToYaml(config));
  }
  WriteTextAtomic(done, MetricsJson(m).dump(2) + "\n");
  return m;
}

CommandResult RunPretrain(const GlobalOptions& g, const PretrainOptions& o) {
  const auto start = Clock::now();
  const SonicBoomConfig config = ResolveConfig(RecipeSources(g, false));
  // the calibration family: the preset's and the as-built structures widened 1.5x
  // (configs/beyond.yaml, configs/built_beyond.yaml), its own seed and sample indices, so that
  // its pool is not the training pool stretched
  SonicBoomConfig beyond = ResolveConfig(RecipeSources(g, true));
  beyond.seed = config.seed + 7;
  // a pool of 8 structures (the layer's 48 cost a set-up as long as the training's): calibration
  // asks for structures unlike the training's, not for many of them
  beyond.randomize.structure_variants =
      std::min<int64_t>(beyond.randomize.structure_variants, kCalibrationStructures);
  CheckOutput(g, {o.out, "--out", o.force}, {});
  // everything is made in OUT.partial (a rerun continues it) and becomes OUT once calibrated
  const std::string work = o.out + ".partial";
  const OutputLock lock(o.out);
  const std::string data_dir = (fs::path(work) / "data").string();
  MakeDirectories(data_dir);
  const std::string train_path = (fs::path(data_dir) / "train.h5").string();
  const std::string calibration_path = (fs::path(data_dir) / "calibration.h5").string();
  const std::string model_dir = (fs::path(work) / "model").string();

  spdlog::info("pretrain 1/4: simulating {} strikes of a tube as built", o.strikes);
  const int64_t valid_train = GenerateStage(
      config, train_path, {.count = o.strikes, .threads = g.threads, .show_progress = !g.quiet});
  spdlog::info("pretrain 2/4: simulating {} calibration strikes beyond the training pool",
               o.calibration_strikes);
  const int64_t valid_calibration =
      GenerateStage(beyond, calibration_path,
                    {.count = o.calibration_strikes,
                     .first_index = 240000,
                     .threads = g.threads,
                     .show_progress = !g.quiet});
  const double generate_s = MillisecondsSince(start) / 1e3;

  spdlog::info("pretrain 3/4: training {} ({} epochs, {} networks)", model_dir,
               config.train.epochs, config.train.ensemble_members);
  const auto train_start = Clock::now();
  const learning::Metrics validation = TrainStage(
      config, train_path, model_dir, (fs::path(work) / "trained.json").string(), g);
  const double train_s = MillisecondsSince(train_start) / 1e3;

  spdlog::info("pretrain 4/4: calibrating the intervals on {}", calibration_path);
  GlobalOptions run_options = g;
  run_options.sources = {};
  const CommandResult calibration =
      RunCalibrate(run_options, model_dir, {calibration_path}, o.calibration_fit);
  spdlog::info("{}", calibration.text);

  // the run becomes OUT: the model's files at its top, the recipe's record beside them
  const json record = {{"strikes", o.strikes},
                       {"calibration_strikes", o.calibration_strikes},
                       {"valid_train", valid_train},
                       {"valid_calibration", valid_calibration},
                       {"validation", MetricsJson(validation)},
                       {"calibration", json::parse(calibration.json)},
                       {"calibration_fit", NameOf(o.calibration_fit)},
                       {"calibration_ranges", CalibrationRanges(beyond)},
                       {"generate_s", generate_s},
                       {"train_s", train_s},
                       {"wall_s", MillisecondsSince(start) / 1e3},
                       {"threads", g.threads}};
  WriteTextAtomic((fs::path(model_dir) / "pretrain.json").string(), record.dump(2) + "\n");
  if (o.keep_data) {
    fs::rename(data_dir, fs::path(model_dir) / "data");
  }
  std::error_code ec;
  fs::remove(fs::path(work) / "trained.json", ec);
  ReplaceDirectory(model_dir, o.out);
  fs::remove_all(work, ec);
  const json result = {{"run_dir", o.out}, {"pretrain", record}};
  return {result.dump(),
          fmt::format("pretrained {}: validation MED {:.2f} cm, angle {:.1f} deg ({} strikes); "
                      "wall {:.0f} s (simulate {:.0f} s, train {:.0f} s)\n{}",
                      o.out, validation.med_cm, validation.angle_err_deg, validation.n,
                      MillisecondsSince(start) / 1e3, generate_s, train_s, calibration.text)};
}

}  // namespace

void RegisterPretrain(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<PretrainOptions>();
  auto* cmd = app.add_subcommand(
      "pretrain",
      "the recommended sim-to-real model in one resumable command: strikes of a tube as built "
      "(configs/ts4 + randomized + built), the transfer model (configs/transfer.yaml), intervals "
      "calibrated beyond the training pool");
  cmd->add_option("--strikes", o->strikes, "training strikes")
      ->check(NumberIn(100, 1e7, false, true));
  cmd->add_option("--calibration-strikes", o->calibration_strikes,
                  "strikes of structures beyond the pool that the intervals are fitted on")
      ->check(NumberIn(30, 1e6, false, true));
  AddEnumOption(cmd, "--calibration-fit", &o->calibration_fit,
                "likelihood (default) | coverage: how the intervals are fitted (calibrate --fit)");
  cmd->add_option("--out", o->out, "run directory")->required();
  cmd->add_flag("--force", o->force, "replace an existing run (once the new one is done)");
  cmd->add_flag("--keep-data", o->keep_data,
                "keep the generated datasets in OUT/data (3000 strikes of 2 s: about 3 GB)");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunPretrain(g, *o); }; });
}

}  // namespace sonicboom::experiments
