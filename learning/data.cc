// Feature checks, statistics, batch assembly with augmentation, batched prediction and the
// run-directory files.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <torch/serialize.h>
#include <torch/version.h>

#include "internal/data.h"
#include "internal/json_archive.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::learning::internal {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Throws SchemaError when a shape field is not positive.
void RequirePositive(const std::string& what, const char* field, int64_t value) {
  if (value <= 0) {
    throw SchemaError(fmt::format("{}: {} = {} must be positive", what, field, value));
  }
}

// Throws SchemaError when an array does not hold `expected` values.
void RequireSize(const std::string& what, const char* array, size_t size, int64_t expected,
                 const std::string& shape) {
  if (static_cast<int64_t>(size) != expected) {
    throw SchemaError(fmt::format("{}: {} holds {} values, expected {} = {}", what, array, size,
                                  expected, shape));
  }
}

void RequireEqual(const std::string& what, const char* field, int64_t expected, int64_t actual) {
  if (expected != actual) {
    throw SchemaError(
        fmt::format("{}: {} = {}, but the model expects {}", what, field, actual, expected));
  }
}

}  // namespace

void CheckFeatureSet(const FeatureSet& f, const ModalitySet& use, const std::string& what) {
  const int64_t n = f.size();
  if (f.theta_rad.size() != f.z_m.size()) {
    throw SchemaError(
        fmt::format("{}: {} heights but {} angles", what, f.z_m.size(), f.theta_rad.size()));
  }
  if (use.audio) {
    RequirePositive(what, "channels", f.channels);
    RequirePositive(what, "mels", f.mels);
    RequirePositive(what, "frames", f.frames);
    RequireSize(what, "mel", f.mel.size(), n * f.channels * f.mels * f.frames,
                fmt::format("{} x {} x {} x {}", n, f.channels, f.mels, f.frames));
  }
  if (use.gcc) {
    RequirePositive(what, "gcc_pairs", f.gcc_pairs);
    RequirePositive(what, "gcc_lags", f.gcc_lags);
    RequireSize(what, "gcc", f.gcc.size(), n * f.gcc_pairs * f.gcc_lags,
                fmt::format("{} x {} x {}", n, f.gcc_pairs, f.gcc_lags));
  }
  if (use.proprio) {
    RequirePositive(what, "proprio_rows", f.proprio_rows);
    RequirePositive(what, "proprio_features", f.proprio_features);
    RequireSize(what, "proprio", f.proprio.size(), n * f.proprio_rows * f.proprio_features,
                fmt::format("{} x {} x {}", n, f.proprio_rows, f.proprio_features));
  }
}

void CheckSameShapes(const FeatureSet& expected, const FeatureSet& actual, const ModalitySet& use,
                     const std::string& what) {
  if (use.audio) {
    RequireEqual(what, "channels", expected.channels, actual.channels);
    RequireEqual(what, "mels", expected.mels, actual.mels);
    RequireEqual(what, "frames", expected.frames, actual.frames);
  }
  if (use.gcc) {
    RequireEqual(what, "gcc_pairs", expected.gcc_pairs, actual.gcc_pairs);
    RequireEqual(what, "gcc_lags", expected.gcc_lags, actual.gcc_lags);
  }
  if (use.proprio) {
    RequireEqual(what, "proprio_rows", expected.proprio_rows, actual.proprio_rows);
    RequireEqual(what, "proprio_features", expected.proprio_features, actual.proprio_features);
  }
}

std::string ShapesText(const FeatureSet& f, const ModalitySet& use) {
  std::vector<std::string> parts;
  if (use.audio) parts.push_back(fmt::format("audio {} x {} x {}", f.channels, f.mels, f.frames));
  if (use.gcc) parts.push_back(fmt::format("GCC {} x {}", f.gcc_pairs, f.gcc_lags));
  if (use.proprio) {
    parts.push_back(fmt::format("proprio {} x {}", f.proprio_rows, f.proprio_features));
  }
  return fmt::format("{}", fmt::join(parts, ", "));
}

