#pragma once
// A dataset file opened for reading: identity, shapes and ragged-column checks on open, then
// per-sample reads of metadata, contacts and audio. Shared by the reader and merge.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "internal/dataset_schema.h"
#include "internal/watchdog.h"
#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::internal::dataset {

// A complete (or, when allowed, incomplete) dataset file opened for reading.
class DatasetFile {
 public:
  // kVirtualSource: the file is a shard a virtual merge reads in place; it may not itself be
  // a virtual merge (a chain, or a merge naming itself, would never end)
  enum class Role { kDataset, kVirtualSource };

  DatasetFile(const std::string& path, bool allow_incomplete, Role role = Role::kDataset)
      : guard_(path + ": reading the file"), path_(path) {
    // opening reads only metadata: seconds at most, unless libhdf5 loops on a corrupted file
    const ReadDeadline deadline(path + ": reading the file");
    file_ = h5::OpenFileReadOnly(path);
    const hid_t root = file_.get();

    // Identity: schema name and version, then completeness.
    std::string schema;
    if (h5::HasAttr(root, "schema", path)) {
      try {
        schema = h5::ReadStringAttr(root, "schema", path);
      } catch (const IoError&) {
        schema = "(not a string)";
      }
    }
    if (schema != kDatasetSchema) {
      throw SchemaError(path + ": not a sonicboom dataset (schema attribute '" + schema +
                        "', expected '" + kDatasetSchema + "')");
    }
    const std::string version = h5::HasAttr(root, "schema_version", path)
                                    ? h5::ReadStringAttr(root, "schema_version", path)
                                    : std::string("(missing)");
    if (version != kDatasetSchemaVersion && version != kDatasetSchemaVersionWithoutContacts) {
      throw SchemaError(path + ": dataset schema_version " + version + ", this build reads " +
                        kDatasetSchemaVersion + " and " + kDatasetSchemaVersionWithoutContacts);
    }
    info_.schema_version = version;
    has_contacts_ = version == kDatasetSchemaVersion;
    info_.complete = h5::IsComplete(root, path);
    if (!info_.complete && !allow_incomplete) {
      throw SchemaError(path +
                        ": incomplete dataset (no `complete` attribute): written by a run that "
                        "did not finish");
    }

    // Root metadata.
    info_.source = h5::ReadStringAttr(root, "source", path);
    info_.config_yaml = h5::ReadStringAttr(root, "config_yaml", path);
    info_.software_version = h5::ReadStringAttr(root, "software_version", path);
    info_.sample_rate_hz = h5::ReadDoubleAttr(root, "sample_rate_hz", path);
    info_.proprio_rate_hz = h5::ReadDoubleAttr(root, "proprio_rate_hz", path);
    info_.global_seed = h5::ReadUint64Attr(root, "global_seed", path);
    info_.shard = h5::ReadInt64Attr(root, "shard", path);
    info_.num_shards = h5::ReadInt64Attr(root, "num_shards", path);
    if (h5::HasAttr(root, "flushed_samples", path)) {
      info_.flushed_samples = h5::ReadInt64Attr(root, "flushed_samples", path);
    }
    if (h5::HasAttr(root, "first_index", path) && h5::HasAttr(root, "index_count", path)) {
      info_.first_index = h5::ReadInt64Attr(root, "first_index", path);
      info_.index_count = h5::ReadInt64Attr(root, "index_count", path);
      if (info_.first_index < 0 || info_.index_count < 0 ||
          info_.first_index > std::numeric_limits<int64_t>::max() - info_.index_count) {
        throw SchemaError(path + ": generated range first_index " +
                          std::to_string(info_.first_index) + ", index_count " +
                          std::to_string(info_.index_count) + " is not a range of indices");
      }
    }
    if (info_.num_shards < 1 || info_.shard < 0 || info_.shard >= info_.num_shards) {
      throw SchemaError(path + ": shard " + std::to_string(info_.shard) + " of " +
                        std::to_string(info_.num_shards) + " is not a shard");
    }

    // Every column.
    columns_.audio = h5::OpenDataset(root, kAudioPath, path);
    columns_.proprio = h5::OpenDataset(root, kProprioPath, path);
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      columns_.scalar_labels[f] = h5::OpenDataset(root, kScalarLabels[f].path, path);
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      columns_.vector_labels[f] = h5::OpenDataset(root, kVectorLabels[f].path, path);
    }
    columns_.sample_index = h5::OpenDataset(root, kSampleIndexPath, path);
    columns_.seed = h5::OpenDataset(root, kSeedPath, path);
    columns_.valid = h5::OpenDataset(root, kValidPath, path);
    columns_.invalid_reason = h5::OpenDataset(root, kInvalidReasonPath, path);
    columns_.clipped = h5::OpenDataset(root, kClippedPath, path);
    if (has_contacts_) OpenContactColumns();
    if (H5Lexists(root, "index", H5P_DEFAULT) > 0 &&
        H5Lexists(root, kProvenancePath, H5P_DEFAULT) > 0) {
      columns_.provenance = h5::OpenDataset(root, kProvenancePath, path);
    }
    // Randomized draws, when the file has them: (N, P) with P names.
    if (H5Lexists(root, kVariationPath, H5P_DEFAULT) > 0) {
      columns_.variation = h5::OpenDataset(root, kVariationPath, path);
      const std::string names = h5::ReadStringAttr(columns_.variation.get(), "names", path);
      std::stringstream list(names);
      for (std::string name; std::getline(list, name, ',');) info_.variation_names.push_back(name);
      const std::vector<hsize_t> dims = h5::Dims(columns_.variation.get(), path, kVariationPath);
      if (dims.size() != 2 || dims[1] != info_.variation_names.size()) {
        throw SchemaError(path + ": /variation must have shape (N, " +
                          std::to_string(info_.variation_names.size()) +
                          ") for its names attribute '" + names + "'");
      }
    }

