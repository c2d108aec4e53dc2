// `eval`: a trained localizer's errors on a dataset.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

namespace {

// One CSV row per valid strike: its index, label, prediction (the calibrated predictive
// distribution's z standard deviation and theta concentration; empty without one) and error.
std::string PredictionsCsv(const learning::FeatureSet& set,
                           const std::vector<learning::Prediction>& predictions,
                           const std::vector<uint64_t>& indices, double radius_m) {
  std::string csv = "index,z_m,theta_rad,z_pred_m,theta_pred_rad,z_std_m,theta_kappa,error_cm\n";
  for (int64_t r = 0; r < set.size(); ++r) {
    const learning::Prediction& p = predictions[r];
    const std::string spread = p.has_uncertainty()
                                   ? fmt::format("{:.9g},{:.9g}", p.z_std_m, p.theta_kappa)
                                   : std::string(",");
    csv += fmt::format("{},{:.9g},{:.9g},{:.9g},{:.9g},{},{:.6g}\n", indices[r], set.z_m[r],
                       set.theta_rad[r], p.z_m, p.theta_rad, spread,
                       learning::SurfaceErrorCm(p, set.z_m[r], set.theta_rad[r], radius_m));
  }
  return csv;
}

// The material of what each strike's labelled contact touched (the contact episode nearest the
// label's time), by row of `indices`; "" where the file does not say (a capture).
std::vector<std::string> StrikeMaterials(const std::string& data,
                                         const std::vector<uint64_t>& indices) {
  const DatasetReader reader(data);
  std::map<uint64_t, std::string> material_of;
  for (int64_t r = 0; r < reader.size(); ++r) {
    const StrikeSample meta = reader.ReadMeta(r);
    const ContactEpisode* nearest = nullptr;
    for (const ContactEpisode& e : meta.contacts) {
      if (e.kind == ContactEpisode::Kind::kBrush) continue;
      if (nearest == nullptr ||
          std::abs(e.time_s - meta.label.time_s) < std::abs(nearest->time_s - meta.label.time_s)) {
        nearest = &e;
      }
    }
    material_of[meta.index] = nearest != nullptr ? nearest->material : std::string();
  }
  std::vector<std::string> materials;
  for (uint64_t index : indices) materials.push_back(material_of[index]);
  return materials;
}

// The metrics of each struck material's strikes, when the strikes hit more than one (paper
// §V-C2's novel-material breakdown); null otherwise.
json ByMaterial(const std::vector<std::string>& materials,
                const std::vector<learning::Prediction>& predictions,
                const learning::FeatureSet& set, double radius_m, std::string* text) {
  std::map<std::string, std::vector<size_t>> rows_of;
  for (size_t r = 0; r < materials.size(); ++r) {
    if (!materials[r].empty()) rows_of[materials[r]].push_back(r);
  }
  if (rows_of.size() < 2) return nullptr;
  json by = json::object();
  for (const auto& [material, rows] : rows_of) {
    // the group's labels and predictions alone (ComputeMetrics reads nothing else)
    learning::FeatureSet truth;
    std::vector<learning::Prediction> group;
    for (size_t r : rows) {
      truth.z_m.push_back(set.z_m[r]);
      truth.theta_rad.push_back(set.theta_rad[r]);
      group.push_back(predictions[r]);
    }
    const learning::Metrics m = learning::ComputeMetrics(group, truth, radius_m);
    by[material] = MetricsJson(m);
    *text += fmt::format("  {}: {} strikes, MED {:.2f} cm, height {:.2f} cm, angle {:.1f} deg\n",
                         material, m.n, m.med_cm, m.height_err_cm, m.angle_err_deg);
  }
  return by;
}

// Valid strikes whose label is not known (NaN z or θ), named by row and column: eval scores the
// labelled ones only, and says which it left out.
std::vector<std::string> UnlabelledStrikes(const std::string& data) {
  const DatasetReader reader(data);
  std::vector<std::string> unlabelled;
  for (int64_t r = 0; r < reader.size(); ++r) {
    const StrikeSample meta = reader.ReadMeta(r);
    if (!meta.valid) continue;
    const char* column = std::isnan(meta.label.z_m)         ? "label/z_m"
                         : std::isnan(meta.label.theta_rad) ? "label/theta_rad"
                                                            : nullptr;
    if (column != nullptr) {
      unlabelled.push_back(
          fmt::format("sample row {} (index {}): {} is NaN", r, meta.index, column));
    }
  }
  return unlabelled;
}

// The first few entries of a list, "; "-separated, and how many more.
std::string FirstFew(const std::vector<std::string>& items) {
  constexpr size_t kShown = 5;
  std::string text;
  for (size_t i = 0; i < std::min(items.size(), kShown); ++i) text += (i ? "; " : "") + items[i];
  if (items.size() > kShown) text += fmt::format("; and {} more", items.size() - kShown);
  return text;
}

}  // namespace

