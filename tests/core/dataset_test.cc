#include "sonicboom/core/constants.h"
#include "sonicboom/core/dataset.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/core/array_file.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;

// A fresh directory under the system temp directory, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::random_device device;
    const uint64_t tag = (static_cast<uint64_t>(device()) << 32) ^ device();
    path_ = fs::temp_directory_path() / ("sonicboom_test_" + std::to_string(tag));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string File(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

DatasetInfo MakeInfo(bool audio_int16) {
  DatasetInfo info;
  info.source = "sim";
  info.config_yaml = "seed: 42\nsim:\n  dt_s: 0.0001\n";
  info.sample_rate_hz = 48000.0;
  info.proprio_rate_hz = 200.0;
  info.channels = 2;
  info.audio_frames = 64;
  info.proprio_rows = 3;
  info.audio_int16 = audio_int16;
  info.global_seed = 42;
  return info;
}

// Contact episode j of sample `index`: distinct values in every field, UTF-8 names.
ContactEpisode MakeContact(uint64_t index, int j) {
  ContactEpisode contact;
  contact.time_s = 0.002 + 1e-4 * static_cast<double>(index) + 0.01 * j;
  contact.duration_s = 1.5e-4 * (j + 1);
  contact.z_m = 0.07 * j - 0.09 + 1e-3 * static_cast<double>(index);
  contact.theta_rad = -2.5 + 1.7 * j + 0.01 * static_cast<double>(index);
  contact.point_m = Eigen::Vector3d(0.0254 * std::cos(contact.theta_rad),
                                    0.0254 * std::sin(contact.theta_rad), contact.z_m);
  contact.normal = Eigen::Vector3d(std::cos(contact.theta_rad), std::sin(contact.theta_rad), 0.0);
  contact.normal_speed_m_s = 0.4 + 0.1 * j;
  contact.effective_mass_kg = 0.35 + 0.01 * static_cast<double>(index);
  contact.impulse_Ns = 0.02 / (j + 1);
  contact.peak_force_N = 120.5 - 10.0 * j;
  contact.kind = static_cast<ContactEpisode::Kind>(j % 3);
  contact.object = j == 2 ? "rod T22L42 \u2014 \u00f822" : "rod T22L42";
  contact.material = j == 1 ? "rubber" : "wood";
  return contact;
}

// Contacts of sample `index`: 3, 0 or 1 episodes for index % 3 = 0, 1, 2.
std::vector<ContactEpisode> MakeContacts(uint64_t index) {
  constexpr std::array<int, 3> kCounts = {3, 0, 1};
  std::vector<ContactEpisode> contacts;
  for (int j = 0; j < kCounts[index % 3]; ++j) contacts.push_back(MakeContact(index, j));
  return contacts;
}

// Deterministic content of sample `index` (contacts by MakeContacts, also when invalid); an
// invalid sample carries no audio or proprio.
StrikeSample MakeSample(uint64_t index, const DatasetInfo& info, bool valid = true,
                        const std::string& reason = "no_contact") {
  StrikeSample sample;
  sample.index = index;
  sample.seed = 1000 + 7 * index;
  sample.valid = valid;
  sample.label.z_m = 0.1 * static_cast<double>(index) - 0.05;
  sample.label.theta_rad = 0.3 * static_cast<double>(index) - 1.0;
  sample.label.point_m = Eigen::Vector3d(0.02, -0.01 * index, 0.1 * index);
  sample.label.normal = Eigen::Vector3d(0.6, 0.8, 0.0);
  sample.label.impulse_Ns = 0.01 * (index + 1);
  sample.label.time_s = 0.002 + 1e-4 * index;
  sample.label.normal_speed_m_s = 0.5 + 0.25 * index;
  sample.label.duration_s = 1e-4 * (index + 1);
  sample.contacts = MakeContacts(index);
  if (!valid) {
    sample.invalid_reason = reason;
    return sample;
  }
  sample.audio.resize(info.channels, info.audio_frames);
  for (int c = 0; c < info.channels; ++c) {
    for (int64_t t = 0; t < info.audio_frames; ++t) {
      sample.audio(c, t) = 0.8f * std::sin(0.1f * t * (c + 1) + index) / (1.0f + index);
    }
  }
  // Sample 0 exceeds full scale in one place (clamped to 1 in int16 files).
  if (index == 0) {
    sample.audio(0, 5) = 1.5f;
    sample.clipped = true;
  }
  sample.proprio.resize(info.proprio_rows, kProprioFeatures);
  for (int64_t r = 0; r < info.proprio_rows; ++r) {
    for (int j = 0; j < kProprioFeatures; ++j) {
      sample.proprio(r, j) = static_cast<float>(index) + 0.1f * r + 0.01f * j;
    }
  }
  return sample;
}

// Writes samples with the given indices; those in `invalid` are invalid.
void WriteDataset(const std::string& path, const DatasetInfo& info,
                  const std::vector<uint64_t>& indices, const std::vector<uint64_t>& invalid = {}) {
  DatasetWriter writer(path, info);
  for (uint64_t index : indices) {
    const bool valid = std::find(invalid.begin(), invalid.end(), index) == invalid.end();
    writer.Append(MakeSample(index, info, valid));
  }
  writer.Finish();
}

void ExpectLabelsEqual(const ContactLabel& a, const ContactLabel& b) {
  EXPECT_EQ(a.z_m, b.z_m);
  EXPECT_EQ(a.theta_rad, b.theta_rad);
  EXPECT_EQ(a.point_m, b.point_m);
  EXPECT_EQ(a.normal, b.normal);
  EXPECT_EQ(a.impulse_Ns, b.impulse_Ns);
  EXPECT_EQ(a.time_s, b.time_s);
  EXPECT_EQ(a.normal_speed_m_s, b.normal_speed_m_s);
  EXPECT_EQ(a.duration_s, b.duration_s);
}

// Every field of every episode equal, strings included.
void ExpectContactsEqual(const std::vector<ContactEpisode>& got,
                         const std::vector<ContactEpisode>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t j = 0; j < got.size(); ++j) {
    SCOPED_TRACE("contact " + std::to_string(j));
    EXPECT_EQ(got[j].time_s, want[j].time_s);
    EXPECT_EQ(got[j].duration_s, want[j].duration_s);
    EXPECT_EQ(got[j].z_m, want[j].z_m);
    EXPECT_EQ(got[j].theta_rad, want[j].theta_rad);
    EXPECT_EQ(got[j].point_m, want[j].point_m);
    EXPECT_EQ(got[j].normal, want[j].normal);
    EXPECT_EQ(got[j].normal_speed_m_s, want[j].normal_speed_m_s);
    EXPECT_EQ(got[j].effective_mass_kg, want[j].effective_mass_kg);
    EXPECT_EQ(got[j].impulse_Ns, want[j].impulse_Ns);
    EXPECT_EQ(got[j].peak_force_N, want[j].peak_force_N);
    EXPECT_EQ(got[j].kind, want[j].kind);
    EXPECT_EQ(got[j].object, want[j].object);
    EXPECT_EQ(got[j].material, want[j].material);
  }
}