MelStats ComputeMelStats(const FeatureSet& f, const std::vector<int64_t>& records) {
  const int64_t c_count = f.channels, plane = f.mels * f.frames;
  MelStats stats{std::vector<float>(c_count, 0.0f), std::vector<float>(c_count, 1.0f)};
  // One channel per task; two passes (mean, then squared deviations) in double.
  tbb::parallel_for(int64_t{0}, c_count, [&](int64_t c) {
    const double count = static_cast<double>(records.size()) * static_cast<double>(plane);
    if (count == 0.0) return;
    double sum = 0.0;
    for (int64_t r : records) {
      const float* x = f.mel.data() + (r * c_count + c) * plane;
      for (int64_t i = 0; i < plane; ++i) sum += x[i];
    }
    const double mean = sum / count;
    double squares = 0.0;
    for (int64_t r : records) {
      const float* x = f.mel.data() + (r * c_count + c) * plane;
      for (int64_t i = 0; i < plane; ++i) squares += (x[i] - mean) * (x[i] - mean);
    }
    stats.mean[c] = static_cast<float>(mean);
    stats.std[c] = static_cast<float>(std::max(std::sqrt(squares / count), 1e-12));
  });
  return stats;
}

Augmentation DrawAugmentation(const TrainConfig& config, int64_t crop_frames, int64_t mels,
                              uint64_t seed, int64_t epoch, int64_t record) {
  Rng rng(SampleSeed(SampleSeed(seed, static_cast<uint64_t>(epoch)), static_cast<uint64_t>(record)),
          Stream::kTrain);
  Augmentation a;
  // Shift uniform in [-time_shift_frames, +time_shift_frames].
  const int64_t s = config.time_shift_frames;
  a.shift_frames = static_cast<int64_t>(rng.UniformInt(static_cast<uint64_t>(2 * s + 1))) - s;
  // One time mask and one frequency mask, widths uniform in [0, limit].
  a.time_mask_width = std::min<int64_t>(
      static_cast<int64_t>(rng.UniformInt(static_cast<uint64_t>(config.time_mask_frames + 1))),
      crop_frames);
  a.time_mask_start = static_cast<int64_t>(
      rng.UniformInt(static_cast<uint64_t>(crop_frames - a.time_mask_width + 1)));
  a.freq_mask_width = std::min<int64_t>(
      static_cast<int64_t>(rng.UniformInt(static_cast<uint64_t>(config.freq_mask_bands + 1))),
      mels);
  a.freq_mask_start =
      static_cast<int64_t>(rng.UniformInt(static_cast<uint64_t>(mels - a.freq_mask_width + 1)));
  // polarity last: the draws above stay what they were without it
  if (config.polarity_flip && rng.UniformInt(2) == 1) a.sign = -1.0f;
  if (config.time_stretch > 0.0) {
    const double ln = std::log1p(config.time_stretch);
    a.stretch = std::exp(ln * (2.0 * rng.Uniform() - 1.0));
  }
  if (config.rotate_rings) a.rotation = static_cast<int64_t>(rng.UniformInt(kRingDiscs));
  // mirror last: the draws above stay what they were without it
  if (config.mirror_rings) a.mirror = rng.UniformInt(2) == 1;
  return a;
}

double SymmetricTheta(double theta_rad, const Augmentation& a) {
  const double turned = theta_rad + 2.0 * kPi * static_cast<double>(a.rotation) / kRingDiscs;
  return a.mirror ? -turned : turned;
}

double UnturnedTheta(double seen_rad, const Augmentation& a) {
  const double turned = a.mirror ? -seen_rad : seen_rad;
  return std::remainder(turned - 2.0 * kPi * static_cast<double>(a.rotation) / kRingDiscs,
                        2.0 * kPi);
}

int64_t ProprioShiftRows(int64_t shift_frames, int64_t frame_hop_samples) {
  return std::llround(static_cast<double>(shift_frames * frame_hop_samples) * kProprioRateHz /
                      kSampleRateHz);
}

