// Config serialization and validation, and the localization metrics (no libtorch here).

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

const std::vector<std::string> kAudioEncoders = {"compact", "resnet18", "resnet50"};
const std::vector<std::string> kModalities = {"audio", "gcc", "proprio"};

// Bounds of an integer that must be at least 1.
Bounds AtLeastOne() { return Bounds::Closed(1.0, std::numeric_limits<double>::infinity()); }

[[noreturn]] void Reject(const std::string& key, const std::string& shown, const std::string& why) {
  throw ConfigError(fmt::format("config key '{}' = {}: {}", key, shown, why));
}

// Checks an integer against its lower limit.
void RequireAtLeast(const std::string& key, int64_t value, int64_t lo) {
  if (value < lo) Reject(key, std::to_string(value), fmt::format("must be at least {}", lo));
}

// Checks a real number against its bounds (also rejects NaN).
void RequireIn(const std::string& key, double value, const Bounds& bounds) {
  if (!std::isfinite(value) || !bounds.Contains(value)) {
    Reject(key, fmt::format("{}", value), fmt::format("must lie in {}", bounds.Describe()));
  }
}

}  // namespace

void ModelConfig::Serialize(Archive* a) {
  a->VisitChoice("audio_encoder", &audio_encoder, kAudioEncoders);
  a->Visit("width", &width, AtLeastOne());
  a->Visit("blocks", &blocks, AtLeastOne());
  a->Visit("heads", &heads, AtLeastOne());
  a->Visit("dropout", &dropout, Bounds{0.0, 1.0, false, true});
  a->Visit("modalities", &modalities);
  a->Visit("crop_frames", &crop_frames, AtLeastOne());
}

void ModelConfig::Validate() const {
  if (std::find(kAudioEncoders.begin(), kAudioEncoders.end(), audio_encoder) ==
      kAudioEncoders.end()) {
    Reject("model.audio_encoder", "'" + audio_encoder + "'",
           fmt::format("must be one of {}", fmt::join(kAudioEncoders, ", ")));
  }
  RequireAtLeast("model.width", width, 1);
  RequireAtLeast("model.blocks", blocks, 1);
  RequireAtLeast("model.heads", heads, 1);
  if (width % heads != 0) {
    Reject("model.heads", std::to_string(heads),
           fmt::format("must divide model.width = {}", width));
  }
  RequireIn("model.dropout", dropout, Bounds{0.0, 1.0, false, true});
  // Modalities: a non-empty set of known names.
  if (modalities.empty()) {
    Reject("model.modalities", "[]",
           fmt::format("must name at least one of {}", fmt::join(kModalities, ", ")));
  }
  std::set<std::string> seen;
  for (const std::string& m : modalities) {
    if (std::find(kModalities.begin(), kModalities.end(), m) == kModalities.end()) {
      Reject("model.modalities", fmt::format("[{}]", fmt::join(modalities, ", ")),
             fmt::format("unknown modality '{}' (choose from {})", m,
                         fmt::join(kModalities, ", ")));
    }
    if (!seen.insert(m).second) {
      Reject("model.modalities", fmt::format("[{}]", fmt::join(modalities, ", ")),
             fmt::format("modality '{}' is listed twice", m));
    }
  }
  RequireAtLeast("model.crop_frames", crop_frames, 1);
}

void TrainConfig::Serialize(Archive* a) {
  a->Visit("epochs", &epochs, AtLeastOne());
  a->Visit("batch_size", &batch_size, AtLeastOne());
  a->Visit("learning_rate", &learning_rate, Bounds::Positive());
  a->Visit("lr_step_epochs", &lr_step_epochs, AtLeastOne());
  a->Visit("lr_gamma", &lr_gamma, Bounds::Positive());
  a->Visit("val_fraction", &val_fraction, Bounds{0.0, 1.0, false, true});
  a->Visit("loss_weight_z", &loss_weight_z, Bounds::NonNegative());
  a->Visit("loss_weight_cos", &loss_weight_cos, Bounds::NonNegative());
  a->Visit("loss_weight_sin", &loss_weight_sin, Bounds::NonNegative());
  a->Visit("augment", &augment);
  a->Visit("time_shift_frames", &time_shift_frames, Bounds::NonNegative());
  a->Visit("time_mask_frames", &time_mask_frames, Bounds::NonNegative());
  a->Visit("freq_mask_bands", &freq_mask_bands, Bounds::NonNegative());
  a->Visit("normalize", &normalize);
  a->Visit("threads", &threads, Bounds::NonNegative());
}

