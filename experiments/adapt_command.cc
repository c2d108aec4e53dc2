// `adapt`: a trained run's input and BatchNorm statistics re-estimated on unlabelled strikes of
// a new structure (learning::AdaptToUnlabelled); the result is a new run directory.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

CommandResult RunAdapt(const GlobalOptions& g, const std::string& model_dir,
                       const std::string& data, const std::string& out_dir,
                       const learning::AdaptOptions& options) {
  if (!options.batch_norm && !options.mel_statistics) {
    throw ConfigError(
        "adapt: --keep-batch-norm with --keep-mel-statistics leaves nothing to adapt");
  }
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  // the output rule of every command: not inside the run it reads, nor over the data
  RefuseWritingOverInputs(g, {out_dir}, {{model_dir, "--model"}, {data, "--data"}});
  if (fs::exists(out_dir) && !fs::is_empty(out_dir)) {
    throw ConfigError(fmt::format("{}: exists and is not empty; adapt writes a new run", out_dir));
  }
  // the dataset's features with the run's own settings; labels are not read
  const learning::FeatureSet target = ComputeDatasetFeatures(data, config, g.threads, !g.quiet);
  if (target.size() < learning::kMinFitRecords) {
    throw ConfigError(fmt::format(
        "{}: {} valid strike(s); adapt re-estimates the input and BatchNorm statistics on at "
        "least {}",
        data, target.size(), learning::kMinFitRecords));
  }
  const learning::AdaptReport r = learning::AdaptToUnlabelled(model_dir, target, out_dir, options);
  // the run's config travels with it: eval and localize read it from the run directory
  WriteTextAtomic((fs::path(out_dir) / "config.yaml").string(),
                  ReadText((fs::path(model_dir) / "config.yaml").string()));
  const json j{{"model", model_dir},          {"data", data},
               {"out", out_dir},              {"records", r.records},
               {"members", r.members},        {"batch_norm_layers", r.batch_norm_layers},
               {"batch_norm", options.batch_norm}, {"mel_statistics", options.mel_statistics}};
  std::vector<std::string> refitted;
  if (options.batch_norm) {
    refitted.push_back(fmt::format("{} BatchNorm layers", r.batch_norm_layers));
  }
  if (options.mel_statistics) refitted.push_back("per-mic input statistics");
  const std::string text =
      fmt::format("adapted {} network(s) of {} to {} unlabelled strikes ({}) -> {}\n", r.members,
                  model_dir, r.records, fmt::join(refitted, ", "), out_dir);
  return {j.dump(), text};
}

void RegisterAdapt(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string model, data, out;
    bool keep_batch_norm{false}, keep_mel_statistics{false};
  };
  auto o = std::make_shared<Options>();
  auto* adapt = app.add_subcommand(
      "adapt",
      "adapt a trained localizer to a new structure from unlabelled strikes: its per-mic input "
      "statistics and BatchNorm statistics re-estimated there (labels are not read); writes a "
      "new run");
  adapt->add_option("--model", o->model, "run directory (one network or an ensemble)")
      ->required();
  adapt->add_option("--data", o->data,
                    "strikes of the new structure (.h5; labels, if any, unread)")
      ->required();
  adapt->add_option("--out", o->out, "new run directory (must not exist or be empty)")
      ->required();
  adapt->add_flag("--keep-batch-norm", o->keep_batch_norm,
                  "leave the BatchNorm statistics as trained");
  adapt->add_flag("--keep-mel-statistics", o->keep_mel_statistics,
                  "leave the per-mic input statistics as trained");
  adapt->callback([&g, run, o] {
    learning::AdaptOptions options;
    options.batch_norm = !o->keep_batch_norm;
    options.mel_statistics = !o->keep_mel_statistics;
    *run = [&g, o, options] { return RunAdapt(g, o->model, o->data, o->out, options); };
  });
}

}  // namespace sonicboom::experiments