// Reads back samples written by MakeSample and compares everything.
void ExpectRoundTrip(bool audio_int16) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(audio_int16);
  WriteDataset(path, info, {0, 1, 2}, {1});

  DatasetReader reader(path);
  EXPECT_EQ(reader.size(), 3);
  EXPECT_TRUE(reader.info().complete);
  EXPECT_EQ(reader.info().num_samples, 3);
  EXPECT_EQ(reader.info().source, "sim");
  EXPECT_EQ(reader.info().config_yaml, info.config_yaml);
  EXPECT_FALSE(reader.info().software_version.empty());
  EXPECT_EQ(reader.info().sample_rate_hz, 48000.0);
  EXPECT_EQ(reader.info().proprio_rate_hz, 200.0);
  EXPECT_EQ(reader.info().channels, 2);
  EXPECT_EQ(reader.info().audio_frames, 64);
  EXPECT_EQ(reader.info().proprio_rows, 3);
  EXPECT_EQ(reader.info().audio_int16, audio_int16);
  EXPECT_EQ(reader.info().global_seed, 42u);
  EXPECT_EQ(reader.info().shard, 0);
  EXPECT_EQ(reader.info().num_shards, 1);
  EXPECT_EQ(reader.info().schema_version, "1.1");

  const double tolerance = audio_int16 ? 1.0 / 32767.0 : 0.0;
  for (int64_t i = 0; i < 3; ++i) {
    const bool valid = i != 1;
    const StrikeSample expected = MakeSample(i, info, valid);
    const StrikeSample got = reader.Read(i);
    SCOPED_TRACE("sample " + std::to_string(i));
    EXPECT_EQ(got.index, static_cast<uint64_t>(i));
    EXPECT_EQ(got.seed, 1000u + 7u * i);
    EXPECT_EQ(got.valid, valid);
    EXPECT_EQ(got.invalid_reason, valid ? "" : "no_contact");
    EXPECT_EQ(got.clipped, i == 0);
    ExpectLabelsEqual(got.label, expected.label);
    // Samples 0, 1, 2 have 3, 0 and 1 contacts (the invalid one keeps its contacts too).
    EXPECT_EQ(got.contacts.size(), (std::array<size_t, 3>{3, 0, 1}[i]));
    ExpectContactsEqual(got.contacts, expected.contacts);
    ExpectContactsEqual(reader.ReadMeta(i).contacts, expected.contacts);
    ASSERT_EQ(got.audio.rows(), 2);
    ASSERT_EQ(got.audio.cols(), 64);
    ASSERT_EQ(got.proprio.rows(), 3);
    ASSERT_EQ(got.proprio.cols(), kProprioFeatures);
    if (!valid) {
      // Audio and proprio of an invalid sample without them are stored as zeros.
      EXPECT_EQ(got.audio.cwiseAbs().maxCoeff(), 0.0f);
      EXPECT_EQ(got.proprio.cwiseAbs().maxCoeff(), 0.0f);
      continue;
    }
    EXPECT_EQ(got.proprio, expected.proprio);
    for (int c = 0; c < 2; ++c) {
      for (int t = 0; t < 64; ++t) {
        const float want =
            audio_int16 ? std::clamp(expected.audio(c, t), -1.0f, 1.0f) : expected.audio(c, t);
        ASSERT_NEAR(got.audio(c, t), want, tolerance) << "channel " << c << " frame " << t;
      }
    }
    // ReadMeta gives the same labels without audio.
    const StrikeSample meta = reader.ReadMeta(i);
    EXPECT_EQ(meta.audio.size(), 0);
    ExpectLabelsEqual(meta.label, expected.label);
    EXPECT_EQ(meta.proprio, expected.proprio);
  }
  // The clipped value of sample 0 is full scale in an int16 file and kept in a float32 one.
  EXPECT_NEAR(reader.Read(0).audio(0, 5), audio_int16 ? 1.0f : 1.5f, 1e-6);
}

TEST(DatasetTest, RoundTripInt16) {
  ExpectRoundTrip(true);
}

TEST(DatasetTest, RoundTripFloat32) {
  ExpectRoundTrip(false);
}

TEST(DatasetTest, FinalNameAppearsOnlyAtFinish) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  DatasetWriter writer(path, info);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::exists(path + ".partial"));
  writer.Append(MakeSample(0, info));
  writer.Append(MakeSample(1, info));
  EXPECT_EQ(writer.count(), 2);
  EXPECT_FALSE(fs::exists(path));
  writer.Finish();
  EXPECT_TRUE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".partial"));
  EXPECT_EQ(DatasetReader(path).size(), 2);
}

TEST(DatasetTest, UnfinishedWriterLeavesOnlyRejectedPartial) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  {
    DatasetWriter writer(path, info);
    writer.Append(MakeSample(0, info));
    writer.Append(MakeSample(1, info, false, "penetration"));
  }
  const std::string partial = path + ".partial";
  EXPECT_FALSE(fs::exists(path));
  ASSERT_TRUE(fs::exists(partial));
  try {
    DatasetReader reader(partial);
    FAIL() << "an incomplete dataset was opened";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("incomplete dataset (no `complete` attribute)"),
              std::string::npos)
        << e.what();
  }
  DatasetReader reader(partial, /*allow_incomplete=*/true);
  EXPECT_FALSE(reader.info().complete);
  ASSERT_EQ(reader.size(), 2);
  EXPECT_EQ(reader.Read(1).invalid_reason, "penetration");
  EXPECT_EQ(reader.Read(0).label.z_m, MakeSample(0, info).label.z_m);

  // The summary works on the leftover too.
  const nlohmann::json summary = nlohmann::json::parse(SummarizeDatasetJson(partial));
  EXPECT_EQ(summary["complete"], false);
  EXPECT_EQ(summary["num_samples"], 2);
  EXPECT_EQ(summary["valid"], 1);
  EXPECT_EQ(summary["invalid_reasons"]["penetration"], 1);
}

TEST(DatasetTest, CompleteFileSurvivesUntilFinish) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  WriteDataset(path, info, {0, 1, 2});
  {
    // A second run over the same path that fails leaves the first file untouched.
    DatasetWriter writer(path, info);
    writer.Append(MakeSample(7, info));
  }
  EXPECT_EQ(DatasetReader(path).size(), 3);
  // A stale .partial is replaced by the next writer, which then replaces the file.
  WriteDataset(path, info, {7});
  DatasetReader reader(path);
  ASSERT_EQ(reader.size(), 1);
  EXPECT_EQ(reader.ReadMeta(0).index, 7u);
  EXPECT_FALSE(fs::exists(path + ".partial"));
}

TEST(DatasetTest, WriterRefusesMissingParentDirectory) {
  TempDir dir;
  const std::string path = dir.File("no_such_dir/strikes.h5");
  EXPECT_THROW(DatasetWriter(path, MakeInfo(true)), IoError);
  EXPECT_FALSE(fs::exists(path + ".partial"));
}

TEST(DatasetTest, AppendRefusesWrongShapesAndRepeatedIndex) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  DatasetWriter writer(dir.File("strikes.h5"), info);
  StrikeSample wrong_audio = MakeSample(0, info);
  wrong_audio.audio.resize(2, 63);
  EXPECT_THROW(writer.Append(wrong_audio), SchemaError);
  StrikeSample wrong_proprio = MakeSample(0, info);
  wrong_proprio.proprio.resize(4, kProprioFeatures);
  EXPECT_THROW(writer.Append(wrong_proprio), SchemaError);
  StrikeSample no_audio = MakeSample(0, info);
  no_audio.audio.resize(0, 0);
  EXPECT_THROW(writer.Append(no_audio), SchemaError);
  writer.Append(MakeSample(0, info));
  EXPECT_THROW(writer.Append(MakeSample(0, info)), SchemaError);
  EXPECT_EQ(writer.count(), 1);
}

// Encodes MakeSample(index) for every index; invalid indices carry no audio.
std::vector<DatasetWriter::EncodedSample> EncodeAll(const DatasetWriter& writer,
                                                    const DatasetInfo& info,
                                                    const std::vector<uint64_t>& indices,
                                                    const std::vector<uint64_t>& invalid = {}) {
  std::vector<DatasetWriter::EncodedSample> encoded;
  for (uint64_t index : indices) {
    const bool valid = std::find(invalid.begin(), invalid.end(), index) == invalid.end();
    encoded.push_back(writer.Encode(MakeSample(index, info, valid)));
  }
  return encoded;
}

