// Merging shards: every shard checked against the first, samples ordered by index, stored audio
// chunks copied as they are when the layouts agree.
#include <algorithm>
#include <string>
#include <tuple>
#include <vector>

#include "internal/dataset_file.h"
#include "internal/dataset_writer_impl.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {

using namespace internal::dataset;  // NOLINT: the schema tables

void MergeDatasets(const std::vector<std::string>& shard_paths, const std::string& out_path) {
  if (shard_paths.empty()) throw ConfigError("merge: no shard files given");
  // Every shard must be complete (the reader refuses incomplete ones) and match the first.
  std::vector<DatasetFile> shards;
  shards.reserve(shard_paths.size());
  for (const std::string& path : shard_paths) shards.emplace_back(path, false);
  const DatasetFile& first = shards.front();
  for (const DatasetFile& shard : shards) {
    const DatasetInfo& a = first.info();
    const DatasetInfo& b = shard.info();
    auto refuse = [&](const std::string& what, const std::string& va, const std::string& vb) {
      throw SchemaError("merge: " + shard.path() + " has " + what + " " + vb + " but " +
                        first.path() + " has " + va);
    };
    // Mixed versions would leave the 1.0 samples looking as if they had no contacts.
    if (b.schema_version != a.schema_version) {
      refuse("schema_version", a.schema_version, b.schema_version);
    }
    if (b.config_yaml != a.config_yaml) {
      throw SchemaError("merge: " + shard.path() + " was generated with a different config_yaml " +
                        "than " + first.path());
    }
    if (b.source != a.source) refuse("source", a.source, b.source);
    if (b.global_seed != a.global_seed) {
      refuse("global_seed", std::to_string(a.global_seed), std::to_string(b.global_seed));
    }
    if (b.sample_rate_hz != a.sample_rate_hz) {
      refuse("sample_rate_hz", std::to_string(a.sample_rate_hz), std::to_string(b.sample_rate_hz));
    }
    if (b.proprio_rate_hz != a.proprio_rate_hz) {
      refuse("proprio_rate_hz", std::to_string(a.proprio_rate_hz),
             std::to_string(b.proprio_rate_hz));
    }
    if (b.channels != a.channels || b.audio_frames != a.audio_frames) {
      refuse("audio shape", std::to_string(a.channels) + " x " + std::to_string(a.audio_frames),
             std::to_string(b.channels) + " x " + std::to_string(b.audio_frames));
    }
    if (b.proprio_rows != a.proprio_rows) {
      refuse("proprio_rows", std::to_string(a.proprio_rows), std::to_string(b.proprio_rows));
    }
    if (b.audio_int16 != a.audio_int16) {
      refuse("audio dtype", a.audio_int16 ? "int16" : "float32",
             b.audio_int16 ? "int16" : "float32");
    }
  }

  // (sample index, shard, row) of every sample, ordered by sample index; no index twice.
  std::vector<std::tuple<uint64_t, size_t, int64_t>> order;
  for (size_t k = 0; k < shards.size(); ++k) {
    const std::vector<uint64_t> indices =
        ReadColumn<uint64_t>(shards[k].columns().sample_index.get(), H5T_NATIVE_UINT64,
                             shards[k].size(), shards[k].path(), kSampleIndexPath);
    for (int64_t row = 0; row < shards[k].size(); ++row) order.emplace_back(indices[row], k, row);
  }
  std::sort(order.begin(), order.end());
  for (size_t n = 1; n < order.size(); ++n) {
    const auto& [index, k, row] = order[n];
    const auto& [previous_index, previous_k, previous_row] = order[n - 1];
    if (index == previous_index) {
      throw SchemaError("merge: sample index " + std::to_string(index) + " appears in " +
                        shards[previous_k].path() + " (row " + std::to_string(previous_row) +
                        ") and " + shards[k].path() + " (row " + std::to_string(row) + ")");
    }
  }

  // One unsharded output of the shards' version, written atomically by DatasetWriter; it gives
  // each sample's contacts new offsets in the merged table.
  DatasetInfo out_info = first.info();
  out_info.shard = 0;
  out_info.num_shards = 1;
  DatasetWriter writer(out_path, out_info, /*with_contacts=*/first.has_contacts());
  DatasetWriter::Impl& out = *writer.impl_;
  std::vector<bool> copy_raw_audio(shards.size());
  for (size_t k = 0; k < shards.size(); ++k) {
    copy_raw_audio[k] = h5::SameChunkStorage(shards[k].columns().audio.get(),
                                             out.columns.audio.get(), shards[k].path(), kAudioPath);
  }
  for (const auto& [index, k, row] : order) {
    StrikeSample sample;
    shards[k].ReadMeta(row, &sample);
    // Audio: copy the stored (compressed) chunk when the layouts agree, else decode and encode.
    if (copy_raw_audio[k]) {
      const h5::RawChunk chunk =
          h5::ReadRawChunk(shards[k].columns().audio.get(), {static_cast<hsize_t>(row), 0, 0},
                           shards[k].path(), kAudioPath);
      if (!chunk.bytes.empty()) {
        DatasetWriter::EncodedSample encoded;
        encoded.meta = std::move(sample);
        encoded.audio_chunk.assign(chunk.bytes.begin(), chunk.bytes.end());
        encoded.filter_mask = chunk.filter_mask;
        writer.AppendEncoded(encoded);
        continue;
      }
    }
    sample.audio = shards[k].ReadAudio(row);
    writer.Append(sample);
  }
  writer.Finish();
}

}  // namespace sonicboom