void TrainConfig::Validate() const {
  RequireAtLeast("train.epochs", epochs, 1);
  RequireAtLeast("train.batch_size", batch_size, 1);
  RequireIn("train.learning_rate", learning_rate, Bounds::Positive());
  RequireAtLeast("train.lr_step_epochs", lr_step_epochs, 1);
  RequireIn("train.lr_gamma", lr_gamma, Bounds::Positive());
  RequireIn("train.val_fraction", val_fraction, Bounds{0.0, 1.0, false, true});
  RequireIn("train.loss_weight_z", loss_weight_z, Bounds::NonNegative());
  RequireIn("train.loss_weight_cos", loss_weight_cos, Bounds::NonNegative());
  RequireIn("train.loss_weight_sin", loss_weight_sin, Bounds::NonNegative());
  if (loss_weight_z + loss_weight_cos + loss_weight_sin <= 0.0) {
    Reject("train.loss_weight_z", fmt::format("{}", loss_weight_z),
           "at least one of train.loss_weight_z/cos/sin must be positive");
  }
  RequireAtLeast("train.time_shift_frames", time_shift_frames, 0);
  RequireAtLeast("train.time_mask_frames", time_mask_frames, 0);
  RequireAtLeast("train.freq_mask_bands", freq_mask_bands, 0);
  RequireAtLeast("train.threads", threads, 0);
}

Metrics ComputeMetrics(const std::vector<Prediction>& predictions, const FeatureSet& truth,
                       double surface_radius_m) {
  if (static_cast<int64_t>(predictions.size()) != truth.size() ||
      truth.theta_rad.size() != truth.z_m.size()) {
    throw SchemaError(fmt::format(
        "ComputeMetrics: {} predictions for {} heights and {} angles of ground truth",
        predictions.size(), truth.z_m.size(), truth.theta_rad.size()));
  }
  // The published code's cylinder radius (metres), combined with heights in cm.
  constexpr double kReferenceRadius = 0.06;
  double sum_med = 0.0, sum_dz = 0.0, sum_dtheta = 0.0, sum_reference = 0.0;
  int64_t n = 0;
  for (size_t i = 0; i < predictions.size(); ++i) {
    const double z_true = truth.z_m[i], theta_true = truth.theta_rad[i];
    if (std::isnan(z_true) || std::isnan(theta_true)) continue;
    const double z_pred = predictions[i].z_m, theta_pred = predictions[i].theta_rad;
    // Surface points (r cos, r sin, z) in metres; the distance is reported in cm.
    const double dx = surface_radius_m * (std::cos(theta_pred) - std::cos(theta_true));
    const double dy = surface_radius_m * (std::sin(theta_pred) - std::sin(theta_true));
    const double dz = z_pred - z_true;
    sum_med += 100.0 * std::sqrt(dx * dx + dy * dy + dz * dz);
    sum_dz += 100.0 * std::abs(dz);
    // Angle difference wrapped into [-pi, pi], so errors across +-pi count the short way.
    sum_dtheta += std::abs(std::remainder(theta_pred - theta_true, 2.0 * std::numbers::pi)) *
                  180.0 / std::numbers::pi;
    // Reference (mixed-unit) variant: height in cm, radius in m.
    const double rx = kReferenceRadius * (std::cos(theta_pred) - std::cos(theta_true));
    const double ry = kReferenceRadius * (std::sin(theta_pred) - std::sin(theta_true));
    const double rz = 100.0 * dz;
    sum_reference += std::sqrt(rx * rx + ry * ry + rz * rz);
    ++n;
  }
  Metrics metrics;
  metrics.n = n;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  metrics.med_cm = n > 0 ? sum_med / n : nan;
  metrics.height_err_cm = n > 0 ? sum_dz / n : nan;
  metrics.angle_err_deg = n > 0 ? sum_dtheta / n : nan;
  metrics.reference_med_cm = n > 0 ? sum_reference / n : nan;
  return metrics;
}

FeatureSet FeatureSet::ShapesOnly() const {
  FeatureSet shapes;
  shapes.channels = channels;
  shapes.mels = mels;
  shapes.frames = frames;
  shapes.gcc_pairs = gcc_pairs;
  shapes.gcc_lags = gcc_lags;
  shapes.proprio_rows = proprio_rows;
  shapes.proprio_features = proprio_features;
  return shapes;
}

FeatureSet FeatureSet::SelectRows(const std::vector<int64_t>& rows) const {
  // copy each chosen row of every array
  FeatureSet out = ShapesOnly();
  const int64_t n = static_cast<int64_t>(rows.size());
  const int64_t mel_size = channels * mels * frames;
  const int64_t gcc_size = gcc_pairs * gcc_lags;
  const int64_t prop_size = proprio_rows * proprio_features;
  out.mel.resize(n * mel_size);
  out.gcc.resize(n * gcc_size);
  out.proprio.resize(n * prop_size);
  out.z_m.resize(n);
  out.theta_rad.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    const int64_t r = rows[i];
    SONICBOOM_DEMAND(r >= 0 && r < size());
    std::copy_n(mel.begin() + r * mel_size, mel_size, out.mel.begin() + i * mel_size);
    std::copy_n(gcc.begin() + r * gcc_size, gcc_size, out.gcc.begin() + i * gcc_size);
    std::copy_n(proprio.begin() + r * prop_size, prop_size, out.proprio.begin() + i * prop_size);
    out.z_m[i] = z_m[r];
    out.theta_rad[i] = theta_rad[r];
  }
  return out;
}

}  // namespace sonicboom::learning
