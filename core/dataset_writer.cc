// DatasetWriter: samples appended to "<path>.partial" (audio shuffled and deflated off the
// writing thread, the same stream HDF5's filter makes), flushed now and then, `complete` last,
// then renamed into place.
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include "internal/dataset_writer_impl.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

using namespace internal::dataset;  // NOLINT: the schema tables

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
  auto fail = [&](const std::string& what) { throw ConfigError(path + ": dataset " + what); };
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
  const int status =
      compress2(compressed.data(), &size, bytes.data(), static_cast<uLong>(bytes.size()), level);
  if (status != Z_OK) {
    throw IoError(where + ": cannot deflate the audio chunk (zlib status " +
                  std::to_string(status) + ")");
  }
  compressed.resize(size);
  return compressed;
}
}  // namespace

using namespace internal::dataset;  // NOLINT: the schema tables

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
  s.lock.emplace(h5::PrepareAtomicWrite(path));
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
  if (s.info.first_index >= 0 && s.info.index_count >= 0) {
    h5::WriteInt64Attr(root, "first_index", s.info.first_index, file);
    h5::WriteInt64Attr(root, "index_count", s.info.index_count, file);
  }
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
  s.columns.proprio =
      h5::CreateExtendable(root, kProprioPath, H5T_IEEE_F32LE,
                           {{k, kProprioFeatures}, proprio_chunk_rows, kDeflateLevel}, file);

  // Labels (N) and (N, 3) float64; index columns (N).
  for (size_t f = 0; f < kScalarLabels.size(); ++f) {
    s.columns.scalar_labels[f] = h5::CreateExtendable(root, kScalarLabels[f].path, H5T_IEEE_F64LE,
                                                      {{}, kColumnChunkRows, -1}, file);
  }
  for (size_t f = 0; f < kVectorLabels.size(); ++f) {
    s.columns.vector_labels[f] = h5::CreateExtendable(root, kVectorLabels[f].path, H5T_IEEE_F64LE,
                                                      {{3}, kColumnChunkRows, -1}, file);
  }
  s.columns.sample_index =
      h5::CreateExtendable(root, kSampleIndexPath, H5T_STD_U64LE, {{}, kColumnChunkRows, -1}, file);
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
  if (!raw_audio && !audio_missing && (sample.audio.rows() != c || sample.audio.cols() != t)) {
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
  // Labels: finite, or NaN when not known.
  for (const auto& field : kScalarLabels) {
    if (std::isinf(sample.label.*field.member)) {
      throw SchemaError(where + ": label " + field.path + " is infinite");
    }
  }
  // Randomized draws: one finite value per name.
  if (sample.variation.size() != info.variation_names.size()) {
    throw SchemaError(where + ": has " + std::to_string(sample.variation.size()) +
                      " randomized values, the file stores " +
                      std::to_string(info.variation_names.size()));
  }
  for (size_t j = 0; j < sample.variation.size(); ++j) {
    if (!std::isfinite(sample.variation[j])) {
      throw SchemaError(where + ": randomized value " + info.variation_names[j] + " is not finite");
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
    h5::AppendRows(columns.provenance.get(), string_type.get(), &origin, 1, file, kProvenancePath);
  }
  indices.insert(sample.index);
  ++count;

  // Periodic flush so that a crash leaves a readable .partial.
  if (std::chrono::steady_clock::now() - last_flush >= kFlushInterval) Flush();
}

void DatasetWriter::Impl::Flush() {
  // the samples on disk after this flush: what a resume may trust of a killed writer's file
  h5::WriteInt64Attr(file_handle.get(), "flushed_samples", count, partial);
  h5::CheckStatus(H5Fflush(file_handle.get(), H5F_SCOPE_LOCAL), partial, "", "flush");
  last_flush = std::chrono::steady_clock::now();
}

void DatasetWriter::Flush() {
  impl_->Flush();
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
  h5::AppendRows(columns.contact_first.get(), H5T_NATIVE_INT64, &first, 1, file, kContactFirstPath);
  h5::AppendRows(columns.contact_count.get(), H5T_NATIVE_INT64, &m, 1, file, kContactCountPath);
  contact_rows += m;
}

void DatasetWriter::Finish() {
  Impl& s = *impl_;
  SONICBOOM_DEMAND(!s.finished);
  h5::WriteInt64Attr(s.file_handle.get(), "num_samples", s.count, s.partial);
  // every sample is on disk (and the file does not depend on when the periodic flushes fell)
  h5::WriteInt64Attr(s.file_handle.get(), "flushed_samples", s.count, s.partial);
  // `complete` is the last thing written.
  h5::MarkComplete(s.file_handle.get(), s.partial);
  s.columns.CloseAll(s.partial);
  s.string_type.Reset();
  s.file_handle.Close(s.partial, "");
  h5::CommitAtomicWrite(s.path);
  s.finished = true;
}

int64_t DatasetWriter::count() const {
  return impl_->count;
}

}  // namespace sonicboom