namespace {

// One row of a crop (crop samples from `start` of a src row of `frames`) read through a time
// stretch about the crop's centre: linear interpolation between source samples, the fill
// outside the source and under the masks.
void StretchedRow(const float* src, int64_t frames, int64_t start, int64_t crop,
                  const Augmentation& a, float fill, bool band_masked, float* row) {
  const double centre = static_cast<double>(start) + 0.5 * static_cast<double>(crop - 1);
  for (int64_t t = 0; t < crop; ++t) {
    const double x = centre + (static_cast<double>(start + t) - centre) / a.stretch;
    const bool masked =
        band_masked || (t >= a.time_mask_start && t < a.time_mask_start + a.time_mask_width);
    const double lo = std::floor(x);
    const int64_t k = static_cast<int64_t>(lo);
    if (masked || k < 0 || k + 1 >= frames) {
      row[t] = fill;
      continue;
    }
    const double w = x - lo;
    row[t] = a.sign * static_cast<float>((1.0 - w) * src[k] + w * src[k + 1]);
  }
}

}  // namespace

Batch AssembleBatch(const FeatureSet& f, const std::vector<int64_t>& records,
                    const ModalitySet& use, int64_t crop_frames,
                    const std::vector<Augmentation>* augment, const std::vector<float>& mel_fill) {
  const int64_t b_count = static_cast<int64_t>(records.size());
  Batch batch;
  if (use.audio) batch.mel = torch::empty({b_count, f.channels, f.mels, crop_frames});
  if (use.gcc) batch.gcc = torch::empty({b_count, f.gcc_pairs, f.gcc_lags});
  if (use.proprio) batch.proprio = torch::empty({b_count, f.proprio_rows, f.proprio_features});
  const int64_t centre_start = CentreCropStart(f.frames, crop_frames);
  // Each record fills its own slice of the batch tensors.
  tbb::parallel_for(int64_t{0}, b_count, [&](int64_t b) {
    const int64_t r = records[b];
    const Augmentation a = augment ? (*augment)[b] : Augmentation{};
    if (use.audio) {
      // (C, mels, crop) slice: shifted crop, out-of-range frames and masks set to the fill.
      float* dst = batch.mel.data_ptr<float>() + b * f.channels * f.mels * crop_frames;
      const int64_t start = centre_start + a.shift_frames;
      for (int64_t c = 0; c < f.channels; ++c) {
        // the disc this channel reads once the record is turned (train.rotate_rings), then
        // mirrored (train.mirror_rings): disc (-p - rotation) mod 3 of its ring
        const int64_t ring = c / kRingDiscs * kRingDiscs;
        const int64_t p = a.mirror ? (kRingDiscs - (c - ring)) % kRingDiscs : c - ring;
        const int64_t read = ring + (p - a.rotation + kRingDiscs) % kRingDiscs;
        for (int64_t m = 0; m < f.mels; ++m) {
          const float* src = f.mel.data() + ((r * f.channels + read) * f.mels + m) * f.frames;
          float* row = dst + (c * f.mels + m) * crop_frames;
          const bool band_masked =
              m >= a.freq_mask_start && m < a.freq_mask_start + a.freq_mask_width;
          if (a.stretch != 1.0) {
            StretchedRow(src, f.frames, start, crop_frames, a, mel_fill[c], band_masked, row);
            continue;
          }
          for (int64_t t = 0; t < crop_frames; ++t) {
            const int64_t src_t = start + t;
            const bool masked = band_masked || (t >= a.time_mask_start &&
                                                t < a.time_mask_start + a.time_mask_width);
            row[t] = (masked || src_t < 0 || src_t >= f.frames) ? mel_fill[c] : a.sign * src[src_t];
          }
        }
      }
    }
    if (use.gcc) {
      // (pairs, lags) slice: lags are not time, so never shifted.
      const int64_t size = f.gcc_pairs * f.gcc_lags;
      std::copy_n(f.gcc.data() + r * size, size, batch.gcc.data_ptr<float>() + b * size);
    }
    if (use.proprio) {
      // (rows, features) slice, shifted by the rows matching the mel shift, zero fill.
      const int64_t shift = ProprioShiftRows(a.shift_frames, f.frame_hop_samples);
      const int64_t size = f.proprio_rows * f.proprio_features;
      const float* src = f.proprio.data() + r * size;
      float* dst = batch.proprio.data_ptr<float>() + b * size;
      for (int64_t row = 0; row < f.proprio_rows; ++row) {
        const int64_t src_row = row + shift;
        float* out = dst + row * f.proprio_features;
        if (src_row < 0 || src_row >= f.proprio_rows) {
          std::fill_n(out, f.proprio_features, 0.0f);
        } else {
          std::copy_n(src + src_row * f.proprio_features, f.proprio_features, out);
        }
      }
    }
  });
  return batch;
}

