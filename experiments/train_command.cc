// `train`: a localizer trained on a dataset, or fine-tuned from a pretrained run.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "internal/pseudo_labels.h"
#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// --pseudo-labels: the pretrained run answers every strike (with its own turn and mirror
// averaging) and the fraction it is surest of keeps those answers as labels; the data's labels,
// where it has them, only score the pseudo-labels (a diagnostic nothing else reads)
json ApplyPseudoLabels(const std::string& init_from, double keep_fraction,
                       learning::FeatureSet* features, std::vector<uint64_t>* indices) {
  const learning::Localizer localizer(init_from);
  const std::vector<learning::Prediction> predictions = localizer.Predict(*features);
  const double radius_m = localizer.surface_radius_m();
  const PseudoLabelSelection s = SelectPseudoLabels(predictions, keep_fraction, radius_m);
  json j{{"source", init_from},
         {"fraction", keep_fraction},
         {"records", features->size()},
         {"kept", s.rows.size()}};
  if (std::isfinite(s.spread_limit_cm)) j["spread_limit_cm"] = s.spread_limit_cm;
  // the kept answers and the data's labels of their strikes (labels only: the metrics read no
  // features, and WithPseudoLabels below copies the kept rows' features once)
  std::vector<learning::Prediction> kept;
  std::vector<uint64_t> kept_indices;
  learning::FeatureSet truth = features->ShapesOnly();
  for (const int64_t r : s.rows) {
    const auto row = static_cast<size_t>(r);
    kept.push_back(predictions[row]);
    kept_indices.push_back((*indices)[row]);
    truth.z_m.push_back(features->z_m[row]);
    truth.theta_rad.push_back(features->theta_rad[row]);
  }
  const learning::Metrics m = learning::ComputeMetrics(kept, truth, radius_m);
  if (m.n > 0) j["med_cm_against_labels"] = m.med_cm;
  *features = WithPseudoLabels(*features, predictions, s.rows);
  *indices = std::move(kept_indices);
  return j;
}

// The run's own files beside what training writes: its config, and how it was fine-tuned and
// pseudo-labelled.
void WriteRunSidecars(const std::string& work, const SonicBoomConfig& config, const TrainOptions& o,
                      const json& pseudo) {
  WriteTextAtomic((fs::path(work) / "config.yaml").string(), ConfigToYaml(config));
  if (!o.init_from.empty()) {
    const json init{
        {"init_from", o.init_from}, {"freeze", NameOf(o.freeze)}, {"norm", NameOf(o.norm)}};
    WriteTextAtomic((fs::path(work) / "fine_tune.json").string(), init.dump(2) + "\n");
  }
  if (!pseudo.is_null()) {
    WriteTextAtomic((fs::path(work) / "pseudo_labels.json").string(), pseudo.dump(2) + "\n");
  }
}

}  // namespace