TEST(DatasetTest, EncodedSamplesReadBackLikeAppendedOnes) {
  for (const bool audio_int16 : {true, false}) {
    SCOPED_TRACE(audio_int16 ? "int16" : "float32");
    TempDir dir;
    const DatasetInfo info = MakeInfo(audio_int16);
    const std::vector<uint64_t> indices = {0, 1, 2, 3};
    WriteDataset(dir.File("appended.h5"), info, indices, {2});
    {
      DatasetWriter writer(dir.File("encoded.h5"), info);
      for (const DatasetWriter::EncodedSample& sample : EncodeAll(writer, info, indices, {2})) {
        // The metadata travels without the audio, which the chunk now holds.
        EXPECT_EQ(sample.meta.audio.size(), 0);
        ExpectContactsEqual(sample.meta.contacts, MakeContacts(sample.meta.index));
        EXPECT_FALSE(sample.audio_chunk.empty());
        EXPECT_EQ(sample.filter_mask, 0u);
        writer.AppendEncoded(sample);
      }
      EXPECT_EQ(writer.count(), 4);
      writer.Finish();
    }
    DatasetReader appended(dir.File("appended.h5"));
    DatasetReader encoded(dir.File("encoded.h5"));
    ASSERT_EQ(encoded.size(), 4);
    for (int64_t i = 0; i < 4; ++i) {
      SCOPED_TRACE("sample " + std::to_string(i));
      const StrikeSample want = appended.Read(i);
      const StrikeSample got = encoded.Read(i);
      EXPECT_EQ(got.index, want.index);
      EXPECT_EQ(got.seed, want.seed);
      EXPECT_EQ(got.valid, want.valid);
      EXPECT_EQ(got.invalid_reason, want.invalid_reason);
      EXPECT_EQ(got.clipped, want.clipped);
      ExpectLabelsEqual(got.label, want.label);
      EXPECT_EQ(got.proprio, want.proprio);
      EXPECT_EQ(got.audio, want.audio);
      // Samples 0..3 have 3, 0, 1 and 3 contacts.
      ExpectContactsEqual(got.contacts, MakeContacts(i));
      ExpectContactsEqual(want.contacts, MakeContacts(i));
    }
    // And both hold what was written (up to int16 rounding).
    const double tolerance = audio_int16 ? 0.5 / 32767.0 + 1e-7 : 0.0;
    const Eigen::MatrixXf expected = MakeSample(3, info).audio;
    EXPECT_LE((encoded.Read(3).audio - expected).cwiseAbs().maxCoeff(), tolerance);
    EXPECT_EQ(encoded.Read(2).audio.cwiseAbs().maxCoeff(), 0.0f);
  }
}

TEST(DatasetTest, EncodeFromManyThreadsGivesTheSerialBytes) {
  for (const bool audio_int16 : {true, false}) {
    SCOPED_TRACE(audio_int16 ? "int16" : "float32");
    TempDir dir;
    DatasetInfo info = MakeInfo(audio_int16);
    info.channels = 3;
    info.audio_frames = 4000;
    DatasetWriter writer(dir.File("strikes.h5"), info);
    std::vector<uint64_t> indices;
    for (uint64_t i = 0; i < 24; ++i) indices.push_back(i);
    const std::vector<DatasetWriter::EncodedSample> serial =
        EncodeAll(writer, info, indices, {5, 17});

    // Four threads each encode every sample, in different orders, while the writer appends.
    constexpr int kThreads = 4;
    std::vector<std::vector<DatasetWriter::EncodedSample>> parallel(
        kThreads, std::vector<DatasetWriter::EncodedSample>(indices.size()));
    std::vector<std::thread> threads;
    // Steps coprime with 24 visit every sample once.
    constexpr std::array<size_t, kThreads> kSteps = {1, 5, 7, 11};
    for (int k = 0; k < kThreads; ++k) {
      threads.emplace_back([&, k] {
        for (size_t n = 0; n < indices.size(); ++n) {
          const size_t i = (n * kSteps[k] + k) % indices.size();
          const bool valid = i != 5 && i != 17;
          parallel[k][i] = writer.Encode(MakeSample(indices[i], info, valid));
        }
      });
    }
    for (const DatasetWriter::EncodedSample& sample : serial) writer.AppendEncoded(sample);
    for (std::thread& thread : threads) thread.join();

    for (int k = 0; k < kThreads; ++k) {
      for (size_t i = 0; i < indices.size(); ++i) {
        SCOPED_TRACE("thread " + std::to_string(k) + " sample " + std::to_string(i));
        EXPECT_EQ(parallel[k][i].audio_chunk, serial[i].audio_chunk);
        EXPECT_EQ(parallel[k][i].filter_mask, serial[i].filter_mask);
        EXPECT_EQ(parallel[k][i].meta.index, serial[i].meta.index);
        EXPECT_EQ(parallel[k][i].meta.proprio, serial[i].meta.proprio);
      }
    }
    // Different audio gives different chunks, and compressible audio a chunk below raw size.
    EXPECT_NE(serial[0].audio_chunk, serial[1].audio_chunk);
    const size_t raw_bytes = info.channels * info.audio_frames * (audio_int16 ? 2 : 4);
    EXPECT_LT(serial[5].audio_chunk.size(), raw_bytes / 10);  // all zeros
    writer.Finish();
    EXPECT_EQ(DatasetReader(dir.File("strikes.h5")).size(), 24);
  }
}

TEST(DatasetTest, EncodeAndAppendEncodedRefuseBadSamples) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  DatasetWriter writer(dir.File("strikes.h5"), info);
  StrikeSample wrong_audio = MakeSample(0, info);
  wrong_audio.audio.resize(3, 64);
  EXPECT_THROW(writer.Encode(wrong_audio), SchemaError);
  StrikeSample wrong_proprio = MakeSample(0, info);
  wrong_proprio.proprio.resize(3, kProprioFeatures + 1);
  EXPECT_THROW(writer.Encode(wrong_proprio), SchemaError);
  StrikeSample not_finite = MakeSample(0, info);
  not_finite.audio(1, 7) = std::nanf("");
  EXPECT_THROW(writer.Encode(not_finite), SchemaError);
  // Non-finite audio of an invalid sample is stored as zeros.
  not_finite.valid = false;
  EXPECT_NO_THROW(writer.Encode(not_finite));

  DatasetWriter::EncodedSample empty_chunk = writer.Encode(MakeSample(0, info));
  empty_chunk.audio_chunk.clear();
  EXPECT_THROW(writer.AppendEncoded(empty_chunk), SchemaError);
  DatasetWriter::EncodedSample bad_proprio = writer.Encode(MakeSample(0, info));
  bad_proprio.meta.proprio.resize(1, kProprioFeatures);
  EXPECT_THROW(writer.AppendEncoded(bad_proprio), SchemaError);
  EXPECT_EQ(writer.count(), 0);
  const DatasetWriter::EncodedSample sample = writer.Encode(MakeSample(0, info));
  writer.AppendEncoded(sample);
  EXPECT_THROW(writer.AppendEncoded(sample), SchemaError);
  EXPECT_THROW(writer.Append(MakeSample(0, info)), SchemaError);
  EXPECT_EQ(writer.count(), 1);
}

TEST(DatasetTest, ReaderErrors) {
  TempDir dir;
  // Missing file.
  try {
    DatasetReader reader(dir.File("missing.h5"));
    FAIL() << "a missing file was opened";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.h5: no such file"), std::string::npos)
        << e.what();
  }
  // A text file.
  const std::string text = dir.File("notes.h5");
  std::ofstream(text) << "these are not the strikes you are looking for\n";
  EXPECT_THROW(DatasetReader reader(text), IoError);
  // An HDF5 file of another kind.
  const std::string other = dir.File("other.h5");
  WriteArrayFile(other, "sonicboom.model", {{"w", {2}, {1.0f, 2.0f}}}, {});
  EXPECT_THROW(DatasetReader reader(other), SchemaError);
  // A dataset of another schema version.
  const std::string future = dir.File("future.h5");
  WriteArrayFile(future, kDatasetSchema, {{"w", {1}, {1.0f}}}, {{"schema_version", "9.0"}});
  try {
    DatasetReader reader(future);
    FAIL() << "a dataset of another schema version was opened";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("schema_version 9.0"), std::string::npos) << e.what();
  }
}

TEST(DatasetTest, ReadIsRangeChecked) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  WriteDataset(path, MakeInfo(true), {0, 1});
  DatasetReader reader(path);
  EXPECT_NO_THROW(reader.Read(1));
  EXPECT_THROW(reader.Read(2), IoError);
  EXPECT_THROW(reader.Read(-1), IoError);
  EXPECT_THROW(reader.ReadMeta(2), IoError);
}