torch::Tensor AssembleTargets(const FeatureSet& f, const std::vector<int64_t>& records,
                              const std::vector<Augmentation>* augment) {
  // (B, 3): z in cm, cos theta, sin theta (theta turned with the record)
  torch::Tensor targets = torch::empty({static_cast<int64_t>(records.size()), 3});
  auto acc = targets.accessor<float, 2>();
  for (size_t b = 0; b < records.size(); ++b) {
    const int64_t r = records[b];
    const double theta =
        augment != nullptr ? SymmetricTheta(f.theta_rad[r], (*augment)[b]) : f.theta_rad[r];
    acc[b][0] = static_cast<float>(f.z_m[r] * 100.0);
    acc[b][1] = static_cast<float>(std::cos(theta));
    acc[b][2] = static_cast<float>(std::sin(theta));
  }
  return targets;
}

std::vector<Prediction> PredictAll(NetworkImpl& network, const FeatureSet& f, int64_t crop_frames,
                                   const Augmentation& symmetry) {
  network.eval();
  // inference mode: no autograd record and no version counters on the tensors made here
  c10::InferenceMode inference;
  const std::vector<float> fill = network.MelMean();
  std::vector<Prediction> predictions(f.size());
  for (int64_t first = 0; first < f.size(); first += kPredictBatch) {
    const int64_t count = std::min(kPredictBatch, f.size() - first);
    std::vector<int64_t> records(count);
    for (int64_t i = 0; i < count; ++i) records[i] = first + i;
    // every record turned and mirrored alike (none: as is)
    Augmentation turned;
    turned.rotation = symmetry.rotation;
    turned.mirror = symmetry.mirror;
    const bool moved = turned.rotation != 0 || turned.mirror;
    const std::vector<Augmentation> augment(count, turned);
    // (B, 3) = (z_cm, cos, sin), then (log sigma_z_cm, log kappa) with the uncertainty head
    torch::Tensor out = network
                            .forward(AssembleBatch(f, records, network.modalities(), crop_frames,
                                                   moved ? &augment : nullptr, fill))
                            .contiguous();
    auto acc = out.accessor<float, 2>();
    const bool uncertain = out.size(1) == 5;
    for (int64_t i = 0; i < count; ++i) {
      Prediction& p = predictions[first + i];
      p.z_m = acc[i][0] / 100.0;
      p.theta_rad = std::atan2(double{acc[i][2]}, double{acc[i][1]});
      if (moved) p.theta_rad = UnturnedTheta(p.theta_rad, turned);
      if (uncertain) {
        p.z_std_m = std::exp(double{acc[i][3]}) / 100.0;
        p.theta_kappa = std::exp(double{acc[i][4]});
      }
    }
  }
  return predictions;
}

void SaveModuleAtomically(torch::nn::Module& module, const std::string& path) {
  torch::serialize::OutputArchive archive;
  module.save(archive);
  WriteArchiveAtomically(archive, path);
}

