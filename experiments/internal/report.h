#pragma once
/// Pieces of command set-up and output shared by several commands.

#include <nlohmann/json.hpp>

#include <string>

#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// A run directory's own config (RUN/config.yaml) as the base layer, then --config and --set:
/// what eval, localize, listen and a fine-tune resolve. IoError when the run is missing.
SonicBoomConfig ResolveWithRun(const GlobalOptions& g, const std::string& run_dir);

/// Metrics as the JSON object `sonicboom eval --json` prints.
nlohmann::json MetricsJson(const learning::Metrics& m);

/// One localization as `localize` and `listen` print it: z, θ, the surface point in the tube
/// frame and, from a model with one, the predictive distribution (std, κ, 90 % intervals; null
/// otherwise). Appends the same in words to `text`.
nlohmann::json PredictionJson(const learning::Prediction& p, const TubeConfig& tube,
                              std::string* text);

}  // namespace sonicboom::experiments