    CheckVirtualSources(role);

    // Shapes: audio (N, C, T) int16 or float32 with `scale`, proprio (N, K, 10).
    const std::vector<hsize_t> audio_dims = h5::Dims(columns_.audio.get(), path, kAudioPath);
    if (audio_dims.size() != 3) {
      throw SchemaError(path + ": /audio has rank " + std::to_string(audio_dims.size()) +
                        ", expected 3 (N, C, T)");
    }
    info_.channels = static_cast<int>(audio_dims[1]);
    info_.audio_frames = static_cast<int64_t>(audio_dims[2]);
    h5::Handle audio_type(
        h5::CheckId(H5Dget_type(columns_.audio.get()), path, kAudioPath, "read type of"));
    const std::string audio_dtype = h5::DtypeName(audio_type.get());
    if (audio_dtype != "int16" && audio_dtype != "float32") {
      throw SchemaError(path + ": /audio is " + audio_dtype + ", expected int16 or float32");
    }
    info_.audio_int16 = audio_dtype == "int16";
    audio_scale_ = h5::ReadDoubleAttr(columns_.audio.get(), "scale", path);
    const std::vector<hsize_t> proprio_dims = h5::Dims(columns_.proprio.get(), path, kProprioPath);
    if (proprio_dims.size() != 3 || proprio_dims[2] != kProprioFeatures) {
      throw SchemaError(path + ": /proprio must have shape (N, K, " +
                        std::to_string(kProprioFeatures) + ")");
    }
    info_.proprio_rows = static_cast<int64_t>(proprio_dims[1]);

