// `demo`: a small randomized dataset, a model trained on it, and its table against a constant.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/baselines.h"
#include "sonicboom/learning/learning.h"

#include "embedded_configs.h"
#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string MetricsRow(const std::string& name, const learning::Metrics& m) {
  return fmt::format("| {:<28} | {:>13.2f} | {:>15.2f} | {:>15.1f} |\n", name, m.med_cm,
                     m.height_err_cm, m.angle_err_deg);
}

}  // namespace

const std::string& DemoConfigYaml() {
  // the log-mel transfer model on the default scene, where the arm moves: its proprioception
  // joins the audio (docs/transfer.md). Sized to finish in a few minutes on 2 cores: one network
  // (configs/transfer.yaml's waveform ensemble is the better model, and trains far longer).
  static const std::string yaml = R"(model:
  modalities: [audio, proprio]
demo:
  train_count: 3200
  test_count: 400
)";
  return yaml;
}

CommandResult RunDemo(const GlobalOptions& g, const std::string& out_dir_arg) {
  const auto start = std::chrono::steady_clock::now();
  ConfigSources sources = g.sources;
  // the demo trains the robust model a new user should start from: randomized structures,
  // strikers and sensor chains (configs/randomized.yaml) and the transfer model
  // (configs/transfer_mel.yaml), then its own sizes
  sources.embedded_layers = {{"configs/randomized.yaml (embedded)", kEmbedded_randomized_yaml},
                             {"configs/transfer_mel.yaml (embedded)", kEmbedded_transfer_mel_yaml},
                             {"demo defaults", DemoConfigYaml()}};
  const SonicBoomConfig config = ResolveConfig(sources);

  // a fresh run directory; never overwrite a finished run
  const std::string run_dir = out_dir_arg.empty() ? "runs/demo-" + UtcTimestamp() : out_dir_arg;
  if (fs::exists(fs::path(run_dir) / "metrics.json")) {
    throw IoError(fmt::format("{}: holds a finished run; choose another --out", run_dir));
  }
  MakeDirectories(run_dir);
  WriteTextAtomic((fs::path(run_dir) / "config.yaml").string(), ConfigToYaml(config));
  spdlog::info("demo run directory: {}", run_dir);

  // data: training strikes and held-out strikes with disjoint sample indices
  const std::string train_path = (fs::path(run_dir) / "train.h5").string();
  const std::string test_path = (fs::path(run_dir) / "test.h5").string();
  spdlog::info("step 1/3: simulating {} training and {} held-out strikes", config.demo.train_count,
               config.demo.test_count);
  const GenerateResult gen_train = GenerateDataset(
      config, train_path,
      {.count = config.demo.train_count, .threads = g.threads, .show_progress = !g.quiet});
  const GenerateResult gen_test = GenerateDataset(config, test_path,
                                                  {.count = config.demo.test_count,
                                                   .first_index = config.demo.train_count,
                                                   .threads = g.threads,
                                                   .show_progress = !g.quiet});

  // training
  spdlog::info("step 2/3: training ({} epochs)", config.train.epochs);
  const std::string model_dir = (fs::path(run_dir) / "model").string();
  MakeDirectories(model_dir);
  WriteTextAtomic((fs::path(model_dir) / "config.yaml").string(), ConfigToYaml(config));
  const auto train_start = std::chrono::steady_clock::now();
  const learning::Metrics val =
      TrainOnDataset(config, train_path, model_dir, false, g.threads, g.quiet);
  const double train_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - train_start).count();

  // evaluation on held-out strikes, against a constant predictor (training mean z, mean angle)
  spdlog::info("step 3/3: evaluating on held-out strikes");
  const learning::FeatureSet test = ComputeDatasetFeatures(test_path, config, g.threads, !g.quiet);
  learning::Localizer localizer(model_dir);
  const learning::Metrics model_metrics =
      learning::ComputeMetrics(localizer.Predict(test), test, config.tube.outer_radius_m);
  const learning::FeatureSet train_labels = DatasetLabels(train_path, config);
  const learning::Prediction constant =
      learning::ConstantPrediction(train_labels.z_m, train_labels.theta_rad);
  const learning::Metrics baseline = learning::ComputeMetrics(
      std::vector<learning::Prediction>(test.size(), constant), test, config.tube.outer_radius_m);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // results: metrics.json is written last and marks the run finished
  json result = {{"run_dir", run_dir},
                 {"train_strikes", gen_train.written},
                 {"test_strikes", gen_test.written},
                 {"valid_train", gen_train.valid},
                 {"valid_test", gen_test.valid},
                 {"model", MetricsJson(model_metrics)},
                 {"validation", MetricsJson(val)},
                 {"constant_baseline", MetricsJson(baseline)},
                 {"generate_s", gen_train.wall_s + gen_test.wall_s},
                 {"train_s", train_s},
                 {"wall_s", wall_s}};
  WriteTextAtomic((fs::path(run_dir) / "metrics.json").string(), result.dump(2) + "\n");

  std::string text = fmt::format(
      "\nSonicBoom demo: {} held-out strikes (trained on {}, {} epochs, {} encoder, width {})\n\n",
      model_metrics.n, gen_train.valid, config.train.epochs, NameOf(config.model.audio_encoder),
      config.model.width);
  text += "| method                       | 3-D MED (cm)  | height err (cm) | angle err (deg) |\n";
  text += "|------------------------------|---------------|-----------------|-----------------|\n";
  text += MetricsRow("multimodal transformer", model_metrics);
  text += MetricsRow("constant (train mean)", baseline);
  text += fmt::format(
      "\nMED: mean 3-D distance between surface points (r = {} m). "
      "Wall time {:.0f} s (simulate {:.0f} s, train {:.0f} s).\n"
      "Run directory: {}\n",
      config.tube.outer_radius_m, wall_s, gen_train.wall_s + gen_test.wall_s, train_s, run_dir);
  return {result.dump(), text};
}

void RegisterDemo(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto out = std::make_shared<std::string>();
  auto* demo = app.add_subcommand("demo",
                                  "generate a small dataset, train, evaluate on held-out "
                                  "strikes and print the result table");
  demo->add_option("--out", *out, "run directory (default runs/demo-<UTC time>)");
  demo->callback([&g, run, out] { *run = [&g, out] { return RunDemo(g, *out); }; });
}

}  // namespace sonicboom::experiments