TEST(DatasetTest, EmptyDatasetRoundTrips) {
  TempDir dir;
  const std::string path = dir.File("empty.h5");
  WriteDataset(path, MakeInfo(false), {});
  DatasetReader reader(path);
  EXPECT_EQ(reader.size(), 0);
  EXPECT_TRUE(reader.info().complete);
  const nlohmann::json summary = nlohmann::json::parse(SummarizeDatasetJson(path));
  EXPECT_EQ(summary["num_samples"], 0);
  EXPECT_TRUE(summary["z_m"]["min"].is_null());
}

// A fault while a dataset is open is put down to the file (libhdf5 over-reads damaged files
// until it faults: docs/robustness.md) and ends with exit status 1 naming it; once the file is
// closed, or when an invariant of ours fails, a fault keeps its default action.
TEST(DatasetFaultTest, AFaultWhileADatasetIsOpenNamesTheFile) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  TempDir dir;
  const std::string path = dir.File("open.h5");
  WriteDataset(path, MakeInfo(false), {0, 1});
  EXPECT_EXIT(
      {
        DatasetReader reader(path);
        std::raise(SIGSEGV);
      },
      ::testing::ExitedWithCode(1),
      "open.h5: reading the file crashed \\(segmentation fault\\): the file is corrupted");
  EXPECT_EXIT(
      {
        { DatasetReader reader(path); }
        std::raise(SIGSEGV);
      },
      ::testing::KilledBySignal(SIGSEGV), "");
  EXPECT_EXIT(
      {
        DatasetReader reader(path);
        SONICBOOM_DEMAND(reader.size() == 0);
      },
      ::testing::KilledBySignal(SIGABRT), "internal invariant failed");
}

TEST(DatasetTest, NoProprioRows) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  DatasetInfo info = MakeInfo(true);
  info.proprio_rows = 0;
  WriteDataset(path, info, {5, 6});
  DatasetReader reader(path);
  ASSERT_EQ(reader.size(), 2);
  EXPECT_EQ(reader.info().proprio_rows, 0);
  const StrikeSample sample = reader.Read(1);
  EXPECT_EQ(sample.index, 6u);
  EXPECT_EQ(sample.proprio.rows(), 0);
  EXPECT_EQ(sample.proprio.cols(), kProprioFeatures);
  EXPECT_NEAR(sample.audio(1, 3), MakeSample(6, info).audio(1, 3), 1.0 / 32767.0);
}

TEST(MergeTest, JoinsShardsInSampleIndexOrder) {
  TempDir dir;
  DatasetInfo info = MakeInfo(true);
  info.num_shards = 2;
  info.shard = 0;
  WriteDataset(dir.File("shard0.h5"), info, {0, 2, 4}, {2});
  info.shard = 1;
  WriteDataset(dir.File("shard1.h5"), info, {1, 3});
  const std::string out = dir.File("merged.h5");
  // Shard order on the command line does not matter.
  MergeDatasets({dir.File("shard1.h5"), dir.File("shard0.h5")}, out);

  DatasetReader reader(out);
  ASSERT_EQ(reader.size(), 5);
  EXPECT_TRUE(reader.info().complete);
  EXPECT_EQ(reader.info().shard, 0);
  EXPECT_EQ(reader.info().num_shards, 1);
  EXPECT_EQ(reader.info().global_seed, 42u);
  EXPECT_EQ(reader.info().config_yaml, info.config_yaml);
  DatasetReader shard0(dir.File("shard0.h5"));
  DatasetReader shard1(dir.File("shard1.h5"));
  for (int64_t i = 0; i < 5; ++i) {
    SCOPED_TRACE("sample " + std::to_string(i));
    const StrikeSample got = reader.Read(i);
    // Audio is carried over bit for bit from the shard that holds the sample.
    EXPECT_EQ(got.audio, (i % 2 == 0 ? shard0 : shard1).Read(i / 2).audio);
    const StrikeSample expected = MakeSample(i, info, i != 2);
    EXPECT_EQ(got.index, static_cast<uint64_t>(i));
    EXPECT_EQ(got.seed, expected.seed);
    EXPECT_EQ(got.valid, i != 2);
    ExpectLabelsEqual(got.label, expected.label);
    ExpectContactsEqual(got.contacts, expected.contacts);
    if (i != 2) {
      EXPECT_EQ(got.proprio, expected.proprio);
      EXPECT_NEAR(got.audio(1, 10), expected.audio(1, 10), 1.0 / 32767.0);
    }
  }
  // Offsets re-based onto the merged table: samples 0..4 have 3, 0, 1, 3, 0 contacts, while
  // shard 0 (0, 2, 4) stored them at rows 0, 3, 4 and shard 1 (1, 3) at rows 0, 0.
  EXPECT_EQ(ReadArray(dir.File("shard1.h5"), "index/contact_first").data,
            (std::vector<float>{0, 0}));
  EXPECT_EQ(ReadArray(out, "index/contact_first").data, (std::vector<float>{0, 3, 3, 4, 7}));
  EXPECT_EQ(ReadArray(out, "index/contact_count").data, (std::vector<float>{3, 0, 1, 3, 0}));
  EXPECT_EQ(ReadArray(out, "contacts/sample_row").data, (std::vector<float>{0, 0, 0, 2, 3, 3, 3}));
}

// A randomized dataset stores each sample's draws in /variation, named; merge carries them.
TEST(DatasetTest, VariationTableRoundTripsAndMerges) {
  TempDir dir;
  DatasetInfo info = MakeInfo(true);
  info.variation_names = {"youngs_modulus_scale", "sensitivity_scale_0", "sensitivity_scale_1"};
  info.num_shards = 2;
  const auto write = [&](const std::string& path, int shard, std::vector<uint64_t> indices) {
    info.shard = shard;
    DatasetWriter writer(path, info);
    for (const uint64_t i : indices) {
      StrikeSample s = MakeSample(i, info, i != 2);
      s.variation = {1.0 + 0.01 * i, 0.5 + i, 2.0 - 0.1 * i};
      writer.Append(s);
    }
    writer.Finish();
  };
  write(dir.File("s0.h5"), 0, {0, 2});
  write(dir.File("s1.h5"), 1, {1, 3});
  MergeDatasets({dir.File("s0.h5"), dir.File("s1.h5")}, dir.File("m.h5"));
  for (const std::string name : {"s1.h5", "m.h5"}) {
    SCOPED_TRACE(name);
    DatasetReader reader(dir.File(name));
    EXPECT_EQ(reader.info().variation_names, info.variation_names);
    for (int64_t row = 0; row < reader.size(); ++row) {
      const StrikeSample got = reader.ReadMeta(row);
      const double i = static_cast<double>(got.index);
      EXPECT_EQ(got.variation, (std::vector<double>{1.0 + 0.01 * i, 0.5 + i, 2.0 - 0.1 * i}));
    }
  }
  // a sample whose draws do not match the names, or are not finite, is refused
  DatasetWriter writer(dir.File("bad.h5"), info);
  StrikeSample s = MakeSample(0, info);
  s.variation = {1.0};
  EXPECT_THROW(writer.Append(s), SchemaError);
  s.variation = {1.0, NAN, 1.0};
  EXPECT_THROW(writer.Append(s), SchemaError);
  // a dataset without draws has no /variation and reads back none
  WriteDataset(dir.File("plain.h5"), MakeInfo(true), {0});
  DatasetReader plain(dir.File("plain.h5"));
  EXPECT_TRUE(plain.info().variation_names.empty());
  EXPECT_TRUE(plain.Read(0).variation.empty());
  EXPECT_ANY_THROW(ReadArray(dir.File("plain.h5"), "variation"));
  EXPECT_EQ(ReadArray(dir.File("m.h5"), "variation").data.size(), 12u);
}

