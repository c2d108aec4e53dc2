#pragma once
/// Pieces of command output shared by several commands.

#include <nlohmann/json.hpp>

#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// Metrics as the JSON object `sonicboom eval --json` prints.
nlohmann::json MetricsJson(const learning::Metrics& m);

}  // namespace sonicboom::experiments
