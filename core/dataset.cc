#include "sonicboom/core/dataset.h"

#include <nlohmann/json.hpp>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <tuple>
#include <unordered_set>
#include <utility>

#include "internal/h5util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace h5 = internal::h5;

// int16 PCM full scale: stored value = round(clamp(x, -1, 1) * 32767).
constexpr double kInt16FullScale = 32767.0;
// Rows per chunk of the per-sample scalar and label columns.
constexpr hsize_t kColumnChunkRows = 1024;
// Proprio chunks hold as many samples as fit in about this many bytes (at least one).
constexpr hsize_t kProprioChunkBytes = 256 * 1024;
// deflate level of the audio and proprio chunks (after the shuffle filter).
constexpr int kDeflateLevel = 1;
// An unfinished file is flushed at most this often, so a crash leaves a readable prefix.
constexpr std::chrono::seconds kFlushInterval{2};

// Dataset paths below the root.
constexpr const char* kAudioPath = "audio";
constexpr const char* kProprioPath = "proprio";
constexpr const char* kSampleIndexPath = "index/sample_index";
constexpr const char* kSeedPath = "index/seed";
constexpr const char* kValidPath = "index/valid";
constexpr const char* kInvalidReasonPath = "index/invalid_reason";
constexpr const char* kClippedPath = "index/clipped";
constexpr const char* kProvenancePath = "index/provenance";  // recorded datasets only
constexpr const char* kVariationPath = "variation";  // (N, P) f64, attr `names`
constexpr const char* kContactFirstPath = "index/contact_first";
constexpr const char* kContactCountPath = "index/contact_count";
constexpr const char* kContactSampleRowPath = "contacts/sample_row";
constexpr const char* kContactKindPath = "contacts/kind";
constexpr const char* kContactObjectPath = "contacts/object";
constexpr const char* kContactMaterialPath = "contacts/material";

// Names of the contact kind codes 0, 1, 2, as the `names` attribute of /contacts/kind lists them.
constexpr std::array<const char*, 4> kContactKindNames = {"impact", "bounce", "press", "brush"};
constexpr const char* kContactKindNamesAttr = "impact,bounce,press,brush";

// Coverage of first contacts in the summary: 5 bins of z over [-h, h] and 6 of theta. h in units
// of 0.1 mm, so that the z edges are exact decimals (the nearest doubles to them).
constexpr int kCoverageHalfLengthTenthMm = 1015;
constexpr int kCoverageZBins = 5;
constexpr int kCoverageThetaBins = 6;
static_assert(kCoverageHalfLengthTenthMm % kCoverageZBins == 0);

// Scalar float64 label columns, shape (N).
struct ScalarLabelField {
  const char* path;
  double ContactLabel::*member;
};
constexpr std::array<ScalarLabelField, 6> kScalarLabels{{
    {"label/z_m", &ContactLabel::z_m},
    {"label/theta_rad", &ContactLabel::theta_rad},
    {"label/impulse_Ns", &ContactLabel::impulse_Ns},
    {"label/time_s", &ContactLabel::time_s},
    {"label/normal_speed_m_s", &ContactLabel::normal_speed_m_s},
    {"label/duration_s", &ContactLabel::duration_s},
}};

// 3-vector float64 label columns in the tube frame, shape (N, 3).
struct VectorLabelField {
  const char* path;
  Eigen::Vector3d ContactLabel::*member;
};
constexpr std::array<VectorLabelField, 2> kVectorLabels{{
    {"label/point_m", &ContactLabel::point_m},
    {"label/normal", &ContactLabel::normal},
}};

// Scalar float64 contact columns, shape (M).
struct ScalarContactField {
  const char* path;
  double ContactEpisode::*member;
};
constexpr std::array<ScalarContactField, 8> kScalarContacts{{
    {"contacts/time_s", &ContactEpisode::time_s},
    {"contacts/duration_s", &ContactEpisode::duration_s},
    {"contacts/z_m", &ContactEpisode::z_m},
    {"contacts/theta_rad", &ContactEpisode::theta_rad},
    {"contacts/normal_speed_m_s", &ContactEpisode::normal_speed_m_s},
    {"contacts/effective_mass_kg", &ContactEpisode::effective_mass_kg},
    {"contacts/impulse_Ns", &ContactEpisode::impulse_Ns},
    {"contacts/peak_force_N", &ContactEpisode::peak_force_N},
}};

// 3-vector float64 contact columns in the tube frame, shape (M, 3).
struct VectorContactField {
  const char* path;
  Eigen::Vector3d ContactEpisode::*member;
};
constexpr std::array<VectorContactField, 2> kVectorContacts{{
    {"contacts/point_m", &ContactEpisode::point_m},
    {"contacts/normal", &ContactEpisode::normal},
}};

// Open handles of the contact table (M rows, schema 1.1).
struct ContactColumns {
  h5::Handle sample_row;
  std::array<h5::Handle, kScalarContacts.size()> scalars;
  std::array<h5::Handle, kVectorContacts.size()> vectors;
  h5::Handle kind;
  h5::Handle object;
  h5::Handle material;

  // (handle, path) of every contact column.
  std::vector<std::pair<hid_t, std::string>> All() const {
    std::vector<std::pair<hid_t, std::string>> all = {{sample_row.get(), kContactSampleRowPath},
                                                      {kind.get(), kContactKindPath},
                                                      {object.get(), kContactObjectPath},
                                                      {material.get(), kContactMaterialPath}};
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      all.emplace_back(scalars[f].get(), kScalarContacts[f].path);
    }
    for (size_t f = 0; f < kVectorContacts.size(); ++f) {
      all.emplace_back(vectors[f].get(), kVectorContacts[f].path);
    }
    return all;
  }

  // Closes every column (a no-op for columns never opened), reporting failures as IoError.
  void CloseAll(const std::string& file) {
    sample_row.Close(file, kContactSampleRowPath);
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      scalars[f].Close(file, kScalarContacts[f].path);
    }
    for (size_t f = 0; f < kVectorContacts.size(); ++f) {
      vectors[f].Close(file, kVectorContacts[f].path);
    }
    kind.Close(file, kContactKindPath);
    object.Close(file, kContactObjectPath);
    material.Close(file, kContactMaterialPath);
  }
};