TEST(MergeTest, RefusesDuplicateIndices) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  WriteDataset(dir.File("a.h5"), info, {0, 1, 2});
  WriteDataset(dir.File("b.h5"), info, {2, 3});
  const std::string out = dir.File("merged.h5");
  try {
    MergeDatasets({dir.File("a.h5"), dir.File("b.h5")}, out);
    FAIL() << "duplicate indices were merged";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("sample index 2"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(MergeTest, RefusesMismatchedConfigAndIncompleteShards) {
  TempDir dir;
  DatasetInfo info = MakeInfo(true);
  WriteDataset(dir.File("a.h5"), info, {0});
  info.config_yaml = "seed: 43\n";
  WriteDataset(dir.File("b.h5"), info, {1});
  EXPECT_THROW(MergeDatasets({dir.File("a.h5"), dir.File("b.h5")}, dir.File("m.h5")), SchemaError);
  EXPECT_FALSE(fs::exists(dir.File("m.h5")));

  // A shard whose run did not finish.
  info = MakeInfo(true);
  {
    DatasetWriter writer(dir.File("c.h5"), info);
    writer.Append(MakeSample(2, info));
  }
  EXPECT_THROW(MergeDatasets({dir.File("a.h5"), dir.File("c.h5.partial")}, dir.File("m.h5")),
               SchemaError);
  // Another audio shape.
  info.audio_frames = 32;
  WriteDataset(dir.File("d.h5"), info, {3});
  EXPECT_THROW(MergeDatasets({dir.File("a.h5"), dir.File("d.h5")}, dir.File("m.h5")), SchemaError);
}

TEST(SummaryTest, CountsValidAndInvalidWithReasons) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  {
    DatasetWriter writer(path, info);
    writer.Append(MakeSample(0, info));
    writer.Append(MakeSample(1, info, false, "no_contact"));
    writer.Append(MakeSample(2, info));
    writer.Append(MakeSample(3, info, false, "no_contact"));
    writer.Append(MakeSample(4, info, false, "penetration"));
    // reasons differing only in their numbers count together
    writer.Append(MakeSample(5, info, false, "penetration 1.0219 mm at t = 0.4585 s (limit 1e-3)"));
    writer.Append(MakeSample(6, info, false, "penetration 2.5 mm at t = -0.25 s (limit 1e-3)"));
    writer.Finish();
  }
  const nlohmann::json summary = nlohmann::json::parse(SummarizeDatasetJson(path));
  EXPECT_EQ(summary["invalid_reasons"]["penetration # mm at t = # s (limit #)"], 2)
      << summary["invalid_reasons"];
  EXPECT_EQ(summary["file"], path);
  EXPECT_EQ(summary["kind"], "dataset");
  EXPECT_EQ(summary["schema_version"], kDatasetSchemaVersion);
  EXPECT_EQ(summary["complete"], true);
  EXPECT_EQ(summary["source"], "sim");
  EXPECT_EQ(summary["num_samples"], 7);
  EXPECT_EQ(summary["valid"], 2);
  EXPECT_EQ(summary["invalid"], 5);
  EXPECT_EQ(summary["invalid_reasons"].size(), 3u);
  EXPECT_EQ(summary["invalid_reasons"]["no_contact"], 2);
  EXPECT_EQ(summary["invalid_reasons"]["penetration"], 1);
  EXPECT_EQ(summary["clipped"], 1);
  EXPECT_EQ(summary["channels"], 2);
  EXPECT_EQ(summary["audio_frames"], 64);
  EXPECT_EQ(summary["sample_rate_hz"], 48000.0);
  EXPECT_EQ(summary["proprio_rows"], 3);
  EXPECT_EQ(summary["shard"], 0);
  EXPECT_EQ(summary["num_shards"], 1);
  EXPECT_EQ(summary["global_seed"], 42);
  // Label ranges over the valid samples 0 and 2 only.
  const StrikeSample s0 = MakeSample(0, info);
  const StrikeSample s2 = MakeSample(2, info);
  EXPECT_DOUBLE_EQ(summary["z_m"]["min"].get<double>(), s0.label.z_m);
  EXPECT_DOUBLE_EQ(summary["z_m"]["max"].get<double>(), s2.label.z_m);
  EXPECT_DOUBLE_EQ(summary["z_m"]["mean"].get<double>(), 0.5 * (s0.label.z_m + s2.label.z_m));
  EXPECT_DOUBLE_EQ(summary["theta_rad"]["max"].get<double>(), s2.label.theta_rad);
  EXPECT_DOUBLE_EQ(summary["impulse_Ns"]["min"].get<double>(), s0.label.impulse_Ns);
  EXPECT_DOUBLE_EQ(summary["normal_speed_m_s"]["max"].get<double>(), s2.label.normal_speed_m_s);
  // Sample 0 peaks at full scale (clamped), sample 2 below 0.8 / 3.
  EXPECT_NEAR(summary["audio_peak"]["max"].get<double>(), 1.0, 1e-6);
  EXPECT_NEAR(summary["audio_peak"]["min"].get<double>(), s2.audio.cwiseAbs().maxCoeff(),
              1.0 / 32767.0);
}

// One contact with the fields the summary looks at.
ContactEpisode SummaryContact(double z_m, double theta_rad, ContactEpisode::Kind kind,
                              const std::string& object) {
  ContactEpisode contact;
  contact.z_m = z_m;
  contact.theta_rad = theta_rad;
  contact.kind = kind;
  contact.object = object;
  return contact;
}

TEST(SummaryTest, CountsContactsByKindAndObjectAndFirstContactCoverage) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  using Kind = ContactEpisode::Kind;
  using sonicboom::kPi;
  std::vector<StrikeSample> samples;
  for (uint64_t i = 0; i < 6; ++i) samples.push_back(MakeSample(i, info, i != 1, "penetration"));
  // Valid 0: first contact in z bin 0, theta 0.5 rad = 28.6 deg in bin (0, 60].
  samples[0].contacts = {SummaryContact(-0.09, 0.5, Kind::kImpact, "rod A"),
                         SummaryContact(0.0, 0.0, Kind::kBounce, "rod A"),
                         SummaryContact(0.1, -1.0, Kind::kPress, "rod B")};
  // Invalid 1: not counted.
  samples[1].contacts = {SummaryContact(0.0, 0.0, Kind::kPress, "ignored"),
                         SummaryContact(0.0, 0.0, Kind::kPress, "ignored")};
  // Valid 2: no contacts.
  samples[2].contacts.clear();
  // Valid 3: z at the upper edge (last bin is closed), theta = pi (180 deg, last bin).
  samples[3].contacts = {SummaryContact(0.1015, kPi, Kind::kImpact, "rod A")};
  // Valid 4: z beyond the tube: outside the coverage grid.
  samples[4].contacts = {SummaryContact(0.2, 0.0, Kind::kBounce, "rod B")};
  // Valid 5: z = 0 (middle bin), theta = -pi wraps to 180 deg; no object name.
  samples[5].contacts = {SummaryContact(0.0, -kPi, Kind::kImpact, "")};
  {
    DatasetWriter writer(path, info);
    for (const StrikeSample& sample : samples) writer.Append(sample);
    writer.Finish();
  }

  const nlohmann::json summary = nlohmann::json::parse(SummarizeDatasetJson(path));
  const nlohmann::json& contacts = summary["contacts"];
  EXPECT_EQ(contacts["recorded"], true);
  EXPECT_EQ(contacts["total"], 6);
  EXPECT_EQ(contacts["per_sample"]["min"], 0);
  EXPECT_EQ(contacts["per_sample"]["max"], 3);
  EXPECT_DOUBLE_EQ(contacts["per_sample"]["mean"].get<double>(), 6.0 / 5.0);
  EXPECT_EQ(contacts["kinds"],
            nlohmann::json({{"impact", 3}, {"bounce", 2}, {"press", 1}, {"brush", 0}}));
  EXPECT_EQ(contacts["objects"], nlohmann::json({{"rod A", 3}, {"rod B", 2}, {"(unnamed)", 1}}));
  const nlohmann::json& coverage = contacts["coverage"];
  EXPECT_EQ(coverage["z_bins_m"],
            nlohmann::json({-0.1015, -0.0609, -0.0203, 0.0203, 0.0609, 0.1015}));
  EXPECT_EQ(coverage["theta_bins_deg"],
            nlohmann::json({-180.0, -120.0, -60.0, 0.0, 60.0, 120.0, 180.0}));
  // Rows are z bins, columns theta bins.
  std::vector<std::vector<int>> want(5, std::vector<int>(6, 0));
  want[0][3] = 1;  // sample 0
  want[4][5] = 1;  // sample 3
  want[2][5] = 1;  // sample 5
  EXPECT_EQ(coverage["counts"], nlohmann::json(want));
  EXPECT_EQ(coverage["outside"], 1);
}

