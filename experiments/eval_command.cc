// `eval`: a trained localizer's errors on a dataset.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

CommandResult RunEval(const GlobalOptions& g, const std::string& model_dir,
                      const std::string& data) {
  const SonicBoomConfig config = ResolveWithRun(g, model_dir);
  learning::Localizer localizer(model_dir);
  const learning::FeatureSet set = ComputeDatasetFeatures(data, config, g.threads, !g.quiet);
  const learning::Metrics m =
      learning::ComputeMetrics(localizer.Predict(set), set, localizer.surface_radius_m());
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
  return {MetricsJson(m).dump(), text};
}

void RegisterEval(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string model, data;
  };
  auto o = std::make_shared<Options>();
  auto* eval = app.add_subcommand("eval", "evaluate a trained localizer on a dataset");
  eval->add_option("--model", o->model, "run directory")->required();
  eval->add_option("--data", o->data, "dataset (.h5)")->required();
  eval->callback([&g, run, o] { *run = [&g, o] { return RunEval(g, o->model, o->data); }; });
}

}  // namespace sonicboom::experiments
