// `calibrate`: a finished run's predictive intervals refitted on labelled strikes other than its
// validation split (structures beyond the training pool, or captures of the user's own robot).
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "internal/records.h"
#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Where a strike was read: the file, its row and sample index.
struct StrikePlace {
  std::string path;
  int64_t row{0};
  uint64_t index{0};
};

// What makes a strike that strike: its audio, arm and label, as read (a digest).
uint64_t StrikeDigest(const StrikeSample& s) {
  uint64_t h = internal::Fnv1a(s.audio.data(), sizeof(float) * s.audio.size());
  h = internal::Fnv1a(s.proprio.data(), sizeof(float) * s.proprio.size(), h);
  const double label[2] = {s.label.z_m, s.label.theta_rad};
  return internal::Fnv1a(label, sizeof(label), h);
}

// Every strike counts once: a dataset given twice, a renamed copy, a merge beside its shards or
// one strike under two indices would pass the minimum with the same strikes twice.
void RefuseRepeatedStrikes(const GlobalOptions& g, const SonicBoomConfig& config,
                           const std::vector<std::string>& data) {
  std::map<uint64_t, StrikePlace> seen;
  for (size_t k = 0; k < data.size(); ++k) {
    for (size_t j = 0; j < k; ++j) {
      std::error_code ec;
      if (data[j] == data[k] || fs::equivalent(data[j], data[k], ec)) {
        throw ConfigError(fmt::format(
            "--data {} is given twice (the same file as --data {}): each strike counts once "
            "toward the {} a fit needs",
            data[k], data[j], learning::kMinFitRecords));
      }
    }
    const DatasetReader reader(data[k]);
    const ValidRecords valid = ReadValidRecords(reader, data[k], config);
    std::vector<uint64_t> digests(valid.rows.size());
    ForEachRecord(reader, valid.rows, g.threads, "strikes", false,
                  [&](int64_t i, const StrikeSample& s) { digests[i] = StrikeDigest(s); });
    for (size_t i = 0; i < digests.size(); ++i) {
      const StrikePlace here{data[k], valid.rows[i], valid.metas[i].index};
      const auto [it, fresh] = seen.emplace(digests[i], here);
      if (fresh) continue;
      throw ConfigError(fmt::format(
          "{} row {} (index {}) is the strike of {} row {} (index {}): the same audio, arm and "
          "label; each strike counts once toward the {} a fit needs",
          here.path, here.row, here.index, it->second.path, it->second.row, it->second.index,
          learning::kMinFitRecords));
    }
  }
}

}  // namespace

CommandResult RunCalibrate(const GlobalOptions& g, const std::string& model_dir,
                           const std::vector<std::string>& data, learning::IntervalFit fit) {
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  learning::Localizer localizer(model_dir);
  if (!localizer.has_uncertainty()) {
    throw ConfigError(fmt::format(
        "{}: the model has no uncertainty head (trained with train.uncertainty_weight = 0): "
        "there are no intervals to calibrate",
        model_dir));
  }
  RefuseRepeatedStrikes(g, config, data);
  // the run's calibrated predictions of every dataset, and their labels, in order
  std::vector<learning::Prediction> predictions;
  learning::FeatureSet labels;
  for (const std::string& path : data) {
    const learning::FeatureSet set = ComputeDatasetFeatures(path, config, g.threads, !g.quiet);
    const std::vector<learning::Prediction> p = localizer.Predict(set);
    predictions.insert(predictions.end(), p.begin(), p.end());
    labels.z_m.insert(labels.z_m.end(), set.z_m.begin(), set.z_m.end());
    labels.theta_rad.insert(labels.theta_rad.end(), set.theta_rad.begin(), set.theta_rad.end());
  }
  std::string source;
  for (const std::string& path : data) source += (source.empty() ? "" : ", ") + path;
  const learning::Recalibration r = learning::Recalibrate(model_dir, predictions, labels, source, fit);
  // the same records under the new scales
  const learning::Metrics before =
      learning::ComputeMetrics(predictions, labels, localizer.surface_radius_m());
  for (learning::Prediction& p : predictions) p = learning::ApplyCalibration(p, r.relative);
  const learning::Metrics after =
      learning::ComputeMetrics(predictions, labels, localizer.surface_radius_m());
  auto scales = [](const learning::UncertaintyCalibration& c) {
    return json{{"z_std_scale", c.z_std_scale}, {"kappa_scale", c.kappa_scale}};
  };
  const json j{{"model", model_dir},        {"data", data},
               {"before", scales(r.before)}, {"relative", scales(r.relative)},
               {"after", scales(r.after)},   {"metrics_before", MetricsJson(before)},
               {"metrics_after", MetricsJson(after)}};
  const std::string text = fmt::format(
      "{} strikes of {}: sigma_z x {:.3g} and kappa x {:.3g} on top of the stored scales "
      "(now {:.3g}, {:.3g})\n"
      "90 % coverage before: z {:.2f}, theta {:.2f}; after: z {:.2f}, theta {:.2f}\n",
      after.n, source, r.relative.z_std_scale, r.relative.kappa_scale, r.after.z_std_scale,
      r.after.kappa_scale, before.z_coverage_90, before.theta_coverage_90, after.z_coverage_90,
      after.theta_coverage_90);
  return {j.dump(), text};
}

void RegisterCalibrate(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string model;
    std::vector<std::string> data;
    learning::IntervalFit fit{learning::IntervalFit::kLikelihood};
  };
  auto o = std::make_shared<Options>();
  auto* calibrate = app.add_subcommand(
      "calibrate",
      "refit a trained localizer's interval scales on other labelled strikes (e.g. structures "
      "beyond the training pool, or captures of your robot); stored in the run");
  calibrate->add_option("--model", o->model, "run directory (one network or an ensemble)")
      ->required();
  calibrate->add_option("--data", o->data, "labelled dataset(s) (.h5), pooled")->required();
  AddEnumOption(calibrate, "--fit", &o->fit,
                "likelihood (the scales minimizing the mean NLL; default) | coverage (90 % of the "
                "strikes inside their 90 % intervals: for strikes unlike the training's)");
  calibrate->callback([&g, run, o] {
    *run = [&g, o] { return RunCalibrate(g, o->model, o->data, o->fit); };
  });
}

}  // namespace sonicboom::experiments