TEST(DatasetTest, RefusesUnknownContactKind) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  DatasetWriter writer(dir.File("strikes.h5"), info);
  StrikeSample sample = MakeSample(0, info);
  sample.contacts[1].kind = static_cast<ContactEpisode::Kind>(4);  // 0..3 are named
  EXPECT_THROW(writer.Append(sample), SchemaError);
  EXPECT_THROW(writer.Encode(sample), SchemaError);
  EXPECT_EQ(writer.count(), 0);
}

TEST(ArrayFileTest, RoundTripAndSummary) {
  TempDir dir;
  const std::string path = dir.File("model.h5");
  const std::string long_text(300, 'x');
  WriteArrayFile(path, "sonicboom.test",
                 {{"encoder/weight", {2, 3}, {1, 2, 3, 4, 5, 6}},
                  {"bias", {3}, {-1.5f, 0.0f, 2.25f}},
                  {"scale", {}, {0.5f}}},
                 {{"note", "hello"}, {"config_yaml", long_text}});
  EXPECT_FALSE(fs::exists(path + ".partial"));

  const NamedArray weight = ReadArray(path, "encoder/weight");
  EXPECT_EQ(weight.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(weight.data, (std::vector<float>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(ReadArray(path, "bias").data, (std::vector<float>{-1.5f, 0.0f, 2.25f}));
  const NamedArray scale = ReadArray(path, "scale");
  EXPECT_TRUE(scale.shape.empty());
  EXPECT_EQ(scale.data, std::vector<float>{0.5f});
  EXPECT_EQ(ReadStringAttr(path, "note"), "hello");
  EXPECT_EQ(ReadStringAttr(path, "schema"), "sonicboom.test");
  EXPECT_EQ(ReadStringAttr(path, "config_yaml"), long_text);
  EXPECT_TRUE(IsHdf5File(path));
  EXPECT_THROW(ReadArray(path, "encoder/missing"), IoError);
  EXPECT_THROW(ReadArray(path, "decoder/weight"), IoError);
  EXPECT_THROW(ReadStringAttr(path, "missing"), IoError);
  EXPECT_THROW(ReadArray(dir.File("missing.h5"), "bias"), IoError);

  const nlohmann::json summary = nlohmann::json::parse(SummarizeH5Json(path));
  EXPECT_EQ(summary["kind"], "hdf5");
  EXPECT_EQ(summary["schema"], "sonicboom.test");
  EXPECT_EQ(summary["complete"], true);
  EXPECT_EQ(summary["attrs"]["note"], "hello");
  EXPECT_EQ(summary["attrs"]["config_yaml"]["length"], 300);
  ASSERT_EQ(summary["arrays"].size(), 3u);
  bool found_weight = false;
  for (const nlohmann::json& array : summary["arrays"]) {
    if (array["name"] == "/encoder/weight") {
      found_weight = true;
      EXPECT_EQ(array["shape"], nlohmann::json::array({2, 3}));
      EXPECT_EQ(array["dtype"], "float32");
    }
  }
  EXPECT_TRUE(found_weight);
}

TEST(ArrayFileTest, RefusesBadInputAndIncompleteFiles) {
  TempDir dir;
  EXPECT_THROW(WriteArrayFile(dir.File("a.h5"), "s", {{"w", {2, 2}, {1, 2, 3}}}, {}), IoError);
  EXPECT_THROW(WriteArrayFile(dir.File("a.h5"), "s", {{"w", {1}, {1}}, {"w", {1}, {2}}}, {}),
               IoError);
  EXPECT_THROW(WriteArrayFile(dir.File("nodir/a.h5"), "s", {{"w", {1}, {1}}}, {}), IoError);
  EXPECT_FALSE(fs::exists(dir.File("a.h5")));
  // An unfinished dataset is an incomplete HDF5 file.
  const DatasetInfo info = MakeInfo(true);
  { DatasetWriter writer(dir.File("d.h5"), info); }
  EXPECT_THROW(ReadArray(dir.File("d.h5.partial"), "audio"), SchemaError);
  const nlohmann::json summary = nlohmann::json::parse(SummarizeH5Json(dir.File("d.h5.partial")));
  EXPECT_EQ(summary["complete"], false);
  EXPECT_EQ(summary["schema"], kDatasetSchema);
}

// Runs `argv` (no shell) and returns its standard output and error, the exit status in *status.
std::string RunCommand(const std::vector<std::string>& argv, int* status) {
  const sonicboom::testing::CliRun run = sonicboom::testing::RunProgram(argv, "");
  *status = run.exit_code;
  return run.out + run.err;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Checksum of stored audio values in (N, C, T) order: the sum of value * (2 k + 1) modulo 2^64
// over the k-th value, where an int16 value counts as its sign-extended 64-bit pattern and a
// float32 value as its 32-bit pattern. `audio` holds (C x T) full-scale records; `int16_scaled`:
// the values were read back from int16 storage (stored / 32767), else they are written values
// that int16 storage clamps and rounds.
uint64_t StoredAudioChecksum(const std::vector<Eigen::MatrixXf>& audio, bool audio_int16,
                             bool int16_scaled) {
  uint64_t checksum = 0;
  uint64_t k = 0;
  for (const Eigen::MatrixXf& record : audio) {
    for (int64_t c = 0; c < record.rows(); ++c) {
      for (int64_t t = 0; t < record.cols(); ++t, ++k) {
        const double x = record(c, t);
        uint64_t value = 0;
        if (audio_int16) {
          const int64_t pcm = int16_scaled ? std::lround(x * 32767.0)
                                           : std::lround(std::clamp(x, -1.0, 1.0) * 32767.0);
          value = static_cast<uint64_t>(pcm);
        } else {
          uint32_t bits = 0;
          const float f = record(c, t);
          std::memcpy(&bits, &f, sizeof(bits));
          value = bits;
        }
        checksum += value * (2 * k + 1);
      }
    }
  }
  return checksum;
}

// Reads /audio of argv[1] with h5py and prints the checksum of StoredAudioChecksum; stores the
// expected values (argv[3]: raw little-endian values of the file's dtype, shape as /audio)
// through HDF5's own shuffle + deflate (level 1) filters in argv[2] and compares the stored
// chunks of both files byte for byte.
constexpr const char* kCompareChunksPy = R"py(
import sys
import h5py
import numpy as np

with h5py.File(sys.argv[1], "r") as f:
    audio = f["audio"]
    data = audio[...]
    expected = np.fromfile(sys.argv[3], dtype=data.dtype.newbyteorder("<")).reshape(data.shape)
    if data.dtype == np.int16:
        values = data.astype(np.int64).view(np.uint64).ravel()
    else:
        values = data.view(np.uint32).astype(np.uint64).ravel()
    weights = np.arange(values.size, dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    checksum = int((values * weights).sum(dtype=np.uint64))
    with h5py.File(sys.argv[2], "w") as g:
        ref = g.create_dataset("audio", data=expected, chunks=(1,) + data.shape[1:],
                               maxshape=(None,) + data.shape[1:], shuffle=True,
                               compression="gzip", compression_opts=1)
        equal = 0
        for n in range(data.shape[0]):
            mask_a, chunk_a = audio.id.read_direct_chunk((n, 0, 0))
            mask_b, chunk_b = ref.id.read_direct_chunk((n, 0, 0))
            equal += int(mask_a == mask_b and chunk_a == chunk_b)
    print(f"dtype={data.dtype} rows={data.shape[0]} shuffle={audio.shuffle} "
          f"compression={audio.compression} level={audio.compression_opts} "
          f"equal_values={np.array_equal(data, expected)} equal_chunks={equal} "
          f"checksum={checksum}")
)py";

TEST(H5pyTest, EncodedChunksMatchHdf5FilterPipeline) {
  for (const bool audio_int16 : {true, false}) {
    SCOPED_TRACE(audio_int16 ? "int16" : "float32");
    TempDir dir;
    // The shape `sonicboom generate` writes: 6 channels of 2 s at 44.1 kHz.
    DatasetInfo info = MakeInfo(audio_int16);
    info.channels = 6;
    info.audio_frames = 88200;
    const std::string path = dir.File("strikes.h5");
    {
      DatasetWriter writer(path, info);
      for (const DatasetWriter::EncodedSample& sample : EncodeAll(writer, info, {0, 1, 2}, {1})) {
        writer.AppendEncoded(sample);
      }
      writer.Finish();
    }
    // What was written (sample 1 is invalid: zeros), and what the C++ reader reads back.
    std::vector<Eigen::MatrixXf> written, read;
    DatasetReader reader(path);
    for (uint64_t i = 0; i < 3; ++i) {
      written.push_back(i == 1 ? Eigen::MatrixXf::Zero(info.channels, info.audio_frames)
                               : MakeSample(i, info).audio);
      read.push_back(reader.Read(static_cast<int64_t>(i)).audio);
    }
    const uint64_t written_checksum = StoredAudioChecksum(written, audio_int16, false);
    const uint64_t read_checksum = StoredAudioChecksum(read, audio_int16, true);
    EXPECT_EQ(read_checksum, written_checksum);
    // The written values as the file should store them, raw little endian (x86), for h5py.
    const std::string expected_path = dir.File("expected.raw");
    {
      std::ofstream raw(expected_path, std::ios::binary);
      for (const Eigen::MatrixXf& record : written) {
        for (int64_t c = 0; c < record.rows(); ++c) {
          for (int64_t t = 0; t < record.cols(); ++t) {
            if (audio_int16) {
              const auto pcm = static_cast<int16_t>(
                  std::lround(std::clamp(static_cast<double>(record(c, t)), -1.0, 1.0) * 32767.0));
              raw.write(reinterpret_cast<const char*>(&pcm), sizeof(pcm));
            } else {
              const float x = record(c, t);
              raw.write(reinterpret_cast<const char*>(&x), sizeof(x));
            }
          }
        }
      }
    }
    const std::string script = dir.File("compare_chunks.py");
    std::ofstream(script) << kCompareChunksPy;
    int status = -1;
    const std::string output =
        RunCommand({"/usr/bin/python3", script, path, dir.File("ref.h5"), expected_path}, &status);
    ASSERT_EQ(status, 0) << output;
    const std::string dtype = audio_int16 ? "int16" : "float32";
    EXPECT_NE(output.find("dtype=" + dtype +
                          " rows=3 shuffle=True compression=gzip level=1 "
                          "equal_values=True equal_chunks=3 "),
              std::string::npos)
        << output;
    // h5py, through HDF5's filters, decodes the values that were written.
    EXPECT_NE(output.find("checksum=" + std::to_string(written_checksum) + "\n"), std::string::npos)
        << output << "written checksum " << written_checksum;
  }
}

// Edits a dataset file in place with h5py: argv[1] "downgrade" turns a 1.1 file into a 1.0 one
// (no contact table, schema_version "1.0"); "wrong_owner" points sample row 2 at sample 0's
// first contact; "past_end" gives sample row 0 more contacts than the table holds;
// "infinite_theta" sets sample row 1's theta label to +inf.
constexpr const char* kEditDatasetPy = R"py(
import sys
import h5py

mode, path = sys.argv[1], sys.argv[2]
with h5py.File(path, "r+") as f:
    if mode == "downgrade":
        del f["contacts"]
        del f["index/contact_first"]
        del f["index/contact_count"]
        f.attrs["schema_version"] = "1.0"
    elif mode == "wrong_owner":
        f["index/contact_first"][2] = 0
    elif mode == "past_end":
        f["index/contact_count"][0] = 99
    elif mode == "infinite_theta":
        f["label/theta_rad"][1] = float("inf")
    else:
        sys.exit("unknown mode " + mode)
print("edited", mode)
)py";

// Runs kEditDatasetPy on `path`.
void EditDataset(const TempDir& dir, const std::string& mode, const std::string& path) {
  const std::string script = dir.File("edit_dataset.py");
  std::ofstream(script) << kEditDatasetPy;
  int status = -1;
  const std::string output =
      RunCommand({"/usr/bin/python3", script, mode, path}, &status);
  ASSERT_EQ(status, 0) << output;
  ASSERT_NE(output.find("edited " + mode), std::string::npos) << output;
}

// An infinite label is refused where it is written and where it is read (eval once aborted on
// one); NaN stays the mark of an unknown label.
TEST(H5pyTest, InfiniteLabelsAreRefusedOnWriteAndOnRead) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  {
    DatasetWriter writer(dir.File("w.h5"), info);
    StrikeSample infinite = MakeSample(0, info);
    infinite.label.theta_rad = std::numeric_limits<double>::infinity();
    try {
      writer.Append(infinite);
      ADD_FAILURE() << "an infinite label was written";
    } catch (const SchemaError& e) {
      EXPECT_NE(std::string(e.what()).find("sample 0: label label/theta_rad is infinite"),
                std::string::npos)
          << e.what();
    }
    StrikeSample unknown = MakeSample(1, info);
    unknown.label.z_m = std::numeric_limits<double>::quiet_NaN();
    EXPECT_NO_THROW(writer.Append(unknown));
  }
  const std::string path = dir.File("edited.h5");
  WriteDataset(path, info, {0, 1, 2});
  EditDataset(dir, "infinite_theta", path);
  DatasetReader reader(path);
  EXPECT_NO_THROW(reader.ReadMeta(0));
  try {
    reader.ReadMeta(1);
    ADD_FAILURE() << "an infinite label was read";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("edited.h5: /label/theta_rad of sample row 1 is infinite"),
              std::string::npos)
        << e.what();
  }
}

TEST(H5pyTest, Version10FilesReadWithoutContacts) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  const std::string old_a = dir.File("old_a.h5");
  const std::string old_b = dir.File("old_b.h5");
  WriteDataset(old_a, info, {0, 2}, {2});
  WriteDataset(old_b, info, {1, 3});
  EditDataset(dir, "downgrade", old_a);
  EditDataset(dir, "downgrade", old_b);

  // The reader accepts 1.0 and reports no contacts; everything else is there.
  DatasetReader reader(old_a);
  EXPECT_EQ(reader.info().schema_version, "1.0");
  ASSERT_EQ(reader.size(), 2);
  const StrikeSample sample = reader.Read(0);
  EXPECT_TRUE(sample.contacts.empty());
  EXPECT_TRUE(reader.ReadMeta(1).contacts.empty());
  ExpectLabelsEqual(sample.label, MakeSample(0, info).label);
  EXPECT_EQ(sample.proprio, MakeSample(0, info).proprio);

  // The summary says contacts were not recorded.
  const nlohmann::json summary = nlohmann::json::parse(SummarizeDatasetJson(old_a));
  EXPECT_EQ(summary["schema_version"], "1.0");
  EXPECT_EQ(summary["contacts"]["recorded"], false);
  EXPECT_EQ(summary["contacts"]["total"], 0);
  EXPECT_EQ(summary["contacts"]["per_sample"]["max"], 0);
  EXPECT_EQ(summary["contacts"]["coverage"]["outside"], 0);

  // Merging 1.0 shards gives a 1.0 file without a contact table.
  const std::string merged = dir.File("merged_old.h5");
  MergeDatasets({old_b, old_a}, merged);
  DatasetReader merged_reader(merged);
  EXPECT_EQ(merged_reader.info().schema_version, "1.0");
  ASSERT_EQ(merged_reader.size(), 4);
  for (int64_t i = 0; i < 4; ++i) {
    EXPECT_EQ(merged_reader.ReadMeta(i).index, static_cast<uint64_t>(i));
    EXPECT_TRUE(merged_reader.Read(i).contacts.empty());
  }
  EXPECT_THROW(ReadArray(merged, "index/contact_first"), IoError);

  // Mixing 1.0 and 1.1 shards is refused, naming both versions.
  const std::string current = dir.File("current.h5");
  WriteDataset(current, info, {4});
  const std::string mixed = dir.File("mixed.h5");
  try {
    MergeDatasets({current, old_a}, mixed);
    FAIL() << "shards of schema 1.0 and 1.1 were merged";
  } catch (const SchemaError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("schema_version 1.0"), std::string::npos) << message;
    EXPECT_NE(message.find("has 1.1"), std::string::npos) << message;
  }
  EXPECT_FALSE(fs::exists(mixed));
}

