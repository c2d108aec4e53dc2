// Config serialization and validation, and the localization metrics (no libtorch here).

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "internal/uncertainty.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {
namespace {

const std::vector<std::string> kModalities = {"audio", "gcc", "proprio"};

// Bounds of an integer that must be at least 1.
Bounds AtLeastOne() {
  return Bounds::Closed(1.0, std::numeric_limits<double>::infinity());
}

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
  a->Visit("audio_encoder", &audio_encoder);
  a->Visit("width", &width, AtLeastOne());
  a->Visit("blocks", &blocks, AtLeastOne());
  a->Visit("heads", &heads, AtLeastOne());
  a->Visit("dropout", &dropout, Bounds{0.0, 1.0, false, true});
  a->Visit("modalities", &modalities);
  a->Visit("crop_frames", &crop_frames, AtLeastOne());
  a->Visit("gcc_encoder", &gcc_encoder);
  a->Visit("arrival_picks", &arrival_picks);
  a->Visit("turn_average", &turn_average);
  a->Visit("mirror_average", &mirror_average);
}

void ModelConfig::Validate() const {
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
      Reject(
          "model.modalities", fmt::format("[{}]", fmt::join(modalities, ", ")),
          fmt::format("unknown modality '{}' (choose from {})", m, fmt::join(kModalities, ", ")));
    }
    if (!seen.insert(m).second) {
      Reject("model.modalities", fmt::format("[{}]", fmt::join(modalities, ", ")),
             fmt::format("modality '{}' is listed twice", m));
    }
  }
  RequireAtLeast("model.crop_frames", crop_frames, 1);
  // the picks are read off the waveform the audio features carry
  if (arrival_picks != ArrivalPicks::kNone && !seen.contains("audio")) {
    Reject("model.arrival_picks", std::string(NameOf(arrival_picks)),
           fmt::format("needs audio in model.modalities (got [{}])", fmt::join(modalities, ", ")));
  }
  // a turned strike moves its audio; a GCC pair or an arm pose would have to turn too
  if (turn_average && modalities != std::vector<std::string>{"audio"}) {
    Reject("model.turn_average", "true",
           fmt::format("needs model.modalities = [audio] (got [{}])", fmt::join(modalities, ", ")));
  }
  // the mirror images are taken of each turn
  if (mirror_average && !turn_average) {
    Reject("model.mirror_average", "true", "needs model.turn_average = true");
  }
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
  a->Visit("uncertainty_weight", &uncertainty_weight, Bounds::NonNegative());
  a->Visit("augment", &augment);
  a->Visit("time_shift_frames", &time_shift_frames, Bounds::NonNegative());
  a->Visit("time_mask_frames", &time_mask_frames, Bounds::NonNegative());
  a->Visit("freq_mask_bands", &freq_mask_bands, Bounds::NonNegative());
  a->Visit("polarity_flip", &polarity_flip);
  a->Visit("time_stretch", &time_stretch, Bounds{0.0, 0.5, false, false});
  a->Visit("rotate_rings", &rotate_rings);
  a->Visit("mirror_rings", &mirror_rings);
  a->Visit("normalize", &normalize);
  a->Visit("keep_best", &keep_best);
  a->Visit("ensemble_members", &ensemble_members, AtLeastOne());
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
  RequireIn("train.uncertainty_weight", uncertainty_weight, Bounds::NonNegative());
  RequireAtLeast("train.time_shift_frames", time_shift_frames, 0);
  RequireAtLeast("train.time_mask_frames", time_mask_frames, 0);
  RequireAtLeast("train.freq_mask_bands", freq_mask_bands, 0);
  RequireIn("train.time_stretch", time_stretch, Bounds{0.0, 0.5, false, false});
  RequireAtLeast("train.ensemble_members", ensemble_members, 1);
  RequireAtLeast("train.threads", threads, 0);
}

double SurfaceErrorCm(const Prediction& p, double z_m, double theta_rad, double surface_radius_m) {
  // Surface points (r cos, r sin, z) in metres; the distance is reported in cm.
  const double dx = surface_radius_m * (std::cos(p.theta_rad) - std::cos(theta_rad));
  const double dy = surface_radius_m * (std::sin(p.theta_rad) - std::sin(theta_rad));
  const double dz = p.z_m - z_m;
  return 100.0 * std::sqrt(dx * dx + dy * dy + dz * dz);
}

