// Merging shards: every shard checked against the first, samples ordered by index, stored audio
// chunks copied as they are when the layouts agree.
#include <algorithm>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "internal/dataset_file.h"
#include "internal/dataset_writer_impl.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {

using namespace internal::dataset;  // NOLINT: the schema tables

namespace {

// Appends row `row` of `from` to `writer`: its stored (compressed) audio chunk as it is when
// `raw` (the layouts agree), else decoded and encoded again. Everything is read before anything
// is appended.
void CopySample(const DatasetFile& from, int64_t row, bool raw, DatasetWriter* writer) {
  StrikeSample sample;
  from.ReadMeta(row, &sample);
  if (raw) {
    const h5::RawChunk chunk = h5::ReadRawChunk(
        from.columns().audio.get(), {static_cast<hsize_t>(row), 0, 0}, from.path(), kAudioPath);
    if (!chunk.bytes.empty()) {
      DatasetWriter::EncodedSample encoded;
      encoded.meta = std::move(sample);
      encoded.audio_chunk.assign(chunk.bytes.begin(), chunk.bytes.end());
      encoded.filter_mask = chunk.filter_mask;
      writer->AppendEncoded(encoded);
      return;
    }
  }
  sample.audio = from.ReadAudio(row);
  writer->Append(sample);
}

// Shards of one generated set: the same num_shards and range, every shard number once. Files of
// one shard each (num_shards 1, e.g. runs over different --first-index ranges) merge freely.
void CheckShardSet(const std::vector<DatasetFile>& shards) {
  const DatasetInfo& a = shards.front().info();
  std::vector<const DatasetFile*> by_shard(static_cast<size_t>(std::max<int64_t>(a.num_shards, 1)));
  for (const DatasetFile& shard : shards) {
    const DatasetInfo& b = shard.info();
    if (b.num_shards != a.num_shards) {
      throw SchemaError("merge: " + shard.path() + " is shard " + std::to_string(b.shard) + " of " +
                        std::to_string(b.num_shards) + " but " + shards.front().path() +
                        " is one of " + std::to_string(a.num_shards));
    }
    if (a.num_shards == 1) continue;
    if (b.first_index != a.first_index || b.index_count != a.index_count) {
      throw SchemaError(
          "merge: " + shard.path() + " was generated over indices [" +
          std::to_string(b.first_index) + ", " + std::to_string(b.first_index + b.index_count) +
          ") but " + shards.front().path() + " over [" + std::to_string(a.first_index) + ", " +
          std::to_string(a.first_index + a.index_count) + ") (--count or --first-index differ)");
    }
    if (b.shard < 0 || b.shard >= a.num_shards) {
      throw SchemaError("merge: " + shard.path() + " has shard " + std::to_string(b.shard) +
                        " outside [0, " + std::to_string(a.num_shards) + ")");
    }
    const DatasetFile*& slot = by_shard[static_cast<size_t>(b.shard)];
    if (slot != nullptr) {
      throw SchemaError("merge: " + slot->path() + " and " + shard.path() + " are both shard " +
                        std::to_string(b.shard));
    }
    slot = &shard;
  }
  if (a.num_shards == 1) return;
  std::string missing;
  for (size_t s = 0; s < by_shard.size(); ++s) {
    if (by_shard[s] == nullptr) missing += (missing.empty() ? "" : ", ") + std::to_string(s);
  }
  if (!missing.empty()) {
    throw SchemaError("merge: " + std::to_string(shards.size()) + " of " +
                      std::to_string(a.num_shards) + " shards given; missing shard " + missing);
  }
}

}  // namespace