TEST(H5pyTest, ReaderRefusesBrokenContactOffsets) {
  TempDir dir;
  const DatasetInfo info = MakeInfo(true);
  // Samples 0, 1, 2, 3 own contact rows [0, 3), [3, 3), [3, 4), [4, 7); sample 2 is pointed at
  // row 0 (the table still ends with sample 3's contacts, so the file opens).
  const std::string wrong_owner = dir.File("wrong_owner.h5");
  WriteDataset(wrong_owner, info, {0, 1, 2, 3});
  EditDataset(dir, "wrong_owner", wrong_owner);
  DatasetReader reader(wrong_owner);
  EXPECT_EQ(reader.Read(0).contacts.size(), 3u);
  EXPECT_EQ(reader.Read(3).contacts.size(), 3u);
  try {
    reader.Read(2);
    FAIL() << "contacts of another sample were read";
  } catch (const SchemaError& e) {
    EXPECT_NE(std::string(e.what()).find("belongs to sample row 0"), std::string::npos) << e.what();
  }
  const std::string past_end = dir.File("past_end.h5");
  WriteDataset(past_end, info, {0, 1, 2});
  EditDataset(dir, "past_end", past_end);
  EXPECT_THROW(DatasetReader(past_end).ReadMeta(0), SchemaError);
  EXPECT_THROW(SummarizeDatasetJson(past_end), SchemaError);
}