void WriteArchiveAtomically(torch::serialize::OutputArchive& archive, const std::string& path) {
  // serialized in memory first, then written by the checked writer: torch's file writer throws
  // from its destructor when the disk fills, which ends the process
  std::string bytes;
  try {
    archive.save_to([&bytes](const void* data, size_t size) {
      bytes.append(static_cast<const char*>(data), size);
      return size;
    });
  } catch (const c10::Error& e) {
    throw IoError(fmt::format("{}: cannot serialize: {}", path, e.what_without_backtrace()));
  }
  WriteTextAtomic(path, bytes);
}

void LoadModuleChecked(torch::nn::Module& module, torch::serialize::InputArchive& archive,
                       const std::string& origin) {
  // Shapes as built; loading replaces tensors wholesale, so compare afterwards.
  std::vector<std::pair<std::string, std::vector<int64_t>>> built;
  for (const auto& item : module.named_parameters()) {
    built.emplace_back(item.key(), item.value().sizes().vec());
  }
  for (const auto& item : module.named_buffers()) {
    built.emplace_back(item.key(), item.value().sizes().vec());
  }
  try {
    module.load(archive);
  } catch (const c10::Error& e) {
    throw SchemaError(fmt::format("{}: unreadable or written for another model: {}", origin,
                                  e.what_without_backtrace()));
  }
  std::map<std::string, std::vector<int64_t>> loaded;
  for (const auto& item : module.named_parameters()) {
    loaded[item.key()] = item.value().sizes().vec();
  }
  for (const auto& item : module.named_buffers()) loaded[item.key()] = item.value().sizes().vec();
  for (const auto& [name, sizes] : built) {
    if (loaded[name] != sizes) {
      throw SchemaError(fmt::format("{}: tensor '{}' has shape [{}], the model expects [{}]",
                                    origin, name, fmt::join(loaded[name], ", "),
                                    fmt::join(sizes, ", ")));
    }
  }
}