    // Sample count: the rows every column has (a crashed writer may leave ragged columns).
    hsize_t rows = std::numeric_limits<hsize_t>::max();
    hsize_t most_rows = 0;
    for (const auto& [dataset, name] : columns_.All()) {
      const hsize_t column_rows = h5::Dims(dataset, path, name).at(0);
      rows = std::min(rows, column_rows);
      most_rows = std::max(most_rows, column_rows);
    }
    info_.num_samples = static_cast<int64_t>(rows);
    if (info_.complete) {
      const int64_t declared = h5::ReadInt64Attr(root, "num_samples", path);
      if (declared != info_.num_samples || most_rows != rows) {
        throw SchemaError(path + ": num_samples attribute is " + std::to_string(declared) +
                          " but the columns hold between " + std::to_string(rows) + " and " +
                          std::to_string(most_rows) + " rows");
      }
    }
    if (has_contacts_) CheckContactTable();
    CheckNumericColumns();
    CheckUniqueIndices();
  }

  const std::string& path() const { return path_; }
  const DatasetInfo& info() const { return info_; }

  // What a virtual merge records of a shard it reads in place, to know it again: seed, shard,
  // range, shapes and a digest of the config and of every row's sample index and seed. A shard
  // rendered again from the same seed and range has the same identity (generation is
  // deterministic); another seed, range, config or file has another.
  std::string ShardIdentity() const {
    const auto n = static_cast<size_t>(info_.num_samples);
    std::vector<uint64_t> indices(n), seeds(n);
    if (n > 0) {
      h5::ReadRows(columns_.sample_index.get(), H5T_NATIVE_UINT64, indices.data(), 0, n, path_,
                   kSampleIndexPath);
      h5::ReadRows(columns_.seed.get(), H5T_NATIVE_UINT64, seeds.data(), 0, n, path_, kSeedPath);
    }
    uint64_t digest = internal::Fnv1a(info_.config_yaml.data(), info_.config_yaml.size());
    digest = internal::Fnv1a(indices.data(), sizeof(uint64_t) * n, digest);
    digest = internal::Fnv1a(seeds.data(), sizeof(uint64_t) * n, digest);
    std::ostringstream text;
    text << "seed " << info_.global_seed << ", shard " << info_.shard << " of " << info_.num_shards
         << ", range " << info_.first_index << "+" << info_.index_count << ", " << n << " x "
         << info_.channels << " x " << info_.audio_frames << (info_.audio_int16 ? " int16" : " float32")
         << ", digest " << std::hex << digest;
    return text.str();
  }
  int64_t size() const { return info_.num_samples; }

  // Index fields, labels and proprio of sample i.
  void ReadMeta(int64_t i, StrikeSample* sample) const {
    CheckRange(i);
    const ReadDeadline deadline(path_ + ": reading sample row " + std::to_string(i));
    const hid_t u64 = H5T_NATIVE_UINT64;
    const hid_t u8 = H5T_NATIVE_UINT8;
    sample->index = ReadOne<uint64_t>(columns_.sample_index.get(), u64, i, path_, kSampleIndexPath);
    sample->seed = ReadOne<uint64_t>(columns_.seed.get(), u64, i, path_, kSeedPath);
    sample->valid = ReadOne<uint8_t>(columns_.valid.get(), u8, i, path_, kValidPath) != 0;
    sample->clipped = ReadOne<uint8_t>(columns_.clipped.get(), u8, i, path_, kClippedPath) != 0;
    sample->invalid_reason =
        h5::ReadStringRows(columns_.invalid_reason.get(), static_cast<hsize_t>(i), 1, path_,
                           kInvalidReasonPath)
            .at(0);
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      const double value = ReadOne<double>(columns_.scalar_labels[f].get(), H5T_NATIVE_DOUBLE, i,
                                           path_, kScalarLabels[f].path);
      // NaN means "not known"; an infinite label is damage, refused before it becomes a result
      if (std::isinf(value)) {
        throw SchemaError(path_ + ": /" + kScalarLabels[f].path + " of sample row " +
                          std::to_string(i) +
                          " is infinite (labels are finite, or NaN when unknown)");
      }
      sample->label.*kScalarLabels[f].member = value;
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      Eigen::Vector3d& v = sample->label.*kVectorLabels[f].member;
      h5::ReadRows(columns_.vector_labels[f].get(), H5T_NATIVE_DOUBLE, v.data(),
                   static_cast<hsize_t>(i), 1, path_, kVectorLabels[f].path);
    }
    // (K, 10) row-major in the file.
    const int64_t k = info_.proprio_rows;
    std::vector<float> proprio(static_cast<size_t>(k) * kProprioFeatures);
    h5::ReadRows(columns_.proprio.get(), H5T_NATIVE_FLOAT, proprio.data(), static_cast<hsize_t>(i),
                 1, path_, kProprioPath);
    for (size_t k = 0; k < proprio.size(); ++k) {
      if (!std::isfinite(proprio[k])) {
        throw SchemaError(path_ + ": /" + kProprioPath + " of sample row " + std::to_string(i) +
                          " holds a non-finite value (row " + std::to_string(k / kProprioFeatures) +
                          ", column " + std::to_string(k % kProprioFeatures) + ")");
      }
    }
    sample->proprio =
        Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            proprio.data(), k, kProprioFeatures);
    sample->contacts = ReadContacts(i);
    if (columns_.provenance.valid()) {
      sample->provenance = h5::ReadStringRows(columns_.provenance.get(), static_cast<hsize_t>(i), 1,
                                              path_, kProvenancePath)
                               .at(0);
    }
    sample->variation.assign(info_.variation_names.size(), 0.0);
    if (!sample->variation.empty()) {
      h5::ReadRows(columns_.variation.get(), H5T_NATIVE_DOUBLE, sample->variation.data(),
                   static_cast<hsize_t>(i), 1, path_, kVariationPath);
    }
  }

  // Contact episodes of sample i: rows [first, first + count) of the contact table; none in a
  // 1.0 file. Throws SchemaError when the offsets or rows do not belong to sample i.
  std::vector<ContactEpisode> ReadContacts(int64_t i) const {
    std::vector<ContactEpisode> contacts;
    if (!has_contacts_) return contacts;
    const auto [first, count] = ContactRange(i);
    if (count == 0) return contacts;
    const hsize_t row0 = static_cast<hsize_t>(first);
    const hsize_t rows = static_cast<hsize_t>(count);
    const ContactColumns& table = columns_.contacts;
    contacts.resize(rows);

    // Every row must name sample i.
    std::vector<int64_t> sample_rows(rows);
    h5::ReadRows(table.sample_row.get(), H5T_NATIVE_INT64, sample_rows.data(), row0, rows, path_,
                 kContactSampleRowPath);
    for (hsize_t r = 0; r < rows; ++r) {
      if (sample_rows[r] != i) {
        throw SchemaError(path_ + ": contact row " + std::to_string(row0 + r) + " of sample " +
                          std::to_string(i) + " belongs to sample row " +
                          std::to_string(sample_rows[r]));
      }
    }
    // Numbers: (M) and (M, 3) float64.
    std::vector<double> values(3 * rows);
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      h5::ReadRows(table.scalars[f].get(), H5T_NATIVE_DOUBLE, values.data(), row0, rows, path_,
                   kScalarContacts[f].path);
      for (hsize_t r = 0; r < rows; ++r) contacts[r].*kScalarContacts[f].member = values[r];
    }
    for (size_t f = 0; f < kVectorContacts.size(); ++f) {
      h5::ReadRows(table.vectors[f].get(), H5T_NATIVE_DOUBLE, values.data(), row0, rows, path_,
                   kVectorContacts[f].path);
      for (hsize_t r = 0; r < rows; ++r) {
        contacts[r].*kVectorContacts[f].member =
            Eigen::Vector3d(values[3 * r], values[3 * r + 1], values[3 * r + 2]);
      }
    }
    // Kind codes (M) u8 and the strings.
    std::vector<uint8_t> kinds(rows);
    h5::ReadRows(table.kind.get(), H5T_NATIVE_UINT8, kinds.data(), row0, rows, path_,
                 kContactKindPath);
    const std::vector<std::string> objects =
        h5::ReadStringRows(table.object.get(), row0, rows, path_, kContactObjectPath);
    const std::vector<std::string> materials =
        h5::ReadStringRows(table.material.get(), row0, rows, path_, kContactMaterialPath);
    for (hsize_t r = 0; r < rows; ++r) {
      contacts[r].kind = KindFromCode(kinds[r], row0 + r);
      contacts[r].object = objects[r];
      contacts[r].material = materials[r];
    }
    return contacts;
  }

  // (first, count) of sample i's contact rows, checked against the table. (0, 0) in a 1.0 file.
  std::pair<int64_t, int64_t> ContactRange(int64_t i) const {
    CheckRange(i);
    if (!has_contacts_) return {0, 0};
    const int64_t first = ReadOne<int64_t>(columns_.contact_first.get(), H5T_NATIVE_INT64, i, path_,
                                           kContactFirstPath);
    const int64_t count = ReadOne<int64_t>(columns_.contact_count.get(), H5T_NATIVE_INT64, i, path_,
                                           kContactCountPath);
    CheckContactRange(i, first, count);
    return {first, count};
  }

  // Throws SchemaError unless [first, first + count) lies within the contact table.
  void CheckContactRange(int64_t i, int64_t first, int64_t count) const {
    if (first < 0 || count < 0 || first > contact_rows_ || count > contact_rows_ - first) {
      throw SchemaError(path_ + ": sample row " + std::to_string(i) + " has contacts from row " +
                        std::to_string(first) + ", " + std::to_string(count) +
                        " of them, outside the contact table of " + std::to_string(contact_rows_) +
                        " rows");
    }
  }

  // The episode kind of a stored code; SchemaError for an unknown code.
  ContactEpisode::Kind KindFromCode(uint8_t code, hsize_t row) const {
    if (code >= kContactKindNames.size()) {
      throw SchemaError(path_ + ": " + kContactKindPath + " row " + std::to_string(row) +
                        " holds unknown code " + std::to_string(code));
    }
    return static_cast<ContactEpisode::Kind>(code);
  }

  // Audio of sample i, (channels x T) in full-scale units.
  Eigen::MatrixXf ReadAudio(int64_t i) const {
    CheckRange(i);
    const ReadDeadline deadline(path_ + ": reading the audio of sample row " + std::to_string(i));
    using RowMajorInt16 = Eigen::Matrix<int16_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    using RowMajorFloat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const int64_t c = info_.channels;
    const int64_t t = info_.audio_frames;
    if (info_.audio_int16) {
      RowMajorInt16 pcm(c, t);
      h5::ReadRows(columns_.audio.get(), H5T_NATIVE_INT16, pcm.data(), static_cast<hsize_t>(i), 1,
                   path_, kAudioPath);
      return (pcm.cast<double>() * audio_scale_).cast<float>();
    }
    RowMajorFloat audio(c, t);
    h5::ReadRows(columns_.audio.get(), H5T_NATIVE_FLOAT, audio.data(), static_cast<hsize_t>(i), 1,
                 path_, kAudioPath);
    if (audio_scale_ != 1.0) audio *= static_cast<float>(audio_scale_);
    if (!audio.allFinite()) {
      Eigen::Index channel = 0, frame = 0;
      (!audio.array().isFinite()).cast<int>().maxCoeff(&channel, &frame);
      throw SchemaError(path_ + ": /" + kAudioPath + " of sample row " + std::to_string(i) +
                        " holds a non-finite sample (channel " + std::to_string(channel) +
                        ", frame " + std::to_string(frame) + ")");
    }
    return audio;
  }

  const Columns& columns() const { return columns_; }
  bool has_contacts() const { return has_contacts_; }
  int64_t contact_rows() const { return contact_rows_; }

 private:
  // Opens the per-sample contact offsets and the contact table (schema 1.1).
  void OpenContactColumns() {
    const hid_t root = file_.get();
    columns_.contact_first = h5::OpenDataset(root, kContactFirstPath, path_);
    columns_.contact_count = h5::OpenDataset(root, kContactCountPath, path_);
    ContactColumns& table = columns_.contacts;
    table.sample_row = h5::OpenDataset(root, kContactSampleRowPath, path_);
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      table.scalars[f] = h5::OpenDataset(root, kScalarContacts[f].path, path_);
    }
    for (size_t f = 0; f < kVectorContacts.size(); ++f) {
      table.vectors[f] = h5::OpenDataset(root, kVectorContacts[f].path, path_);
    }
    table.kind = h5::OpenDataset(root, kContactKindPath, path_);
    table.object = h5::OpenDataset(root, kContactObjectPath, path_);
    table.material = h5::OpenDataset(root, kContactMaterialPath, path_);
  }

  // Contact rows M: the rows every contact column holds (a crashed writer may leave them
  // ragged). A complete file has equal columns ending with the last sample's contacts.
  void CheckContactTable() {
    hsize_t rows = std::numeric_limits<hsize_t>::max();
    hsize_t most_rows = 0;
    for (const auto& [dataset, name] : columns_.contacts.All()) {
      const std::vector<hsize_t> dims = h5::Dims(dataset, path_, name);
      const bool vector = name == kVectorContacts[0].path || name == kVectorContacts[1].path;
      if (dims.size() != (vector ? 2u : 1u) || (vector && dims[1] != 3)) {
        throw SchemaError(path_ + ": /" + name + " must have shape " + (vector ? "(M, 3)" : "(M)"));
      }
      rows = std::min(rows, dims[0]);
      most_rows = std::max(most_rows, dims[0]);
    }
    contact_rows_ = static_cast<int64_t>(rows);
    if (!info_.complete) return;
    const int64_t n = info_.num_samples;
    int64_t end = 0;
    if (n > 0) {
      const auto [first, count] = ContactRange(n - 1);
      end = first + count;
    }
    if (most_rows != rows || end != contact_rows_) {
      throw SchemaError(path_ + ": the contact table holds between " + std::to_string(rows) +
                        " and " + std::to_string(most_rows) + " rows but the samples' contacts " +
                        "end at row " + std::to_string(end));
    }
  }

  // Labels, proprioception and the contact table's numbers are floating point: an integer
  // column (z in millimetres, say) would be read as metres without a word.
  void CheckNumericColumns() const {
    auto require_float = [&](hid_t dataset, const std::string& name) {
      h5::Handle type(h5::CheckId(H5Dget_type(dataset), path_, name, "read type of"));
      if (H5Tget_class(type.get()) != H5T_FLOAT) {
        throw SchemaError(path_ + ": /" + name + " is " + h5::DtypeName(type.get()) +
                          ", expected floating point in SI units (docs/dataset.md)");
      }
    };
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      require_float(columns_.scalar_labels[f].get(), kScalarLabels[f].path);
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      require_float(columns_.vector_labels[f].get(), kVectorLabels[f].path);
    }
    require_float(columns_.proprio.get(), kProprioPath);
    if (!has_contacts_) return;
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      require_float(columns_.contacts.scalars[f].get(), kScalarContacts[f].path);
    }
    for (size_t f = 0; f < kVectorContacts.size(); ++f) {
      require_float(columns_.contacts.vectors[f].get(), kVectorContacts[f].path);
    }
  }

  // Every sample index once: a repeated index is the same strike twice (merged twice, or a
  // hand-edited file), which would leak between a split's training and validation parts.
  void CheckUniqueIndices() const {
    const int64_t n = info_.num_samples;
    std::vector<uint64_t> indices(static_cast<size_t>(n));
    if (n > 0) {
      h5::ReadRows(columns_.sample_index.get(), H5T_NATIVE_UINT64, indices.data(), 0,
                   static_cast<hsize_t>(n), path_, kSampleIndexPath);
    }
    std::vector<std::pair<uint64_t, int64_t>> sorted(indices.size());
    for (int64_t r = 0; r < n; ++r) sorted[static_cast<size_t>(r)] = {indices[r], r};
    std::sort(sorted.begin(), sorted.end());
    for (size_t k = 1; k < sorted.size(); ++k) {
      if (sorted[k].first == sorted[k - 1].first) {
        throw SchemaError(path_ + ": sample index " + std::to_string(sorted[k].first) +
                          " appears twice (rows " + std::to_string(sorted[k - 1].second) + " and " +
                          std::to_string(sorted[k].second) + ")");
      }
    }
  }

  // A virtual audio column (merge --virtual) reads its shards where they were: every one there,
  // a plain dataset, and the same shard the merge recorded (libhdf5 would read a missing or
  // replaced source as silence, or another seed's audio under this file's labels).
  void CheckVirtualSources(Role role) const {
    namespace fs = std::filesystem;
    const std::vector<std::string> sources =
        h5::VirtualSourceFiles(columns_.audio.get(), path_, kAudioPath);
    if (sources.empty()) return;
    if (role == Role::kVirtualSource) {
      throw SchemaError(path_ + ": a shard read by a virtual merge is itself a virtual merge");
    }
    if (!h5::HasAttr(columns_.audio.get(), kShardIdentitiesAttr, path_)) {
      throw SchemaError(path_ + ": /audio is a virtual dataset without the identities of its " +
                        "shards (made by an older merge --virtual): merge the shards again");
    }
    // one line per shard: its path as stored, a tab, its identity
    std::istringstream recorded(
        h5::ReadStringAttr(columns_.audio.get(), kShardIdentitiesAttr, path_));
    std::vector<std::pair<std::string, std::string>> identities;
    for (std::string line; std::getline(recorded, line);) {
      const size_t tab = line.find('\t');
      if (tab != std::string::npos) identities.emplace_back(line.substr(0, tab), line.substr(tab + 1));
    }
    for (const std::string& source : sources) {
      const fs::path resolved = fs::path(source).is_absolute()
                                    ? fs::path(source)
                                    : fs::absolute(path_).parent_path() / source;
      if (!fs::exists(resolved)) {
        throw SchemaError(path_ + ": /audio is a virtual dataset over " + resolved.string() +
                          ", which is missing (a merge --virtual reads its shards in place)");
      }
      const auto entry = std::find_if(identities.begin(), identities.end(),
                                      [&](const auto& id) { return id.first == source; });
      if (entry == identities.end()) {
        throw SchemaError(path_ + ": /audio reads " + source + ", whose identity it does not record");
      }
      std::string now;
      try {
        now = DatasetFile(resolved.string(), false, Role::kVirtualSource).ShardIdentity();
      } catch (const Error& e) {
        throw SchemaError(path_ + ": its shard " + resolved.string() +
                          " (merge --virtual reads it in place) cannot be read: " + e.what());
      }
      if (now != entry->second) {
        throw SchemaError(path_ + ": its shard " + resolved.string() +
                          " changed since the merge (merge --virtual reads it in place): it was " +
                          entry->second + ", it is " + now + "; merge the shards again");
      }
    }
  }

  void CheckRange(int64_t i) const {
    if (i < 0 || i >= info_.num_samples) {
      throw IoError(path_ + ": sample " + std::to_string(i) + " out of range [0, " +
                    std::to_string(info_.num_samples) + ")");
    }
  }

  FaultGuard guard_;  // first: it outlives the file handle (libhdf5 may fault closing a bad file)
  std::string path_;
  h5::Handle file_;
  Columns columns_;
  DatasetInfo info_;
  double audio_scale_{1.0};
  bool has_contacts_{false};  // schema 1.1: the file has a contact table
  int64_t contact_rows_{0};   // M
};

}  // namespace sonicboom::internal::dataset