CommandResult RunEval(const GlobalOptions& g, const std::string& model_dir,
                      const std::string& data, const EvalOptions& options) {
  const std::string& predictions_csv = options.predictions_csv;
  if (!predictions_csv.empty()) {
    CheckOutput(g, {predictions_csv, "--predictions", options.force},
                {{data, "--data"}, {model_dir, "--model"}});
  }
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  // mirror images are taken of each turn, so --mirror-average turns too
  learning::Localizer localizer(model_dir,
                                {.turn_average = options.turn_average || options.mirror_average,
                                 .mirror_average = options.mirror_average});
  std::vector<uint64_t> indices;
  const learning::FeatureSet set =
      ComputeDatasetFeatures(data, config, g.threads, !g.quiet, &indices);
  // strikes without a label (NaN) are not scored: all of them refused, some skipped and named
  const std::vector<std::string> unlabelled = UnlabelledStrikes(data);
  if (static_cast<int64_t>(unlabelled.size()) == set.size()) {
    throw SchemaError(fmt::format(
        "{}: no valid strike has a known label ({}): eval scores answers against labels; "
        "`localize` answers unlabelled strikes",
        data, FirstFew(unlabelled)));
  }
  if (!unlabelled.empty()) {
    spdlog::warn("{}: {} of {} valid strikes not scored, their label is not known: {}", data,
                 unlabelled.size(), set.size(), FirstFew(unlabelled));
  }
  const std::vector<learning::Prediction> predictions = localizer.Predict(set);
  const learning::Metrics m =
      learning::ComputeMetrics(predictions, set, localizer.surface_radius_m());
  if (!predictions_csv.empty()) {
    WriteTextAtomic(predictions_csv,
                    PredictionsCsv(set, predictions, indices, localizer.surface_radius_m()));
  }
  std::string text = fmt::format(
      "{} strikes: MED {:.2f} cm, height {:.2f} cm, angle {:.1f} deg "
      "(published-code MED {:.2f})\n",
      m.n, m.med_cm, m.height_err_cm, m.angle_err_deg, m.reference_med_cm);
  if (std::isfinite(m.nll)) {
    text += fmt::format(
        "coverage of the 50 % / 90 % intervals: z {:.2f} / {:.2f}, theta {:.2f} / "
        "{:.2f}; mean NLL {:.3f} (z in cm, theta in rad)\n",
        m.z_coverage_50, m.z_coverage_90, m.theta_coverage_50, m.theta_coverage_90, m.nll);
  }
  // per struck material, when the strikes hit several
  json result = MetricsJson(m);
  if (!unlabelled.empty()) result["unlabelled"] = unlabelled.size();
  const json by = ByMaterial(StrikeMaterials(data, indices), predictions, set,
                             localizer.surface_radius_m(), &text);
  if (!by.is_null()) result["by_material"] = by;
  return {result.dump(), text};
}

void RegisterEval(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string model, data;
    EvalOptions eval;
  };
  auto o = std::make_shared<Options>();
  auto* eval = app.add_subcommand("eval", "evaluate a trained localizer on a dataset");
  eval->add_option("--model", o->model, "run directory")->required();
  eval->add_option("--data", o->data, "dataset (.h5)")->required();
  eval->add_option("--predictions", o->eval.predictions_csv,
                   "also write one CSV row per strike: index, label, prediction, error (cm)");
  eval->add_flag("--force", o->eval.force,
                 "replace an existing predictions file (once the new one is complete)");
  eval->add_flag("--turn-average", o->eval.turn_average,
                 "answer by the layout's symmetry: each strike also read with its rings turned "
                 "by 120 and 240 degrees, answers turned back and combined (audio-only models)");
  eval->add_flag("--mirror-average", o->eval.mirror_average,
                 "--turn-average with each turn also read mirrored about theta 0 (in each ring "
                 "discs 1 and 2 swapped): six answers combined");
  eval->callback([&g, run, o] {
    *run = [&g, o] { return RunEval(g, o->model, o->data, o->eval); };
  });
}

}  // namespace sonicboom::experiments