// Prints dtype, shape, chunks and maxshape of every contact dataset and the stored values of a
// small file, as h5py sees them.
constexpr const char* kContactLayoutPy = R"py(
import sys
import h5py

with h5py.File(sys.argv[1], "r") as f:
    print("version", f.attrs["schema_version"])
    names = ["index/contact_first", "index/contact_count", "contacts/sample_row",
             "contacts/time_s", "contacts/duration_s", "contacts/z_m", "contacts/theta_rad",
             "contacts/normal_speed_m_s", "contacts/effective_mass_kg", "contacts/impulse_Ns",
             "contacts/peak_force_N", "contacts/point_m", "contacts/normal", "contacts/kind",
             "contacts/object", "contacts/material"]
    for name in names:
        d = f[name]
        kind = "string" if h5py.check_string_dtype(d.dtype) else str(d.dtype)
        print(name, kind, d.shape, d.chunks, d.maxshape)
    print("first", f["index/contact_first"][:].tolist())
    print("count", f["index/contact_count"][:].tolist())
    print("sample_row", f["contacts/sample_row"][:].tolist())
    print("kind", f["contacts/kind"][:].tolist(), f["contacts/kind"].attrs["names"])
    print("object", f["contacts/object"].asstr()[:].tolist())
    print("material", f["contacts/material"].asstr()[:].tolist())
    print("utf8", h5py.check_string_dtype(f["contacts/object"].dtype).encoding)
)py";

TEST(H5pyTest, ContactTableLayout) {
  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  // Samples 0, 1, 2, 3 have 3, 0, 1, 3 contacts.
  WriteDataset(path, MakeInfo(true), {0, 1, 2, 3});
  const std::string script = dir.File("layout.py");
  std::ofstream(script) << kContactLayoutPy;
  int status = -1;
  const std::string output = RunCommand({"/usr/bin/python3", script, path}, &status);
  ASSERT_EQ(status, 0) << output;
  const std::vector<std::string> want = {
      "version 1.1\n",
      "index/contact_first int64 (4,) (1024,) (None,)\n",
      "index/contact_count int64 (4,) (1024,) (None,)\n",
      "contacts/sample_row int64 (7,) (1024,) (None,)\n",
      "contacts/time_s float64 (7,) (1024,) (None,)\n",
      "contacts/peak_force_N float64 (7,) (1024,) (None,)\n",
      "contacts/point_m float64 (7, 3) (1024, 3) (None, 3)\n",
      "contacts/normal float64 (7, 3) (1024, 3) (None, 3)\n",
      "contacts/kind uint8 (7,) (1024,) (None,)\n",
      "contacts/object string (7,) (1024,) (None,)\n",
      "contacts/material string (7,) (1024,) (None,)\n",
      "first [0, 3, 3, 4]\n",
      "count [3, 0, 1, 3]\n",
      "sample_row [0, 0, 0, 2, 3, 3, 3]\n",
      "kind [0, 1, 2, 0, 0, 1, 2] impact,bounce,press,brush\n",
      "object ['rod T22L42', 'rod T22L42', 'rod T22L42 \u2014 \u00f822', 'rod T22L42', "
      "'rod T22L42', 'rod T22L42', 'rod T22L42 \u2014 \u00f822']\n",
      "material ['wood', 'rubber', 'wood', 'wood', 'wood', 'rubber', 'wood']\n",
      "utf8 utf-8\n"};
  for (const std::string& line : want) {
    EXPECT_NE(output.find(line), std::string::npos) << "missing: " << line << output;
  }
}

TEST(H5pyTest, DocumentedExampleReadsDataset) {
  const std::string script =
      std::string(SONICBOOM_SOURCE_DIR) + "/scripts/examples/read_dataset.py";
  const std::string docs = std::string(SONICBOOM_SOURCE_DIR) + "/docs/dataset.md";
  // docs/dataset.md shows the script verbatim.
  const std::string script_text = ReadText(script);
  ASSERT_FALSE(script_text.empty()) << script;
  EXPECT_NE(ReadText(docs).find(script_text), std::string::npos)
      << docs << " does not contain " << script << " verbatim";

  TempDir dir;
  const std::string path = dir.File("strikes.h5");
  const DatasetInfo info = MakeInfo(true);
  WriteDataset(path, info, {0, 1, 2}, {1});
  int status = -1;
  const std::string output = RunCommand({"/usr/bin/python3", script, path}, &status);
  ASSERT_EQ(status, 0) << output;
  EXPECT_NE(output.find("samples: 3 valid: 2 channels: 2 frames: 64 sample_rate_hz: 48000 "
                        "proprio_rows: 3"),
            std::string::npos)
      << output;
  // First label z_m = -0.05, theta_rad = -1; sample 0 peaks at full scale.
  EXPECT_NE(output.find("first: index=0 z_m=-0.050000 theta_rad=-1.000000"), std::string::npos)
      << output;
  EXPECT_NE(output.find("valid=True peak=1.0000"), std::string::npos) << output;
  EXPECT_NE(output.find("invalid: index=1 reason=no_contact"), std::string::npos) << output;
  // Samples 0, 1, 2 have 3, 0, 1 contacts; the first sample's are printed in time order.
  EXPECT_NE(output.find("contacts: total=4 first sample: 3\n"), std::string::npos) << output;
  EXPECT_NE(output.find("  contact: kind=impact time_s=0.002000 z_m=-0.090000 "
                        "theta_rad=-2.500000 impulse_Ns=0.020000 object=rod T22L42 "
                        "material=wood\n  contact: kind=bounce time_s=0.012000 z_m=-0.020000 "
                        "theta_rad=-0.800000 impulse_Ns=0.010000 object=rod T22L42 "
                        "material=rubber\n  contact: kind=press time_s=0.022000 z_m=0.050000 "
                        "theta_rad=0.900000 impulse_Ns=0.006667 "
                        "object=rod T22L42 \u2014 \u00f822 material=wood\n"),
            std::string::npos)
      << output;

  // A 1.0 file has no contacts to print.
  EditDataset(dir, "downgrade", path);
  const std::string old_output = RunCommand({"/usr/bin/python3", script, path}, &status);
  ASSERT_EQ(status, 0) << old_output;
  EXPECT_NE(old_output.find("first: index=0 z_m=-0.050000"), std::string::npos) << old_output;
  EXPECT_NE(old_output.find("contacts: not recorded (schema_version 1.0)"), std::string::npos)
      << old_output;

  // The script refuses an unfinished file.
  { DatasetWriter writer(dir.File("partial.h5"), info); }
  RunCommand({"/usr/bin/python3", script, dir.File("partial.h5.partial")}, &status);
  EXPECT_NE(status, 0);
}

}  // namespace
}  // namespace sonicboom
