// `reproduce`'s report: DIR/report.md written from the content of DIR/results.json, one section
// per part of the paper's evaluation, each pointing at the figure scripts/plot.py draws.
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/reproduce.h"

namespace sonicboom::experiments {

using nlohmann::json;

namespace {

// One figure cell: a metric in cm with two decimals, or a dash.
std::string Cm(const json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? fmt::format("{:.2f}", j[key].get<double>()) : "–";
}

// One row's cells: MED / height (cm) / angle (°), and 90 % z / θ coverage when it has them.
std::string EvalCells(const json& e, bool coverage) {
  std::string cells = fmt::format("{} / {} / {:.1f}", Cm(e, "med_cm"), Cm(e, "height_err_cm"),
                                  e.value("angle_err_deg", 0.0));
  if (coverage && e.contains("z_coverage_90")) {
    cells += fmt::format(" / {:.2f}, {:.2f}", e.value("z_coverage_90", 0.0),
                         e.value("theta_coverage_90", 0.0));
  }
  return cells;
}

// The transfer study's section of the report.
std::string TransferSection(const json& t) {
  const json& rows = t["rows"];
  std::string md = fmt::format(
      "## Transfer to another theory (docs/transfer.md, docs/reference_model.md)\n\n"
      "configs/transfer.yaml trained on {} randomized ts4 strikes (configs/randomized.yaml; at "
      "this size train.epochs {} and train.ensemble_members {}, 0 meaning the config's), scored on "
      "ts4's held-out strikes "
      "as our shell renders them and as the reference solid renders them (a 3-D solid with its "
      "own contact, damping and sensor chain; modes to {:.0f} Hz on {:.1f} mm elements). Then "
      "n labelled solid strikes beyond the held-out ones: the model fine-tuned on them (every "
      "layer, lr 3e-4, 40 epochs: the recipe docs/captures.md chose where the pretrained model "
      "is wrong), and the same network from scratch on them. Nothing is chosen here.\n\n"
      "| model | shell: MED / height / angle | solid: MED / height / angle / 90 % z, θ |\n"
      "|---|---|---|\n| transfer, zero-shot | {} | {} |\n"
      "| arrival locator (no training) | {} | {} |\n",
      t["train_strikes"].get<int64_t>(), t["epochs"].get<int64_t>(), t["members"].get<int64_t>(),
      t["solid_band_hz"].get<double>(), 1e3 * t["solid_element_m"].get<double>(),
      EvalCells(rows["zero_shot_shell"], false), EvalCells(rows["zero_shot_solid"], true),
      EvalCells(rows["arrival_shell"], false), EvalCells(rows["arrival_solid"], false));
  for (const json& point : rows["fewshot"]) {
    const int64_t n = point["n"].get<int64_t>();
    md += fmt::format("| fine-tuned on {} solid strikes | – | {} |\n", n,
                      EvalCells(point["tuned"], true));
    md +=
        fmt::format("| from scratch on the {} | – | {} |\n", n, EvalCells(point["scratch"], true));
  }
  return md + "\n![transfer and few-shot](transfer.png)\n\n";
}

}  // namespace

// DIR/report.md from results.json's content.
std::string ReproduceReport(const json& r, const std::string& size) {
  std::string md = fmt::format(
      "# SonicBoom: the paper's evaluation reproduced (`sonicboom reproduce --size {}`)\n\n"
      "Checkout {} (the repository's HEAD when this report was written); seed {}; {} ts1 training "
      "strikes, {} held-out strikes per scenario (sample indices from {}); {} hardware threads. "
      "Every figure below comes from results.json beside this file (scripts/plot.py draws "
      "them).\n\n",
      size, r["commit"].get<std::string>(), r["seed"].get<uint64_t>(),
      r["train_strikes"].get<int64_t>(), r["test_strikes_per_scenario"].get<int64_t>(),
      kTestFirstIndex, r["machine"]["hardware_threads"].get<unsigned>());
  // per scenario: ours, the published code's metric, the paper's, the baselines
  md +=
      "## Localization per scenario (paper Table II and Fig. 5)\n\n| scenario | MED (cm) | "
      "published-code MED | paper | height (cm) | angle (°) | 90 % z / θ coverage |";
  for (const auto& [name, unused] : r["baselines"].items()) md += fmt::format(" {} MED |", name);
  md += "\n|---|---|---|---|---|---|---|";
  for (size_t b = 0; b < r["baselines"].size(); ++b) md += "---|";
  md += "\n";
  for (const char* ts : kScenarios) {
    const json& s = r["scenarios"][ts];
    md += fmt::format("| {} | {} | {} | {:.2f} | {} | {:.1f} | {:.2f} / {:.2f} |", ts,
                      Cm(s, "med_cm"), Cm(s, "reference_med_cm"), s["paper_med_cm"].get<double>(),
                      Cm(s, "height_err_cm"), s["angle_err_deg"].get<double>(),
                      s.value("z_coverage_90", 0.0), s.value("theta_coverage_90", 0.0));
    for (const auto& [name, per] : r["baselines"].items())
      md += fmt::format(" {} |", Cm(per[ts], "med_cm"));
    md += "\n";
  }
  md += "\n![per-strike errors](errors.png)\n\n";
  if (r["materials"].is_object()) {
    const json& m = r["materials"];
    md += fmt::format(
        "Novel striker materials (configs/materials.yaml: wood, aluminium and PVC strikers, as "
        "ts4; paper §V-C2), the same model: MED {} cm, height {} cm, angle {:.1f}° over {} "
        "strikes.\n\n",
        Cm(m, "med_cm"), Cm(m, "height_err_cm"), m["angle_err_deg"].get<double>(),
        m["n"].get<int64_t>());
    if (m.contains("by_material")) {
      md +=
          "| striker material | strikes | MED (cm) | height (cm) | angle (°) |\n"
          "|---|---|---|---|---|\n";
      for (const auto& [material, per] : m["by_material"].items()) {
        md += fmt::format("| {} | {} | {} | {} | {:.1f} |\n", material, per["n"].get<int64_t>(),
                          Cm(per, "med_cm"), Cm(per, "height_err_cm"),
                          per["angle_err_deg"].get<double>());
      }
      md += "\n";
    }
  }
  // ablations
  md += fmt::format(
      "## Modality ablation (paper Fig. 6: the scenario model, configs/{}, trained on ts1 and "
      "tested on every scenario's held-out strikes; errors on ts1, then the MED on each)\n\n",
      size == "paper" ? "study.yaml" : "study_fast.yaml");
  md += AblationTableMarkdown(r["ablations"], /*descriptions=*/false);
  md += "\n![ablations](ablation.png)\n\n";
  if (!r["preprocessing"].is_null()) {
    md += fmt::format(
        "## Preprocessing ablation (the lightweight model: configs/{}'s network and training over "
        "the scenario model's features, as the paper ran its own with a lightweight CNN; same "
        "strikes)\n\n{}\n",
        kLightModelConfig, AblationTableMarkdown(r["preprocessing"], /*descriptions=*/false));
  }
  // the haptic map
  const json& m = r["map"];
  md += fmt::format(
      "## Haptic map (paper §V-C): the ts3 taps placed with the arm's logged pose\n\n{} taps: "
      "MED {} cm between each predicted and true contact point; RMS Chamfer distance {} cm "
      "(predicted to true, the paper's), {} cm (true to predicted); RMS distance to the branch "
      "surface {} cm (the true points: {} cm, the placement's check).\n\n![map](map/map.png)\n\n"
      "## The data\n\n![ts3 coverage and one strike](coverage_ts3.png)\n\n"
      "## A figure of a study with its own command (copied from docs/, not rerun here)\n\n"
      "![the fidelity ladder](fidelity_pareto.png)\n\n*`sonicboom fidelity` (docs/fidelity.md)."
      "*\n\n",
      m["taps"].get<int64_t>(), Cm(m, "med_cm"), Cm(m, "chamfer_cm"), Cm(m, "reverse_chamfer_cm"),
      Cm(m, "surface_cm"), Cm(m, "true_surface_cm"));
  md += TransferSection(r["transfer"]);
  // how each figure was made
  md +=
      "## Stages, wall times and commands\n\n| stage | wall (s, when it ran) | this run |\n"
      "|---|---|---|\n";
  bool any_resumed = false;
  for (const json& stage : r["wall_s"]) {
    const bool resumed = stage.value("resumed", false);
    any_resumed = any_resumed || resumed;
    md += fmt::format("| {} | {:.1f}{} | {} |\n", stage["stage"].get<std::string>(),
                      stage["s"].get<double>(), resumed ? "*" : "",
                      stage["reused"].get<bool>() ? "reused" : "ran");
  }
  if (any_resumed) {
    md +=
        "\n\\* resumed after the process running it stopped: the wall time of the process "
        "that finished it.\n";
  }
  md += fmt::format(
      "\nEach stage is the command of the same name on the same files: `generate --config "
      "configs/tsK.yaml --first-index {}` for the held-out sets, `train --config configs/ts1.yaml "
      "--config configs/{}` for the model, `eval --predictions`, `baseline --method M` (kNN with "
      "k = 1 and all GCC lags), `ablate --configs configs/ablations` (over configs/study_fast.yaml "
      "for the preprocessing rows), `map` and `inspect --png`; "
      "for the transfer study `generate --config configs/ts4.yaml --config "
      "configs/randomized.yaml --set scene.stationary.z_grid_m=0`, `train --config "
      "configs/transfer.yaml`, `rerender`, `train --init-from RUN --freeze none --lr 3e-4 "
      "--epochs 40` and `baseline --method arrival`. Not run by this report: the fidelity "
      "ladder (`sonicboom fidelity`) and the benchmark's eight shell families "
      "(scripts/transfer_benchmark.sh).\n",
      kTestFirstIndex, size == "paper" ? "study.yaml" : "study_fast.yaml");
  return md;
}

}  // namespace sonicboom::experiments
