#pragma once
// The dataset writer's state, shared by the writer and merge (which appends stored audio chunks).

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_set>
#include <vector>

#include "internal/dataset_schema.h"

namespace sonicboom {

struct DatasetWriter::Impl {
  std::optional<OutputLock> lock;  // first: released last, after the file is in place
  std::string path;
  std::string partial;
  DatasetInfo info;
  internal::h5::Handle file_handle;
  internal::dataset::Columns columns;
  internal::h5::Handle string_type;
  int64_t count{0};
  bool with_contacts{true};  // schema 1.1; false only when merging 1.0 shards
  int64_t contact_rows{0};   // M, rows of the contact table so far
  bool finished{false};
  std::unordered_set<uint64_t> indices;
  std::chrono::steady_clock::time_point last_flush;

  // Throws SchemaError when the sample does not fit the file; `raw_audio`: audio comes as a
  // stored chunk, not in the sample. Reads only what the constructor set (thread-safe).
  void CheckSample(const StrikeSample& sample, bool raw_audio) const;
  // Throws SchemaError when the writer is finished or the index was written already.
  void CheckNewIndex(uint64_t index) const;
  // The stored chunk of the sample's audio row, (1, C, T) shuffled and deflated (thread-safe).
  std::vector<unsigned char> EncodeAudio(const StrikeSample& sample) const;
  // Appends proprio, labels, contacts and index fields, counts the sample and flushes now and
  // then.
  void WriteAllButAudio(const StrikeSample& sample);
  // Appends the sample's contact episodes to the contact table (schema 1.1).
  void WriteContacts(const StrikeSample& sample);
  void Flush();  // flushed_samples attribute, then H5Fflush
  // Creates the per-sample contact offsets and the empty contact table.
  void CreateContactColumns();
};

}  // namespace sonicboom
