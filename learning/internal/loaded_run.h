#pragma once
/// A trained network read back from a run directory (model.json + model.pt): what the
/// Localizer predicts with and what unlabelled adaptation starts from.

#include <string>

#include "internal/data.h"
#include "internal/network.h"

namespace sonicboom::learning::internal {

struct LoadedRun {
  ModelFile file;
  Network network{nullptr};  // in eval mode
};

/// One run directory (not an ensemble's). Throws IoError for a missing directory or file and
/// SchemaError naming the file for anything unreadable or inconsistent.
LoadedRun LoadRun(const std::string& run_dir);

}  // namespace sonicboom::learning::internal
