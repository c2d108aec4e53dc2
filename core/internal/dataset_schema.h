#pragma once
// The dataset file's schema as code: column paths, the label and contact field tables, the open
// column handles, and whole-column reads (docs/dataset.md). Private to core; HDF5 stays here.

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "internal/h5util.h"
#include "sonicboom/core/dataset.h"

namespace sonicboom::internal::dataset {

namespace h5 = internal::h5;

// Dataset paths below the root.
constexpr const char* kAudioPath = "audio";
// attribute of a virtual /audio (merge --virtual): "source path\tshard identity" per line
constexpr const char* kShardIdentitiesAttr = "shard_identities";
constexpr const char* kProprioPath = "proprio";
constexpr const char* kSampleIndexPath = "index/sample_index";
constexpr const char* kSeedPath = "index/seed";
constexpr const char* kValidPath = "index/valid";
constexpr const char* kInvalidReasonPath = "index/invalid_reason";
constexpr const char* kClippedPath = "index/clipped";
constexpr const char* kProvenancePath = "index/provenance";  // recorded datasets only
constexpr const char* kVariationPath = "variation";          // (N, P) f64, attr `names`
constexpr const char* kContactFirstPath = "index/contact_first";
constexpr const char* kContactCountPath = "index/contact_count";
constexpr const char* kContactSampleRowPath = "contacts/sample_row";
constexpr const char* kContactKindPath = "contacts/kind";
constexpr const char* kContactObjectPath = "contacts/object";
constexpr const char* kContactMaterialPath = "contacts/material";

// Names of the contact kind codes 0, 1, 2, as the `names` attribute of /contacts/kind lists them.
constexpr std::array<const char*, 4> kContactKindNames = {"impact", "bounce", "press", "brush"};
constexpr const char* kContactKindNamesAttr = "impact,bounce,press,brush";

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
  h5::Handle variation;   // only in a randomized dataset
  h5::Handle provenance;  // only in a recorded dataset

  // (handle, path) of every per-sample column (N rows), for checks that apply to all of them.
  std::vector<std::pair<hid_t, std::string>> All() const {
    std::vector<std::pair<hid_t, std::string>> all = {{audio.get(), kAudioPath},
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

}  // namespace sonicboom::internal::dataset
