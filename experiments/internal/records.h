#pragma once
/// Dataset passes shared by the feature path and the baselines: the valid rows of a file, and a
/// parallel pass over records (HDF5 reads serial, the work per record parallel).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sonicboom/core/dataset.h"
#include "sonicboom/experiments/config.h"

namespace sonicboom::experiments {

/// Valid rows of a dataset, in file order, with their metadata (no audio).
struct ValidRecords {
  std::vector<int64_t> rows;
  std::vector<StrikeSample> metas;
};
/// SchemaError naming `path` when no sample is valid, when the records' length is not the one
/// the config states, or when a valid sample's label lies off the config's tube (its units are
/// not metres and radians).
ValidRecords ReadValidRecords(const DatasetReader& reader, const std::string& path,
                              const SonicBoomConfig& config);

/// Calls fn(i, sample of rows[i]) for every i, on `threads` workers (0 = all cores), with a
/// progress line named `name`. Reads are serialized; fn runs in parallel.
void ForEachRecord(const DatasetReader& reader, const std::vector<int64_t>& rows, int threads,
                   const std::string& name, bool show_progress,
                   const std::function<void(int64_t, const StrikeSample&)>& fn);

}  // namespace sonicboom::experiments
