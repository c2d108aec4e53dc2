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
#include "sonicboom/learning/fine_tune.h"
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

// fine_tune.json of a fixed recipe (null: no fine-tune)
json FixedTuneRecord(const TrainOptions& o) {
  if (o.init_from.empty()) return nullptr;
  return {{"init_from", o.init_from}, {"freeze", NameOf(o.freeze)}, {"norm", NameOf(o.norm)}};
}

// The run's own files beside what training writes: its config, and how it was fine-tuned
// (`fine_tune`, fine_tune.json) and pseudo-labelled.
void WriteRunSidecars(const std::string& work, const SonicBoomConfig& config, const json& fine_tune,
                      const json& pseudo) {
  WriteTextAtomic((fs::path(work) / "config.yaml").string(), ConfigToYaml(config));
  if (!fine_tune.is_null()) {
    WriteTextAtomic((fs::path(work) / "fine_tune.json").string(), fine_tune.dump(2) + "\n");
  }
  if (!pseudo.is_null()) {
    WriteTextAtomic((fs::path(work) / "pseudo_labels.json").string(), pseudo.dump(2) + "\n");
  }
}

// Each member of an ensemble is a run of its own too (eval, localize, a fine-tune from it).
void WriteMemberConfigs(const std::string& work, const SonicBoomConfig& config) {
  for (const std::string& member : learning::EnsembleMembers(work)) {
    WriteTextAtomic((fs::path(member) / "config.yaml").string(), ConfigToYaml(config));
  }
}

// --tune auto's refusals, before anything is read: what it cannot judge or run.
void CheckAutoTune(const TrainOptions& o, const learning::DataParallel& parallel) {
  if (o.init_from.empty()) {
    throw ConfigError("--tune auto chooses how to fine-tune a pretrained run: give --init-from RUN");
  }
  if (o.pseudo_labels > 0.0) {
    throw ConfigError("--tune auto judges candidates by the data's labels, which --pseudo-labels "
                      "replaces: give a fixed recipe (--freeze F --lr LR)");
  }
  if (o.resume) {
    throw ConfigError("--tune auto does not resume: give the recipe its fine_tune.json chose "
                      "(--freeze F --lr LR)");
  }
  if (parallel.world_size > 1) throw ConfigError("--tune auto runs in one process (WORLD_SIZE 1)");
}

json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// One candidate of fine_tune.json: its recipe, per-fold held-out MEDs and test against the
// pretrained weights.
json CandidateRecord(const learning::AutoFineTuneResult& r, size_t c) {
  json j{{"name", r.candidates[c].name},
         {"fold_med_cm", r.fold_med_cm[c]},
         {"mean_med_cm", r.choice.mean_med_cm[c]}};
  if (const auto& recipe = r.candidates[c].recipe) {
    j["freeze"] = NameOf(recipe->freeze);
    j["learning_rate"] = recipe->learning_rate;
    j["folds_better"] = r.choice.folds_better[c];
    j["paired_t"] = Number(r.choice.t_statistic[c]);
  }
  return j;
}

// fine_tune.json of --tune auto: the candidates' folds, the choice, why, and the calibration.
json AutoTuneRecord(const TrainOptions& o, const learning::AutoFineTuneOptions& a,
                    const learning::AutoFineTuneResult& r, const std::string& calibration) {
  json candidates = json::array();
  for (size_t c = 0; c < r.candidates.size(); ++c) candidates.push_back(CandidateRecord(r, c));
  const learning::FineTuneCandidate& chosen = r.candidates[static_cast<size_t>(r.choice.chosen)];
  json j{{"init_from", o.init_from},
         {"tune", "auto"},
         {"norm", NameOf(o.norm)},
         {"strikes", r.fold_of_row.size()},
         {"folds", r.fold_med_cm.front().size()},
         {"epochs", a.train.epochs},
         {"selection",
          {{"rule", "a tuned candidate replaces the pretrained weights only when a one-sided "
                    "paired t-test over the folds' held-out MED says it is lower"},
           {"alpha", a.selection.alpha},
           {"t_critical", r.choice.t_critical}}},
         {"candidates", candidates},
         {"chosen", chosen.name},
         {"why", r.choice.why},
         {"calibration", calibration}};
  if (chosen.recipe) {
    j["freeze"] = NameOf(chosen.recipe->freeze);
    j["learning_rate"] = chosen.recipe->learning_rate;
  }
  return j;
}

// The chosen recipe trained on every labelled strike (the per-epoch log reads them too; the
// cross-validation judged it), with the pretrained scales, refitted on the recipe's out-of-fold
// answers where there are kMinFitRecords of them. Returns the calibration in words.
std::string TrainChosen(const SonicBoomConfig& config, const learning::FeatureSet& labelled,
                        const learning::AutoFineTuneResult& r, const TrainOptions& o,
                        const std::string& work, bool quiet) {
  learning::FineTune tune;
  tune.init_from = o.init_from;
  tune.freeze = r.candidates[static_cast<size_t>(r.choice.chosen)].recipe->freeze;
  tune.refit_normalization = o.norm == NormPolicy::kRefit;
  tune.calibration = learning::FineTune::Calibration::kKeepPretrained;
  TrainOnSplit(config, FeatureSplit{labelled, labelled}, work, /*resume=*/false, quiet, tune);
  const int64_t usable = learning::CalibrationRecords(r.held_out, labelled);
  if (usable < learning::kMinFitRecords) {
    return fmt::format("the pretrained run's scales, kept: {} out-of-fold answers, fewer than the "
                       "{} a fit needs",
                       usable, learning::kMinFitRecords);
  }
  const learning::Recalibration rc = learning::Recalibrate(
      work, r.held_out, labelled, "out-of-fold answers of the --tune auto cross-validation");
  return fmt::format("the pretrained run's scales refitted on the chosen recipe's {} out-of-fold "
                     "answers (sigma_z x {:.3g}, kappa x {:.3g})",
                     usable, rc.relative.z_std_scale, rc.relative.kappa_scale);
}