CommandResult RunTrain(const GlobalOptions& g, const TrainOptions& o) {
  // a fine-tune starts from the pretrained run's config (its model and features), then the
  // user's layers; a fresh run from the defaults
  learning::FineTune fine_tune;
  fine_tune.init_from = o.init_from;
  fine_tune.freeze = o.freeze;
  fine_tune.refit_normalization = o.norm == NormPolicy::kRefit;
  if (o.init_from.empty() &&
      (o.freeze != learning::FineTune::Freeze::kNone || o.norm != NormPolicy::kKeep)) {
    throw ConfigError("--freeze and --norm apply to a fine-tune: give --init-from RUN");
  }
  if (o.init_from.empty() && o.pseudo_labels > 0.0) {
    throw ConfigError("--pseudo-labels labels strikes by a pretrained run: give --init-from RUN");
  }
  if (!o.init_from.empty() && fs::absolute(o.init_from) == fs::absolute(o.out)) {
    throw ConfigError(fmt::format(
        "--init-from {} is the output run; fine-tune into another directory", o.init_from));
  }
  const SonicBoomConfig config = o.init_from.empty() ? Resolve(g) : ResolveWithRun(g, o.init_from);
  if (!fs::exists(o.data)) throw IoError(fmt::format("{}: no such dataset", o.data));
  // data parallel (RANK/WORLD_SIZE set by a launcher): every process trains its part of each
  // batch; rank 0 alone writes the run (docs/cluster.md)
  const learning::DataParallel parallel = learning::DataParallel::FromEnvironment();
  // the run is written whole in OUT.partial, which replaces OUT once training is done: a killed
  // run never leaves a directory that looks complete, nor harms the run it was replacing
  const std::string work = o.out + ".partial";
  const bool writes = parallel.rank == 0;
  if (writes && o.resume && !fs::exists(work) && !fs::exists(o.out)) {
    throw IoError(fmt::format("{}: nothing to resume (neither it nor {} exists)", o.out, work));
  }
  const std::vector<ReadPath> reads = {{o.data, "--data"}, {o.init_from, "--init-from"}};
  if (writes && !o.resume) CheckOutput(g, {o.out, "--out", o.force}, reads);
  if (writes && o.resume) RefuseWritingOverInputs(g, {o.out}, reads);
  // the whole dataset is read before anything is written: a damaged file refused, or one that
  // ends the process inside libhdf5 (docs/robustness.md), leaves no OUT.partial behind
  std::vector<uint64_t> indices;
  learning::FeatureSet features =
      ComputeDatasetFeatures(o.data, config, g.threads, !g.quiet, &indices);
  json pseudo;
  if (o.pseudo_labels > 0.0) {
    pseudo = ApplyPseudoLabels(o.init_from, o.pseudo_labels, &features, &indices);
  }
  if (!writes) {
    // reads rank 0's OUT.partial when resuming, writes nothing
    TrainOnFeatures(config, std::move(features), indices, o.data, work, o.resume, g.quiet,
                    fine_tune, parallel);
    const json j = {
        {"run_dir", o.out}, {"rank", parallel.rank}, {"world_size", parallel.world_size}};
    return {j.dump(), fmt::format("rank {} of {}: trained in data parallel; rank 0 writes {}\n",
                                  parallel.rank, parallel.world_size, o.out)};
  }
  // one trainer of a run at a time: a second refuses instead of deleting the first's OUT.partial
  // (taken once the data is read: a file that crashes libhdf5 leaves no lock file behind)
  const OutputLock lock(o.out);
  std::error_code ec;
  // what this command makes goes again if it is refused: a fresh run, or the copy of a finished
  // run trained further; an interrupted run resumed keeps its checkpoint and files as they were
  const bool made_work = !o.resume || !fs::exists(work);
  if (o.resume && made_work) {
    // more epochs for a finished run: in a copy, which replaces it once done
    fs::copy(o.out, work, fs::copy_options::recursive, ec);
    if (ec) {
      const std::string why = ec.message();
      fs::remove_all(work, ec);
      throw IoError(fmt::format("{}: cannot copy {} to resume it: {}", work, o.out, why));
    }
  } else if (!o.resume) {
    fs::remove_all(work, ec);  // a killed run's leftovers, not resumed
  }
  MakeDirectories(work);
  // a fresh run says what it is before it trains; a resumed one once it has trained
  if (made_work) WriteRunSidecars(work, config, o, pseudo);
  learning::Metrics m;
  try {
    m = TrainOnFeatures(config, std::move(features), indices, o.data, work, o.resume, g.quiet,
                        fine_tune, parallel);
  } catch (const Error&) {
    if (made_work) fs::remove_all(work, ec);
    throw;
  }
  if (!made_work) WriteRunSidecars(work, config, o, pseudo);
  // each member of an ensemble is a run of its own too (eval, localize, a fine-tune from it)
  for (const std::string& member : learning::EnsembleMembers(work)) {
    WriteTextAtomic((fs::path(member) / "config.yaml").string(), ConfigToYaml(config));
  }
  ReplaceDirectory(work, o.out);
  json j = MetricsJson(m);
  j["run_dir"] = o.out;
  if (!pseudo.is_null()) j["pseudo_labels"] = pseudo;
  if (parallel.world_size > 1) j["world_size"] = parallel.world_size;
  return {j.dump(), fmt::format("trained {}: validation MED {:.2f} cm, height {:.2f} cm, angle "
                                "{:.1f} deg ({} strikes)\n",
                                o.out, m.med_cm, m.height_err_cm, m.angle_err_deg, m.n)};
}

void RegisterTrain(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    TrainOptions train;
    double lr = 0.0;
    int64_t epochs = 0;
  };
  auto o = std::make_shared<Options>();
  auto* train = app.add_subcommand("train",
                                   "train a localizer on a dataset, or fine-tune a "
                                   "pretrained one (--init-from)");
  train->add_option("--data", o->train.data, "training dataset (.h5)")->required();
  train->add_option("--out", o->train.out, "run directory")->required();
  train->add_flag("--resume", o->train.resume,
                  "continue an interrupted run (RUN.partial) from its checkpoint, or train a "
                  "finished one further");
  train->add_flag("--force", o->train.force,
                  "replace an existing run directory (once the new run is complete)");
  train->add_option("--init-from", o->train.init_from,
                    "pretrained run directory: start from its weights and config");
  AddEnumOption(train, "--freeze", &o->train.freeze,
                "none | encoders | all-but-head (with --init-from)");
  AddEnumOption(train, "--norm", &o->train.norm,
                "keep | refit the per-mic mel statistics (with --init-from; default keep)");
  train
      ->add_option("--pseudo-labels", o->train.pseudo_labels,
                   "self-training (with --init-from): keep this fraction of the data's strikes, "
                   "those the pretrained run is surest of, labelled by its answers; the "
                   "data's labels are not read")
      ->check(NumberIn(0.0, 1.0, true));
  train->add_option("--lr", o->lr, "learning rate (sets train.learning_rate)")
      ->check(NumberIn(0.0, 1.0, true));
  train->add_option("--epochs", o->epochs, "epochs (sets train.epochs)")
      ->check(NumberIn(1, 100000, false, true));
  train->callback([&g, run, o] {
    if (o->lr > 0.0) g.sources.overrides.push_back(fmt::format("train.learning_rate={}", o->lr));
    if (o->epochs > 0) g.sources.overrides.push_back(fmt::format("train.epochs={}", o->epochs));
    *run = [&g, o] { return RunTrain(g, o->train); };
  });
}

}  // namespace sonicboom::experiments
