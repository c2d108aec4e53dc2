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
  std::string origin;        // its model.json, for messages
};

/// One run directory (not an ensemble's). Throws IoError for a missing directory or file and
/// SchemaError naming the file for anything unreadable or inconsistent.
LoadedRun LoadRun(const std::string& run_dir);

/// Checks that `features` hold what the run reads, in its shapes: the whole-window spectrogram
/// as trained or exactly its centre crop. SchemaError naming the run's model.json, `what`, the
/// first difference and both shapes.
void CheckFeaturesFor(const LoadedRun& run, const FeatureSet& features, const std::string& what);

}  // namespace sonicboom::learning::internal