Metrics ComputeMetrics(const std::vector<Prediction>& predictions, const FeatureSet& truth,
                       double surface_radius_m) {
  if (static_cast<int64_t>(predictions.size()) != truth.size() ||
      truth.theta_rad.size() != truth.z_m.size()) {
    throw SchemaError(
        fmt::format("ComputeMetrics: {} predictions for {} heights and {} angles of ground truth",
                    predictions.size(), truth.z_m.size(), truth.theta_rad.size()));
  }
  // The published code's cylinder radius (metres), combined with heights in cm.
  constexpr double kReferenceRadius = 0.06;
  double sum_med = 0.0, sum_dz = 0.0, sum_dtheta = 0.0, sum_reference = 0.0;
  int64_t n = 0;
  // Predictive distribution: interval hits and log-likelihoods, while every record has one.
  const double z_half_50 = GaussianIntervalHalfWidth(0.5);
  const double z_half_90 = GaussianIntervalHalfWidth(0.9);
  bool uncertain = true;
  int64_t z_in_50 = 0, z_in_90 = 0, theta_in_50 = 0, theta_in_90 = 0;
  double sum_nll = 0.0;
  for (size_t i = 0; i < predictions.size(); ++i) {
    const double z_true = truth.z_m[i], theta_true = truth.theta_rad[i];
    if (std::isnan(z_true) || std::isnan(theta_true)) continue;
    const double z_pred = predictions[i].z_m, theta_pred = predictions[i].theta_rad;
    const double dz = z_pred - z_true;
    sum_med += SurfaceErrorCm(predictions[i], z_true, theta_true, surface_radius_m);
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
    uncertain = uncertain && predictions[i].has_uncertainty();
    if (uncertain) {
      const double z_std = predictions[i].z_std_m, kappa = predictions[i].theta_kappa;
      const double dtheta =
          std::abs(std::remainder(theta_pred - theta_true, 2.0 * std::numbers::pi));
      z_in_50 += std::abs(dz) <= z_half_50 * z_std;
      z_in_90 += std::abs(dz) <= z_half_90 * z_std;
      // inside the central interval of probability p <=> its own central probability <= p
      const double inside = VonMisesCentralProbability(kappa, dtheta);
      theta_in_50 += inside <= 0.5;
      theta_in_90 += inside <= 0.9;
      // z in cm, theta in rad
      sum_nll +=
          internal::GaussianNll(100.0 * dz, 100.0 * z_std) + internal::VonMisesNll(dtheta, kappa);
    }
  }
  Metrics metrics;
  metrics.n = n;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  metrics.med_cm = n > 0 ? sum_med / n : nan;
  metrics.height_err_cm = n > 0 ? sum_dz / n : nan;
  metrics.angle_err_deg = n > 0 ? sum_dtheta / n : nan;
  metrics.reference_med_cm = n > 0 ? sum_reference / n : nan;
  if (n > 0 && uncertain) {
    metrics.z_coverage_50 = double(z_in_50) / n;
    metrics.z_coverage_90 = double(z_in_90) / n;
    metrics.theta_coverage_50 = double(theta_in_50) / n;
    metrics.theta_coverage_90 = double(theta_in_90) / n;
    metrics.nll = sum_nll / n;
  }
  return metrics;
}

int64_t CentreCropStart(int64_t frames, int64_t crop_frames) {
  return frames / 2 - crop_frames / 2;
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
  shapes.frame_hop_samples = frame_hop_samples;
  return shapes;
}

namespace {

// an array of `rows` rows of row_size values, or empty (an unused modality)
void CheckRows(const char* what, const char* name, size_t values, int64_t rows, int64_t row_size) {
  if (values != 0 && static_cast<int64_t>(values) != rows * row_size) {
    throw SchemaError(fmt::format("FeatureSet::{}: {} holds {} values, expected {} x {}", what,
                                  name, values, rows, row_size));
  }
}

}  // namespace

void FeatureSet::KeepRows(const std::vector<int64_t>& ascending_rows) {
  const int64_t n = static_cast<int64_t>(ascending_rows.size());
  for (int64_t i = 0; i < n; ++i) {
    SONICBOOM_DEMAND(ascending_rows[i] >= 0 && ascending_rows[i] < size());
    SONICBOOM_DEMAND(i == 0 || ascending_rows[i] > ascending_rows[i - 1]);
  }
  // row i moves from ascending_rows[i] >= i: forward copies never overwrite a row still to move
  auto keep = [&](const char* name, auto* values, int64_t row_size) {
    CheckRows("KeepRows", name, values->size(), size(), row_size);
    if (values->empty()) return;
    for (int64_t i = 0; i < n; ++i) {
      if (ascending_rows[i] == i) continue;
      std::copy_n(values->begin() + ascending_rows[i] * row_size, row_size,
                  values->begin() + i * row_size);
    }
    values->resize(n * row_size);
  };
  keep("mel", &mel, channels * mels * frames);
  keep("gcc", &gcc, gcc_pairs * gcc_lags);
  keep("proprio", &proprio, proprio_rows * proprio_features);
  keep("theta_rad", &theta_rad, 1);
  keep("z_m", &z_m, 1);  // last: size() reads it
}

FeatureSet FeatureSet::SelectRows(const std::vector<int64_t>& rows) const {
  // copy each chosen row of every array; an empty array (an unused modality) stays empty
  FeatureSet out = ShapesOnly();
  const int64_t n = static_cast<int64_t>(rows.size());
  auto select = [&](const char* name, const std::vector<float>& from, int64_t row_size,
                    std::vector<float>* to) {
    CheckRows("SelectRows", name, from.size(), size(), row_size);
    if (from.empty()) return;
    to->resize(n * row_size);
    for (int64_t i = 0; i < n; ++i) {
      std::copy_n(from.begin() + rows[i] * row_size, row_size, to->begin() + i * row_size);
    }
  };
  for (int64_t r : rows) SONICBOOM_DEMAND(r >= 0 && r < size());
  select("mel", mel, channels * mels * frames, &out.mel);
  select("gcc", gcc, gcc_pairs * gcc_lags, &out.gcc);
  select("proprio", proprio, proprio_rows * proprio_features, &out.proprio);
  out.z_m.resize(n);
  out.theta_rad.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    out.z_m[i] = z_m[rows[i]];
    out.theta_rad[i] = theta_rad[rows[i]];
  }
  return out;
}

}  // namespace sonicboom::learning