// Open handles of every dataset of a dataset file.
struct Columns {
  h5::Handle audio;
  h5::Handle proprio;
  std::array<h5::Handle, kScalarLabels.size()> scalar_labels;
  std::array<h5::Handle, kVectorLabels.size()> vector_labels;
  h5::Handle sample_index;
  h5::Handle seed;
  h5::Handle valid;
  h5::Handle invalid_reason;
  h5::Handle clipped;
  // Schema 1.1 only (left empty for a 1.0 file): per-sample offsets (N) and the table (M).
  h5::Handle contact_first;
  h5::Handle contact_count;
  ContactColumns contacts;
  h5::Handle variation;  // only in a randomized dataset
  h5::Handle provenance;  // only in a recorded dataset

  // (handle, path) of every per-sample column (N rows), for checks that apply to all of them.
  std::vector<std::pair<hid_t, std::string>> All() const {
    std::vector<std::pair<hid_t, std::string>> all = {
        {audio.get(), kAudioPath},
        {proprio.get(), kProprioPath},
        {sample_index.get(), kSampleIndexPath},
        {seed.get(), kSeedPath},
        {valid.get(), kValidPath},
        {invalid_reason.get(), kInvalidReasonPath},
        {clipped.get(), kClippedPath}};
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      all.emplace_back(scalar_labels[f].get(), kScalarLabels[f].path);
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      all.emplace_back(vector_labels[f].get(), kVectorLabels[f].path);
    }
    if (contact_first.valid()) all.emplace_back(contact_first.get(), kContactFirstPath);
    if (contact_count.valid()) all.emplace_back(contact_count.get(), kContactCountPath);
    if (variation.valid()) all.emplace_back(variation.get(), kVariationPath);
    if (provenance.valid()) all.emplace_back(provenance.get(), kProvenancePath);
    return all;
  }

  // Closes every column, reporting failures (pending writes) as IoError.
  void CloseAll(const std::string& file) {
    audio.Close(file, kAudioPath);
    proprio.Close(file, kProprioPath);
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      scalar_labels[f].Close(file, kScalarLabels[f].path);
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      vector_labels[f].Close(file, kVectorLabels[f].path);
    }
    sample_index.Close(file, kSampleIndexPath);
    seed.Close(file, kSeedPath);
    valid.Close(file, kValidPath);
    invalid_reason.Close(file, kInvalidReasonPath);
    clipped.Close(file, kClippedPath);
    contact_first.Close(file, kContactFirstPath);
    contact_count.Close(file, kContactCountPath);
    contacts.CloseAll(file);
    variation.Close(file, kVariationPath);
    provenance.Close(file, kProvenancePath);
  }
};

// Current UTC time as ISO 8601, e.g. "2024-05-01T12:34:56Z".
std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

// Refuses dataset metadata that cannot describe a file.
void CheckInfo(const std::string& path, const DatasetInfo& info) {
  auto fail = [&](const std::string& what) {
    throw ConfigError(path + ": dataset " + what);
  };
  if (info.channels < 1) fail("channels must be >= 1, got " + std::to_string(info.channels));
  if (info.audio_frames < 1) {
    fail("audio_frames must be >= 1, got " + std::to_string(info.audio_frames));
  }
  if (info.proprio_rows < 0) {
    fail("proprio_rows must be >= 0, got " + std::to_string(info.proprio_rows));
  }
  if (!(info.sample_rate_hz > 0.0)) {
    fail("sample_rate_hz must be > 0, got " + std::to_string(info.sample_rate_hz));
  }
  if (!(info.proprio_rate_hz > 0.0)) {
    fail("proprio_rate_hz must be > 0, got " + std::to_string(info.proprio_rate_hz));
  }
  if (info.num_shards < 1) fail("num_shards must be >= 1, got " + std::to_string(info.num_shards));
  if (info.shard < 0 || info.shard >= info.num_shards) {
    fail("shard must be in [0, " + std::to_string(info.num_shards) + "), got " +
         std::to_string(info.shard));
  }
}

// int16 PCM value of a full-scale sample; non-finite values (only in invalid samples) become 0.
int16_t ToPcm16(float x) {
  if (!std::isfinite(x)) return 0;
  // Round half away from zero, as std::lround, without its cost per audio value.
  const double scaled = std::clamp(static_cast<double>(x), -1.0, 1.0) * kInt16FullScale;
  return static_cast<int16_t>(scaled >= 0.0 ? scaled + 0.5 : scaled - 0.5);
}

// HDF5's shuffle filter applied to `values` stored little endian: byte b of element i goes to
// position b * n + i of the (n * sizeof(T)) output bytes.
template <typename T>
std::vector<unsigned char> ShuffleLittleEndian(const std::vector<T>& values) {
  constexpr size_t kSize = sizeof(T);
  static_assert(std::endian::native == std::endian::little ||
                std::endian::native == std::endian::big);
  const size_t n = values.size();
  std::vector<unsigned char> shuffled(n * kSize);
  for (size_t i = 0; i < n; ++i) {
    unsigned char bytes[kSize];
    std::memcpy(bytes, &values[i], kSize);
    for (size_t b = 0; b < kSize; ++b) {
      shuffled[b * n + i] = bytes[std::endian::native == std::endian::little ? b : kSize - 1 - b];
    }
  }
  return shuffled;
}

// HDF5's deflate filter: one zlib stream made by compress2 at `level` into a compressBound buffer.
std::vector<unsigned char> Deflate(const std::vector<unsigned char>& bytes, int level,
                                   const std::string& where) {
  uLongf size = compressBound(static_cast<uLong>(bytes.size()));
  std::vector<unsigned char> compressed(size);
  const int status = compress2(compressed.data(), &size, bytes.data(),
                               static_cast<uLong>(bytes.size()), level);
  if (status != Z_OK) {
    throw IoError(where + ": cannot deflate the audio chunk (zlib status " +
                  std::to_string(status) + ")");
  }
  compressed.resize(size);
  return compressed;
}

// Reads one row of a column of fixed-size values.
template <typename T>
T ReadOne(hid_t dataset, hid_t mem_type, int64_t i, const std::string& file, const char* path) {
  T value{};
  h5::ReadRows(dataset, mem_type, &value, static_cast<hsize_t>(i), 1, file, path);
  return value;
}

// Reads the first n rows of a 1-D column.
template <typename T>
std::vector<T> ReadColumn(hid_t dataset, hid_t mem_type, int64_t n, const std::string& file,
                          const char* path) {
  std::vector<T> values(n);
  h5::ReadRows(dataset, mem_type, values.data(), 0, static_cast<hsize_t>(n), file, path);
  return values;
}