json ReadJsonFile(const std::string& path) {
  if (!fs::is_regular_file(path)) throw IoError(fmt::format("{}: file not found", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot open", path));
  std::stringstream text;
  text << in.rdbuf();
  try {
    return json::parse(text.str());
  } catch (const json::exception& e) {
    throw SchemaError(fmt::format("{}: malformed JSON: {}", path, e.what()));
  }
}

json ShapesToJson(const FeatureSet& f) {
  return json{{"channels", f.channels},
              {"mels", f.mels},
              {"frames", f.frames},
              {"gcc_pairs", f.gcc_pairs},
              {"gcc_lags", f.gcc_lags},
              {"proprio_rows", f.proprio_rows},
              {"proprio_features", f.proprio_features}};
}

FeatureSet ShapesFromJson(const json& j, const std::string& origin) {
  if (!j.is_object()) throw SchemaError(fmt::format("{}: 'shapes' must be an object", origin));
  FeatureSet f;
  auto read = [&](const char* key, int64_t* value) {
    auto it = j.find(key);
    if (it == j.end() || !it->is_number_integer()) {
      throw SchemaError(fmt::format("{}: 'shapes.{}' is missing or not an integer", origin, key));
    }
    *value = it->get<int64_t>();
  };
  read("channels", &f.channels);
  read("mels", &f.mels);
  read("frames", &f.frames);
  read("gcc_pairs", &f.gcc_pairs);
  read("gcc_lags", &f.gcc_lags);
  read("proprio_rows", &f.proprio_rows);
  read("proprio_features", &f.proprio_features);
  return f;
}

json MetricsToJson(const Metrics& m) {
  auto number = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  return json{{"n", m.n},
              {"med_cm", number(m.med_cm)},
              {"height_err_cm", number(m.height_err_cm)},
              {"angle_err_deg", number(m.angle_err_deg)},
              {"reference_med_cm", number(m.reference_med_cm)},
              {"z_coverage_50", number(m.z_coverage_50)},
              {"z_coverage_90", number(m.z_coverage_90)},
              {"theta_coverage_50", number(m.theta_coverage_50)},
              {"theta_coverage_90", number(m.theta_coverage_90)},
              {"nll", number(m.nll)}};
}

json ModelFileToJson(const ModelFile& file, const TrainConfig& train_config,
                     const Metrics& val_metrics, int64_t epochs_trained) {
  json j{{"format", "sonicboom-model"},
         {"version", 1},
         {"model", ConfigToJson(file.model_config)},
         {"shapes", ShapesToJson(file.shapes)},
         {"surface_radius_m", file.surface_radius_m},
         {"seed", file.seed},
         {"train", ConfigToJson(train_config)},
         {"epochs_trained", epochs_trained},
         {"val_metrics", MetricsToJson(val_metrics)},
         {"software", json{{"name", "sonicboom"}, {"libtorch", TORCH_VERSION}}}};
  if (file.has_calibration) {
    j["uncertainty"] =
        json{{"z_std_scale", file.calibration.z_std_scale},
             {"kappa_scale", file.calibration.kappa_scale},
             {"method", file.calibration_method},
             {"records", file.uncalibrated_val_metrics.n},
             {"uncalibrated_val_metrics", MetricsToJson(file.uncalibrated_val_metrics)}};
  }
  return j;
}

ModelFile ModelFileFromJson(const json& j, const std::string& origin) {
  if (!j.is_object() || j.value("format", std::string()) != "sonicboom-model") {
    throw SchemaError(
        fmt::format("{}: not a SonicBoom model file (format != sonicboom-model)", origin));
  }
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"] != 1) {
    throw SchemaError(fmt::format("{}: unsupported model file version (expected 1)", origin));
  }
  if (!j.contains("model")) throw SchemaError(fmt::format("{}: 'model' is missing", origin));
  if (!j.contains("shapes")) throw SchemaError(fmt::format("{}: 'shapes' is missing", origin));
  ModelFile file;
  // a file written before model.arrival_picks, turn_average or mirror_average existed lacks it
  json model = j["model"];
  if (model.is_object() && !model.contains("arrival_picks")) model["arrival_picks"] = "none";
  if (model.is_object() && !model.contains("turn_average")) model["turn_average"] = false;
  if (model.is_object() && !model.contains("mirror_average")) model["mirror_average"] = false;
  file.model_config = ConfigFromJson<ModelConfig>(model, origin + " (model)");
  try {
    file.model_config.Validate();
  } catch (const ConfigError& e) {
    throw SchemaError(fmt::format("{}: {}", origin, e.what()));
  }
  file.shapes = ShapesFromJson(j["shapes"], origin);
  CheckFeatureSet(file.shapes, SelectedModalities(file.model_config), origin);
  if (!j.contains("surface_radius_m") || !j["surface_radius_m"].is_number() ||
      !(j["surface_radius_m"].get<double>() > 0.0)) {
    throw SchemaError(fmt::format("{}: 'surface_radius_m' must be a positive number", origin));
  }
  file.surface_radius_m = j["surface_radius_m"].get<double>();
  if (!j.contains("seed") || !j["seed"].is_number_unsigned()) {
    throw SchemaError(fmt::format("{}: 'seed' must be a non-negative integer", origin));
  }
  file.seed = j["seed"].get<uint64_t>();
  // Calibration of the predictive distribution; absent in older files (scales stay 1).
  if (j.contains("uncertainty")) {
    file.calibration = CalibrationFromJson(j["uncertainty"], origin);
    file.has_calibration = true;
  }
  return file;
}

UncertaintyCalibration CalibrationFromJson(const json& u, const std::string& origin) {
  auto scale = [&](const char* key) {
    constexpr double lo = UncertaintyCalibration::kMinScale, hi = UncertaintyCalibration::kMaxScale;
    if (!u.is_object() || !u.contains(key) || !u[key].is_number() ||
        !(u[key].get<double>() >= lo && u[key].get<double>() <= hi)) {
      throw SchemaError(fmt::format("{}: 'uncertainty.{}' must be a number in [{:g}, {:g}]",
                                    origin, key, lo, hi));
    }
    return u[key].get<double>();
  };
  return {scale("z_std_scale"), scale("kappa_scale")};
}

}  // namespace sonicboom::learning::internal
