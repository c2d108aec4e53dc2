// `inspect`'s summary of a dataset file: counts, invalid reasons, label and audio ranges, and the
// contacts by kind, object and (z, theta) coverage.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "internal/dataset_file.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

using namespace internal::dataset;  // NOLINT: the schema tables

// Coverage of first contacts in the summary: 5 bins of z over [-h, h] and 6 of theta. h in units
// of 0.1 mm, so that the z edges are exact decimals (the nearest doubles to them).
constexpr int kCoverageHalfLengthTenthMm = 1015;
constexpr int kCoverageZBins = 5;
constexpr int kCoverageThetaBins = 6;
static_assert(kCoverageHalfLengthTenthMm % kCoverageZBins == 0);

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
  return std::min(static_cast<int>(above - edges.begin()) - 1, static_cast<int>(edges.size()) - 2);
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
        std::vector<double> column = ReadColumn<double>(table.scalars[f].get(), H5T_NATIVE_DOUBLE,
                                                        m, path, kScalarContacts[f].path);
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

// An invalid reason with its numbers replaced by '#', so that reasons differing only in a time
// or a depth count together ("penetration # mm ... at t = # s").
std::string ReasonCategory(const std::string& reason) {
  std::string out;
  for (size_t i = 0; i < reason.size();) {
    const bool sign =
        (reason[i] == '-' || reason[i] == '+') && i + 1 < reason.size() &&
        std::isdigit(static_cast<unsigned char>(reason[i + 1])) &&
        (i == 0 || reason[i - 1] == ' ' || reason[i - 1] == '(' || reason[i - 1] == '[');
    if (!sign && !std::isdigit(static_cast<unsigned char>(reason[i]))) {
      out += reason[i++];
      continue;
    }
    // a number: sign, digits, fraction, exponent
    i += sign ? 1 : 0;
    while (i < reason.size() &&
           (std::isdigit(static_cast<unsigned char>(reason[i])) || reason[i] == '.' ||
            reason[i] == 'e' || ((reason[i] == '-' || reason[i] == '+') && reason[i - 1] == 'e'))) {
      ++i;
    }
    out += '#';
  }
  return out;
}

}  // namespace

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
        return ReadColumn<double>(columns.scalar_labels[f].get(), H5T_NATIVE_DOUBLE, n, path, name);
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
      ++invalid_reasons[reasons[i].empty() ? std::string("(no reason)")
                                           : ReasonCategory(reasons[i])];
      continue;
    }
    ++valid_count;
    // ranges over the values known (NaN: not known, e.g. a capture's impulse)
    for (auto [column, value] :
         {std::pair{&valid_z, z[i]}, std::pair{&valid_theta, theta[i]},
          std::pair{&valid_impulse, impulse[i]}, std::pair{&valid_speed, speed[i]}}) {
      if (!std::isnan(value)) column->push_back(value);
    }
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