// The pretrained run, files and all (weights, members, calibration), as the result.
void CopyPretrained(const std::string& from, const std::string& work) {
  for (const auto& e : fs::directory_iterator(from)) {
    fs::copy(e.path(), fs::path(work) / e.path().filename(),
             fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  }
}

// --tune auto into `work` (made, empty): cross-validation on the labelled strikes, then the
// chosen recipe trained on all of them or the pretrained run copied; `work` becomes o.out.
CommandResult RunAutoTune(SonicBoomConfig config, const learning::FeatureSet& features,
                          const std::vector<uint64_t>& indices, const TrainOptions& o,
                          const std::string& work, bool quiet) {
  std::vector<int64_t> rows;
  std::vector<uint64_t> labelled_indices;
  for (size_t r = 0; r < indices.size(); ++r) {
    if (!std::isfinite(features.z_m[r]) || !std::isfinite(features.theta_rad[r])) continue;
    rows.push_back(static_cast<int64_t>(r));
    labelled_indices.push_back(indices[r]);
  }
  const learning::FeatureSet labelled = features.SelectRows(rows);
  learning::AutoFineTuneOptions a;
  a.init_from = o.init_from;
  a.model = config.model;
  a.train = config.train;
  a.refit_normalization = o.norm == NormPolicy::kRefit;
  a.surface_radius_m = config.tube.outer_radius_m;
  a.seed = config.seed;
  a.work_dir = (fs::path(work) / "cross_validation").string();
  a.show_progress = !quiet;
  const learning::AutoFineTuneResult r = learning::CrossValidateFineTune(labelled, labelled_indices, a);
  fs::remove_all(a.work_dir);
  const learning::FineTuneCandidate& chosen = r.candidates[static_cast<size_t>(r.choice.chosen)];
  std::string calibration = "the pretrained run's, kept with its weights";
  if (chosen.recipe) {
    config.train.learning_rate = chosen.recipe->learning_rate;
    config.train.keep_best = false;
    calibration = TrainChosen(config, labelled, r, o, work, quiet);
  } else {
    CopyPretrained(o.init_from, work);
  }
  const json record = AutoTuneRecord(o, a, r, calibration);
  WriteRunSidecars(work, config, record, nullptr);
  WriteMemberConfigs(work, config);
  ReplaceDirectory(work, o.out);
  const learning::Metrics held = learning::ComputeMetrics(r.held_out, labelled, a.surface_radius_m);
  const json j{{"run_dir", o.out}, {"fine_tune", record}, {"held_out", MetricsJson(held)}};
  return {j.dump(),
          fmt::format("fine-tuned {} (--tune auto, {}-fold cross-validation on {} strikes): {}\n"
                      "chosen: {}; over its {} out-of-fold answers MED {:.2f} cm, height {:.2f} cm, "
                      "angle {:.1f} deg\n",
                      o.out, r.fold_med_cm.front().size(), labelled.size(), r.choice.why,
                      chosen.name, held.n, held.med_cm, held.height_err_cm, held.angle_err_deg)};
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
  if (o.tune == TuneMode::kAuto) CheckAutoTune(o, parallel);
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
  if (o.tune == TuneMode::kAuto) {
    try {
      return RunAutoTune(config, features, indices, o, work, g.quiet);
    } catch (const Error&) {
      fs::remove_all(work, ec);
      throw;
    }
  }
  // a fresh run says what it is before it trains; a resumed one once it has trained
  if (made_work) WriteRunSidecars(work, config, FixedTuneRecord(o), pseudo);
  learning::Metrics m;
  try {
    m = TrainOnFeatures(config, std::move(features), indices, o.data, work, o.resume, g.quiet,
                        fine_tune, parallel);
  } catch (const Error&) {
    if (made_work) fs::remove_all(work, ec);
    throw;
  }
  if (!made_work) WriteRunSidecars(work, config, FixedTuneRecord(o), pseudo);
  WriteMemberConfigs(work, config);
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
  CLI::Option* freeze = AddEnumOption(train, "--freeze", &o->train.freeze,
                                      "none | encoders | all-but-head (with --init-from; a "
                                      "fixed recipe)");
  CLI::Option* tune = AddEnumOption(
      train, "--tune", &o->train.tune,
      "auto | fixed (with --init-from): auto, the default unless --freeze, --lr, --pseudo-labels "
      "or --resume is given, cross-validates the pretrained weights against two fine-tunes on "
      "the data's strikes and keeps the weights unless a tune is better (docs/captures.md)");
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
  train->callback([&g, run, o, freeze, tune] {
    if (o->lr > 0.0) g.sources.overrides.push_back(fmt::format("train.learning_rate={}", o->lr));
    if (o->epochs > 0) g.sources.overrides.push_back(fmt::format("train.epochs={}", o->epochs));
    const bool recipe = freeze->count() > 0 || o->lr > 0.0;
    const bool fixed = recipe || o->train.pseudo_labels > 0.0 || o->train.resume;
    if (tune->count() == 0) {
      o->train.tune = !o->train.init_from.empty() && !fixed ? TuneMode::kAuto : TuneMode::kFixed;
    }
    const bool conflict = o->train.tune == TuneMode::kAuto && recipe;
    *run = [&g, o, conflict] {
      if (conflict) {
        throw ConfigError("--tune auto chooses the freeze mode and learning rate itself: drop "
                          "--freeze and --lr, or give --tune fixed");
      }
      return RunTrain(g, o->train);
    };
  });
}

}  // namespace sonicboom::experiments
