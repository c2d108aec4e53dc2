#pragma once
/// The strike dataset file (HDF5, docs/dataset.md). HDF5 headers stay in core/dataset_*.cc and
/// core/internal/.
///
/// Layout (N samples, C channels, T audio frames, K proprio rows):
///   /audio                  (N, C, T) int16 or float32; attr `scale` maps stored values to full
///   scale 1 /label/z_m (N) f64, /label/theta_rad (N) f64, /label/point_m (N,3) f64 tube frame,
///   /label/normal (N,3) f64, /label/impulse_Ns (N) f64, /label/time_s (N) f64,
///   /label/normal_speed_m_s (N) f64, /label/duration_s (N) f64
///   /proprio                (N, K, 10) f32: position m (3), quaternion wxyz (4), velocity m/s (3)
///   /index/sample_index (N) u64, /index/seed (N) u64, /index/valid (N) u8,
///   /index/invalid_reason (N) variable-length string, /index/clipped (N) u8,
///   /index/contact_first (N) i64, /index/contact_count (N) i64: sample n's contacts are the
///   rows [first, first + count) of the contact table (schema 1.1)
///   /contacts/sample_row (M) i64: the row n of the sample a contact belongs to
///   /contacts/time_s, duration_s, z_m, theta_rad, normal_speed_m_s, effective_mass_kg,
///   impulse_Ns, peak_force_N (M) f64; /contacts/point_m (M,3) f64, /contacts/normal (M,3) f64,
///   tube frame; /contacts/kind (M) u8 (attr `names` = "impact,bounce,press");
///   /contacts/object, /contacts/material (M) variable-length UTF-8 strings
///   /index/provenance (N) variable-length string, only in a recorded dataset (source
///   "hardware"): the file each sample was imported from
///   /variation (N, P) f64, only when the config randomizes: sample n's drawn values, attr `names`
///   = the P comma-separated names (randomize.h)
///   root attrs: schema, schema_version, software_version, source, config_yaml, sample_rate_hz,
///               proprio_rate_hz, global_seed, shard, num_shards, num_samples, created_utc,
///               and `complete` = 1, written last.
/// The file is written as "<path>.partial" and renamed after `complete` is set.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/sample.h"

namespace sonicboom {

inline constexpr const char* kDatasetSchema = "sonicboom.strikes";
/// The version this build writes: 1.1 stores every contact episode of each sample.
inline constexpr const char* kDatasetSchemaVersion = "1.1";
/// The previous version, still read: no contact table (samples read with no contacts).
inline constexpr const char* kDatasetSchemaVersionWithoutContacts = "1.0";

/// File-level metadata of a dataset.
struct DatasetInfo {
  std::string source{"sim"};     // "sim" or "hardware"
  std::string config_yaml;       // resolved config that produced the file
  std::string software_version;  // filled by the writer when empty
  double sample_rate_hz{44100.0};
  double proprio_rate_hz{100.0};
  int channels{6};
  int64_t audio_frames{0};  // T
  int64_t proprio_rows{0};  // K
  bool audio_int16{true};   // store audio as int16 PCM (the DAQ's output) or float32
  uint64_t global_seed{0};
  int64_t shard{0};
  int64_t num_shards{1};
  // the generated index range [first_index, first_index + index_count) that the shards split;
  // -1: not recorded (imported data, files of earlier versions)
  int64_t first_index{-1};
  int64_t index_count{-1};
  int64_t num_samples{0};      // reader: samples in the file
  bool complete{false};        // reader: the `complete` attribute
  int64_t flushed_samples{0};  // reader: samples an (interrupted) writer had flushed
  std::string schema_version;  // reader: the file's version; the writer writes the current
  std::vector<std::string> variation_names;  // (P) randomized draws stored per sample; empty: none
};

/// Appends samples in order. Append, AppendEncoded and Finish run on one thread at a time;
/// Encode may run on any number of threads concurrently (with each other and with the appends),
/// so that the costly audio compression leaves the writing thread. Finish() sets `complete` and
/// renames the file. Destroyed without Finish(), it leaves only "<path>.partial", plainly
/// incomplete.
class DatasetWriter {
 public:
  /// A sample with its audio chunk already encoded exactly as the file's filter pipeline would
  /// (shuffle, then deflate), made by Encode() on any thread.
  struct EncodedSample {
    StrikeSample meta;                       // labels, index fields, proprio, contacts; no audio
    std::vector<unsigned char> audio_chunk;  // stored bytes of the (1, C, T) audio chunk
    uint32_t filter_mask{0};                 // filters skipped, as HDF5 records it (0: none)
  };