namespace {

// The virtual audio column of a merge: each shard's audio placed at its samples' merged rows,
// which must be every stride-th row from some start (shards of one generated set interleave so;
// files of one range each follow one another). Source paths relative to the output's directory;
// `identities` gets a line "path\tidentity" per source, so that a reader knows a shard again.
std::vector<h5::VirtualSource> AudioSources(
    const std::vector<DatasetFile>& shards,
    const std::vector<std::tuple<uint64_t, size_t, int64_t>>& order, const std::string& out_path,
    std::string* identities) {
  namespace fs = std::filesystem;
  std::vector<std::vector<hsize_t>> merged_rows(shards.size());
  for (size_t n = 0; n < order.size(); ++n) merged_rows[std::get<1>(order[n])].push_back(n);
  const fs::path out_dir = fs::absolute(out_path).parent_path();
  std::vector<h5::VirtualSource> sources;
  for (size_t k = 0; k < shards.size(); ++k) {
    const std::vector<hsize_t>& rows = merged_rows[k];
    if (rows.empty()) continue;
    if (!h5::VirtualSourceFiles(shards[k].columns().audio.get(), shards[k].path(), kAudioPath)
             .empty()) {
      throw SchemaError("merge --virtual: " + shards[k].path() +
                        " is itself a virtual merge; merge its shards, or merge it by copy");
    }
    const hsize_t stride = rows.size() > 1 ? rows[1] - rows[0] : 1;
    for (size_t r = 1; r < rows.size(); ++r) {
      if (rows[r] - rows[r - 1] != stride) {
        throw SchemaError("merge --virtual: the samples of " + shards[k].path() +
                          " do not fall on every " + std::to_string(stride) +
                          "-th row of the merged order; merge by copy instead");
      }
    }
    const fs::path source = fs::absolute(shards[k].path()).lexically_relative(out_dir);
    sources.push_back(
        {source.string(), std::string("/") + kAudioPath, rows.size(), rows[0], stride});
    *identities += source.string() + "\t" + shards[k].ShardIdentity() + "\n";
  }
  return sources;
}

}  // namespace

void MergeDatasets(const std::vector<std::string>& shard_paths, const std::string& out_path,
                   bool virtual_audio) {
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

  CheckShardSet(shards);

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

  // a generated range is whole: every index of it once
  const DatasetInfo& a = first.info();
  if (a.num_shards > 1 && a.index_count >= 0 &&
      static_cast<int64_t>(order.size()) != a.index_count) {
    throw SchemaError("merge: the shards hold " + std::to_string(order.size()) +
                      " samples, their range [" + std::to_string(a.first_index) + ", " +
                      std::to_string(a.first_index + a.index_count) + ") has " +
                      std::to_string(a.index_count));
  }

  // One unsharded output of the shards' version, written atomically by DatasetWriter; it gives
  // each sample's contacts new offsets in the merged table. Unsharded inputs of different ranges
  // give an output whose range is not recorded.
  DatasetInfo out_info = first.info();
  out_info.shard = 0;
  out_info.num_shards = 1;
  for (const DatasetFile& shard : shards) {
    if (shard.info().first_index != a.first_index || shard.info().index_count != a.index_count) {
      out_info.first_index = out_info.index_count = -1;
    }
  }
  DatasetWriter writer(out_path, out_info, /*with_contacts=*/first.has_contacts());
  DatasetWriter::Impl& out = *writer.impl_;
  if (virtual_audio) {
    // the audio stays in the shards: a virtual column over them replaces the stored one, and
    // every other column is copied
    const hid_t root = out.file_handle.get();
    std::string identities;
    const std::vector<h5::VirtualSource> sources =
        AudioSources(shards, order, out_path, &identities);
    out.columns.audio.Reset();
    h5::CheckStatus(H5Ldelete(root, kAudioPath, H5P_DEFAULT), out.partial, kAudioPath, "replace");
    out.columns.audio = h5::CreateVirtual(
        root, kAudioPath, out_info.audio_int16 ? H5T_STD_I16LE : H5T_IEEE_F32LE, order.size(),
        {static_cast<hsize_t>(out_info.channels), static_cast<hsize_t>(out_info.audio_frames)},
        sources, out.partial);
    h5::WriteStringAttr(out.columns.audio.get(), kShardIdentitiesAttr, identities, out.partial);
    h5::WriteDoubleAttr(out.columns.audio.get(), "scale",
                        h5::ReadDoubleAttr(first.columns().audio.get(), "scale", first.path()),
                        out.partial);
    for (const auto& [index, k, row] : order) {
      StrikeSample sample;
      shards[k].ReadMeta(row, &sample);
      out.CheckNewIndex(sample.index);
      out.CheckSample(sample, /*raw_audio=*/true);
      out.WriteAllButAudio(sample);
    }
    writer.Finish();
    return;
  }
  std::vector<bool> copy_raw_audio(shards.size());
  for (size_t k = 0; k < shards.size(); ++k) {
    copy_raw_audio[k] = h5::SameChunkStorage(shards[k].columns().audio.get(),
                                             out.columns.audio.get(), shards[k].path(), kAudioPath);
  }
  for (const auto& [index, k, row] : order) CopySample(shards[k], row, copy_raw_audio[k], &writer);
  writer.Finish();
}