// A complete (or, when allowed, incomplete) dataset file opened for reading.
class DatasetFile {
 public:
  DatasetFile(const std::string& path, bool allow_incomplete) : path_(path) {
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
    const std::vector<hsize_t> proprio_dims =
        h5::Dims(columns_.proprio.get(), path, kProprioPath);
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
  }

  const std::string& path() const { return path_; }
  const DatasetInfo& info() const { return info_; }
  int64_t size() const { return info_.num_samples; }

  // Index fields, labels and proprio of sample i.
  void ReadMeta(int64_t i, StrikeSample* sample) const {
    CheckRange(i);
    const hid_t u64 = H5T_NATIVE_UINT64;
    const hid_t u8 = H5T_NATIVE_UINT8;
    sample->index = ReadOne<uint64_t>(columns_.sample_index.get(), u64, i, path_,
                                      kSampleIndexPath);
    sample->seed = ReadOne<uint64_t>(columns_.seed.get(), u64, i, path_, kSeedPath);
    sample->valid = ReadOne<uint8_t>(columns_.valid.get(), u8, i, path_, kValidPath) != 0;
    sample->clipped = ReadOne<uint8_t>(columns_.clipped.get(), u8, i, path_, kClippedPath) != 0;
    sample->invalid_reason = h5::ReadStringRows(columns_.invalid_reason.get(),
                                                static_cast<hsize_t>(i), 1, path_,
                                                kInvalidReasonPath)
                                 .at(0);
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      sample->label.*kScalarLabels[f].member = ReadOne<double>(
          columns_.scalar_labels[f].get(), H5T_NATIVE_DOUBLE, i, path_, kScalarLabels[f].path);
    }
    for (size_t f = 0; f < kVectorLabels.size(); ++f) {
      Eigen::Vector3d& v = sample->label.*kVectorLabels[f].member;
      h5::ReadRows(columns_.vector_labels[f].get(), H5T_NATIVE_DOUBLE, v.data(),
                   static_cast<hsize_t>(i), 1, path_, kVectorLabels[f].path);
    }
    // (K, 10) row-major in the file.
    const int64_t k = info_.proprio_rows;
    std::vector<float> proprio(static_cast<size_t>(k) * kProprioFeatures);
    h5::ReadRows(columns_.proprio.get(), H5T_NATIVE_FLOAT, proprio.data(),
                 static_cast<hsize_t>(i), 1, path_, kProprioPath);
    sample->proprio =
        Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            proprio.data(), k, kProprioFeatures);
    sample->contacts = ReadContacts(i);
    if (columns_.provenance.valid()) {
      sample->provenance = h5::ReadStringRows(columns_.provenance.get(), static_cast<hsize_t>(i),
                                              1, path_, kProvenancePath)
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
    const int64_t first =
        ReadOne<int64_t>(columns_.contact_first.get(), H5T_NATIVE_INT64, i, path_,
                         kContactFirstPath);
    const int64_t count =
        ReadOne<int64_t>(columns_.contact_count.get(), H5T_NATIVE_INT64, i, path_,
                         kContactCountPath);
    CheckContactRange(i, first, count);
    return {first, count};
  }

  // Throws SchemaError unless [first, first + count) lies within the contact table.
  void CheckContactRange(int64_t i, int64_t first, int64_t count) const {
    if (first < 0 || count < 0 || first > contact_rows_ || count > contact_rows_ - first) {
      throw SchemaError(path_ + ": sample row " + std::to_string(i) + " has contacts [" +
                        std::to_string(first) + ", " + std::to_string(first + count) +
                        ") outside the contact table of " + std::to_string(contact_rows_) +
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
    using RowMajorInt16 =
        Eigen::Matrix<int16_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    using RowMajorFloat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const int64_t c = info_.channels;
    const int64_t t = info_.audio_frames;
    if (info_.audio_int16) {
      RowMajorInt16 pcm(c, t);
      h5::ReadRows(columns_.audio.get(), H5T_NATIVE_INT16, pcm.data(), static_cast<hsize_t>(i),
                   1, path_, kAudioPath);
      return (pcm.cast<double>() * audio_scale_).cast<float>();
    }
    RowMajorFloat audio(c, t);
    h5::ReadRows(columns_.audio.get(), H5T_NATIVE_FLOAT, audio.data(), static_cast<hsize_t>(i), 1,
                 path_, kAudioPath);
    if (audio_scale_ != 1.0) audio *= static_cast<float>(audio_scale_);
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
        throw SchemaError(path_ + ": /" + name + " must have shape " +
                          (vector ? "(M, 3)" : "(M)"));
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

  void CheckRange(int64_t i) const {
    if (i < 0 || i >= info_.num_samples) {
      throw IoError(path_ + ": sample " + std::to_string(i) + " out of range [0, " +
                    std::to_string(info_.num_samples) + ")");
    }
  }

  std::string path_;
  h5::Handle file_;
  Columns columns_;
  DatasetInfo info_;
  double audio_scale_{1.0};
  bool has_contacts_{false};   // schema 1.1: the file has a contact table
  int64_t contact_rows_{0};    // M
};

// {"min": .., "max": .., "mean": ..} of values (nulls when empty).
nlohmann::ordered_json RangeJson(const std::vector<double>& values, bool with_mean) {
  nlohmann::ordered_json range = {{"min", nullptr}, {"max", nullptr}};
  if (with_mean) range["mean"] = nullptr;
  if (values.empty()) return range;
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  range["min"] = *lo;
  range["max"] = *hi;
  if (with_mean) {
    double sum = 0.0;
    for (double v : values) sum += v;
    range["mean"] = sum / static_cast<double>(values.size());
  }
  return range;
}

// Bin of `value` among ascending `edges` (bins [e_b, e_b+1), the last closed); -1 outside.
int BinClosedBelow(const std::vector<double>& edges, double value) {
  if (!std::isfinite(value) || value < edges.front() || value > edges.back()) return -1;
  const auto above = std::upper_bound(edges.begin(), edges.end(), value);
  return std::min(static_cast<int>(above - edges.begin()) - 1,
                  static_cast<int>(edges.size()) - 2);
}

// Bin of an angle in degrees among ascending `edges` spanning (-180, 180] (bins (e_b, e_b+1]),
// after wrapping it into that range; -1 when not finite.
int AngleBin(const std::vector<double>& edges, double degrees) {
  if (!std::isfinite(degrees)) return -1;
  double wrapped = std::fmod(degrees, 360.0);
  if (wrapped <= -180.0) wrapped += 360.0;
  if (wrapped > 180.0) wrapped -= 360.0;
  const auto at_or_above = std::lower_bound(edges.begin(), edges.end(), wrapped);
  return std::clamp(static_cast<int>(at_or_above - edges.begin()) - 1, 0,
                    static_cast<int>(edges.size()) - 2);
}

// The summary's "contacts" object over the valid samples of `dataset`: totals, contacts per
// sample, counts by kind and object, and the (z, theta) coverage of each sample's first contact.
nlohmann::ordered_json ContactsSummaryJson(const DatasetFile& dataset,
                                           const std::vector<uint8_t>& valid) {
  const std::string& path = dataset.path();
  const Columns& columns = dataset.columns();
  const int64_t n = dataset.size();
  const int64_t m = dataset.contact_rows();

  // Offsets (N) and the summarized contact columns (M); a 1.0 file has no contacts.
  std::vector<int64_t> first(n, 0), count(n, 0);
  std::vector<uint8_t> kinds;
  std::vector<std::string> objects;
  std::vector<double> z, theta;
  if (dataset.has_contacts()) {
    first = ReadColumn<int64_t>(columns.contact_first.get(), H5T_NATIVE_INT64, n, path,
                                kContactFirstPath);
    count = ReadColumn<int64_t>(columns.contact_count.get(), H5T_NATIVE_INT64, n, path,
                                kContactCountPath);
    const ContactColumns& table = columns.contacts;
    kinds = ReadColumn<uint8_t>(table.kind.get(), H5T_NATIVE_UINT8, m, path, kContactKindPath);
    objects = h5::ReadStringRows(table.object.get(), 0, static_cast<hsize_t>(m), path,
                                 kContactObjectPath);
    for (size_t f = 0; f < kScalarContacts.size(); ++f) {
      const std::string name = kScalarContacts[f].path;
      if (name == "contacts/z_m" || name == "contacts/theta_rad") {
        std::vector<double> column = ReadColumn<double>(table.scalars[f].get(),
                                                        H5T_NATIVE_DOUBLE, m, path,
                                                        kScalarContacts[f].path);
        (name == "contacts/z_m" ? z : theta) = std::move(column);
      }
    }
  }

  // Coverage bin edges: z in m over [-h, h], theta in degrees over (-180, 180].
  std::vector<double> z_edges(kCoverageZBins + 1), theta_edges(kCoverageThetaBins + 1);
  for (int b = 0; b <= kCoverageZBins; ++b) {
    const int tenth_mm = (2 * b - kCoverageZBins) * (kCoverageHalfLengthTenthMm / kCoverageZBins);
    z_edges[b] = tenth_mm / 1e4;
  }
  for (int b = 0; b <= kCoverageThetaBins; ++b) {
    theta_edges[b] = -180.0 + 360.0 * b / kCoverageThetaBins;
  }

  // Counts over the valid samples.
  int64_t total = 0;
  int64_t outside = 0;
  std::vector<double> per_sample;
  std::array<int64_t, kContactKindNames.size()> by_kind{};
  std::map<std::string, int64_t> by_object;
  std::vector<std::vector<int64_t>> coverage(kCoverageZBins,
                                             std::vector<int64_t>(kCoverageThetaBins, 0));
  for (int64_t i = 0; i < n; ++i) {
    if (valid[i] == 0) continue;
    per_sample.push_back(static_cast<double>(count[i]));
    if (count[i] == 0) continue;
    dataset.CheckContactRange(i, first[i], count[i]);
    total += count[i];
    for (int64_t r = first[i]; r < first[i] + count[i]; ++r) {
      ++by_kind[static_cast<size_t>(dataset.KindFromCode(kinds[r], static_cast<hsize_t>(r)))];
      ++by_object[objects[r].empty() ? std::string("(unnamed)") : objects[r]];
    }
    // The first contact in time order.
    const int z_bin = BinClosedBelow(z_edges, z[first[i]]);
    const int theta_bin = AngleBin(theta_edges, theta[first[i]] * 180.0 / std::numbers::pi);
    if (z_bin < 0 || theta_bin < 0) {
      ++outside;
    } else {
      ++coverage[z_bin][theta_bin];
    }
  }

  nlohmann::ordered_json contacts;
  contacts["recorded"] = dataset.has_contacts();
  contacts["total"] = total;
  nlohmann::ordered_json per_sample_json = {{"min", nullptr}, {"max", nullptr}, {"mean", nullptr}};
  if (!per_sample.empty()) {
    const auto [lo, hi] = std::minmax_element(per_sample.begin(), per_sample.end());
    per_sample_json["min"] = static_cast<int64_t>(*lo);
    per_sample_json["max"] = static_cast<int64_t>(*hi);
    per_sample_json["mean"] = static_cast<double>(total) / static_cast<double>(per_sample.size());
  }
  contacts["per_sample"] = per_sample_json;
  nlohmann::ordered_json kinds_json = nlohmann::ordered_json::object();
  for (size_t k = 0; k < kContactKindNames.size(); ++k) {
    kinds_json[kContactKindNames[k]] = by_kind[k];
  }
  contacts["kinds"] = kinds_json;
  contacts["objects"] = nlohmann::ordered_json(by_object);
  contacts["coverage"] = {{"z_bins_m", z_edges},
                          {"theta_bins_deg", theta_edges},
                          {"counts", coverage},
                          {"outside", outside}};
  return contacts;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// DatasetWriter

struct DatasetWriter::Impl {
  std::string path;
  std::string partial;
  DatasetInfo info;
  h5::Handle file_handle;
  Columns columns;
  h5::Handle string_type;
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
  // Creates the per-sample contact offsets and the empty contact table.
  void CreateContactColumns();
};

DatasetWriter::DatasetWriter(const std::string& path, const DatasetInfo& info)
    : DatasetWriter(path, info, /*with_contacts=*/true) {}

DatasetWriter::DatasetWriter(const std::string& path, const DatasetInfo& info, bool with_contacts)
    : impl_(std::make_unique<Impl>()) {
  CheckInfo(path, info);
  Impl& s = *impl_;
  s.with_contacts = with_contacts;
  s.path = path;
  s.partial = h5::PartialPath(path);
  s.info = info;
  if (s.info.software_version.empty()) s.info.software_version = SONICBOOM_VERSION;
  h5::PrepareAtomicWrite(path);
  s.file_handle = h5::CreateFile(s.partial);
  s.string_type = h5::VlenStringType();
  const hid_t root = s.file_handle.get();
  const std::string& file = s.partial;

  // Root attributes; num_samples and `complete` follow in Finish().
  h5::WriteStringAttr(root, "schema", kDatasetSchema, file);
  h5::WriteStringAttr(root, "schema_version",
                      with_contacts ? kDatasetSchemaVersion : kDatasetSchemaVersionWithoutContacts,
                      file);
  h5::WriteStringAttr(root, "software_version", s.info.software_version, file);
  h5::WriteStringAttr(root, "source", s.info.source, file);
  h5::WriteStringAttr(root, "config_yaml", s.info.config_yaml, file);
  h5::WriteDoubleAttr(root, "sample_rate_hz", s.info.sample_rate_hz, file);
  h5::WriteDoubleAttr(root, "proprio_rate_hz", s.info.proprio_rate_hz, file);
  h5::WriteUint64Attr(root, "global_seed", s.info.global_seed, file);
  h5::WriteInt64Attr(root, "shard", s.info.shard, file);
  h5::WriteInt64Attr(root, "num_shards", s.info.num_shards, file);
  h5::WriteStringAttr(root, "created_utc", UtcNow(), file);

  // Audio (N, C, T): one sample per chunk, shuffle + deflate; `scale` maps to full scale 1.
  const hsize_t c = static_cast<hsize_t>(s.info.channels);
  const hsize_t t = static_cast<hsize_t>(s.info.audio_frames);
  s.columns.audio =
      h5::CreateExtendable(root, kAudioPath, s.info.audio_int16 ? H5T_STD_I16LE : H5T_IEEE_F32LE,
                           {{c, t}, 1, kDeflateLevel}, file);
  h5::WriteDoubleAttr(s.columns.audio.get(), "scale",
                      s.info.audio_int16 ? 1.0 / kInt16FullScale : 1.0, file);

  // Proprio (N, K, 10) float32, chunks of about kProprioChunkBytes.
  const hsize_t k = static_cast<hsize_t>(s.info.proprio_rows);
  const hsize_t proprio_row_bytes = std::max<hsize_t>(k * kProprioFeatures * sizeof(float), 1);
  const hsize_t proprio_chunk_rows =
      std::clamp<hsize_t>(kProprioChunkBytes / proprio_row_bytes, 1, kColumnChunkRows);
  s.columns.proprio = h5::CreateExtendable(root, kProprioPath, H5T_IEEE_F32LE,
                                           {{k, kProprioFeatures}, proprio_chunk_rows,
                                            kDeflateLevel},
                                           file);

  // Labels (N) and (N, 3) float64; index columns (N).
  for (size_t f = 0; f < kScalarLabels.size(); ++f) {
    s.columns.scalar_labels[f] = h5::CreateExtendable(root, kScalarLabels[f].path, H5T_IEEE_F64LE,
                                                      {{}, kColumnChunkRows, -1}, file);
  }
  for (size_t f = 0; f < kVectorLabels.size(); ++f) {
    s.columns.vector_labels[f] = h5::CreateExtendable(root, kVectorLabels[f].path, H5T_IEEE_F64LE,
                                                      {{3}, kColumnChunkRows, -1}, file);
  }
  s.columns.sample_index = h5::CreateExtendable(root, kSampleIndexPath, H5T_STD_U64LE,
                                                {{}, kColumnChunkRows, -1}, file);
  s.columns.seed =
      h5::CreateExtendable(root, kSeedPath, H5T_STD_U64LE, {{}, kColumnChunkRows, -1}, file);
  s.columns.valid =
      h5::CreateExtendable(root, kValidPath, H5T_STD_U8LE, {{}, kColumnChunkRows, -1}, file);
  s.columns.invalid_reason = h5::CreateExtendable(root, kInvalidReasonPath, s.string_type.get(),
                                                  {{}, kColumnChunkRows, -1}, file);
  s.columns.clipped =
      h5::CreateExtendable(root, kClippedPath, H5T_STD_U8LE, {{}, kColumnChunkRows, -1}, file);
  if (s.with_contacts) s.CreateContactColumns();
  // Where each recorded sample came from.
  if (s.info.source == "hardware") {
    s.columns.provenance = h5::CreateExtendable(root, kProvenancePath, s.string_type.get(),
                                                {{}, kColumnChunkRows, -1}, file);
  }
  // Randomized draws (N, P) f64 with their names.
  if (!s.info.variation_names.empty()) {
    const hsize_t p = s.info.variation_names.size();
    s.columns.variation = h5::CreateExtendable(root, kVariationPath, H5T_IEEE_F64LE,
                                               {{p}, kColumnChunkRows, -1}, file);
    std::string names;
    for (const std::string& name : s.info.variation_names) {
      names += (names.empty() ? "" : ",") + name;
    }
    h5::WriteStringAttr(s.columns.variation.get(), "names", names, file);
  }
  s.last_flush = std::chrono::steady_clock::now();
}

void DatasetWriter::Impl::CreateContactColumns() {
  const hid_t root = file_handle.get();
  const std::string& file = partial;
  const h5::ExtendableLayout scalar_layout{{}, kColumnChunkRows, -1};
  const h5::ExtendableLayout vector_layout{{3}, kColumnChunkRows, -1};
  // Offsets (N) int64: sample n's contacts are rows [first, first + count).
  columns.contact_first =
      h5::CreateExtendable(root, kContactFirstPath, H5T_STD_I64LE, scalar_layout, file);
  columns.contact_count =
      h5::CreateExtendable(root, kContactCountPath, H5T_STD_I64LE, scalar_layout, file);
  // The table (M) and (M, 3): owning sample row, numbers, kind codes, strings.
  ContactColumns& table = columns.contacts;
  table.sample_row =
      h5::CreateExtendable(root, kContactSampleRowPath, H5T_STD_I64LE, scalar_layout, file);
  for (size_t f = 0; f < kScalarContacts.size(); ++f) {
    table.scalars[f] =
        h5::CreateExtendable(root, kScalarContacts[f].path, H5T_IEEE_F64LE, scalar_layout, file);
  }
  for (size_t f = 0; f < kVectorContacts.size(); ++f) {
    table.vectors[f] =
        h5::CreateExtendable(root, kVectorContacts[f].path, H5T_IEEE_F64LE, vector_layout, file);
  }
  table.kind = h5::CreateExtendable(root, kContactKindPath, H5T_STD_U8LE, scalar_layout, file);
  h5::WriteStringAttr(table.kind.get(), "names", kContactKindNamesAttr, file);
  table.object =
      h5::CreateExtendable(root, kContactObjectPath, string_type.get(), scalar_layout, file);
  table.material =
      h5::CreateExtendable(root, kContactMaterialPath, string_type.get(), scalar_layout, file);
}

DatasetWriter::~DatasetWriter() = default;

void DatasetWriter::Append(const StrikeSample& sample) {
  impl_->CheckNewIndex(sample.index);
  AppendEncoded(Encode(sample));
}

DatasetWriter::EncodedSample DatasetWriter::Encode(const StrikeSample& sample) const {
  impl_->CheckSample(sample, /*raw_audio=*/false);
  EncodedSample encoded;
  encoded.audio_chunk = impl_->EncodeAudio(sample);
  // Everything but the audio, which the chunk now carries.
  encoded.meta.index = sample.index;
  encoded.meta.seed = sample.seed;
  encoded.meta.valid = sample.valid;
  encoded.meta.invalid_reason = sample.invalid_reason;
  encoded.meta.label = sample.label;
  encoded.meta.proprio = sample.proprio;
  encoded.meta.clipped = sample.clipped;
  encoded.meta.contacts = sample.contacts;
  encoded.meta.variation = sample.variation;
  encoded.meta.provenance = sample.provenance;
  return encoded;
}

void DatasetWriter::AppendEncoded(const EncodedSample& sample) {
  Impl& s = *impl_;
  s.CheckSample(sample.meta, /*raw_audio=*/true);
  s.CheckNewIndex(sample.meta.index);
  if (sample.audio_chunk.empty()) {
    throw SchemaError(s.partial + ": sample " + std::to_string(sample.meta.index) +
                      ": empty encoded audio chunk");
  }
  h5::AppendRawChunkRow(s.columns.audio.get(), sample.filter_mask, sample.audio_chunk.data(),
                        sample.audio_chunk.size(), s.partial, kAudioPath);
  s.WriteAllButAudio(sample.meta);
}

void DatasetWriter::Impl::CheckSample(const StrikeSample& sample, bool raw_audio) const {
  const std::string where = partial + ": sample " + std::to_string(sample.index);
  const int64_t c = info.channels;
  const int64_t t = info.audio_frames;
  const int64_t k = info.proprio_rows;
  // Shapes: audio (C x T), proprio (K x 10); an invalid sample may carry neither (zeros stored).
  const bool audio_missing = !sample.valid && sample.audio.size() == 0;
  if (!raw_audio && !audio_missing &&
      (sample.audio.rows() != c || sample.audio.cols() != t)) {
    throw SchemaError(where + ": audio is " + std::to_string(sample.audio.rows()) + " x " +
                      std::to_string(sample.audio.cols()) + ", expected " + std::to_string(c) +
                      " x " + std::to_string(t));
  }
  const bool proprio_missing = !sample.valid && sample.proprio.size() == 0;
  if (!proprio_missing &&
      (sample.proprio.rows() != k || sample.proprio.cols() != kProprioFeatures)) {
    throw SchemaError(where + ": proprio is " + std::to_string(sample.proprio.rows()) + " x " +
                      std::to_string(sample.proprio.cols()) + ", expected " + std::to_string(k) +
                      " x " + std::to_string(kProprioFeatures));
  }
  if (!raw_audio && sample.valid && !sample.audio.allFinite()) {
    throw SchemaError(where + ": valid sample has non-finite audio");
  }
  // Randomized draws: one finite value per name.
  if (sample.variation.size() != info.variation_names.size()) {
    throw SchemaError(where + ": has " + std::to_string(sample.variation.size()) +
                      " randomized values, the file stores " +
                      std::to_string(info.variation_names.size()));
  }
  for (size_t j = 0; j < sample.variation.size(); ++j) {
    if (!std::isfinite(sample.variation[j])) {
      throw SchemaError(where + ": randomized value " + info.variation_names[j] +
                        " is not finite");
    }
  }
  // Contacts: only a 1.1 file stores them; kind codes must be known.
  if (!with_contacts && !sample.contacts.empty()) {
    throw SchemaError(where + ": has " + std::to_string(sample.contacts.size()) +
                      " contacts, but a schema " + kDatasetSchemaVersionWithoutContacts +
                      " file stores none");
  }
  for (size_t j = 0; j < sample.contacts.size(); ++j) {
    const auto code = static_cast<size_t>(sample.contacts[j].kind);
    if (code >= kContactKindNames.size()) {
      throw SchemaError(where + ": contact " + std::to_string(j) + " has unknown kind code " +
                        std::to_string(code));
    }
  }
}

void DatasetWriter::Impl::CheckNewIndex(uint64_t index) const {
  SONICBOOM_DEMAND(!finished);
  if (indices.count(index) > 0) {
    throw SchemaError(partial + ": sample " + std::to_string(index) +
                      ": sample index written twice");
  }
}

std::vector<unsigned char> DatasetWriter::Impl::EncodeAudio(const StrikeSample& sample) const {
  // One (C, T) row-major row as int16 PCM or float32; zeros when an invalid sample has none.
  const int64_t c = info.channels;
  const int64_t t = info.audio_frames;
  const bool audio_missing = sample.audio.size() == 0;
  const std::string where = partial + ": sample " + std::to_string(sample.index);
  if (info.audio_int16) {
    std::vector<int16_t> pcm(static_cast<size_t>(c * t), 0);
    if (!audio_missing) {
      for (int64_t ch = 0; ch < c; ++ch) {
        for (int64_t j = 0; j < t; ++j) pcm[ch * t + j] = ToPcm16(sample.audio(ch, j));
      }
    }
    return Deflate(ShuffleLittleEndian(pcm), kDeflateLevel, where);
  }
  std::vector<float> audio(static_cast<size_t>(c * t), 0.0f);
  if (!audio_missing) {
    for (int64_t ch = 0; ch < c; ++ch) {
      for (int64_t j = 0; j < t; ++j) audio[ch * t + j] = sample.audio(ch, j);
    }
  }
  return Deflate(ShuffleLittleEndian(audio), kDeflateLevel, where);
}

void DatasetWriter::Impl::WriteAllButAudio(const StrikeSample& sample) {
  const std::string& file = partial;
  // Proprio row, (K, 10) row-major float32; zeros when an invalid sample has none.
  const int64_t k = info.proprio_rows;
  std::vector<float> proprio(static_cast<size_t>(k * kProprioFeatures), 0.0f);
  if (sample.proprio.size() > 0) {
    for (int64_t r = 0; r < k; ++r) {
      for (int j = 0; j < kProprioFeatures; ++j) {
        proprio[r * kProprioFeatures + j] = sample.proprio(r, j);
      }
    }
  }
  h5::AppendRows(columns.proprio.get(), H5T_NATIVE_FLOAT, proprio.data(), 1, file, kProprioPath);

  // Labels.
  for (size_t f = 0; f < kScalarLabels.size(); ++f) {
    const double value = sample.label.*kScalarLabels[f].member;
    h5::AppendRows(columns.scalar_labels[f].get(), H5T_NATIVE_DOUBLE, &value, 1, file,
                   kScalarLabels[f].path);
  }
  for (size_t f = 0; f < kVectorLabels.size(); ++f) {
    const Eigen::Vector3d value = sample.label.*kVectorLabels[f].member;
    h5::AppendRows(columns.vector_labels[f].get(), H5T_NATIVE_DOUBLE, value.data(), 1, file,
                   kVectorLabels[f].path);
  }

  // Contacts before the per-sample offsets that point at them.
  if (with_contacts) WriteContacts(sample);

  // Index columns.
  const uint8_t valid = sample.valid ? 1 : 0;
  const uint8_t clipped = sample.clipped ? 1 : 0;
  const char* reason = sample.invalid_reason.c_str();
  h5::AppendRows(columns.sample_index.get(), H5T_NATIVE_UINT64, &sample.index, 1, file,
                 kSampleIndexPath);
  h5::AppendRows(columns.seed.get(), H5T_NATIVE_UINT64, &sample.seed, 1, file, kSeedPath);
  h5::AppendRows(columns.valid.get(), H5T_NATIVE_UINT8, &valid, 1, file, kValidPath);
  h5::AppendRows(columns.invalid_reason.get(), string_type.get(), &reason, 1, file,
                 kInvalidReasonPath);
  h5::AppendRows(columns.clipped.get(), H5T_NATIVE_UINT8, &clipped, 1, file, kClippedPath);
  if (columns.variation.valid()) {
    h5::AppendRows(columns.variation.get(), H5T_NATIVE_DOUBLE, sample.variation.data(), 1, file,
                   kVariationPath);
  }
  if (columns.provenance.valid()) {
    const char* origin = sample.provenance.c_str();
    h5::AppendRows(columns.provenance.get(), string_type.get(), &origin, 1, file,
                   kProvenancePath);
  }
  indices.insert(sample.index);
  ++count;

  // Periodic flush so that a crash leaves a readable .partial.
  const auto now = std::chrono::steady_clock::now();
  if (now - last_flush >= kFlushInterval) {
    h5::CheckStatus(H5Fflush(file_handle.get(), H5F_SCOPE_LOCAL), file, "", "flush");
    last_flush = now;
  }
}

void DatasetWriter::Impl::WriteContacts(const StrikeSample& sample) {
  const std::string& file = partial;
  const int64_t first = contact_rows;
  const int64_t m = static_cast<int64_t>(sample.contacts.size());
  const hsize_t rows = static_cast<hsize_t>(m);
  ContactColumns& table = columns.contacts;
  // Owning sample row (this sample's row n) and the numbers, (m) and (m, 3) row-major.
  const std::vector<int64_t> sample_rows(rows, count);
  h5::AppendRows(table.sample_row.get(), H5T_NATIVE_INT64, sample_rows.data(), rows, file,
                 kContactSampleRowPath);
  std::vector<double> values(3 * rows);
  for (size_t f = 0; f < kScalarContacts.size(); ++f) {
    for (hsize_t r = 0; r < rows; ++r) values[r] = sample.contacts[r].*kScalarContacts[f].member;
    h5::AppendRows(table.scalars[f].get(), H5T_NATIVE_DOUBLE, values.data(), rows, file,
                   kScalarContacts[f].path);
  }
  for (size_t f = 0; f < kVectorContacts.size(); ++f) {
    for (hsize_t r = 0; r < rows; ++r) {
      const Eigen::Vector3d& v = sample.contacts[r].*kVectorContacts[f].member;
      for (int d = 0; d < 3; ++d) values[3 * r + d] = v[d];
    }
    h5::AppendRows(table.vectors[f].get(), H5T_NATIVE_DOUBLE, values.data(), rows, file,
                   kVectorContacts[f].path);
  }
  // Kind codes and strings.
  std::vector<uint8_t> kinds(rows);
  std::vector<const char*> objects(rows), materials(rows);
  for (hsize_t r = 0; r < rows; ++r) {
    kinds[r] = static_cast<uint8_t>(sample.contacts[r].kind);
    objects[r] = sample.contacts[r].object.c_str();
    materials[r] = sample.contacts[r].material.c_str();
  }
  h5::AppendRows(table.kind.get(), H5T_NATIVE_UINT8, kinds.data(), rows, file, kContactKindPath);
  h5::AppendRows(table.object.get(), string_type.get(), objects.data(), rows, file,
                 kContactObjectPath);
  h5::AppendRows(table.material.get(), string_type.get(), materials.data(), rows, file,
                 kContactMaterialPath);
  // The sample's offsets.
  h5::AppendRows(columns.contact_first.get(), H5T_NATIVE_INT64, &first, 1, file,
                 kContactFirstPath);
  h5::AppendRows(columns.contact_count.get(), H5T_NATIVE_INT64, &m, 1, file, kContactCountPath);
  contact_rows += m;
}

void DatasetWriter::Finish() {
  Impl& s = *impl_;
  SONICBOOM_DEMAND(!s.finished);
  h5::WriteInt64Attr(s.file_handle.get(), "num_samples", s.count, s.partial);
  // `complete` is the last thing written.
  h5::MarkComplete(s.file_handle.get(), s.partial);
  s.columns.CloseAll(s.partial);
  s.string_type.Reset();
  s.file_handle.Close(s.partial, "");
  h5::CommitAtomicWrite(s.path);
  s.finished = true;
}

int64_t DatasetWriter::count() const { return impl_->count; }

// ---------------------------------------------------------------------------------------------
// DatasetReader

struct DatasetReader::Impl {
  DatasetFile file;
};

DatasetReader::DatasetReader(const std::string& path, bool allow_incomplete)
    : impl_(std::make_unique<Impl>(Impl{DatasetFile(path, allow_incomplete)})) {}

DatasetReader::~DatasetReader() = default;
DatasetReader::DatasetReader(DatasetReader&&) noexcept = default;
DatasetReader& DatasetReader::operator=(DatasetReader&&) noexcept = default;

const DatasetInfo& DatasetReader::info() const { return impl_->file.info(); }

int64_t DatasetReader::size() const { return impl_->file.size(); }

StrikeSample DatasetReader::ReadMeta(int64_t i) const {
  StrikeSample sample;
  impl_->file.ReadMeta(i, &sample);
  return sample;
}

StrikeSample DatasetReader::Read(int64_t i) const {
  StrikeSample sample;
  impl_->file.ReadMeta(i, &sample);
  sample.audio = impl_->file.ReadAudio(i);
  return sample;
}

// ---------------------------------------------------------------------------------------------
// Merging and summaries

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

// An invalid reason with its numbers replaced by '#', so that reasons differing only in a time
// or a depth count together ("penetration # mm ... at t = # s").
static std::string ReasonCategory(const std::string& reason) {
  std::string out;
  for (size_t i = 0; i < reason.size();) {
    const bool sign = (reason[i] == '-' || reason[i] == '+') && i + 1 < reason.size() &&
                      std::isdigit(static_cast<unsigned char>(reason[i + 1])) &&
                      (i == 0 || reason[i - 1] == ' ' || reason[i - 1] == '(' || reason[i - 1] == '[');
    if (!sign && !std::isdigit(static_cast<unsigned char>(reason[i]))) {
      out += reason[i++];
      continue;
    }
    // a number: sign, digits, fraction, exponent
    i += sign ? 1 : 0;
    while (i < reason.size() && (std::isdigit(static_cast<unsigned char>(reason[i])) ||
                                 reason[i] == '.' || reason[i] == 'e' ||
                                 ((reason[i] == '-' || reason[i] == '+') && reason[i - 1] == 'e'))) {
      ++i;
    }
    out += '#';
  }
  return out;
}

std::string SummarizeDatasetJson(const std::string& path) {
  const DatasetFile dataset(path, /*allow_incomplete=*/true);
  const DatasetInfo& info = dataset.info();
  const Columns& columns = dataset.columns();
  const int64_t n = dataset.size();

  // Whole index and label columns (one value per sample).
  const std::vector<uint8_t> valid =
      ReadColumn<uint8_t>(columns.valid.get(), H5T_NATIVE_UINT8, n, path, kValidPath);
  const std::vector<uint8_t> clipped =
      ReadColumn<uint8_t>(columns.clipped.get(), H5T_NATIVE_UINT8, n, path, kClippedPath);
  const std::vector<std::string> reasons = h5::ReadStringRows(
      columns.invalid_reason.get(), 0, static_cast<hsize_t>(n), path, kInvalidReasonPath);
  auto label_column = [&](const char* name) {
    for (size_t f = 0; f < kScalarLabels.size(); ++f) {
      if (std::string(kScalarLabels[f].path) == name) {
        return ReadColumn<double>(columns.scalar_labels[f].get(), H5T_NATIVE_DOUBLE, n, path,
                                  name);
      }
    }
    throw IoError(path + ": no label column " + name);
  };
  const std::vector<double> z = label_column("label/z_m");
  const std::vector<double> theta = label_column("label/theta_rad");
  const std::vector<double> impulse = label_column("label/impulse_Ns");
  const std::vector<double> speed = label_column("label/normal_speed_m_s");

  // Counts, and label/audio statistics over valid samples only.
  int64_t valid_count = 0;
  int64_t clipped_count = 0;
  std::map<std::string, int64_t> invalid_reasons;
  std::vector<double> valid_z, valid_theta, valid_impulse, valid_speed, audio_peak;
  for (int64_t i = 0; i < n; ++i) {
    if (clipped[i] != 0) ++clipped_count;
    if (valid[i] == 0) {
      ++invalid_reasons[reasons[i].empty() ? std::string("(no reason)") : ReasonCategory(reasons[i])];
      continue;
    }
    ++valid_count;
    valid_z.push_back(z[i]);
    valid_theta.push_back(theta[i]);
    valid_impulse.push_back(impulse[i]);
    valid_speed.push_back(speed[i]);
    audio_peak.push_back(dataset.ReadAudio(i).cwiseAbs().maxCoeff());
  }

  nlohmann::ordered_json summary;
  summary["file"] = path;
  summary["kind"] = "dataset";
  summary["schema_version"] = info.schema_version;
  summary["complete"] = info.complete;
  summary["source"] = info.source;
  summary["software_version"] = info.software_version;
  summary["num_samples"] = n;
  summary["valid"] = valid_count;
  summary["invalid"] = n - valid_count;
  summary["invalid_reasons"] = invalid_reasons;
  summary["clipped"] = clipped_count;
  summary["channels"] = info.channels;
  summary["audio_frames"] = info.audio_frames;
  summary["audio_dtype"] = info.audio_int16 ? "int16" : "float32";
  summary["sample_rate_hz"] = info.sample_rate_hz;
  summary["proprio_rows"] = info.proprio_rows;
  summary["proprio_rate_hz"] = info.proprio_rate_hz;
  summary["shard"] = info.shard;
  summary["num_shards"] = info.num_shards;
  summary["global_seed"] = info.global_seed;
  summary["z_m"] = RangeJson(valid_z, true);
  summary["theta_rad"] = RangeJson(valid_theta, false);
  summary["impulse_Ns"] = RangeJson(valid_impulse, false);
  summary["normal_speed_m_s"] = RangeJson(valid_speed, false);
  summary["audio_peak"] = RangeJson(audio_peak, false);
  summary["contacts"] = ContactsSummaryJson(dataset, valid);
  return summary.dump(2);
}

}  // namespace sonicboom