  /// Creates "<path>.partial" (overwriting a stale one). Throws IoError.
  DatasetWriter(const std::string& path, const DatasetInfo& info);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  /// Appends one sample with its contact episodes; its audio must be (channels x audio_frames)
  /// and its proprio (proprio_rows x 10). Throws IoError / SchemaError.
  void Append(const StrikeSample& sample);
  /// Checks the sample like Append (shapes, finite audio of a valid sample) and encodes its audio
  /// chunk: (C, T) as int16 PCM or float32 little endian, shuffled, deflated. Thread-safe; the
  /// sample index is checked for repeats only by AppendEncoded. Throws SchemaError / IoError.
  EncodedSample Encode(const StrikeSample& sample) const;
  /// Appends a sample encoded by Encode() of this writer (or of one with the same channels,
  /// audio_frames and audio dtype): stores its chunk as is. Throws IoError / SchemaError.
  void AppendEncoded(const EncodedSample& sample);
  /// Writes num_samples and `complete`, closes, renames to the final path.
  void Finish();
  /// Writes what was appended to disk: a writer killed after this leaves these samples readable
  /// in "<path>.partial" (ResumeDatasetWriter carries them over). Appends flush every 2 s.
  void Flush();
  int64_t count() const;

 private:
  // Merging copies compressed audio chunks straight into the writer's file, and writes shards of
  // version 1.0 as a 1.0 file (`with_contacts` false: no contact table).
  friend void MergeDatasets(const std::vector<std::string>& shard_paths,
                            const std::string& out_path, bool virtual_audio);
  friend std::unique_ptr<DatasetWriter> ResumeDatasetWriter(
      const std::string& path, const DatasetInfo& info,
      const std::function<bool(int64_t row, uint64_t index)>& expected, int64_t* kept);
  DatasetWriter(const std::string& path, const DatasetInfo& info, bool with_contacts);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Random access to a complete dataset file. Safe to use from one thread at a time.
class DatasetReader {
 public:
  /// Opens `path`. Throws IoError when missing or not HDF5, SchemaError when it is not a
  /// sonicboom dataset, has a schema version other than 1.1 or 1.0, or lacks `complete` (unless
  /// allow_incomplete).
  explicit DatasetReader(const std::string& path, bool allow_incomplete = false);
  ~DatasetReader();
  DatasetReader(DatasetReader&&) noexcept;
  DatasetReader& operator=(DatasetReader&&) noexcept;

  const DatasetInfo& info() const;
  int64_t size() const;
  /// Labels, index fields, proprio and contacts of sample i (no audio); a 1.0 file has no
  /// contacts.
  StrikeSample ReadMeta(int64_t i) const;
  /// Everything of sample i, audio scaled to full scale 1, contacts included.
  StrikeSample Read(int64_t i) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Joins shard files (same schema version and config, any order) into one file ordered by sample
/// index, contacts carried over with re-based offsets. Shards of version 1.0 give a 1.0 file.
/// Refuses incomplete shards, mixed versions, mismatched configs and duplicate indices
/// (SchemaError), and shards of one generated set (num_shards > 1) that are not all there or
/// were generated over different ranges. With `virtual_audio` the output's /audio is an HDF5
/// virtual dataset over the shards' (no audio copied; the shards must stay where they are,
/// found relative to the output); every other column is copied.
void MergeDatasets(const std::vector<std::string>& shard_paths, const std::string& out_path,
                   bool virtual_audio = false);

/// The same dataset: what a writer's partial file must share with a new run to be resumed, and a
/// finished file with a rerun to be skipped (source, config_yaml, global seed, shard, num_shards,
/// generated range, shapes and audio dtype).
bool SameDatasetIdentity(const DatasetInfo& a, const DatasetInfo& b);

/// A writer for `path` that resumes what an interrupted writer of the same dataset left: the
/// samples of "<path>.partial" whose every column (and contact rows) was written, kept while
/// expected(row, sample index) holds, are copied (audio chunks as stored) into the new writer;
/// *kept is their number. Without a partial, or with one of another identity or unreadable, the
/// writer starts empty (*kept = 0) and the stale partial is replaced. While the kept samples are
/// copied the old partial waits as "<path>.resume", so an interruption of the copy loses nothing.
std::unique_ptr<DatasetWriter> ResumeDatasetWriter(
    const std::string& path, const DatasetInfo& info,
    const std::function<bool(int64_t row, uint64_t index)>& expected, int64_t* kept);

/// A human-readable (and JSON) summary of a dataset file: counts, valid/invalid with reasons,
/// label ranges, audio peak statistics, completeness, and contact counts by kind and object with
/// the (z, theta) coverage of first contacts.
std::string SummarizeDatasetJson(const std::string& path);

}  // namespace sonicboom