bool SameDatasetIdentity(const DatasetInfo& a, const DatasetInfo& b) {
  return a.source == b.source && a.config_yaml == b.config_yaml && a.global_seed == b.global_seed &&
         a.shard == b.shard && a.num_shards == b.num_shards && a.first_index == b.first_index &&
         a.index_count == b.index_count && a.sample_rate_hz == b.sample_rate_hz &&
         a.proprio_rate_hz == b.proprio_rate_hz && a.channels == b.channels &&
         a.audio_frames == b.audio_frames && a.proprio_rows == b.proprio_rows &&
         a.audio_int16 == b.audio_int16 && a.variation_names == b.variation_names;
}

namespace {

// The rows of an interrupted writer's file that can be carried over: every per-sample column
// holds them and their contact rows lie in the table; kept while `expected` holds.
int64_t ResumableRows(const DatasetFile& file,
                      const std::function<bool(int64_t, uint64_t)>& expected) {
  // only what the writer had flushed is trusted (later rows may be half on disk)
  const int64_t flushed = file.info().flushed_samples;
  if (flushed <= 0) return 0;
  int64_t rows = 0;
  const std::vector<uint64_t> indices =
      ReadColumn<uint64_t>(file.columns().sample_index.get(), H5T_NATIVE_UINT64, file.size(),
                           file.path(), kSampleIndexPath);
  for (; rows < std::min(file.size(), flushed); ++rows) {
    if (!expected(rows, indices[static_cast<size_t>(rows)])) break;
    try {
      file.ContactRange(rows);
    } catch (const SchemaError&) {
      break;  // its contact rows were not all written
    }
  }
  return rows;
}

}  // namespace

std::unique_ptr<DatasetWriter> ResumeDatasetWriter(
    const std::string& path, const DatasetInfo& info,
    const std::function<bool(int64_t row, uint64_t index)>& expected, int64_t* kept) {
  namespace fs = std::filesystem;
  *kept = 0;
  const OutputLock lock(path);  // before the partial is moved aside: it may be another writer's
  const std::string partial = h5::PartialPath(path), resume = path + ".resume";
  std::error_code ec;
  // an interrupted copy left both: the .resume file is the whole source, the partial a copy
  if (fs::exists(partial, ec) && !fs::exists(resume, ec)) {
    fs::rename(partial, resume, ec);
    if (ec) throw IoError(partial + ": cannot move aside to resume it: " + ec.message());
  }
  std::unique_ptr<DatasetFile> source;
  if (fs::exists(resume, ec)) {
    try {
      source = std::make_unique<DatasetFile>(resume, /*allow_incomplete=*/true);
      if (!SameDatasetIdentity(source->info(), info)) source.reset();
    } catch (const Error&) {
      source.reset();  // unreadable: start afresh
    }
  }
  auto writer = std::make_unique<DatasetWriter>(path, info);
  if (source) {
    const int64_t rows = ResumableRows(*source, expected);
    const bool raw = h5::SameChunkStorage(source->columns().audio.get(),
                                          writer->impl_->columns.audio.get(), resume, kAudioPath);
    for (; *kept < rows; ++*kept) {
      try {
        CopySample(*source, *kept, raw, writer.get());
      } catch (const Error&) {
        break;  // unreadable from here on: generated again
      }
    }
    writer->Flush();
  }
  source.reset();
  fs::remove(resume, ec);
  if (ec) throw IoError(resume + ": cannot remove after resuming: " + ec.message());
  return writer;
}

}  // namespace sonicboom
